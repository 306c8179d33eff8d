/**
 * test_float_distance.cc: the preload's descriptor distances
 * (cpp_shim/orbslam3/float_distance.h) against brute-force references:
 * the squared L2 kernel against a double-precision sum, and the 0..255
 * matcher scale at ORB-SLAM3's marks (TH_LOW 50 = L2 0.6, stereo 75 = 0.7,
 * TH_HIGH 100 = 0.8), its monotonicity and its bounds.
 */

#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "orbslam3/float_distance.h"

namespace
{
int gFailures = 0, gChecks = 0;

#define CHECK(cond, ...)                                                                                             \
    do                                                                                                               \
    {                                                                                                                \
        ++gChecks;                                                                                                   \
        if (!(cond))                                                                                                 \
        {                                                                                                            \
            ++gFailures;                                                                                             \
            std::printf("FAIL %s:%d: %s: ", __FILE__, __LINE__, #cond);                                              \
            std::printf(__VA_ARGS__);                                                                                \
            std::printf("\n");                                                                                       \
        }                                                                                                            \
    } while (0)

using namespace spslam_orbslam3;
} // namespace

int main()
{
    std::mt19937 rng(7);
    std::normal_distribution<float> normal(0.f, 1.f);
    for (int n : {0, 1, 3, 4, 7, 31, 32, 33, 64, 100, 255, 256, 257})
    {
        std::vector<float> a(n), b(n);
        for (int i = 0; i < n; ++i)
        {
            a[i] = normal(rng);
            b[i] = normal(rng);
        }
        double reference = 0.0;
        for (int i = 0; i < n; ++i)
            reference += (static_cast<double>(a[i]) - b[i]) * (static_cast<double>(a[i]) - b[i]);
        const float got = SquaredL2(a.data(), b.data(), n);
        CHECK(std::fabs(got - reference) <= 1e-5 * (1.0 + reference), "n=%d: %g vs %g", n, got, reference);
    }

    CHECK(MatcherScale(0.f) == 0, "0 -> %d", MatcherScale(0.f));
    CHECK(MatcherScale(0.6f) == kThLow, "TH_LOW: 0.6 -> %d", MatcherScale(0.6f));
    CHECK(MatcherScale(0.7f) == (kThLow + kThHigh) / 2, "stereo: 0.7 -> %d", MatcherScale(0.7f));
    CHECK(MatcherScale(0.8f) == kThHigh, "TH_HIGH: 0.8 -> %d", MatcherScale(0.8f));
    CHECK(MatcherScale(0.59f) < kThLow && MatcherScale(0.61f) >= kThLow, "around TH_LOW");
    CHECK(MatcherScale(0.79f) < kThHigh && MatcherScale(0.81f) > kThHigh, "around TH_HIGH");
    CHECK(MatcherScale(2.f) == 255 && MatcherScale(100.f) == 255, "far rows stay below ORB-SLAM3's 256");
    CHECK(MatcherScale(std::nanf("")) == kNoMatch && MatcherScale(-1.f) == kNoMatch, "invalid -> no match");
    // Ratios of distances below TH_LOW are kept (ORB-SLAM3's mfNNratio tests).
    CHECK(MatcherScale(0.3f) * 2 == MatcherScale(0.6f), "linear below TH_LOW");
    int previous = -1, nonMonotone = 0;
    for (int i = 0; i <= 3000; ++i)
    {
        const int d = MatcherScale(i * 0.001f);
        nonMonotone += d < previous ? 1 : 0;
        previous = d;
    }
    CHECK(nonMonotone == 0, "%d decreasing steps", nonMonotone);

    CHECK(VocabularyScale(0.f) == 0 && VocabularyScale(1.f) == (1 << 24) && VocabularyScale(4.f) == (1 << 26),
          "vocabulary scale");
    CHECK(VocabularyScale(1e9f) == INT_MAX && VocabularyScale(-1.f) == INT_MAX, "vocabulary scale bounds");

    if (gFailures)
    {
        std::printf("FAILED: %d of %d checks\n", gFailures, gChecks);
        return 1;
    }
    std::printf("OK: %d checks passed (float_distance.h)\n", gChecks);
    return 0;
}
