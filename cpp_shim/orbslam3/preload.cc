/**
 * preload.cc: libspslam_orbslam3.so, an LD_PRELOAD library that turns an
 * unmodified ORB-SLAM3 v1.0 binary into SuperPoint-SLAM3.
 *
 * It defines the symbols below; loaded first, it replaces them for the whole
 * process (ORB-SLAM3 reaches every one through its PLT or GOT):
 *
 *   ORB_SLAM3::ORBextractor::ORBextractor(int, float, int, int, int)
 *   ORB_SLAM3::ORBextractor::operator()(...)        -> SuperPoint + ANMS (the C++ shim)
 *   ORB_SLAM3::ORBmatcher::DescriptorDistance       -> L2 on float rows, 0..255 scale
 *   ORB_SLAM3::ORBmatcher::TH_LOW / TH_HIGH          -> 50 / 100 on that scale
 *   DBoW2::FORB::distance / meanValue / fromString / toString, DBoW2::FORB::L
 *                                                    -> 256-float vocabulary words
 *
 * This file needs no OpenCV library (only inline cv::Mat accessors), so it is
 * harmless in a process that never calls these symbols. The extractor and the
 * float vocabulary words live in libspslam_orbslam3_impl.so beside it, which
 * is loaded on first use with RTLD_LOCAL and binds its cv:: calls to the
 * OpenCV already loaded by ORB-SLAM3 (see impl.cc).
 *
 * Modes, from SPSLAM_DESCRIPTORS when the library loads:
 *  - float (default): all of the above;
 *  - binary: only the extractor is ours (sign bits in ORB's 32-byte layout);
 *    the matcher, DBoW2 and the thresholds forward to ORB-SLAM3's own code.
 *
 * Checks, each a message on stderr and exit status 78 instead of a crash:
 *  - the calling process must hold ORB-SLAM3 v1.0 (libORB_SLAM3 with the
 *    v1.0 Settings class) and DBoW2;
 *  - ORB-SLAM3 must allocate ORBextractor with v1.0's size (224 bytes): a
 *    fork with other members would be overwritten or misread;
 *  - the SuperPoint extractor must load (model, ONNX Runtime), and a float
 *    vocabulary must have 256 values per node.
 */

#include <dlfcn.h>
#include <link.h>
#include <malloc.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <string>
#include <vector>

#include <opencv2/core/mat.hpp>
#include <opencv2/core/types.hpp>

#include "float_distance.h"

#define SPSLAM_EXPORT __attribute__((visibility("default")))

// ORB-SLAM3 v1.0's and DBoW2's declarations of the replaced symbols (only
// what fixes their mangled names; the classes' other members are irrelevant).
namespace ORB_SLAM3
{
class SPSLAM_EXPORT ORBextractor
{
public:
    ORBextractor(int nfeatures, float scaleFactor, int nlevels, int iniThFAST, int minThFAST);
    int operator()(const cv::_InputArray& image, const cv::_InputArray& mask, std::vector<cv::KeyPoint>& keypoints,
                   const cv::_OutputArray& descriptors, std::vector<int>& lappingArea);
};

class SPSLAM_EXPORT ORBmatcher
{
public:
    static const int TH_LOW;
    static const int TH_HIGH;
    static int DescriptorDistance(const cv::Mat& a, const cv::Mat& b);
};
} // namespace ORB_SLAM3

namespace DBoW2
{
class SPSLAM_EXPORT FORB
{
public:
    typedef cv::Mat TDescriptor;
    typedef const TDescriptor* pDescriptor;
    // `const int` in DBoW2; writable here so that the mode can set it before
    // the vocabulary loads (the mangled name does not carry the const).
    static int L;
    static void meanValue(const std::vector<pDescriptor>& descriptors, TDescriptor& mean);
    static int distance(const TDescriptor& a, const TDescriptor& b);
    static std::string toString(const TDescriptor& a);
    static void fromString(TDescriptor& a, const std::string& s);
};
} // namespace DBoW2

