/**
 * ORBextractor.cc: ORB-SLAM3's ORBextractor interface over spslam's SuperPoint
 * extractor (C ABI in spslam.h). See ORBextractor.h for the behaviour.
 */

#include "ORBextractor.h"

#include <cmath>
#include <cctype>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <memory>
#include <mutex>
#include <unordered_map>

#include "spslam.h"

namespace ORB_SLAM3
{

const int PATCH_SIZE = 31;
const int HALF_PATCH_SIZE = 15;
const int EDGE_THRESHOLD = 19;
// ORB-SLAM3 never returns a keypoint within EDGE_THRESHOLD - 3 = 16 px of a
// level's border (ComputeKeyPointsOctTree's minBorderX/minBorderY), and
// Frame::ComputeStereoMatches relies on it: its SAD window reads 10 px left
// of a right-image keypoint without a bounds check (and throws otherwise).
const int ORB_SLAM3_MIN_BORDER = EDGE_THRESHOLD - 3;

namespace
{

std::mutex gPathsMutex;
std::string gModelPath;
std::string gOrtLibraryPath;

std::string EnvOrEmpty(const char* name)
{
    const char* value = std::getenv(name);
    return value ? std::string(value) : std::string();
}

std::string Lowercase(std::string text)
{
    for (char& c : text)
        c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return text;
}

// What one ORBextractor owns beyond ORB-SLAM3 v1.0's members (see the header:
// the class keeps v1.0's layout), keyed by the object's address.
struct ExtractorState
{
    SpslamExtractor* extractor = nullptr;
    int descriptorLength = 0;
    bool binaryDescriptors = false;
    std::string lastError;

