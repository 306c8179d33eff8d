/**
 * float_distance.h: L2 distances between SuperPoint descriptor rows, on the
 * integer scales ORB-SLAM3's matcher and DBoW2's vocabulary expect.
 *
 * ORB-SLAM3 v1.0 compiled its thresholds into ORBmatcher.cc as immediates
 * (TH_LOW = 50, TH_HIGH = 100, stereo (50 + 100) / 2 = 75, "no match yet" =
 * 256), so a float descriptor's distance must land on that 0..255 scale with
 * SuperPoint's own thresholds at those marks. spslam measured them
 * (src/matching/thresholds.rs, DistanceThresholds::SUPERPOINT_L2): L2 0.6 for
 * TH_LOW and 0.8 for TH_HIGH. The scale is piecewise linear and monotone:
 *
 *   L2 in [0, 0.6]   ->  L2 * 50 / 0.6          (0 .. 50; ratios preserved)
 *   L2 in (0.6, 1.42] ->  50 + (L2 - 0.6) * 250  (50 .. 255; 0.7 -> 75, 0.8 -> 100)
 *   beyond            ->  255
 *
 * so ORB-SLAM3's TH_LOW, stereo and TH_HIGH tests become L2 < 0.6, 0.7 and
 * 0.8, exactly spslam's own. The vocabulary only needs an order (the nearest
 * child at each tree level), so its distance is the squared L2 in units of
 * 2^-24 (exact enough to tell centres apart; at most 2^26 for unit rows).
 */

#ifndef SPSLAM_ORBSLAM3_FLOAT_DISTANCE_H
#define SPSLAM_ORBSLAM3_FLOAT_DISTANCE_H

#include <cmath>
#include <climits>
#include <cstring>

namespace spslam_orbslam3
{

/// SuperPoint's TH_LOW and TH_HIGH in L2 (src/matching/thresholds.rs).
constexpr float kL2AtThLow = 0.6f;
constexpr float kL2AtThHigh = 0.8f;
/// ORB-SLAM3's compiled-in thresholds, the marks of the integer scale.
constexpr int kThLow = 50;
constexpr int kThHigh = 100;
/// Larger than any scaled distance: what mismatched rows get.
constexpr int kNoMatch = 256;

/// Eight floats as one vector (GCC's vector extension: AVX where the clone
/// has it, two SSE registers otherwise).
typedef float Float8 __attribute__((vector_size(32)));

/// Squared L2 distance of two float rows: 32 floats a step in four
/// eight-float sums, so that the loop needs no shuffles and no -ffast-math
/// (ORB-SLAM3 calls this about 750,000 times a KITTI frame: the preload
/// spent 18-26 % of its samples here when four scalar sums were written out
/// and the compiler interleaved them). Clones for AVX2 + FMA and the
/// baseline (two SSE registers per vector); the CPU picks one when the
/// library loads. The vectors are 256-bit, so an AVX-512 clone would add
/// nothing.
__attribute__((target_clones("arch=x86-64-v3", "default")))
inline float SquaredL2(const float* a, const float* b, int n)
{
    Float8 s0 = {}, s1 = {}, s2 = {}, s3 = {};
    int i = 0;
    for (; i + 32 <= n; i += 32)
    {
        Float8 a0, a1, a2, a3, b0, b1, b2, b3;
        std::memcpy(&a0, a + i, sizeof a0);
        std::memcpy(&a1, a + i + 8, sizeof a1);
        std::memcpy(&a2, a + i + 16, sizeof a2);
        std::memcpy(&a3, a + i + 24, sizeof a3);
        std::memcpy(&b0, b + i, sizeof b0);
        std::memcpy(&b1, b + i + 8, sizeof b1);
        std::memcpy(&b2, b + i + 16, sizeof b2);
        std::memcpy(&b3, b + i + 24, sizeof b3);
        const Float8 d0 = a0 - b0, d1 = a1 - b1, d2 = a2 - b2, d3 = a3 - b3;
        s0 += d0 * d0;
        s1 += d1 * d1;
        s2 += d2 * d2;
        s3 += d3 * d3;
    }
    const Float8 s = (s0 + s1) + (s2 + s3);
    float sum = ((s[0] + s[4]) + (s[1] + s[5])) + ((s[2] + s[6]) + (s[3] + s[7]));
    for (; i < n; ++i)
    {
        const float d = a[i] - b[i];
        sum += d * d;
    }
    return sum;
}

/// An L2 distance on ORB-SLAM3's 0..255 descriptor-distance scale (see above).
inline int MatcherScale(float l2)
{
    if (!(l2 >= 0.f))
        return kNoMatch;
    float scaled;
    if (l2 <= kL2AtThLow)
        scaled = l2 * (static_cast<float>(kThLow) / kL2AtThLow);
    else
        scaled = static_cast<float>(kThLow) +
                 (l2 - kL2AtThLow) * (static_cast<float>(kThHigh - kThLow) / (kL2AtThHigh - kL2AtThLow));
    if (scaled >= 255.f)
        return 255;
    return static_cast<int>(std::lround(scaled));
}

/// A squared L2 distance in units of 2^-24, for the vocabulary's nearest-child search.
inline int VocabularyScale(float squaredL2)
{
    if (!(squaredL2 >= 0.f))
        return INT_MAX;
    const double scaled = static_cast<double>(squaredL2) * 16777216.0;
    return scaled >= static_cast<double>(INT_MAX) ? INT_MAX : static_cast<int>(scaled + 0.5);
}

} // namespace spslam_orbslam3

#endif