namespace
{

using spslam_orbslam3::kThHigh;
using spslam_orbslam3::kThLow;

constexpr int kExitConfig = 78; // EX_CONFIG
constexpr int kFloatLength = 256;
constexpr int kBinaryLength = 32;
// ORB-SLAM3 v1.0's sizeof(ORBextractor) on x86-64 (`operator new(0xe0)`).
constexpr size_t kOrbExtractorSize = 224;

bool gBinaryMode = false;

[[noreturn]] void Fatal(const std::string& message)
{
    std::fprintf(stderr, "[spslam preload] error: %s\n", message.c_str());
    std::fflush(stderr);
    std::fflush(stdout);
    _exit(kExitConfig);
}

__attribute__((constructor)) void ReadMode()
{
    const char* mode = std::getenv("SPSLAM_DESCRIPTORS");
    const std::string value = mode ? mode : "";
    if (value == "binary" || value == "BINARY")
        gBinaryMode = true;
    else if (!value.empty() && value != "float" && value != "FLOAT")
        Fatal("SPSLAM_DESCRIPTORS=" + value + " is not a descriptor mode: use float or binary");
    DBoW2::FORB::L = gBinaryMode ? kBinaryLength : kFloatLength;
}

// ---- ORB-SLAM3's own code (binary mode forwards to it) ----------------------

struct FoundLibraries
{
    std::string orbSlam3;
    std::string dbow2;
};

int FindLibrary(struct dl_phdr_info* info, size_t, void* data)
{
    auto* found = static_cast<FoundLibraries*>(data);
    const char* name = info->dlpi_name ? info->dlpi_name : "";
    const char* base = std::strrchr(name, '/');
    base = base ? base + 1 : name;
    if (std::strncmp(base, "libORB_SLAM3", 12) == 0 && found->orbSlam3.empty())
        found->orbSlam3 = name;
    if (std::strncmp(base, "libDBoW2", 8) == 0 && found->dbow2.empty())
        found->dbow2 = name;
    return 0;
}

struct OrbSlam3
{
    int (*descriptorDistance)(const cv::Mat&, const cv::Mat&) = nullptr;
    int (*forbDistance)(const cv::Mat&, const cv::Mat&) = nullptr;
    void (*forbMeanValue)(const std::vector<const cv::Mat*>&, cv::Mat&) = nullptr;
    void (*forbFromString)(cv::Mat&, const std::string&) = nullptr;
    std::string (*forbToString)(const cv::Mat&) = nullptr;
};

void* Symbol(void* handle, const char* mangled, const std::string& library)
{
    void* symbol = dlsym(handle, mangled);
    if (!symbol)
        Fatal(library + " has no " + mangled + ": this is not ORB-SLAM3 v1.0's library");
    return symbol;
}

// Finds ORB-SLAM3 v1.0 and DBoW2 in the process (they are usually loaded
// privately, RTLD_LOCAL, by a Python extension or the executable) and the
// original definitions of the replaced functions.
const OrbSlam3& OrbSlam3Library()
{
    static OrbSlam3 library;
    static std::once_flag once;
    std::call_once(once, [] {
        FoundLibraries found;
        dl_iterate_phdr(FindLibrary, &found);
        if (found.orbSlam3.empty() || found.dbow2.empty())
            Fatal("libspslam_orbslam3.so is preloaded into a process without ORB-SLAM3 v1.0's libORB_SLAM3 and "
                  "libDBoW2 (found: '" + found.orbSlam3 + "', '" + found.dbow2 +
                  "'); it only works inside ORB-SLAM3 v1.0");
        void* orb = dlopen(found.orbSlam3.c_str(), RTLD_LAZY | RTLD_NOLOAD);
        void* dbow = dlopen(found.dbow2.c_str(), RTLD_LAZY | RTLD_NOLOAD);
        if (!orb || !dbow)
            Fatal("cannot open the loaded ORB-SLAM3 libraries: " + std::string(dlerror()));
        // v1.0 introduced the Settings class; 0.x and other forks lack it.
        Symbol(orb, "_ZN9ORB_SLAM38SettingsC1ERKNSt7__cxx1112basic_stringIcSt11char_traitsIcESaIcEEERKi",
               found.orbSlam3);
        library.descriptorDistance = reinterpret_cast<int (*)(const cv::Mat&, const cv::Mat&)>(
            Symbol(orb, "_ZN9ORB_SLAM310ORBmatcher18DescriptorDistanceERKN2cv3MatES4_", found.orbSlam3));
        library.forbDistance = reinterpret_cast<int (*)(const cv::Mat&, const cv::Mat&)>(
            Symbol(dbow, "_ZN5DBoW24FORB8distanceERKN2cv3MatES4_", found.dbow2));
        library.forbMeanValue = reinterpret_cast<void (*)(const std::vector<const cv::Mat*>&, cv::Mat&)>(
            Symbol(dbow, "_ZN5DBoW24FORB9meanValueERKSt6vectorIPKN2cv3MatESaIS5_EERS3_", found.dbow2));
        library.forbFromString = reinterpret_cast<void (*)(cv::Mat&, const std::string&)>(
            Symbol(dbow, "_ZN5DBoW24FORB10fromStringERN2cv3MatERKNSt7__cxx1112basic_stringIcSt11char_traitsIcESaIcEEE",
                   found.dbow2));
        library.forbToString = reinterpret_cast<std::string (*)(const cv::Mat&)>(
            Symbol(dbow, "_ZN5DBoW24FORB8toStringB5cxx11ERKN2cv3MatE", found.dbow2));
    });
    return library;
}

// ---- libspslam_orbslam3_impl.so (extractor and float words) -----------------

struct Implementation
{
    int (*construct)(void*, int, float, int, int, int, std::string*) = nullptr;
    int (*extract)(void*, const cv::_InputArray&, const cv::_InputArray&, std::vector<cv::KeyPoint>&,
                   const cv::_OutputArray&, std::vector<int>&) = nullptr;
    void (*meanValue)(const std::vector<const cv::Mat*>&, cv::Mat&) = nullptr;
    int (*fromString)(cv::Mat&, const std::string&, int, int, std::string*) = nullptr;
    void (*toString)(const cv::Mat&, std::string*) = nullptr;
};

std::string ImplementationPath()
{
    const char* fromEnvironment = std::getenv("SPSLAM_ORBSLAM3_IMPL");
    if (fromEnvironment && *fromEnvironment)
        return fromEnvironment;
    Dl_info info;
    if (dladdr(reinterpret_cast<void*>(&ReadMode), &info) == 0 || !info.dli_fname)
        Fatal("cannot find where libspslam_orbslam3.so was loaded from; set SPSLAM_ORBSLAM3_IMPL");
    std::string self = info.dli_fname;
    const size_t slash = self.rfind('/');
    const std::string folder = slash == std::string::npos ? "." : self.substr(0, slash);
    return folder + "/libspslam_orbslam3_impl.so";
}

const Implementation& Impl()
{
    static Implementation impl;
    static std::once_flag once;
    std::call_once(once, [] {
        OrbSlam3Library(); // ORB-SLAM3's OpenCV must be loaded before the implementation binds to it
        const std::string path = ImplementationPath();
        void* handle = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
        if (!handle)
            Fatal("cannot load " + path + ": " + dlerror());
        auto need = [&](const char* name) {
            void* symbol = dlsym(handle, name);
            if (!symbol)
                Fatal(path + " has no " + name + " (rebuild it with `make orbslam3-build`)");
            return symbol;
        };
        impl.construct = reinterpret_cast<decltype(impl.construct)>(need("spslam_orbslam3_construct"));
        impl.extract = reinterpret_cast<decltype(impl.extract)>(need("spslam_orbslam3_extract"));
        impl.meanValue = reinterpret_cast<decltype(impl.meanValue)>(need("spslam_orbslam3_mean_value"));
        impl.fromString = reinterpret_cast<decltype(impl.fromString)>(need("spslam_orbslam3_from_string"));
        impl.toString = reinterpret_cast<decltype(impl.toString)>(need("spslam_orbslam3_to_string"));
    });
    return impl;
}

bool IsFloatRow(const cv::Mat& m)
{
    return m.data && m.type() == CV_32F && m.rows == 1 && m.cols > 0;
}

} // namespace

