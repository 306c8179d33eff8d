// stereo_kitti: the shim used the way ORB-SLAM3's stereo Frame uses it.
//
//   stereo_kitti [DATA_DIR [SEQUENCE [FRAME]]]
//
// DATA_DIR defaults to $SPSLAM_DATA, else ../shared/data; SEQUENCE to 06 and
// FRAME to 000000. Two extractors run on the left and right images on two
// std::threads at once (as Frame::Frame for stereo does), then left keypoints
// are matched to right keypoints along rows by brute-force L2 distance on the
// 256-float descriptors: |dy| <= 2 px x the level scale, neighbouring octaves
// only, disparity in [0, 256) px, and a ratio test (best < 0.8 x second best).

#include "ORBextractor.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <thread>
#include <vector>

int main(int argc, char** argv)
{
    const char* env = std::getenv("SPSLAM_DATA");
    const std::string data = argc > 1 ? argv[1] : (env && *env ? env : "../shared/data");
    const std::string sequence = argc > 2 ? argv[2] : "06";
    const std::string frame = argc > 3 ? argv[3] : "000000";
    const std::string base = data + "/kitti/sequences/" + sequence;
    const cv::Mat imLeft = cv::imread(base + "/image_0/" + frame + ".png", cv::IMREAD_UNCHANGED);
    const cv::Mat imRight = cv::imread(base + "/image_1/" + frame + ".png", cv::IMREAD_UNCHANGED);
    if (imLeft.empty() || imRight.empty())
    {
        std::fprintf(stderr, "cannot read %s/image_{0,1}/%s.png (give DATA_DIR or set SPSLAM_DATA)\n", base.c_str(),
                     frame.c_str());
        return 1;
    }

    // KITTI settings of ORB-SLAM3 (Examples/Stereo/KITTI04-12.yaml).
    const int nFeatures = 2000, nLevels = 8, iniThFAST = 20, minThFAST = 7;
    const float scaleFactor = 1.2f;
    ORB_SLAM3::ORBextractor* mpORBextractorLeft =
        new ORB_SLAM3::ORBextractor(nFeatures, scaleFactor, nLevels, iniThFAST, minThFAST);
    ORB_SLAM3::ORBextractor* mpORBextractorRight =
        new ORB_SLAM3::ORBextractor(nFeatures, scaleFactor, nLevels, iniThFAST, minThFAST);
    if (!mpORBextractorLeft->IsValid() || !mpORBextractorRight->IsValid())
    {
        std::fprintf(stderr, "extractor not available: %s\n", mpORBextractorLeft->GetLastError().c_str());
        delete mpORBextractorLeft;
        delete mpORBextractorRight;
        return 1;
    }

    // Frame::Frame (stereo): ExtractORB(0, imLeft, 0, 0) and ExtractORB(1, imRight, 0, 0) on two threads.
    std::vector<cv::KeyPoint> mvKeys, mvKeysRight;
    cv::Mat mDescriptors, mDescriptorsRight;
    std::vector<int> vLapping = {0, 0}, vLappingRight = {0, 0};
    int monoLeft = 0, monoRight = 0;
    const auto t0 = std::chrono::steady_clock::now();
    std::thread threadLeft([&] {
        monoLeft = (*mpORBextractorLeft)(imLeft, cv::Mat(), mvKeys, mDescriptors, vLapping);
    });
    std::thread threadRight([&] {
        monoRight = (*mpORBextractorRight)(imRight, cv::Mat(), mvKeysRight, mDescriptorsRight, vLappingRight);
    });
    threadLeft.join();
    threadRight.join();
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    if (monoLeft < 0 || monoRight < 0)
    {
        std::fprintf(stderr, "extraction failed: %s %s\n", mpORBextractorLeft->GetLastError().c_str(),
                     mpORBextractorRight->GetLastError().c_str());
        delete mpORBextractorLeft;
        delete mpORBextractorRight;
        return 1;
    }
    std::printf("%s frame %s: %zu left + %zu right keypoints, descriptors %dx%d CV_32F, extracted in parallel in %.0f ms\n",
                sequence.c_str(), frame.c_str(), mvKeys.size(), mvKeysRight.size(), mDescriptors.rows,
                mDescriptors.cols, ms);

    // Row index of the right keypoints, as Frame::ComputeStereoMatches builds it.
    const std::vector<float> mvScaleFactors = mpORBextractorLeft->GetScaleFactors();
    const int nRows = mpORBextractorLeft->mvImagePyramid[0].rows;
    std::vector<std::vector<size_t>> vRowIndices(nRows);
    for (size_t iR = 0; iR < mvKeysRight.size(); iR++)
    {
        const cv::KeyPoint& kp = mvKeysRight[iR];
        const float kpY = kp.pt.y;
        const float r = 2.0f * mvScaleFactors[mvKeysRight[iR].octave];
        const int maxr = std::min(nRows - 1, static_cast<int>(std::ceil(kpY + r)));
        const int minr = std::max(0, static_cast<int>(std::floor(kpY - r)));
        for (int yi = minr; yi <= maxr; yi++)
            vRowIndices[yi].push_back(iR);
    }

    const float minD = 0.f, maxD = 256.f, ratio = 0.8f, maxDist = 1.0f;
    std::vector<float> disparities;
    for (size_t iL = 0; iL < mvKeys.size(); iL++)
    {
        const cv::KeyPoint& kpL = mvKeys[iL];
        const int levelL = kpL.octave;
        const float vL = kpL.pt.y, uL = kpL.pt.x;
        const int row = std::min(std::max(static_cast<int>(std::lround(vL)), 0), nRows - 1);
        const std::vector<size_t>& vCandidates = vRowIndices[row];
        const float minU = uL - maxD, maxU = uL - minD;
        float best = INFINITY, second = INFINITY;
        size_t bestIdx = 0;
        const cv::Mat dL = mDescriptors.row(static_cast<int>(iL));
        for (size_t iC : vCandidates)
        {
            const cv::KeyPoint& kpR = mvKeysRight[iC];
            if (kpR.octave < levelL - 1 || kpR.octave > levelL + 1)
                continue;
            if (std::fabs(kpR.pt.y - vL) > 2.0f * mvScaleFactors[levelL])
                continue;
            const float uR = kpR.pt.x;
            if (uR < minU || uR > maxU)
                continue;
            const float dist = static_cast<float>(cv::norm(dL, mDescriptorsRight.row(static_cast<int>(iC)), cv::NORM_L2));
            if (dist < best)
            {
                second = best;
                best = dist;
                bestIdx = iC;
            }
            else if (dist < second)
                second = dist;
        }
        if (best <= maxDist && best < ratio * second)
            disparities.push_back(uL - mvKeysRight[bestIdx].pt.x);
    }

    std::printf("stereo matches: %zu of %zu left keypoints (L2 <= %.1f, ratio %.1f, |dy| <= 2 px x scale)\n",
                disparities.size(), mvKeys.size(), maxDist, ratio);
    if (!disparities.empty())
    {
        std::vector<float> sorted = disparities;
        std::sort(sorted.begin(), sorted.end());
        double sum = 0.0;
        for (float d : sorted)
            sum += d;
        const double mean = sum / sorted.size();
        double var = 0.0;
        for (float d : sorted)
            var += (d - mean) * (d - mean);
        const auto pct = [&](double q) { return sorted[static_cast<size_t>(q * (sorted.size() - 1))]; };
        std::printf("disparity (px): min %.2f, p10 %.2f, median %.2f, p90 %.2f, max %.2f, mean %.2f, std %.2f\n",
                    sorted.front(), pct(0.1), pct(0.5), pct(0.9), sorted.back(), mean,
                    std::sqrt(var / sorted.size()));
    }
    delete mpORBextractorLeft;
    delete mpORBextractorRight;
    return 0;
}
