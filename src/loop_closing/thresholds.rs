//! The loop check's thresholds, ORB-SLAM3's (`LoopClosing.cc`,
//! `DetectCommonRegionsFromBoW` and `DetectAndReffineSim3FromLastKF`) with
//! SuperPoint's L2 descriptor thresholds in the matchers.

/// Every count the multi-stage loop check needs, in the order it needs them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LoopThresholds {
    /// Keyframes in the map before any loop is looked for (ORB-SLAM3: 12,
    /// `KeyFramesInMap() < 12`).
    pub min_keyframes: usize,
    /// Candidates taken from the keyframe database per keyframe (ORB-SLAM3's
    /// `DetectNBestCandidates(…, 3, …)`).
    pub candidates: usize,
    /// Covisible keyframes of the candidate whose points join the search
    /// (ORB-SLAM3's `nNumCovisibles = 10`).
    pub group_size: usize,
    /// Ratio test of the descriptor matching against the candidate group.
    /// ORB-SLAM3 uses 0.9 with Hamming distances; SuperPoint's L2 distances
    /// are less spread, so relocalisation's 0.75 is used (a tighter test:
    /// zero false loops is the hard requirement).
    pub match_ratio: f32,
    /// Descriptor matches with the candidate group (ORB-SLAM3's
    /// `nBoWMatches = 20`).
    pub min_matches: usize,
    /// RANSAC inliers of the relative pose (ORB-SLAM3's `nBoWInliers = 15`).
    pub min_ransac_inliers: usize,
    /// Fraction of the descriptor matches the RANSAC pose must explain (not
    /// in ORB-SLAM3). A revisited place is one rigid transform for the whole
    /// view; perceptual aliasing (the same textures on differently arranged
    /// surfaces) splits the matches between transforms. Chosen from the
    /// curves of `spslam evaluate --set loopcheck` (EVALUATION.md, "The loop
    /// check's thresholds"): over nine runs, every candidate the ground
    /// truth calls wrong explains at most 0.69 of its matches (the aliasing
    /// street, whose look-alike at 0.69 passed every later stage at 0.6 and
    /// was closed as a 105 m false loop), every right one that passes the
    /// other stages 0.86–0.97; the real EuRoC loop pair 0.85 (69 of 81). The
    /// cost: the 7-Scenes kitchen's right candidates explain 0.53–0.78, so
    /// its revisits fall here more often (they fail at the pose
    /// optimisation anyway).
    pub min_ransac_inlier_ratio: f32,
    /// Inliers of the pose optimisation on the matches (ORB-SLAM3's
    /// `nSim3Inliers = 20`).
    pub min_optimised_inliers: usize,
    /// Matches after the first search by projection, window 10 px
    /// (ORB-SLAM3's `nProjMatches = 50`).
    pub min_projection_matches: usize,
    /// Inliers after the second search by projection, window 3 px, and a
    /// last optimisation (ORB-SLAM3's `nProjOptMatches = 80`).
    pub min_reprojection_inliers: usize,
    /// The largest correction, as a fraction of the way travelled since
    /// the candidate (path in metres, turns in degrees), that drift
    /// explains; a monocular map's turns only (not in ORB-SLAM3 for visual
    /// maps; its inertial maps reject a loop that turns gravity: see
    /// [`super::LoopDrift`]). Chosen from `spslam evaluate --set loopcheck`
    /// (EVALUATION.md, "A plausibility gate for loop corrections"): the
    /// right loops there corrected at most 0.51 % of their path, the
    /// repeated-texture look-alikes asked for 87 % and 91 %.
    pub max_drift_ratio: f64,
    /// The translation a correction may have however short the way: this
    /// fraction of the query's median scene depth (a keyframe's position is
    /// known to a fraction of what it sees).
    pub drift_floor_depths: f64,
    /// The rotation a correction may have however little the camera
    /// turned (degrees): ORB-SLAM3's bound on an inertial map's loop yaw
    /// (`LoopClosing::Run`: 0.349 rad).
    pub drift_floor_deg: f64,
    /// How many times its speed before the loss (or in the new map, if
    /// faster) the camera may have moved while lost, for a merge of the
    /// map started after the loss into the map it left
    /// ([`super::HandoverGap`]; not in ORB-SLAM3). 3 leaves room for a
    /// camera that speeds up while it is lost (a judgement, not fitted:
    /// the kidnapped lap's true merge used 0.26 of the bound, EVALUATION.md,
    /// "A handover stage for merges").
    pub max_handover_speedup: f64,
    /// Inliers needed by a covisible or a later keyframe to confirm the loop
    /// at the same correction (ORB-SLAM3's `DetectAndReffineSim3FromLastKF`:
    /// `nProjOptMatches = 50`).
    pub min_confirmation_inliers: usize,
    /// Keyframes agreeing on the loop, the detecting one included, before
    /// it is accepted (ORB-SLAM3's `mnLoopNumCoincidences >= 3`).
    pub confirmations: usize,
    /// Covisible keyframes of the detecting keyframe tried as confirmers
    /// (ORB-SLAM3's `nNumCovisibles = 5` there).
    pub confirming_covisibles: usize,
    /// Later keyframes that may fail to confirm before a pending loop is
    /// dropped (ORB-SLAM3's `mnLoopNumNotFound >= 2`).
    pub max_misses: usize,
    /// Not a threshold: run every stage of a candidate's check, even past
    /// one that fails, as far as the geometry allows, so that the run's
    /// record of the check holds each stage's count (`spslam run
    /// --record-loop-stages`, for the precision–recall curves of these
    /// thresholds). Verdicts are the same; only the time spent grows.
    pub record_every_stage: bool,
}

impl Default for LoopThresholds {
    fn default() -> Self {
        Self {
            min_keyframes: 12,
            candidates: 3,
            group_size: 10,
            match_ratio: 0.75,
            min_matches: 20,
            min_ransac_inliers: 15,
            min_ransac_inlier_ratio: 0.75,
            min_optimised_inliers: 20,
            min_projection_matches: 50,
            min_reprojection_inliers: 80,
            max_drift_ratio: 0.1,
            drift_floor_depths: 0.1,
            drift_floor_deg: 20.0,
            max_handover_speedup: 3.0,
            min_confirmation_inliers: 50,
            confirmations: 3,
            confirming_covisibles: 5,
            max_misses: 2,
            record_every_stage: false,
        }
    }
}