// ---- the replaced symbols -----------------------------------------------------

namespace ORB_SLAM3
{

ORBextractor::ORBextractor(int nfeatures, float scaleFactor, int nlevels, int iniThFAST, int minThFAST)
{
    OrbSlam3Library();
    // ORB-SLAM3 allocates the object with `new`: its usable size tells the
    // size ORB-SLAM3 was compiled with (glibc rounds 224 up to 232).
    const size_t usable = malloc_usable_size(this);
    if (usable < kOrbExtractorSize || usable >= kOrbExtractorSize + 16)
        Fatal("ORB-SLAM3 allocated an ORBextractor of about " + std::to_string(usable) + " bytes; v1.0's is " +
              std::to_string(kOrbExtractorSize) + ": this build's ORBextractor layout does not match v1.0's");
    std::string error;
    if (Impl().construct(this, nfeatures, scaleFactor, nlevels, iniThFAST, minThFAST, &error) != 0)
        Fatal("cannot create the SuperPoint extractor (ORBextractor(" + std::to_string(nfeatures) + ", " +
              std::to_string(scaleFactor) + ", " + std::to_string(nlevels) + ", " + std::to_string(iniThFAST) +
              ", " + std::to_string(minThFAST) + ")): " + error);
}

int ORBextractor::operator()(const cv::_InputArray& image, const cv::_InputArray& mask,
                             std::vector<cv::KeyPoint>& keypoints, const cv::_OutputArray& descriptors,
                             std::vector<int>& lappingArea)
{
    return Impl().extract(this, image, mask, keypoints, descriptors, lappingArea);
}

// On the 0..255 scale of float_distance.h; the same values as ORB's, so both
// modes share them.
const int ORBmatcher::TH_LOW = kThLow;
const int ORBmatcher::TH_HIGH = kThHigh;

int ORBmatcher::DescriptorDistance(const cv::Mat& a, const cv::Mat& b)
{
    if (gBinaryMode || a.type() != CV_32F)
        return OrbSlam3Library().descriptorDistance(a, b);
    if (!IsFloatRow(a) || !IsFloatRow(b) || a.cols != b.cols)
        return spslam_orbslam3::kNoMatch;
    const float l2 = std::sqrt(spslam_orbslam3::SquaredL2(a.ptr<float>(0), b.ptr<float>(0), a.cols));
    return spslam_orbslam3::MatcherScale(l2);
}

} // namespace ORB_SLAM3