    ExtractorState() = default;
    ExtractorState(const ExtractorState&) = delete;
    ExtractorState& operator=(const ExtractorState&) = delete;
    ~ExtractorState() { spslam_extractor_destroy(extractor); }
};

std::mutex gStatesMutex;
std::unordered_map<const void*, std::shared_ptr<ExtractorState>> gStates;

// The state of `owner`; an empty one when there is none (never null).
std::shared_ptr<ExtractorState> StateOf(const void* owner)
{
    std::lock_guard<std::mutex> lock(gStatesMutex);
    auto found = gStates.find(owner);
    if (found != gStates.end())
        return found->second;
    static const std::shared_ptr<ExtractorState> empty = std::make_shared<ExtractorState>();
    return empty;
}

// Installs a fresh state for `owner`, replacing (and so destroying) any left
// by an object that lived at the same address without running our destructor.
std::shared_ptr<ExtractorState> ResetState(const void* owner)
{
    auto state = std::make_shared<ExtractorState>();
    std::lock_guard<std::mutex> lock(gStatesMutex);
    gStates[owner] = state;
    return state;
}

void EraseState(const void* owner)
{
    std::shared_ptr<ExtractorState> state;
    {
        std::lock_guard<std::mutex> lock(gStatesMutex);
        auto found = gStates.find(owner);
        if (found == gStates.end())
            return;
        state = std::move(found->second);
        gStates.erase(found);
    }
    // `state` (and the spslam extractor) is released here, outside the lock.
}

std::string LastSpslamError()
{
    const char* message = spslam_last_error();
    return (message && *message) ? std::string(message) : std::string("(no message)");
}

} // namespace

void ORBextractor::SetRuntimePaths(const std::string& modelPath, const std::string& ortLibraryPath)
{
    std::lock_guard<std::mutex> lock(gPathsMutex);
    gModelPath = modelPath;
    gOrtLibraryPath = ortLibraryPath;
}

void ORBextractor::Fail(const std::string& message)
{
    StateOf(this)->lastError = message;
    std::cerr << "[spslam ORBextractor] " << message << std::endl;
}

ORBextractor::ORBextractor(int _nfeatures, float _scaleFactor, int _nlevels,
         int _iniThFAST, int _minThFAST):
    nfeatures(_nfeatures), scaleFactor(_scaleFactor), nlevels(_nlevels),
    iniThFAST(_iniThFAST), minThFAST(_minThFAST)
{
    const std::shared_ptr<ExtractorState> state = ResetState(this);
    // The tables as ORB-SLAM3's constructor computes them; they are replaced
    // by the library's below (identical by construction, checked by the tests).
    const int levels = std::max(nlevels, 1);
    mvScaleFactor.resize(levels);
    mvLevelSigma2.resize(levels);
    mvScaleFactor[0]=1.0f;
    mvLevelSigma2[0]=1.0f;
    for(int i=1; i<levels; i++)
    {
        mvScaleFactor[i]=mvScaleFactor[i-1]*scaleFactor;
        mvLevelSigma2[i]=mvScaleFactor[i]*mvScaleFactor[i];
    }

    mvInvScaleFactor.resize(levels);
    mvInvLevelSigma2.resize(levels);
    for(int i=0; i<levels; i++)
    {
        mvInvScaleFactor[i]=1.0f/mvScaleFactor[i];
        mvInvLevelSigma2[i]=1.0f/mvLevelSigma2[i];
    }

    mvImagePyramid.resize(levels);

    mnFeaturesPerLevel.resize(levels);
    float factor = 1.0f / scaleFactor;
    float nDesiredFeaturesPerScale = nfeatures*(1 - factor)/(1 - (float)pow((double)factor, (double)levels));

    int sumFeatures = 0;
    for( int level = 0; level < levels-1; level++ )
    {
        mnFeaturesPerLevel[level] = cvRound(nDesiredFeaturesPerScale);
        sumFeatures += mnFeaturesPerLevel[level];
        nDesiredFeaturesPerScale *= factor;
    }
    mnFeaturesPerLevel[levels-1] = std::max(nfeatures - sumFeatures, 0);

    // umax as ORB-SLAM3 computes it (used there by IC_Angle).
    umax.resize(HALF_PATCH_SIZE + 1);
    int v, v0, vmax = cvFloor(HALF_PATCH_SIZE * sqrt(2.f) / 2 + 1);
    int vmin = cvCeil(HALF_PATCH_SIZE * sqrt(2.f) / 2);
    const double hp2 = HALF_PATCH_SIZE*HALF_PATCH_SIZE;
    for (v = 0; v <= vmax; ++v)
        umax[v] = cvRound(sqrt(hp2 - v * v));
    for (v = HALF_PATCH_SIZE, v0 = 0; v >= vmin; --v)
    {
        while (umax[v0] == umax[v0 + 1])
            ++v0;
        umax[v] = v0;
        ++v0;
    }

    // The spslam extractor.
    SpslamConfig config;
    if (spslam_config_from_orb_slam3(nfeatures, _scaleFactor, nlevels, iniThFAST, minThFAST, &config) != SPSLAM_STATUS_OK)
    {
        Fail("invalid parameters (nfeatures=" + std::to_string(nfeatures) + ", scaleFactor=" +
             std::to_string(_scaleFactor) + ", nlevels=" + std::to_string(nlevels) + "): " + LastSpslamError());
        return;
    }

    config.border = std::max<uint32_t>(config.border, ORB_SLAM3_MIN_BORDER);

    std::string modelPath, ortLibraryPath;
    {
        std::lock_guard<std::mutex> lock(gPathsMutex);
        modelPath = gModelPath;
        ortLibraryPath = gOrtLibraryPath;
    }
    // No explicit model: the library picks the precision's default
    // ($SPSLAM_MODEL / $SPSLAM_MODEL_INT8, else models/superpoint[_int8].onnx).
    if (ortLibraryPath.empty())
        ortLibraryPath = EnvOrEmpty("SPSLAM_ORT_LIB");
    if (ortLibraryPath.empty())
        ortLibraryPath = EnvOrEmpty("ORT_DYLIB_PATH");
    config.model_path = modelPath.empty() ? nullptr : modelPath.c_str();
    config.ort_library_path = ortLibraryPath.empty() ? nullptr : ortLibraryPath.c_str();
    const std::string threads = EnvOrEmpty("SPSLAM_THREADS");
    if (!threads.empty())
        config.threads = static_cast<uint32_t>(std::max(0, std::atoi(threads.c_str())));
    // fp32 unless SPSLAM_PRECISION says int8: ORB-SLAM3 runs the extractor on
    // nLevels (usually 8) levels, where the int8 model's border band costs
    // accuracy (EVALUATION.md, "Pyramid levels").
    const std::string precision = Lowercase(EnvOrEmpty("SPSLAM_PRECISION"));
    if (precision.empty() || precision == "fp32")
        config.precision = SPSLAM_PRECISION_FP32;
    else if (precision == "int8")
        config.precision = SPSLAM_PRECISION_INT8;
    else if (!precision.empty())
    {
        Fail("SPSLAM_PRECISION=" + precision + " is not a precision: use fp32 or int8");
        return;
    }
    const std::string descriptors = Lowercase(EnvOrEmpty("SPSLAM_DESCRIPTORS"));
    if (descriptors == "binary")
        state->binaryDescriptors = true;
    else if (!descriptors.empty() && descriptors != "float")
    {
        Fail("SPSLAM_DESCRIPTORS=" + descriptors + " is not a descriptor mode: use float or binary");
        return;
    }
    const std::string device = Lowercase(EnvOrEmpty("SPSLAM_DEVICE"));
    if (device == "auto")
        config.device = SPSLAM_DEVICE_AUTO;
    else if (device == "cpu")
        config.device = SPSLAM_DEVICE_CPU;
    else if (device == "cuda")
        config.device = SPSLAM_DEVICE_CUDA;
    else if (!device.empty())
    {
        Fail("SPSLAM_DEVICE=" + device + " is not a device: use auto, cpu or cuda");
        return;
    }

    SpslamExtractor* extractor = nullptr;
    if (spslam_extractor_create(&config, &extractor) != SPSLAM_STATUS_OK)
    {
        Fail("cannot create the SuperPoint extractor: " + LastSpslamError() +
             " (set SPSLAM_MODEL / SPSLAM_MODEL_INT8 / ORT_DYLIB_PATH or call ORBextractor::SetRuntimePaths)");
        return;
    }

    size_t n = 0, descriptorLength = 0;
    if (spslam_extractor_levels(extractor, &n) != SPSLAM_STATUS_OK ||
        spslam_extractor_descriptor_len(extractor, &descriptorLength) != SPSLAM_STATUS_OK ||
        n != static_cast<size_t>(levels))
    {
        Fail("cannot query the extractor: " + LastSpslamError());
        spslam_extractor_destroy(extractor);
        return;
    }
    if (spslam_extractor_scale_tables(extractor, n, mvScaleFactor.data(), mvInvScaleFactor.data(),
                                      mvLevelSigma2.data(), mvInvLevelSigma2.data(),
                                      mnFeaturesPerLevel.data()) != SPSLAM_STATUS_OK)
    {
        Fail("cannot read the scale tables: " + LastSpslamError());
        spslam_extractor_destroy(extractor);
        return;
    }
    state->extractor = extractor;
    state->descriptorLength = static_cast<int>(descriptorLength);
}

ORBextractor::~ORBextractor()
{
    EraseState(this);
}

bool ORBextractor::IsValid() const
{
    return StateOf(this)->extractor != nullptr;
}

std::string ORBextractor::GetLastError() const
{
    const std::shared_ptr<ExtractorState> state = StateOf(this);
    return state->lastError;
}

int ORBextractor::GetDescriptorLength() const
{
    return StateOf(this)->descriptorLength;
}

bool ORBextractor::BinaryDescriptors() const
{
    return StateOf(this)->binaryDescriptors;
}

void ORBextractor::ComputePyramid(cv::Mat image)
{
    // As ORB-SLAM3: each level lives inside an EDGE_THRESHOLD-bordered buffer
    // (BORDER_REFLECT_101) and mvImagePyramid[level] is the inner ROI, resized
    // from the previous level with INTER_LINEAR.
    for (int level = 0; level < nlevels; ++level)
    {
        float scale = mvInvScaleFactor[level];
        cv::Size sz(cvRound((float)image.cols*scale), cvRound((float)image.rows*scale));
        cv::Size wholeSize(sz.width + EDGE_THRESHOLD*2, sz.height + EDGE_THRESHOLD*2);
        cv::Mat temp(wholeSize, image.type()), masktemp;
        mvImagePyramid[level] = temp(cv::Rect(EDGE_THRESHOLD, EDGE_THRESHOLD, sz.width, sz.height));

        // Compute the resized image
        if( level != 0 )
        {
            cv::resize(mvImagePyramid[level-1], mvImagePyramid[level], sz, 0, 0, cv::INTER_LINEAR);

            cv::copyMakeBorder(mvImagePyramid[level], temp, EDGE_THRESHOLD, EDGE_THRESHOLD, EDGE_THRESHOLD, EDGE_THRESHOLD,
                               cv::BORDER_REFLECT_101+cv::BORDER_ISOLATED);
        }
        else
        {
            cv::copyMakeBorder(image, temp, EDGE_THRESHOLD, EDGE_THRESHOLD, EDGE_THRESHOLD, EDGE_THRESHOLD,
                               cv::BORDER_REFLECT_101);
        }
    }
}

int ORBextractor::operator()( cv::InputArray _image, cv::InputArray _mask, std::vector<cv::KeyPoint>& _keypoints,
                              cv::OutputArray _descriptors, std::vector<int> &vLappingArea)
{
    (void)_mask; // ignored, as in ORB-SLAM3
    if(_image.empty())
        return -1;

    const std::shared_ptr<ExtractorState> state = StateOf(this);
    if (!state->extractor)
    {
        // Keep the construction error as the last error; log it again.
        std::cerr << "[spslam ORBextractor] extractor is not valid (construction failed): " << state->lastError << std::endl;
        _keypoints.clear();
        _descriptors.release();
        return -1;
    }

    cv::Mat image = _image.getMat();
    if (image.type() == CV_8UC3)
        cv::cvtColor(image, image, cv::COLOR_BGR2GRAY);
    else if (image.type() == CV_8UC4)
        cv::cvtColor(image, image, cv::COLOR_BGRA2GRAY);
    else if (image.type() != CV_8UC1)
    {
        Fail("unsupported image type " + cv::typeToString(image.type()) +
             "; give an 8-bit gray (CV_8UC1) or 8-bit colour (CV_8UC3/CV_8UC4) image");
        _keypoints.clear();
        _descriptors.release();
        return -1;
    }

    // Pre-compute the scale pyramid (read by Frame::ComputeStereoMatches).
    ComputePyramid(image);

    SpslamFeatures* features = nullptr;
    const size_t dataLength = image.step[0] * static_cast<size_t>(image.rows - 1) + static_cast<size_t>(image.cols);
    if (spslam_extract(state->extractor, image.data, dataLength, static_cast<size_t>(image.cols),
                       static_cast<size_t>(image.rows), image.step[0], &features) != SPSLAM_STATUS_OK)
    {
        Fail(LastSpslamError());
        _keypoints.clear();
        _descriptors.release();
        return -1;
    }
    SpslamFeaturesView view;
    if (spslam_features_view(features, &view) != SPSLAM_STATUS_OK)
    {
        Fail(LastSpslamError());
        spslam_features_destroy(features);
        _keypoints.clear();
        _descriptors.release();
        return -1;
    }
    SpslamBinaryView binary = {0, 0, nullptr};
    if (state->binaryDescriptors && spslam_features_binary_view(features, &binary) != SPSLAM_STATUS_OK)
    {
        Fail(LastSpslamError());
        spslam_features_destroy(features);
        _keypoints.clear();
        _descriptors.release();
        return -1;
    }
    state->lastError.clear();

    const int nkeypoints = static_cast<int>(view.count);
    const int D = static_cast<int>(view.descriptor_len);
    const int rowBytes = static_cast<int>(binary.bytes_per_row);
    cv::Mat descriptors;
    if( nkeypoints == 0 )
        _descriptors.release();
    else
    {
        if (state->binaryDescriptors)
            _descriptors.create(nkeypoints, rowBytes, CV_8U);
        else
            _descriptors.create(nkeypoints, D, CV_32F);
        descriptors = _descriptors.getMat();
    }

    _keypoints = std::vector<cv::KeyPoint>(nkeypoints);

    // The lapping area (stereo fisheye overlap in ORB-SLAM3): keypoints inside
    // it fill the output from the end backwards, the others from the front.
    const bool hasLapping = vLappingArea.size() >= 2;
    const float lapMin = hasLapping ? static_cast<float>(vLappingArea[0]) : 0.f;
    const float lapMax = hasLapping ? static_cast<float>(vLappingArea[1]) : -1.f;
    int monoIndex = 0, stereoIndex = nkeypoints-1;
    for (int i = 0; i < nkeypoints; ++i)
    {
        const SpslamKeypoint& k = view.keypoints[i];
        const cv::KeyPoint keypoint(k.x, k.y, k.size, k.angle, k.response, k.octave);
        const float* row = view.descriptors + static_cast<size_t>(i) * view.descriptor_len;
        int index;
        if(hasLapping && keypoint.pt.x >= lapMin && keypoint.pt.x <= lapMax)
            index = stereoIndex--;
        else
            index = monoIndex++;
        _keypoints[index] = keypoint;
        if (state->binaryDescriptors)
            std::memcpy(descriptors.ptr<uchar>(index), binary.data + static_cast<size_t>(i) * binary.bytes_per_row,
                        static_cast<size_t>(rowBytes));
        else
            std::memcpy(descriptors.ptr<float>(index), row, sizeof(float) * static_cast<size_t>(D));
    }
    spslam_features_destroy(features);
    return monoIndex;
}

} //namespace ORB_SLAM
