//! The outputs of `spslam run`, written from the system's state however
//! the run ended: the trajectory, the keyframe trajectory, report.txt,
//! report.json and, with ground truth, the evaluation and its plots.

use std::path::{Path, PathBuf};

use anyhow::{anyhow, Context, Result};
use spslam::eval::{write_kitti, write_tum, EvalReport, Trajectory};
use spslam::loop_closing::GlobalBaSummary;
use spslam::optim::Se3;
use spslam::settings::SlamSettings;
use spslam::system::{
    FrameRecord, LoopRecord, MergeRecord, RejectedLoopRecord, SlamSummary, SlamSystem,
};

use crate::plot_plane::PlotPlaneChoice;

use super::candidate_truth::{judge_candidates, JudgedCandidate};
use super::evaluation::{evaluate_run, ground_truth_row, Drift, LinkTruth, RunEvaluation};
use super::frame_loop::{RunEnd, UnreadableFrame};
use super::source::Source;
use spslam::camera::Sensor;
use spslam::eval::ScaleDrift;
use spslam::tracking::TrackingState;

/// Where and what to write, besides the system's state.
pub struct RunOutputs<'a> {
    /// The output folder (it exists).
    pub out: &'a Path,
    /// `--dataset` as given.
    pub dataset: &'a str,
    /// The sequence (its layout and ground truth).
    pub source: &'a Source,
    /// The settings the run used.
    pub settings: &'a SlamSettings,
    /// The camera the run used.
    pub sensor: Sensor,
    /// The number of input frames requested.
    pub frames_total: usize,
    /// How the extractor ran, e.g. `int8 on cpu, 2 levels`.
    pub inference: &'a str,
    /// How local mapping ran (`inline`, `thread`, `thread, 5x slowed`).
    pub mapping: &'a str,
    /// Wall time of the frame loop (extraction pipelined with tracking)
    /// and of local mapping's last keyframes, s.
    pub wall_seconds: f64,
    /// `--plot-plane`.
    pub plot_plane: PlotPlaneChoice,
    /// `--lost-rows`.
    pub lost_rows: LostRows,
}

/// What a frame without a pose gets in the trajectory file (`--lost-rows`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum LostRows {
    /// The last tracked pose carried on at the last velocity
    /// (`spslam::system::GAP_HORIZON_S`), then held.
    Predict,
    /// No row (TUM-format trajectories only).
    Omit,
}

/// report.json.
#[derive(serde::Serialize)]
struct RunReport<'a> {
    dataset: &'a str,
    /// `mono`, `stereo` or `rgbd`.
    sensor: Sensor,
    extractor: &'a str,
    /// How the extractor ran, e.g. `int8 on cpu, 2 levels`.
    inference: &'a str,
    /// How local mapping ran: `inline`, `thread` or `thread, Fx slowed`
    /// (`--mapping-slowdown`).
    mapping: &'a str,
    /// Wall time of the frame loop and local mapping's finish, s.
    wall_seconds: f64,
    /// Wall time per processed frame, ms (the figure to compare runs by).
    wall_ms_per_frame: f64,
    /// Whether every requested frame was processed.
    complete: bool,
    /// `complete`, `interrupted` or `failed: <error>`.
    end: String,
    /// The signal that interrupted the run.
    signal: Option<&'static str>,
    /// Input frames requested.
    frames_total: usize,
    /// Input frames processed (one trajectory row each).
    frames_processed: usize,
    /// The frames skipped because they could not be read.
    unreadable_frames: &'a [UnreadableFrame],
    settings: &'a SlamSettings,
    summary: Option<&'a SlamSummary>,
    evaluation: Option<&'a EvalReport>,
    /// Final-position drift (KITTI-layout runs with ground truth; not for
    /// monocular runs, whose scale is arbitrary).
    drift: Option<Drift>,
    /// Monocular runs: the Sim(3) scale fitted on the first and the last
    /// third of the trajectory, and their ratio.
    scale_drift: Option<ScaleDrift>,
    /// Loops accepted and corrected: query and match input frames,
    /// inliers, the correction's size.
    loops: &'a [LoopRecord],
    /// Loop candidates that passed the descriptor stage and were rejected
    /// later, with the stage and the count reached there.
    rejected_loops: &'a [RejectedLoopRecord],
    /// Merges of the active map into an older map of the atlas: query and
    /// match input frames, the maps, inliers, the transform between them.
    merges: &'a [MergeRecord],
    /// The accepted loops, then the merges, against the ground truth
    /// (runs with ground truth): the true distance between the frames
    /// joined, and whether they are the same place (within 10 m).
    links_ground_truth: Option<&'a [LinkTruth]>,
    /// The global bundle adjustments run after the corrections.
    global_ba: &'a [GlobalBaSummary],
    /// With `--record-loop-stages`: every loop and merge candidate checked,
    /// each stage's count, and (with ground truth) its registration's
    /// truth.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    loop_candidates: Vec<JudgedCandidate<'a>>,
    frames: &'a [FrameRecord],
}

