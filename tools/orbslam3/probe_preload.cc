// Interposition probe for the orbslam3-python 2.0.0 wheel: counts calls to the symbols a
// spslam preload must replace and forwards them to the wheel's originals. Build:
//   g++ -std=c++17 -O2 -fPIC -shared -o libprobe.so probe_preload.cc -ldl
// Run:  python run_stereo.py --vocab VOC --clean-exit --preload ./libprobe.so
// (No OpenCV headers needed: only references to cv:: types cross the interface.)
#include <dlfcn.h>
#include <atomic>
#include <cstdio>
#include <cstdlib>
namespace cv { class Mat; class _InputArray; class _OutputArray; class KeyPoint; }
#include <vector>
static std::atomic<long> n_dd{0}, n_forb{0}, n_op{0}, n_ctor{0};
// The wheel's libraries are dlopen()ed RTLD_LOCAL by Python: RTLD_NEXT cannot see them.
// Look the originals up in the already-loaded library instead (RTLD_NOLOAD, by soname).
template <class F> static F next(const char* s) {
  const char* lib = s[2] == '5' ? "libDBoW2-b725b211.so" : "libORB_SLAM3-98c4e2f1.so";
  void* h = dlopen(lib, RTLD_LAZY | RTLD_NOLOAD);
  void* p = h ? dlsym(h, s) : nullptr; if (!p) { fprintf(stderr, "probe: no %s\n", s); abort(); } return (F)p; }
namespace ORB_SLAM3 {
struct ORBmatcher { static int DescriptorDistance(const cv::Mat&, const cv::Mat&); static const int TH_LOW; static const int TH_HIGH; };
const int ORBmatcher::TH_LOW = 50;
const int ORBmatcher::TH_HIGH = 100;
int ORBmatcher::DescriptorDistance(const cv::Mat& a, const cv::Mat& b) {
  static auto f = next<int (*)(const cv::Mat&, const cv::Mat&)>("_ZN9ORB_SLAM310ORBmatcher18DescriptorDistanceERKN2cv3MatES4_");
  n_dd++; return f(a, b);
}
struct ORBextractor {
  ORBextractor(int, float, int, int, int);
  int operator()(const cv::_InputArray&, const cv::_InputArray&, std::vector<cv::KeyPoint>&, const cv::_OutputArray&, std::vector<int>&);
};
ORBextractor::ORBextractor(int n, float s, int l, int i, int m) {
  static auto f = next<void (*)(void*, int, float, int, int, int)>("_ZN9ORB_SLAM312ORBextractorC1Eifiii");
  n_ctor++; fprintf(stderr, "probe: ORBextractor(%d, %g, %d, %d, %d) at %p\n", n, s, l, i, m, (void*)this); f(this, n, s, l, i, m);
}
int ORBextractor::operator()(const cv::_InputArray& im, const cv::_InputArray& mask, std::vector<cv::KeyPoint>& kp, const cv::_OutputArray& d, std::vector<int>& lap) {
  static auto f = next<int (*)(void*, const cv::_InputArray&, const cv::_InputArray&, std::vector<cv::KeyPoint>&, const cv::_OutputArray&, std::vector<int>&)>(
      "_ZN9ORB_SLAM312ORBextractorclERKN2cv11_InputArrayES4_RSt6vectorINS1_8KeyPointESaIS6_EERKNS1_12_OutputArrayERS5_IiSaIiEE");
  n_op++; return f(this, im, mask, kp, d, lap);
}
}
namespace DBoW2 { struct FORB { static int distance(const cv::Mat&, const cv::Mat&); static const int L; }; const int FORB::L = 32;
int FORB::distance(const cv::Mat& a, const cv::Mat& b) { static auto f = next<int (*)(const cv::Mat&, const cv::Mat&)>("_ZN5DBoW24FORB8distanceERKN2cv3MatES4_"); n_forb++; return f(a, b); } }
__attribute__((destructor)) static void report() { fprintf(stderr, "probe: ctor=%ld operator()=%ld DescriptorDistance=%ld FORB::distance=%ld\n", n_ctor.load(), n_op.load(), n_dd.load(), n_forb.load()); }
