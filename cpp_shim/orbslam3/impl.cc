/**
 * impl.cc: libspslam_orbslam3_impl.so, the part of the ORB-SLAM3 preload that
 * needs OpenCV and spslam. preload.cc loads it on first use (RTLD_LOCAL).
 *
 * It holds the C++ shim (cpp_shim/ORBextractor.cc, whose class has ORB-SLAM3
 * v1.0's exact layout) and spslam's static library, compiled with hidden
 * visibility, and is linked against the OpenCV 4.8 libraries of the
 * orbslam3-python wheel: the same files ORB-SLAM3 has already loaded, so the
 * process holds one OpenCV (Debian's 4.6, which spslam's own build uses, is
 * never loaded). Only the extern "C" functions below are exported.
 */

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <new>
#include <sstream>
#include <string>
#include <vector>

#include "ORBextractor.h"

#define SPSLAM_EXPORT extern "C" __attribute__((visibility("default")))

// ORB-SLAM3 v1.0 allocates 224 bytes (`operator new(0xe0)`) and reads the
// members through its own inline accessors.
static_assert(sizeof(ORB_SLAM3::ORBextractor) == 224, "ORBextractor must keep ORB-SLAM3 v1.0's size");

/// Constructs the shim's extractor in `memory` (allocated by ORB-SLAM3).
/// 0 when it is usable; otherwise 1 and the reason in `error`.
SPSLAM_EXPORT int spslam_orbslam3_construct(void* memory, int nfeatures, float scaleFactor, int nlevels,
                                            int iniThFAST, int minThFAST, std::string* error)
{
    auto* extractor = new (memory) ORB_SLAM3::ORBextractor(nfeatures, scaleFactor, nlevels, iniThFAST, minThFAST);
    if (extractor->IsValid())
        return 0;
    *error = extractor->GetLastError();
    return 1;
}

/// ORBextractor::operator() on an object built by spslam_orbslam3_construct.
SPSLAM_EXPORT int spslam_orbslam3_extract(void* self, const cv::_InputArray& image, const cv::_InputArray& mask,
                                          std::vector<cv::KeyPoint>& keypoints, const cv::_OutputArray& descriptors,
                                          std::vector<int>& lappingArea)
{
    return (*static_cast<ORB_SLAM3::ORBextractor*>(self))(image, mask, keypoints, descriptors, lappingArea);
}

/// DBoW2::FORB::meanValue for float rows: the element-wise mean.
SPSLAM_EXPORT void spslam_orbslam3_mean_value(const std::vector<const cv::Mat*>& rows, cv::Mat& mean)
{
    if (rows.empty())
    {
        mean.release();
        return;
    }
    const int length = rows.front()->cols;
    cv::Mat sum = cv::Mat::zeros(1, length, CV_32F);
    for (const cv::Mat* row : rows)
        sum += *row;
    mean = sum / static_cast<double>(rows.size());
}

/// DBoW2::FORB::fromString, checked: `length` values per node (256 floats, or
/// 32 integers 0..255 in binary mode, where ORB-SLAM3's own parser then runs).
/// 0 on success; otherwise 1 and what is wrong in `error`.
SPSLAM_EXPORT int spslam_orbslam3_from_string(cv::Mat& descriptor, const std::string& text, int length, int binary,
                                              std::string* error)
{
    std::vector<float> values;
    values.reserve(static_cast<size_t>(length));
    const char* cursor = text.c_str();
    while (true)
    {
        while (*cursor == ' ' || *cursor == '\t')
            ++cursor;
        if (*cursor == '\0' || *cursor == '\r' || *cursor == '\n')
            break;
        char* end = nullptr;
        errno = 0;
        const float value = std::strtof(cursor, &end);
        if (end == cursor || errno == ERANGE)
        {
            *error = "'" + std::string(cursor, std::min<size_t>(20, std::strlen(cursor))) + "' is not a number";
            return 1;
        }
        if (binary && (value != static_cast<float>(static_cast<int>(value)) || value < 0.f || value > 255.f))
        {
            *error = "value " + std::to_string(value) +
                     " is not a byte: binary mode needs a vocabulary trained on 32-byte binary descriptors "
                     "(spslam vocab train --descriptors binary)";
            return 1;
        }
        values.push_back(value);
        cursor = end;
    }
    if (static_cast<int>(values.size()) != length)
    {
        *error = std::to_string(values.size()) + " values where the " + (binary ? "binary" : "float") +
                 " mode needs " + std::to_string(length) +
                 (binary ? " (an ORB or binary vocabulary)"
                         : ": float mode needs a SuperPoint float vocabulary (spslam vocab train --descriptors float)");
        return 1;
    }
    if (!binary)
        cv::Mat(1, length, CV_32F, values.data()).copyTo(descriptor);
    return 0;
}

/// DBoW2::FORB::toString for float rows: the values, space separated.
SPSLAM_EXPORT void spslam_orbslam3_to_string(const cv::Mat& descriptor, std::string* text)
{
    std::ostringstream out;
    out.precision(9);
    const float* values = descriptor.ptr<float>(0);
    for (int i = 0; i < descriptor.cols; ++i)
        out << (i ? " " : "") << values[i];
    *text = out.str();
}