/// `(timestamp, T_wc)` rows as an evaluation trajectory.
fn to_trajectory(poses: &[(f64, Se3)]) -> Trajectory {
    Trajectory::new(
        poses.iter().map(|(t, _)| *t).collect(),
        poses.iter().map(|(_, p)| p.to_isometry()).collect(),
    )
}

/// The first line of report.txt: whether the run is complete.
fn status_line(end: &RunEnd, processed: usize, total: usize, unreadable: usize) -> String {
    let skipped = match unreadable {
        0 => String::new(),
        1 => ", 1 unreadable frame skipped (counted as lost)".into(),
        n => format!(", {n} unreadable frames skipped (counted as lost)"),
    };
    match end {
        RunEnd::Complete => format!("run complete: {processed} of {total} frames processed{skipped}\n"),
        RunEnd::Interrupted { signal } => format!(
            "run INCOMPLETE (interrupted by {signal}): {processed} of {total} frames processed{skipped}; the outputs cover those\n"
        ),
        RunEnd::Failed { error } => format!(
            "run INCOMPLETE (failed: {error}): {processed} of {total} frames processed{skipped}; the outputs cover those\n"
        ),
    }
}

/// The timestamp of input frame `frame`, when the run processed it.
fn frame_time(slam: &SlamSystem, frame: usize) -> Option<f64> {
    slam.records()
        .iter()
        .find(|r| r.index == frame)
        .map(|r| r.timestamp)
}

/// The accepted loops as pairs of frame timestamps, for the plot.
fn loop_links(slam: &SlamSystem) -> Vec<(f64, f64)> {
    let time = |frame: usize| frame_time(slam, frame);
    let loops = slam.loops().iter().map(|l| (l.query_frame, l.match_frame));
    let merges = slam.merges().iter().map(|m| (m.query_frame, m.match_frame));
    loops
        .chain(merges)
        .filter_map(|(q, m)| Some((time(q)?, time(m)?)))
        .collect()
}

/// One line per accepted loop, and the rejected candidates' count by stage.
fn loops_text(loops: &[LoopRecord], rejected: &[RejectedLoopRecord]) -> String {
    let mut text = format!(
        "loops closed: {}; candidates rejected after the descriptor stage: {}\n",
        loops.len(),
        rejected.len()
    );
    for l in loops {
        text.push_str(&format!(
            "loop: frame {} -> frame {}, {} inliers, {} confirmations, correction {:.3} m / {:.2} deg, essential graph {} edges in {:.1} ms\n",
            l.query_frame,
            l.match_frame,
            l.inliers,
            l.confirmations,
            l.correction_m,
            l.correction_deg,
            l.correction.graph_edges,
            l.correction.graph_ms
        ));
    }
    for r in rejected {
        let kind = match r.other_map {
            Some(m) => format!("merge candidate in map {m}"),
            None => "loop candidate".to_string(),
        };
        text.push_str(&format!(
            "rejected {kind}: frame {} -> frame {} (score {:.3}) at {:?} ({})\n",
            r.query_frame, r.candidate_frame, r.score, r.stage, r.count
        ));
    }
    text
}

