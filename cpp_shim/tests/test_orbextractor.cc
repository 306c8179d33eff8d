// Tests of the ORB-SLAM3 ORBextractor shim and of the C ABI it wraps.
//
//   test_orbextractor [--small] [DATA_DIR]
//
// DATA_DIR defaults to $SPSLAM_DATA, else ../shared/data; it must hold
// kitti/sequences/06/image_{0,1}/000000.png. When the frames are missing the
// test prints "SKIPPED: ..." and exits 0, unless CI=true (then it fails).
// --small runs everything on a 64x48 crop with 2 levels (for valgrind).
// Exit status: 0 when every check passed, 1 otherwise.

#include "ORBextractor.h"
#include "spslam.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iostream>
#include <string>
#include <thread>
#include <vector>

namespace
{

int gFailures = 0;
int gChecks = 0;

#define CHECK(cond, ...)                                                         \
    do {                                                                         \
        ++gChecks;                                                               \
        if (!(cond)) {                                                           \
            ++gFailures;                                                         \
            std::fprintf(stderr, "FAIL %s:%d: %s: ", __FILE__, __LINE__, #cond); \
            std::fprintf(stderr, __VA_ARGS__);                                   \
            std::fprintf(stderr, "\n");                                          \
        }                                                                        \
    } while (0)

struct Params
{
    bool small = false;
    int nfeatures = 1000;
    float scaleFactor = 1.2f;
    int nlevels = 8;
    int iniThFAST = 20;
    int minThFAST = 7;
    std::vector<int> lapping{400, 800};
};

struct Result
{
    std::vector<cv::KeyPoint> keypoints;
    cv::Mat descriptors;
    int ret = 0;
};

struct Probe : public ORB_SLAM3::ORBextractor
{
    using ORB_SLAM3::ORBextractor::ORBextractor;
    const std::vector<int>& FeaturesPerLevel() const { return mnFeaturesPerLevel; }
    const std::vector<int>& Umax() const { return umax; }
};

std::string EnvOr(const char* name, const std::string& fallback)
{
    const char* v = std::getenv(name);
    return (v && *v) ? std::string(v) : fallback;
}

bool FileExists(const std::string& path)
{
    std::ifstream f(path);
    return f.good();
}

std::string LastError()
{
    return spslam_last_error();
}

Result RunShim(ORB_SLAM3::ORBextractor& extractor, const cv::Mat& image, std::vector<int> lapping)
{
    Result r;
    r.ret = extractor(image, cv::Mat(), r.keypoints, r.descriptors, lapping);
    return r;
}

// As the shim: SPSLAM_THREADS when set, else the config's own threads.
uint32_t ThreadsFromEnv(uint32_t configured)
{
    const std::string threads = EnvOr("SPSLAM_THREADS", "");
    return threads.empty() ? configured : static_cast<uint32_t>(std::max(0, std::atoi(threads.c_str())));
}

// A direct C ABI extraction, copied into the shim's types (original order).
Result RunCApi(const Params& p, const cv::Mat& image)
{
    Result r;
    SpslamConfig config;
    CHECK(spslam_config_from_orb_slam3(p.nfeatures, p.scaleFactor, p.nlevels, p.iniThFAST, p.minThFAST, &config) ==
              SPSLAM_STATUS_OK, "%s", LastError().c_str());
    config.threads = ThreadsFromEnv(config.threads);
    config.precision = SPSLAM_PRECISION_FP32; // the shim's default
    config.border = 16;                         // the shim's: ORB-SLAM3's minimum border (EDGE_THRESHOLD - 3)
    SpslamExtractor* extractor = nullptr;
    if (spslam_extractor_create(&config, &extractor) != SPSLAM_STATUS_OK)
    {
        CHECK(false, "spslam_extractor_create: %s", LastError().c_str());
        return r;
    }
    SpslamFeatures* features = nullptr;
    const size_t len = image.step[0] * (image.rows - 1) + image.cols;
    SpslamStatus status = spslam_extract(extractor, image.data, len, image.cols, image.rows, image.step[0], &features);
    CHECK(status == SPSLAM_STATUS_OK, "spslam_extract: %s", LastError().c_str());
    if (status == SPSLAM_STATUS_OK)
    {
        SpslamFeaturesView view;
        CHECK(spslam_features_view(features, &view) == SPSLAM_STATUS_OK, "%s", LastError().c_str());
        size_t count = 0;
        CHECK(spslam_features_count(features, &count) == SPSLAM_STATUS_OK && count == view.count, "count");
        r.descriptors = cv::Mat(static_cast<int>(view.count), static_cast<int>(view.descriptor_len), CV_32F);
        for (size_t i = 0; i < view.count; ++i)
        {
            const SpslamKeypoint& k = view.keypoints[i];
            r.keypoints.emplace_back(k.x, k.y, k.size, k.angle, k.response, k.octave);
            std::memcpy(r.descriptors.ptr<float>(static_cast<int>(i)), view.descriptors + i * view.descriptor_len,
                        view.descriptor_len * sizeof(float));
        }
        r.ret = static_cast<int>(view.count);
    }
    spslam_features_destroy(features);
    spslam_extractor_destroy(extractor);
    return r;
}

bool SameKeypoint(const cv::KeyPoint& a, const cv::KeyPoint& b)
{
    const float tol = 1e-6f;
    return std::fabs(a.pt.x - b.pt.x) <= tol && std::fabs(a.pt.y - b.pt.y) <= tol &&
           std::fabs(a.size - b.size) <= tol && std::fabs(a.angle - b.angle) <= tol &&
           std::fabs(a.response - b.response) <= tol && a.octave == b.octave;
}

// Compares keypoints and descriptors, in order; returns the max descriptor difference.
double CompareResults(const Result& a, const Result& b, const char* what)
{
    CHECK(a.keypoints.size() == b.keypoints.size(), "%s: %zu vs %zu keypoints", what, a.keypoints.size(),
          b.keypoints.size());
    CHECK(a.ret == b.ret, "%s: return value %d vs %d", what, a.ret, b.ret);
    if (a.keypoints.size() != b.keypoints.size())
        return INFINITY;
    size_t mismatched = 0;
    for (size_t i = 0; i < a.keypoints.size(); ++i)
        mismatched += SameKeypoint(a.keypoints[i], b.keypoints[i]) ? 0 : 1;
    CHECK(mismatched == 0, "%s: %zu keypoints differ", what, mismatched);
    if (a.keypoints.empty())
        return 0.0;
    CHECK(a.descriptors.size() == b.descriptors.size() && a.descriptors.type() == b.descriptors.type(),
          "%s: descriptor matrices differ in shape/type", what);
    if (a.descriptors.size() != b.descriptors.size() || a.descriptors.type() != b.descriptors.type())
        return INFINITY;
    const double diff = cv::norm(a.descriptors, b.descriptors, cv::NORM_INF);
    CHECK(diff <= 1e-6, "%s: descriptors differ by %g", what, diff);
    return diff;
}

void TestScaleTables(const Params& p, Probe& extractor)
{
    // ORB-SLAM3's constructor, verbatim in arithmetic (scaleFactor is a double member there).
    const double scaleFactor = p.scaleFactor;
    std::vector<float> s(p.nlevels), sigma2(p.nlevels), inv(p.nlevels), invSigma2(p.nlevels);
    s[0] = 1.0f;
    sigma2[0] = 1.0f;
    for (int i = 1; i < p.nlevels; i++)
    {
        s[i] = s[i - 1] * scaleFactor;
        sigma2[i] = s[i] * s[i];
    }
    for (int i = 0; i < p.nlevels; i++)
    {
        inv[i] = 1.0f / s[i];
        invSigma2[i] = 1.0f / sigma2[i];
    }
    std::vector<int> quotas(p.nlevels);
    float factor = 1.0f / scaleFactor;
    float desired = p.nfeatures * (1 - factor) / (1 - (float)pow((double)factor, (double)p.nlevels));
    int sum = 0;
    for (int level = 0; level < p.nlevels - 1; level++)
    {
        quotas[level] = cvRound(desired);
        sum += quotas[level];
        desired *= factor;
    }
    quotas[p.nlevels - 1] = std::max(p.nfeatures - sum, 0);

    CHECK(extractor.GetLevels() == p.nlevels, "GetLevels %d", extractor.GetLevels());
    CHECK(extractor.GetScaleFactor() == p.scaleFactor, "GetScaleFactor %g", extractor.GetScaleFactor());
    CHECK(extractor.GetScaleFactors() == s, "mvScaleFactor differs from ORB-SLAM3's formula");
    CHECK(extractor.GetInverseScaleFactors() == inv, "mvInvScaleFactor differs");
    CHECK(extractor.GetScaleSigmaSquares() == sigma2, "mvLevelSigma2 differs");
    CHECK(extractor.GetInverseScaleSigmaSquares() == invSigma2, "mvInvLevelSigma2 differs");
    CHECK(extractor.FeaturesPerLevel() == quotas, "mnFeaturesPerLevel differs from ORB-SLAM3's formula");
    const std::vector<int> umax{15, 15, 15, 15, 14, 14, 14, 13, 13, 12, 11, 10, 9, 8, 6, 3};
    CHECK(extractor.Umax() == umax, "umax differs");
    std::printf("scale tables: %d levels, s[last]=%.6f, quotas[0]=%d: match ORB-SLAM3's formulas\n", p.nlevels,
                s.back(), quotas[0]);
}

void TestPyramid(const Params& p, ORB_SLAM3::ORBextractor& extractor, const cv::Mat& image)
{
    const std::vector<float> inv = extractor.GetInverseScaleFactors();
    CHECK(static_cast<int>(extractor.mvImagePyramid.size()) == p.nlevels, "pyramid has %zu levels",
          extractor.mvImagePyramid.size());
    cv::Mat previous = image;
    for (int level = 0; level < p.nlevels && level < static_cast<int>(extractor.mvImagePyramid.size()); ++level)
    {
        const cv::Mat& l = extractor.mvImagePyramid[level];
        const cv::Size expected(cvRound((float)image.cols * inv[level]), cvRound((float)image.rows * inv[level]));
        CHECK(l.size() == expected, "level %d is %dx%d, expected %dx%d", level, l.cols, l.rows, expected.width,
              expected.height);
        CHECK(l.type() == CV_8UC1, "level %d type", level);
        cv::Mat want;
        if (level == 0)
            want = image;
        else
            cv::resize(previous, want, expected, 0, 0, cv::INTER_LINEAR);
        if (l.size() == want.size())
            CHECK(cv::norm(l, want, cv::NORM_INF) == 0, "level %d pixels differ from the resize chain", level);
        // The ROI has an EDGE_THRESHOLD=19 reflected border around it, as in ORB-SLAM3.
        cv::Size whole;
        cv::Point offset;
        l.locateROI(whole, offset);
        CHECK(offset == cv::Point(19, 19) && whole == cv::Size(l.cols + 38, l.rows + 38), "level %d border", level);
        previous = want;
    }
}

// ORB-SLAM3 v1.0 code compiled against its own header (the preload's case)
// allocates sizeof == 224 and reads the members at v1.0's offsets.
static_assert(sizeof(ORB_SLAM3::ORBextractor) == 224, "ORBextractor keeps ORB-SLAM3 v1.0's size");

// ORB-SLAM3's contract on keypoint positions: never within EDGE_THRESHOLD - 3
// = 16 px of a level's border. Frame::ComputeStereoMatches depends on it: its
// SAD windows read rows v-5..v+5 of the left level and columns u-10..u+11
// around a right keypoint without bounds checks (cv::Mat throws otherwise).
void TestOrbSlam3Borders(ORB_SLAM3::ORBextractor& extractor, const Result& result, const char* what)
{
    const std::vector<float> inv = extractor.GetInverseScaleFactors();
    size_t outside = 0;
    for (const cv::KeyPoint& k : result.keypoints)
    {
        if (k.octave < 0 || k.octave >= static_cast<int>(extractor.mvImagePyramid.size()))
        {
            ++outside;
            continue;
        }
        const cv::Mat& level = extractor.mvImagePyramid[k.octave];
        const int u = cvRound(k.pt.x * inv[k.octave]), v = cvRound(k.pt.y * inv[k.octave]);
        if (u < 16 || v < 16 || u >= level.cols - 16 || v >= level.rows - 16)
            ++outside;
    }
    CHECK(outside == 0, "%s: %zu keypoints within 16 px of their level's border", what, outside);
}

void TestLapping(const Params& p, const Result& plain, ORB_SLAM3::ORBextractor& extractor, const cv::Mat& image)
{
    const Result lapped = RunShim(extractor, image, p.lapping);
    const float lo = static_cast<float>(p.lapping[0]), hi = static_cast<float>(p.lapping[1]);
    std::vector<int> outside, inside;
    for (int i = 0; i < static_cast<int>(plain.keypoints.size()); ++i)
    {
        const float x = plain.keypoints[i].pt.x;
        (x >= lo && x <= hi ? inside : outside).push_back(i);
    }
    CHECK(lapped.ret == static_cast<int>(outside.size()), "lapping: returned %d, expected %zu", lapped.ret,
          outside.size());
    CHECK(lapped.keypoints.size() == plain.keypoints.size(), "lapping: %zu keypoints vs %zu", lapped.keypoints.size(),
          plain.keypoints.size());
    CHECK(!inside.empty() && !outside.empty(), "lapping: the area [%g, %g] should split the keypoints", lo, hi);
    if (lapped.keypoints.size() != plain.keypoints.size())
        return;
    // Outside: first, in order. Inside: at the end, filled from the back (ORB-SLAM3's stereoIndex--).
    std::vector<int> expectedOrder = outside;
    expectedOrder.insert(expectedOrder.end(), inside.rbegin(), inside.rend());
    size_t wrong = 0;
    double maxDiff = 0.0;
    for (size_t j = 0; j < expectedOrder.size(); ++j)
    {
        const int src = expectedOrder[j];
        wrong += SameKeypoint(lapped.keypoints[j], plain.keypoints[src]) ? 0 : 1;
        maxDiff = std::max(maxDiff, cv::norm(lapped.descriptors.row(static_cast<int>(j)),
                                             plain.descriptors.row(src), cv::NORM_INF));
    }
    CHECK(wrong == 0, "lapping: %zu keypoints out of place", wrong);
    CHECK(maxDiff <= 1e-6, "lapping: descriptor rows out of place (max diff %g)", maxDiff);
    for (int j = 0; j < lapped.ret; ++j)
    {
        const float x = lapped.keypoints[j].pt.x;
        CHECK(!(x >= lo && x <= hi), "lapping: keypoint %d (x=%g) inside the area before index %d", j, x, lapped.ret);
    }
    std::printf("lapping area {%d, %d} vs the C ABI: %d outside first, %zu inside at the end (reverse order), "
                "max descriptor difference %g\n",
                p.lapping[0], p.lapping[1], lapped.ret, inside.size(), maxDiff);
}

void TestParallel(const Params& p, ORB_SLAM3::ORBextractor& a, const cv::Mat& left, const cv::Mat& right,
                  const Result& leftSeq, const Result& rightSeq)
{
    ORB_SLAM3::ORBextractor b(p.nfeatures, p.scaleFactor, p.nlevels, p.iniThFAST, p.minThFAST);
    CHECK(a.IsValid() && b.IsValid(), "parallel extractors not valid: %s", b.GetLastError().c_str());
    Result ra, rb;
    std::vector<int> lapA{0, 0}, lapB{0, 0};
    // As ORB-SLAM3's stereo Frame: one std::thread per camera.
    std::thread ta([&] { ra.ret = a(left, cv::Mat(), ra.keypoints, ra.descriptors, lapA); });
    std::thread tb([&] { rb.ret = b(right, cv::Mat(), rb.keypoints, rb.descriptors, lapB); });
    ta.join();
    tb.join();
    CompareResults(ra, leftSeq, "parallel left vs sequential");
    CompareResults(rb, rightSeq, "parallel right vs sequential");
    std::printf("two extractors on two threads: %zu + %zu keypoints, identical to sequential runs\n",
                ra.keypoints.size(), rb.keypoints.size());
}

void TestBadImages(const Params& p, ORB_SLAM3::ORBextractor& extractor, const cv::Mat& gray, const Result& plain)
{
    std::vector<int> lap{0, 0};
    std::vector<cv::KeyPoint> kps;
    cv::Mat desc;
    CHECK(extractor(cv::Mat(), cv::Mat(), kps, desc, lap) == -1, "empty image should give -1");
    cv::Mat f32;
    gray.convertTo(f32, CV_32F);
    CHECK(extractor(f32, cv::Mat(), kps, desc, lap) == -1, "CV_32F image should give -1");
    CHECK(!extractor.GetLastError().empty(), "CV_32F: no error message");
    cv::Mat u16(gray.size(), CV_16UC1, cv::Scalar(1000));
    CHECK(extractor(u16, cv::Mat(), kps, desc, lap) == -1, "CV_16U image should give -1");
    cv::Mat tiny(4, 4, CV_8UC1, cv::Scalar(7));
    CHECK(extractor(tiny, cv::Mat(), kps, desc, lap) == -1, "4x4 image should give -1 (too small)");
    CHECK(kps.empty() && desc.empty(), "outputs should be cleared on error");
    if (p.small)
    {
        std::printf("bad images: empty/CV_32F/CV_16U/4x4 -> -1 (colour and ROI inputs: full mode only)\n");
        return;
    }
    // Colour input is converted to gray: same result as the gray image.
    cv::Mat bgr, bgra;
    cv::cvtColor(gray, bgr, cv::COLOR_GRAY2BGR);
    cv::cvtColor(gray, bgra, cv::COLOR_GRAY2BGRA);
    Result rb = RunShim(extractor, bgr, lap);
    CompareResults(rb, plain, "BGR input vs gray");
    Result rba = RunShim(extractor, bgra, lap);
    CompareResults(rba, plain, "BGRA input vs gray");
    // A non-contiguous ROI works (stride > width).
    cv::Mat padded(gray.rows + 2, gray.cols + 16, CV_8UC1, cv::Scalar(0));
    gray.copyTo(padded(cv::Rect(5, 1, gray.cols, gray.rows)));
    Result rr = RunShim(extractor, padded(cv::Rect(5, 1, gray.cols, gray.rows)), lap);
    CompareResults(rr, plain, "ROI input vs contiguous");
    std::printf("bad images: empty/CV_32F/CV_16U/4x4 -> -1; BGR, BGRA and ROI inputs give the gray result\n");
}

void TestCApiErrors(const Params& p)
{
    SpslamConfig config;
    CHECK(spslam_config_default(nullptr) == SPSLAM_STATUS_NULL_POINTER, "config_default(NULL)");
    CHECK(std::strlen(spslam_last_error()) > 0, "no message for NULL out");
    CHECK(spslam_config_default(&config) == SPSLAM_STATUS_OK, "config_default");
    CHECK(std::strlen(spslam_last_error()) == 0, "message should be empty after a success");
    CHECK(spslam_config_from_orb_slam3(0, 1.2f, 8, 20, 7, &config) == SPSLAM_STATUS_INVALID_ARGUMENT, "nfeatures=0");
    CHECK(spslam_config_from_orb_slam3(p.nfeatures, p.scaleFactor, p.nlevels, 20, 7, &config) == SPSLAM_STATUS_OK,
          "from_orb_slam3");
    config.threads = ThreadsFromEnv(config.threads);

    SpslamExtractor* extractor = reinterpret_cast<SpslamExtractor*>(0x1);
    CHECK(spslam_extractor_create(nullptr, &extractor) == SPSLAM_STATUS_NULL_POINTER && extractor == nullptr,
          "create(NULL config)");
    CHECK(spslam_extractor_create(&config, nullptr) == SPSLAM_STATUS_NULL_POINTER, "create(NULL out)");
    SpslamConfig bad = config;
    bad.scale_factor = 0.5f;
    CHECK(spslam_extractor_create(&bad, &extractor) == SPSLAM_STATUS_INVALID_ARGUMENT, "scale_factor 0.5");
    CHECK(std::string(spslam_last_error()).find("scale_factor") != std::string::npos, "message: %s",
          spslam_last_error());
    bad = config;
    bad.anms = 42;
    CHECK(spslam_extractor_create(&bad, &extractor) == SPSLAM_STATUS_INVALID_ARGUMENT, "anms 42");
    bad = config;
    bad.model_path = "/nonexistent/model.onnx";
    CHECK(spslam_extractor_create(&bad, &extractor) == SPSLAM_STATUS_MODEL_ERROR, "missing model");
    CHECK(std::string(spslam_last_error()).find("/nonexistent/model.onnx") != std::string::npos, "message: %s",
          spslam_last_error());

    CHECK(spslam_extractor_create(&config, &extractor) == SPSLAM_STATUS_OK, "create: %s", LastError().c_str());
    std::vector<uint8_t> pixels(64 * 64, 100);
    SpslamFeatures* out = nullptr;
    struct Case
    {
        const char* what;
        const uint8_t* data;
        size_t len, w, h, stride;
        SpslamStatus expected;
    };
    const Case cases[] = {
        {"NULL data", nullptr, 4096, 64, 64, 64, SPSLAM_STATUS_NULL_POINTER},
        {"zero width", pixels.data(), 4096, 0, 64, 64, SPSLAM_STATUS_IMAGE_ERROR},
        {"zero height", pixels.data(), 4096, 64, 0, 64, SPSLAM_STATUS_IMAGE_ERROR},
        {"stride < width", pixels.data(), 4096, 64, 64, 32, SPSLAM_STATUS_IMAGE_ERROR},
        {"short buffer", pixels.data(), 4095 - 64, 64, 64, 64, SPSLAM_STATUS_IMAGE_ERROR},
        {"huge stride", pixels.data(), 4096, 64, 64, SIZE_MAX / 2, SPSLAM_STATUS_IMAGE_ERROR},
    };
    for (const Case& c : cases)
    {
        out = reinterpret_cast<SpslamFeatures*>(0x1);
        const SpslamStatus s = spslam_extract(extractor, c.data, c.len, c.w, c.h, c.stride, &out);
        CHECK(s == c.expected, "%s: status %d, expected %d", c.what, (int)s, (int)c.expected);
        CHECK(out == nullptr, "%s: out not reset to NULL", c.what);
        CHECK(std::strlen(spslam_last_error()) > 0, "%s: no message", c.what);
        std::printf("  C ABI %-15s -> status %d: %s\n", c.what, (int)s, spslam_last_error());
    }
    CHECK(spslam_extract(nullptr, pixels.data(), 4096, 64, 64, 64, &out) == SPSLAM_STATUS_NULL_POINTER, "NULL handle");
    CHECK(spslam_extract(extractor, pixels.data(), 4096, 64, 64, 64, nullptr) == SPSLAM_STATUS_NULL_POINTER,
          "NULL out");
    // A flat image is valid and gives no keypoints.
    CHECK(spslam_extract(extractor, pixels.data(), 4096, 64, 64, 64, &out) == SPSLAM_STATUS_OK, "flat: %s",
          LastError().c_str());
    SpslamFeaturesView view;
    CHECK(spslam_features_view(out, &view) == SPSLAM_STATUS_OK && view.count == 0 && view.keypoints == nullptr,
          "flat image should give no keypoints");
    CHECK(spslam_features_view(nullptr, &view) == SPSLAM_STATUS_NULL_POINTER, "view(NULL)");
    CHECK(spslam_features_view(out, nullptr) == SPSLAM_STATUS_NULL_POINTER, "view(out NULL)");
    spslam_features_destroy(out);

    size_t levels = 0;
    CHECK(spslam_extractor_levels(extractor, &levels) == SPSLAM_STATUS_OK && levels == (size_t)p.nlevels, "levels");
    std::vector<float> small(1);
    CHECK(spslam_extractor_scale_tables(extractor, levels - 1, small.data(), nullptr, nullptr, nullptr, nullptr) ==
              (levels > 1 ? SPSLAM_STATUS_INVALID_ARGUMENT : SPSLAM_STATUS_OK),
          "short table buffer");
    CHECK(spslam_extractor_scale_tables(nullptr, 8, nullptr, nullptr, nullptr, nullptr, nullptr) ==
              SPSLAM_STATUS_NULL_POINTER,
          "tables(NULL)");
    CHECK(spslam_extractor_levels(extractor, nullptr) == SPSLAM_STATUS_NULL_POINTER, "levels(out NULL)");
    spslam_extractor_destroy(extractor);
    spslam_extractor_destroy(nullptr);
    spslam_features_destroy(nullptr);
    CHECK(std::string(spslam_version()).size() > 0, "version");
    std::printf("C ABI errors: NULL pointers, zero sizes, stride < width, short buffers -> error codes (spslam %s)\n",
                spslam_version());
}

// SPSLAM_DESCRIPTORS=binary: the same keypoints as the float run, and each
// row's 32 bytes hold the float row's sign bits in ORB's layout (bit j of
// byte i = dimension 8i+j > 0), checked bit by bit.
void TestBinaryMode(const Params& p, const cv::Mat& image, const Result& plain)
{
    setenv("SPSLAM_DESCRIPTORS", "binary", 1);
    ORB_SLAM3::ORBextractor binary(p.nfeatures, p.scaleFactor, p.nlevels, p.iniThFAST, p.minThFAST);
    setenv("SPSLAM_DESCRIPTORS", "hamming", 1);
    ORB_SLAM3::ORBextractor bad(p.nfeatures, p.scaleFactor, p.nlevels, p.iniThFAST, p.minThFAST);
    unsetenv("SPSLAM_DESCRIPTORS");
    CHECK(!bad.IsValid() && bad.GetLastError().find("float or binary") != std::string::npos,
          "SPSLAM_DESCRIPTORS=hamming: %s", bad.GetLastError().c_str());
    CHECK(binary.IsValid() && binary.BinaryDescriptors(), "binary mode: %s", binary.GetLastError().c_str());
    const Result r = RunShim(binary, image, {0, 0});
    CHECK(r.descriptors.type() == CV_8U && r.descriptors.cols == 32, "binary descriptors: type %d, %d columns",
          r.descriptors.type(), r.descriptors.cols);
    CHECK(r.keypoints.size() == plain.keypoints.size(), "binary mode: %zu keypoints, float %zu", r.keypoints.size(),
          plain.keypoints.size());
    int wrong = 0;
    for (int k = 0; k < r.descriptors.rows && k < plain.descriptors.rows; ++k)
        for (int d = 0; d < plain.descriptors.cols; ++d)
        {
            const bool bit = (r.descriptors.at<uchar>(k, d / 8) >> (d % 8)) & 1;
            wrong += bit != (plain.descriptors.at<float>(k, d) > 0.f);
        }
    CHECK(wrong == 0, "binary mode: %d sign bits differ from the float rows", wrong);
    std::printf("binary mode: %d x %d CV_8U, every bit the float row's sign\n", r.descriptors.rows,
                r.descriptors.cols);
}

void TestInvalidConstruction(const Params& p, const cv::Mat& gray)
{
    ORB_SLAM3::ORBextractor::SetRuntimePaths("/nonexistent/superpoint.onnx", "");
    ORB_SLAM3::ORBextractor broken(p.nfeatures, p.scaleFactor, p.nlevels, p.iniThFAST, p.minThFAST);
    ORB_SLAM3::ORBextractor::SetRuntimePaths("", "");
    CHECK(!broken.IsValid(), "an extractor with a missing model should not be valid");
    CHECK(broken.GetLastError().find("/nonexistent/superpoint.onnx") != std::string::npos, "message: %s",
          broken.GetLastError().c_str());
    std::vector<int> lap{0, 0};
    std::vector<cv::KeyPoint> kps;
    cv::Mat desc;
    CHECK(broken(gray, cv::Mat(), kps, desc, lap) == -1, "invalid extractor should return -1");
    CHECK(broken.GetLevels() == p.nlevels && broken.GetScaleFactors().size() == (size_t)p.nlevels,
          "tables of an invalid extractor");
    ORB_SLAM3::ORBextractor badParams(-3, 1.2f, 8, 20, 7);
    CHECK(!badParams.IsValid(), "nfeatures=-3 should not be valid");

    // SPSLAM_PRECISION / SPSLAM_DEVICE: unknown values are refused with a
    // message naming what is accepted; SPSLAM_PRECISION=int8 loads the int8 model.
    const char* oldPrecision = std::getenv("SPSLAM_PRECISION");
    const std::string keepPrecision = oldPrecision ? oldPrecision : "";
    setenv("SPSLAM_PRECISION", "fp16", 1);
    ORB_SLAM3::ORBextractor badPrecision(p.nfeatures, p.scaleFactor, p.nlevels, p.iniThFAST, p.minThFAST);
    CHECK(!badPrecision.IsValid() && badPrecision.GetLastError().find("fp32 or int8") != std::string::npos,
          "SPSLAM_PRECISION=fp16: %s", badPrecision.GetLastError().c_str());
    setenv("SPSLAM_PRECISION", "int8", 1);
    ORB_SLAM3::ORBextractor int8(p.nfeatures, p.scaleFactor, p.nlevels, p.iniThFAST, p.minThFAST);
    CHECK(int8.IsValid(), "SPSLAM_PRECISION=int8: %s", int8.GetLastError().c_str());
    std::vector<cv::KeyPoint> int8Keypoints;
    cv::Mat int8Descriptors;
    const int n8 = int8(gray, cv::Mat(), int8Keypoints, int8Descriptors, lap);
    CHECK(n8 > 0 && int8Descriptors.cols == 256, "int8 extraction: %d keypoints", n8);
    if (keepPrecision.empty())
        unsetenv("SPSLAM_PRECISION");
    else
        setenv("SPSLAM_PRECISION", keepPrecision.c_str(), 1);
    const char* oldDevice = std::getenv("SPSLAM_DEVICE");
    const std::string keepDevice = oldDevice ? oldDevice : "";
    setenv("SPSLAM_DEVICE", "tpu", 1);
    ORB_SLAM3::ORBextractor badDevice(p.nfeatures, p.scaleFactor, p.nlevels, p.iniThFAST, p.minThFAST);
    CHECK(!badDevice.IsValid() && badDevice.GetLastError().find("auto, cpu or cuda") != std::string::npos,
          "SPSLAM_DEVICE=tpu: %s", badDevice.GetLastError().c_str());
    if (keepDevice.empty())
        unsetenv("SPSLAM_DEVICE");
    else
        setenv("SPSLAM_DEVICE", keepDevice.c_str(), 1);
    std::printf("invalid construction: logged, IsValid() false, operator() -> -1\n");
}

} // namespace

int main(int argc, char** argv)
{
    std::setvbuf(stdout, nullptr, _IOLBF, 0); // keep stdout and stderr in order in logs
    Params p;
    std::string data = EnvOr("SPSLAM_DATA", "../shared/data");
    for (int i = 1; i < argc; ++i)
    {
        const std::string arg = argv[i];
        if (arg == "--small")
            p.small = true;
        else
            data = arg;
    }
    const std::string leftPath = data + "/kitti/sequences/06/image_0/000000.png";
    const std::string rightPath = data + "/kitti/sequences/06/image_1/000000.png";
    if (!FileExists(leftPath) || !FileExists(rightPath))
    {
        if (EnvOr("CI", "") == "true")
        {
            std::fprintf(stderr, "FAIL: KITTI frames not found under %s (CI=true)\n", data.c_str());
            return 1;
        }
        std::printf("SKIPPED: KITTI frames not found under %s (set SPSLAM_DATA)\n", data.c_str());
        return 0;
    }
    cv::Mat left = cv::imread(leftPath, cv::IMREAD_GRAYSCALE);
    cv::Mat right = cv::imread(rightPath, cv::IMREAD_GRAYSCALE);
    if (left.empty() || right.empty())
    {
        std::fprintf(stderr, "FAIL: cannot decode %s or %s\n", leftPath.c_str(), rightPath.c_str());
        return 1;
    }
    if (p.small)
    {
        // ONNX Runtime's kernels run ~1000x slower under valgrind (15 s for
        // one 64x48 inference), so the memory check uses a small textured crop
        // (80x64: keypoints keep 16 px from the border, as ORB-SLAM3's).
        const cv::Rect crop(712, 162, 80, 64);
        left = left(crop).clone();
        right = right(crop).clone();
        p.nfeatures = 60;
        p.nlevels = 2;
        p.lapping = {30, 50};
    }
    std::printf("spslam %s, %s mode, %dx%d images, nfeatures=%d nlevels=%d\n", spslam_version(),
                p.small ? "small" : "full", left.cols, left.rows, p.nfeatures, p.nlevels);

    Probe extractor(p.nfeatures, p.scaleFactor, p.nlevels, p.iniThFAST, p.minThFAST);
    if (!extractor.IsValid())
    {
        std::fprintf(stderr, "FAIL: the extractor could not be created: %s\n", extractor.GetLastError().c_str());
        return 1;
    }
    CHECK(extractor.GetDescriptorLength() == 256, "descriptor length %d", extractor.GetDescriptorLength());

    TestScaleTables(p, extractor);

    // The reference: a direct C ABI extraction on the same buffer (keypoints in the library's order).
    const Result capi = RunCApi(p, left);
    CHECK(capi.keypoints.size() > (p.small ? 5u : 500u), "too few keypoints: %zu", capi.keypoints.size());
    Result plain = capi;
    if (!p.small)
    {
        // No lapping area ({0, 0}, as ORB-SLAM3's pinhole stereo): the same order as the C ABI.
        plain = RunShim(extractor, left, {0, 0});
        const double diff = CompareResults(plain, capi, "shim vs C ABI");
        CHECK(plain.ret == static_cast<int>(plain.keypoints.size()), "no lapping: ret %d", plain.ret);
        CHECK(plain.descriptors.type() == CV_32F && plain.descriptors.cols == 256, "descriptor matrix type/cols");
        std::printf("shim vs C ABI: %zu keypoints, max descriptor difference %g\n", plain.keypoints.size(), diff);
    }
    // With a lapping area: the shim's output is the C ABI's, reordered as ORB-SLAM3 does.
    TestLapping(p, capi, extractor, left);
    TestPyramid(p, extractor, left);
    TestOrbSlam3Borders(extractor, plain, "left");
    const Result rightPlain = RunShim(extractor, right, {0, 0});
    TestOrbSlam3Borders(extractor, rightPlain, "right");
    TestParallel(p, extractor, left, right, plain, rightPlain);
    TestBadImages(p, extractor, left, plain);
    TestCApiErrors(p);
    TestBinaryMode(p, left, plain);
    TestInvalidConstruction(p, left);

    if (gFailures)
    {
        std::printf("FAILED: %d of %d checks\n", gFailures, gChecks);
        return 1;
    }
    std::printf("OK: %d checks passed\n", gChecks);
    return 0;
}
