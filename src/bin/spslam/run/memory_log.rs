//! `--memory-log`: the process's resident memory and the atlas' size every
//! N frames, written as CSV rows as they are taken (a long run that stops
//! keeps its rows) and plotted at the end of the run.

use std::fs::File;
use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use spslam::eval::{write_line_panels, LinePanel, LineSeries};
use spslam::system::SlamSystem;

/// The CSV's header.
const HEADER: &str =
    "frame,rss_mib,heap_in_use_mib,heap_free_held_mib,global_ba_running,keyframes,map_points,maps,heap_release_ms";

/// One sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MemorySample {
    /// Frames processed so far.
    pub frames: usize,
    /// Resident set size (`VmRSS`), MiB.
    pub rss_mib: f64,
    /// The allocator's live heap (`NaN` where the C library is not glibc).
    pub heap_in_use_mib: f64,
    /// Heap freed but kept by the allocator (`NaN` where not glibc).
    pub heap_free_held_mib: f64,
    /// Whether a global BA was under way: its working set (the whole
    /// map's problem) is then part of the resident memory.
    pub global_ba_running: bool,
    /// Keyframes in every map of the atlas.
    pub keyframes: usize,
    /// Map points in every map of the atlas.
    pub map_points: usize,
    /// Maps in the atlas (merged ones included: they are still held).
    pub maps: usize,
    /// How long the freed heap's hand-backs since the previous sample took
    /// (ms; `spslam::ffi::release_free_heap`).
    pub heap_release_ms: f64,
}

/// The open log.
pub struct MemoryLog {
    path: PathBuf,
    file: File,
    every: usize,
    samples: Vec<MemorySample>,
    /// Hand-back time since the last sample (ms).
    release_ms: f64,
}

/// The process's resident set size in MiB (`VmRSS` of `/proc/self/status`),
/// or `None` where that file does not exist (not Linux).
pub fn resident_mib() -> Option<f64> {
    let status = File::open("/proc/self/status").ok()?;
    BufReader::new(status)
        .lines()
        .map_while(|l| l.ok())
        .find_map(|line| {
            let kib = line.strip_prefix("VmRSS:")?.trim().strip_suffix("kB")?;
            kib.trim().parse::<f64>().ok().map(|k| k / 1024.0)
        })
}

impl MemoryLog {
    /// Creates the CSV file and writes its header; samples every `every`
    /// frames (at least 1).
    pub fn create(path: &Path, every: usize) -> Result<Self> {
        if resident_mib().is_none() {
            anyhow::bail!(
                "--memory-log needs /proc/self/status (Linux) to read the resident memory"
            );
        }
        let mut file =
            File::create(path).with_context(|| format!("cannot create {}", path.display()))?;
        writeln!(file, "{HEADER}").with_context(|| format!("cannot write {}", path.display()))?;
        Ok(Self {
            path: path.to_path_buf(),
            file,
            every: every.max(1),
            samples: Vec::new(),
            release_ms: 0.0,
        })
    }

    /// Counts one hand-back of freed heap that took `ms`; the next sample
    /// reports the sum.
    pub fn heap_released(&mut self, ms: f64) {
        self.release_ms += ms;
    }

    /// Takes a sample when `frames` (processed so far) is a multiple of the
    /// interval, and appends its row to the file.
    pub fn after_frame(&mut self, frames: usize, slam: &SlamSystem) -> Result<()> {
        if !frames.is_multiple_of(self.every) {
            return Ok(());
        }
        let maps = slam.atlas().maps();
        let (mut keyframes, mut map_points) = (0, 0);
        for m in maps {
            // A short read lock per map; a poisoned map is counted as empty
            // (the run reports the poisoning itself).
            if let Ok(map) = m.map.read() {
                keyframes += map.keyframe_count();
                map_points += map.map_point_count();
            }
        }
        let heap = spslam::ffi::heap_usage();
        let sample = MemorySample {
            frames,
            rss_mib: resident_mib().unwrap_or(f64::NAN),
            heap_in_use_mib: heap.map_or(f64::NAN, |h| h.in_use_mib),
            heap_free_held_mib: heap.map_or(f64::NAN, |h| h.free_held_mib),
            global_ba_running: slam.global_ba_running(),
            keyframes,
            map_points,
            maps: maps.len(),
            heap_release_ms: std::mem::take(&mut self.release_ms),
        };
        writeln!(
            self.file,
            "{},{:.1},{:.1},{:.1},{},{},{},{},{:.2}",
            sample.frames,
            sample.rss_mib,
            sample.heap_in_use_mib,
            sample.heap_free_held_mib,
            u8::from(sample.global_ba_running),
            sample.keyframes,
            sample.map_points,
            sample.maps,
            sample.heap_release_ms
        )
        .and_then(|()| self.file.flush())
        .with_context(|| format!("cannot write {}", self.path.display()))?;
        self.samples.push(sample);
        Ok(())
    }

    /// Plots the samples (resident memory; keyframes; map points) into `png`.
    pub fn plot(&self, png: &Path, title: &str) -> Result<()> {
        let series = |name: &str, value: fn(&MemorySample) -> f64| LineSeries {
            name: name.to_string(),
            points: self
                .samples
                .iter()
                .map(|s| (s.frames as f64, value(s)))
                .collect(),
        };
        let panels = [
            LinePanel {
                y_label: "resident memory, MiB".into(),
                series: vec![
                    series("RSS", |s| s.rss_mib),
                    series("heap in use", |s| s.heap_in_use_mib),
                    series("heap freed, held", |s| s.heap_free_held_mib),
                ],
            },
            LinePanel {
                y_label: "keyframes".into(),
                series: vec![series("keyframes (all maps)", |s| s.keyframes as f64)],
            },
            LinePanel {
                y_label: "map points, thousands".into(),
                series: vec![series("map points (all maps)", |s| {
                    s.map_points as f64 / 1e3
                })],
            },
        ];
        write_line_panels(png, title, "frames processed", &panels)
            .with_context(|| format!("cannot plot {}", png.display()))
    }
}