/// One line per merge of the active map into an older one.
fn merges_text(merges: &[MergeRecord]) -> String {
    let mut text = String::new();
    for m in merges {
        // A monocular map's scale; stereo and RGB-D merges are rigid.
        let scale = if m.scale == 1.0 {
            String::new()
        } else {
            format!(", scaled by {:.3}", m.scale)
        };
        text.push_str(&format!(
            "map merge: map {} into map {} at frame {} -> frame {}, {} inliers, {} confirmations, maps {:.2} m / {:.1} deg apart{scale}, {} points fused\n",
            m.merged_map,
            m.into_map,
            m.query_frame,
            m.match_frame,
            m.inliers,
            m.confirmations,
            m.transform_m,
            m.transform_deg,
            m.correction.fused
        ));
    }
    text
}

/// The tracked frames that were localised after the fact, in brackets
/// (empty when there are none).
fn localised_late_text(s: &SlamSummary) -> String {
    let mut parts = Vec::new();
    if s.between_initial_views > 0 {
        parts.push(format!(
            "{} between the monocular initial views",
            s.between_initial_views
        ));
    }
    if s.localised_after_loss > 0 {
        parts.push(format!("{} localised after a loss", s.localised_after_loss));
    }
    if s.corroborated > 0 {
        parts.push(format!(
            "{} lost by tracking, their poses corroborated",
            s.corroborated
        ));
    }
    if s.by_odometry > 0 {
        parts.push(format!(
            "{} lost by tracking, their motion measured by odometry",
            s.by_odometry
        ));
    }
    if parts.is_empty() {
        String::new()
    } else {
        format!(" ({})", parts.join(", "))
    }
}

/// The totals, the mean timings and one line per atlas map.
fn summary_text(dataset: &str, extractor: &str, s: &SlamSummary) -> String {
    let t = &s.mean_timings;
    let mut text = format!(
        "dataset {dataset}, extractor {extractor}\n\
         frames {}: tracked {}{}, lost {} (tracking failures and {} unreadable), before initialisation {}, relocalisations {}\n\
         keyframes inserted {}, live {}; map points {}\n\
         mean ms/frame: extraction {:.1}, stereo {:.1}, tracking {:.1}, mapping {:.1}\n",
        s.frames,
        s.tracked,
        localised_late_text(s),
        s.lost,
        s.unreadable,
        s.not_initialised,
        s.relocalisations,
        s.keyframes_inserted,
        s.keyframes,
        s.map_points,
        t.extraction_ms,
        t.stereo_ms,
        t.tracking_ms,
        t.mapping_ms
    );
    for m in &s.maps {
        text.push_str(&format!(
            "map {}: first frame {}, {} frames, {} tracked, {} keyframes, {} map points",
            m.index, m.first_frame, m.frames, m.tracked, m.keyframes, m.map_points
        ));
        match (m.index, m.anchored_at_frame, m.merged_into) {
            (_, _, Some(into)) => text.push_str(&format!(
                "; merged into map {into}: its keyframes, points and frames are in that map now"
            )),
            (0, _, _) => {}
            (k, Some(n), _) => text.push_str(&format!(
                "; anchored at frame {n}: frames of map {k} are anchored where the pose of frame {n}, the last tracked before the loss, carried on at its velocity for up to {horizon} s, puts them",
                horizon = spslam::system::GAP_HORIZON_S
            )),
            (_, None, _) => {
                text.push_str("; no frame tracked in it: its frames carry on the last known pose and velocity")
            }
        }
        text.push('\n');
    }
    text
}