namespace DBoW2
{

int FORB::L = kFloatLength;

int FORB::distance(const TDescriptor& a, const TDescriptor& b)
{
    if (gBinaryMode || a.type() != CV_32F)
        return OrbSlam3Library().forbDistance(a, b);
    if (!IsFloatRow(a) || !IsFloatRow(b) || a.cols != b.cols)
        return INT_MAX;
    return spslam_orbslam3::VocabularyScale(spslam_orbslam3::SquaredL2(a.ptr<float>(0), b.ptr<float>(0), a.cols));
}

void FORB::meanValue(const std::vector<pDescriptor>& descriptors, TDescriptor& mean)
{
    if (gBinaryMode)
        OrbSlam3Library().forbMeanValue(descriptors, mean);
    else
        Impl().meanValue(descriptors, mean);
}

std::string FORB::toString(const TDescriptor& a)
{
    if (gBinaryMode)
        return OrbSlam3Library().forbToString(a);
    std::string text;
    Impl().toString(a, &text);
    return text;
}

void FORB::fromString(TDescriptor& a, const std::string& s)
{
    std::string error;
    // The implementation checks the node's values (256 floats, or 32 bytes in
    // binary mode) so that a vocabulary of the other kind is named, not misread.
    if (Impl().fromString(a, s, L, gBinaryMode ? 1 : 0, &error) != 0)
        Fatal("vocabulary node '" + s.substr(0, 60) + (s.size() > 60 ? "...'" : "'") + ": " + error);
    if (gBinaryMode)
        OrbSlam3Library().forbFromString(a, s);
}

} // namespace DBoW2