impl RunOutputs<'_> {
    /// Writes the outputs of every frame processed so far. Each output is
    /// attempted even when an earlier one failed; the failures come back
    /// (empty when everything was written).
    pub fn write(
        &self,
        slam: &SlamSystem,
        end: &RunEnd,
        unreadable: &[UnreadableFrame],
    ) -> Vec<anyhow::Error> {
        let mut problems = Vec::new();
        let mut written: Vec<PathBuf> = Vec::new();
        let mut keep = |result: Result<PathBuf>, problems: &mut Vec<anyhow::Error>| match result {
            Ok(path) => written.push(path),
            Err(e) => problems.push(e),
        };

        let trajectory = slam
            .trajectory()
            .map(|poses| to_trajectory(&self.rows_written(poses, slam.records())));
        let trajectory = match trajectory {
            Ok(t) => {
                keep(self.write_trajectory(&t), &mut problems);
                Some(t)
            }
            Err(e) => {
                problems.push(anyhow!("cannot compute the trajectory: {e}"));
                None
            }
        };
        match slam.keyframe_trajectory() {
            Ok(k) => {
                let path = self.out.join("keyframes_tum.txt");
                let result = write_tum(&path, &to_trajectory(&k))
                    .with_context(|| format!("cannot write {}", path.display()))
                    .map(|()| path);
                keep(result, &mut problems);
            }
            Err(e) => problems.push(anyhow!("cannot compute the keyframe trajectory: {e}")),
        }

        let records = slam.records();
        let extractor = slam.extractor_name().to_string();
        let mut text = status_line(end, records.len(), self.frames_total, unreadable.len());
        let wall_ms_per_frame = 1e3 * self.wall_seconds / records.len().max(1) as f64;
        let summary = match slam.summary() {
            Ok(s) => {
                text.push_str(&summary_text(self.dataset, &extractor, &s));
                text.push_str(&format!(
                    "extractor ran as {}; wall time {:.1} s, {wall_ms_per_frame:.1} ms/frame (extraction of frame t+1 overlaps tracking of frame t)\n",
                    self.inference, self.wall_seconds
                ));
                Some(s)
            }
            Err(e) => {
                problems.push(anyhow!("cannot summarise the run: {e}"));
                None
            }
        };
        text.push_str(&loops_text(slam.loops(), slam.rejected_loops()));
        text.push_str(&merges_text(slam.merges()));
        for g in slam.global_ba_runs() {
            text.push_str(&if let Some(failure) = &g.failure {
                format!("global BA: failed and skipped (the map keeps its corrected poses): {failure}\n")
            } else if g.aborted {
                "global BA: aborted by a newer loop\n".to_string()
            } else {
                format!(
                    "global BA: {} keyframes, {} points, {} observations in {:.0} ms; {} keyframes made meanwhile moved with their parents\n",
                    g.keyframes, g.points, g.observations, g.solve_ms, g.propagated_keyframes
                )
            });
        }
        for u in unreadable {
            text.push_str(&format!(
                "unreadable frame {} (skipped, counted as lost): {}: {}\n",
                u.index, u.path, u.reason
            ));
        }
        let evaluated = match &trajectory {
            Some(t) => match self.evaluate(t, end, &loop_links(slam), &mut text) {
                Ok(found) => found,
                Err(e) => {
                    text.push_str(&format!("evaluation failed: {e:#}\n"));
                    problems.push(e.context("evaluation failed"));
                    RunEvaluation::default()
                }
            },
            None => RunEvaluation::default(),
        };

        print!("{text}");
        let path = self.out.join("report.txt");
        let result = std::fs::write(&path, &text)
            .with_context(|| format!("cannot write {}", path.display()))
            .map(|()| path);
        keep(result, &mut problems);
        let loop_candidates = self.judge_loop_candidates(slam, trajectory.as_ref(), &evaluated);
        let report = RunReport {
            dataset: self.dataset,
            sensor: self.sensor,
            extractor: &extractor,
            inference: self.inference,
            mapping: self.mapping,
            wall_seconds: self.wall_seconds,
            wall_ms_per_frame,
            complete: end.is_complete(),
            end: end.label(),
            signal: end.signal(),
            frames_total: self.frames_total,
            frames_processed: records.len(),
            unreadable_frames: unreadable,
            settings: self.settings,
            summary: summary.as_ref(),
            evaluation: evaluated.report.as_ref(),
            drift: evaluated.drift,
            scale_drift: evaluated.scale_drift,
            loops: slam.loops(),
            rejected_loops: slam.rejected_loops(),
            merges: slam.merges(),
            links_ground_truth: evaluated.links.as_deref(),
            global_ba: slam.global_ba_runs(),
            loop_candidates,
            frames: records,
        };
        keep(self.write_json(&report), &mut problems);
        if !written.is_empty() {
            let names: Vec<String> = written.iter().map(|p| p.display().to_string()).collect();
            println!("wrote {}", names.join(", "));
        }
        problems
    }

    /// The trajectory's rows as `--lost-rows` asks: every frame's, or the
    /// tracked frames' only.
    fn rows_written(&self, poses: Vec<(f64, Se3)>, records: &[FrameRecord]) -> Vec<(f64, Se3)> {
        match self.lost_rows {
            LostRows::Predict => poses,
            LostRows::Omit => poses
                .into_iter()
                .zip(records)
                .filter(|(_, r)| r.state == TrackingState::Ok)
                .map(|(row, _)| row)
                .collect(),
        }
    }

    /// `trajectory_kitti.txt` (KITTI layout) or `trajectory_tum.txt` (EuRoC).
    fn write_trajectory(&self, trajectory: &Trajectory) -> Result<PathBuf> {
        let (path, result) = if self.source.is_kitti() {
            let p = self.out.join("trajectory_kitti.txt");
            let r = write_kitti(&p, trajectory);
            (p, r)
        } else {
            let p = self.out.join("trajectory_tum.txt");
            let r = write_tum(&p, trajectory);
            (p, r)
        };
        result.with_context(|| format!("cannot write {}", path.display()))?;
        Ok(path)
    }

    /// The evaluation of the rows written, when there is ground truth.
    fn evaluate(
        &self,
        trajectory: &Trajectory,
        end: &RunEnd,
        links: &[(f64, f64)],
        text: &mut String,
    ) -> Result<RunEvaluation> {
        let Some(gt) = self.source.ground_truth(trajectory.len())? else {
            return Ok(RunEvaluation::default());
        };
        if !end.is_complete() {
            text.push_str(&format!(
                "evaluated over the {} frames processed\n",
                trajectory.len()
            ));
        }
        evaluate_run(
            self.source,
            self.sensor,
            &gt,
            trajectory,
            self.out,
            links,
            self.plot_plane,
            text,
        )
    }

    /// The recorded loop and merge candidates, judged against the ground
    /// truth the run was evaluated with (not judged without one).
    fn judge_loop_candidates<'s>(
        &self,
        slam: &'s SlamSystem,
        estimate: Option<&Trajectory>,
        evaluated: &RunEvaluation,
    ) -> Vec<JudgedCandidate<'s>> {
        let candidates = slam.loop_candidates();
        let empty = Trajectory::new(Vec::new(), Vec::new());
        let gt = evaluated.ground_truth.as_ref().unwrap_or(&empty);
        let estimate = estimate.unwrap_or(&empty);
        let by_index = self.source.is_kitti();
        let row = |frame| ground_truth_row(gt, estimate, by_index, frame_time(slam, frame)?);
        judge_candidates(candidates, gt, row, self.sensor != Sensor::Monocular)
    }

    /// `report.json`.
    fn write_json(&self, report: &RunReport<'_>) -> Result<PathBuf> {
        let path = self.out.join("report.json");
        let file = std::fs::File::create(&path)
            .with_context(|| format!("cannot create {}", path.display()))?;
        let mut writer = std::io::BufWriter::new(file);
        serde_json::to_writer_pretty(&mut writer, report)
            .with_context(|| format!("cannot write {}", path.display()))?;
        std::io::Write::flush(&mut writer)
            .with_context(|| format!("cannot write {}", path.display()))?;
        Ok(path)
    }
}
