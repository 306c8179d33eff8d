//! Coverage-guided fuzzing of every `extern "C"` function of spslam's C ABI
//! (`include/spslam.h`): each input is a sequence of calls, in any order,
//! with handles that are live, NULL, destroyed, of the other kind or made up;
//! image sizes and strides from 0 and 1 to `usize::MAX`; buffers shorter than
//! the geometry; configs with every field anywhere in its type's range; NULL
//! output pointers and arrays shorter than the level count.
//!
//! The harness never lies about what it owns: `data_len` is at most the
//! buffer it allocated, and array capacities are at most their lengths. Those
//! are the caller's side of the contract; everything else is the library's
//! to check. Every handle created in an input is destroyed at its end, so a
//! leak found by LeakSanitizer is the library's.
//!
//! Models: the tiny model (`make_tiny_model.py`, `$SPSLAM_FUZZ_TINY_MODEL`)
//! keeps creation and extraction at about a millisecond; a missing file and a
//! file that is not ONNX cover the model errors. See `fuzz/README.md`.

#![no_main]

use std::ffi::{c_char, CStr, CString};
use std::ptr;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::OnceLock;

use arbitrary::Arbitrary;
use libfuzzer_sys::fuzz_target;
use spslam::ffi::*;

/// The model paths a config can name (NUL-terminated, alive for the process).
struct Models {
    tiny: CString,
    missing: CString,
    not_onnx: CString,
}

fn models() -> &'static Models {
    static MODELS: OnceLock<Models> = OnceLock::new();
    MODELS.get_or_init(|| {
        let tiny = std::env::var("SPSLAM_FUZZ_TINY_MODEL").unwrap_or_else(|_| {
            concat!(env!("CARGO_MANIFEST_DIR"), "/target/tiny_superpoint.onnx").to_string()
        });
        assert!(
            std::path::Path::new(&tiny).is_file(),
            "{tiny} is missing: run fuzz/run.sh (it writes it with make_tiny_model.py)"
        );
        Models {
            tiny: CString::new(tiny).expect("no NUL in the path"),
            missing: c"/nonexistent/superpoint.onnx".to_owned(),
            // A file that exists and is not a model.
            not_onnx: CString::new(concat!(env!("CARGO_MANIFEST_DIR"), "/Cargo.toml"))
                .expect("no NUL in the path"),
        }
    })
}

/// How often the calls that need a working model succeeded, printed every
/// 2^16 inputs when `SPSLAM_FUZZ_STATS` is set (to see that the fuzzer
/// gets past the argument checks).
static INPUTS: AtomicUsize = AtomicUsize::new(0);
static CREATED: AtomicUsize = AtomicUsize::new(0);
static EXTRACTED: AtomicUsize = AtomicUsize::new(0);
static KEYPOINTS: AtomicUsize = AtomicUsize::new(0);

/// Which handle a call gets.
#[derive(Arbitrary, Debug, Clone, Copy)]
enum HandleChoice {
    Null,
    /// A live handle of this input (index modulo their number; NULL when none).
    Live(u8),
    /// A destroyed handle of this input.
    Destroyed(u8),
    /// A live handle of the other kind, cast.
    OtherKind(u8),
    /// An address this library never returned.
    MadeUp(usize),
}

/// A size or stride: small values, boundaries and anything.
#[derive(Arbitrary, Debug, Clone, Copy)]
enum Size {
    Small(u8),
    Exact(u16),
    Any(usize),
    Max,
    HalfMax,
}

impl Size {
    fn value(self) -> usize {
        match self {
            Size::Small(v) => v as usize,
            Size::Exact(v) => v as usize,
            Size::Any(v) => v,
            Size::Max => usize::MAX,
            Size::HalfMax => usize::MAX / 2 + 1,
        }
    }
}

/// An image geometry: anything, or one that fits its buffer (so that
/// extraction is reached often, not only when the fuzzer guesses three
/// related sizes).
#[derive(Arbitrary, Debug, Clone, Copy)]
enum Geometry {
    Free {
        /// Bytes the harness allocates (modulo 16 KiB + 1).
        buffer_len: u16,
        /// How many of them it says are readable (at most `buffer_len`).
        claimed_len: Size,
        width: Size,
        height: Size,
        stride: Size,
    },
    /// 16..=79 × 16..=79 pixels, rows `padding % 8` bytes longer (small:
    /// the code paths are the same at any size, and small images keep an
    /// input at about a millisecond).
    Fitting { width: u8, height: u8, padding: u8 },
}

impl Geometry {
    /// (buffer length, claimed length, width, height, stride).
    fn resolve(self) -> (usize, usize, usize, usize, usize) {
        match self {
            Geometry::Free {
                buffer_len,
                claimed_len,
                width,
                height,
                stride,
            } => {
                let buffer = buffer_len as usize % (16 * 1024 + 1);
                (
                    buffer,
                    claimed_len.value().min(buffer),
                    width.value(),
                    height.value(),
                    stride.value(),
                )
            }
            Geometry::Fitting {
                width,
                height,
                padding,
            } => {
                let (w, h) = (16 + width as usize % 64, 16 + height as usize % 64);
                let stride = w + padding as usize % 8;
                let len = stride * (h - 1) + w;
                (len, len, w, h, stride)
            }
        }
    }
}

#[derive(Arbitrary, Debug, Clone, Copy)]
enum ModelChoice {
    /// The tiny model. (The precision's default models are not used: they
    /// take a second to load; `tests/ffi_abi.rs` covers them.)
    Tiny,
    /// A path that does not exist.
    Missing,
    /// A file that exists and is not ONNX.
    NotOnnx,
}

/// The thread count: 1, or out of range. (0 and 2 start ONNX Runtime's
/// thread pool, whose workers spin after every run: half the fuzzer's
/// time went there, in code that is not spslam's; the ABI passes any
/// valid count through the same way.)
#[derive(Arbitrary, Debug, Clone, Copy)]
enum Threads {
    One,
    TooMany(u32),
}

/// Every field of `SpslamConfig`, anywhere in its type's range (threads
/// excepted: see [`Threads`]).
#[derive(Arbitrary, Debug, Clone, Copy)]
struct FuzzConfig {
    from_orb_slam3: bool,
    n_features: u32,
    scale_factor: f32,
    n_levels: u8,
    n_levels_any: Option<u32>,
    threshold: f32,
    min_threshold: f32,
    nms_radius: u32,
    border: u32,
    anms: i32,
    filter_enabled: i32,
    lattice_min_support: u32,
    min_contrast: f32,
    contrast_radius: u32,
    threads: Threads,
    precision: i32,
    device: i32,
    model: ModelChoice,
    /// Keep the default values of the numeric fields (so that creation
    /// succeeds often enough to reach extraction).
    keep_defaults: bool,
}

#[derive(Arbitrary, Debug)]
enum Op {
    Version,
    LastError,
    ConfigDefault {
        null_out: bool,
    },
    ConfigFromOrbSlam3 {
        nfeatures: i32,
        scale_factor: f32,
        nlevels: i32,
        ini_th_fast: i32,
        min_th_fast: i32,
        null_out: bool,
    },
    Create {
        config: FuzzConfig,
        null_config: bool,
        null_out: bool,
    },
    DestroyExtractor(HandleChoice),
    Extract {
        extractor: HandleChoice,
        geometry: Geometry,
        /// Pixel pattern seed.
        fill: u8,
        null_data: bool,
        null_out: bool,
    },
    View {
        features: HandleChoice,
        null_out: bool,
    },
    BinaryView {
        features: HandleChoice,
        null_out: bool,
    },
    Count {
        features: HandleChoice,
        null_out: bool,
    },
    DestroyFeatures(HandleChoice),
    DescriptorLen {
        extractor: HandleChoice,
        null_out: bool,
    },
    Device {
        extractor: HandleChoice,
        null_out: bool,
    },
    Levels {
        extractor: HandleChoice,
        null_out: bool,
    },
    ScaleTables {
        extractor: HandleChoice,
        capacity: u8,
        /// Bit i set: array i is NULL.
        null_arrays: u8,
    },
}

/// The handles one input created, live and destroyed.
#[derive(Default)]
struct Handles {
    extractors: Vec<*mut SpslamExtractor>,
    destroyed_extractors: Vec<*mut SpslamExtractor>,
    features: Vec<*mut SpslamFeatures>,
    destroyed_features: Vec<*mut SpslamFeatures>,
}

fn pick<T>(list: &[*mut T], index: u8) -> *mut T {
    if list.is_empty() {
        ptr::null_mut()
    } else {
        list[index as usize % list.len()]
    }
}

impl Handles {
    fn extractor(&self, choice: HandleChoice) -> *mut SpslamExtractor {
        match choice {
            HandleChoice::Null => ptr::null_mut(),
            HandleChoice::Live(i) => pick(&self.extractors, i),
            HandleChoice::Destroyed(i) => pick(&self.destroyed_extractors, i),
            HandleChoice::OtherKind(i) => pick(&self.features, i).cast(),
            HandleChoice::MadeUp(address) => address as *mut SpslamExtractor,
        }
    }

    fn features(&self, choice: HandleChoice) -> *mut SpslamFeatures {
        match choice {
            HandleChoice::Null => ptr::null_mut(),
            HandleChoice::Live(i) => pick(&self.features, i),
            HandleChoice::Destroyed(i) => pick(&self.destroyed_features, i),
            HandleChoice::OtherKind(i) => pick(&self.extractors, i).cast(),
            HandleChoice::MadeUp(address) => address as *mut SpslamFeatures,
        }
    }

    /// Records a destroy call's effect: a live handle becomes destroyed.
    fn forget_extractor(&mut self, handle: *mut SpslamExtractor) {
        if let Some(at) = self.extractors.iter().position(|&h| h == handle) {
            self.extractors.swap_remove(at);
            self.destroyed_extractors.push(handle);
        }
    }

    fn forget_features(&mut self, handle: *mut SpslamFeatures) {
        if let Some(at) = self.features.iter().position(|&h| h == handle) {
            self.features.swap_remove(at);
            self.destroyed_features.push(handle);
        }
    }

    /// A destroyed address that was handed out again is live again.
    fn revive_extractor(&mut self, handle: *mut SpslamExtractor) {
        self.destroyed_extractors.retain(|&h| h != handle);
        self.extractors.push(handle);
    }

    fn revive_features(&mut self, handle: *mut SpslamFeatures) {
        self.destroyed_features.retain(|&h| h != handle);
        self.features.push(handle);
    }
}

impl Drop for Handles {
    fn drop(&mut self) {
        // SAFETY: these handles are live (returned by the library and not
        // destroyed since); each is destroyed once.
        unsafe {
            for &f in &self.features {
                spslam_features_destroy(f);
            }
            for &e in &self.extractors {
                spslam_extractor_destroy(e);
            }
        }
    }
}

/// The status must be one of the enum's values, and a failure must come
/// with a message.
fn check_status(status: SpslamStatus, call: &str) {
    let code = status as i32;
    assert!((0..=8).contains(&code), "{call}: status {code}");
    // SAFETY: never NULL, valid until the next call on this thread.
    let message = unsafe { CStr::from_ptr(spslam_last_error()) };
    if status == SpslamStatus::Ok {
        assert!(message.is_empty(), "{call}: OK with message {message:?}");
    } else {
        assert!(!message.is_empty(), "{call}: {status:?} without a message");
    }
    assert_ne!(status, SpslamStatus::Panic, "{call}: {message:?}");
}

fn c_config(f: &FuzzConfig) -> SpslamConfig {
    let mut c = std::mem::MaybeUninit::<SpslamConfig>::uninit();
    // SAFETY: `c` is writable.
    let status = unsafe {
        if f.from_orb_slam3 {
            spslam_config_from_orb_slam3(1000, 1.2, 8, 20, 7, c.as_mut_ptr())
        } else {
            spslam_config_default(c.as_mut_ptr())
        }
    };
    assert_eq!(status, SpslamStatus::Ok);
    // SAFETY: initialised by the successful call.
    let mut c = unsafe { c.assume_init() };
    let m = models();
    c.model_path = match f.model {
        ModelChoice::Tiny => m.tiny.as_ptr(),
        ModelChoice::Missing => m.missing.as_ptr(),
        ModelChoice::NotOnnx => m.not_onnx.as_ptr(),
    };
    c.threads = match f.threads {
        Threads::One => 1,
        Threads::TooMany(n) => 1025u32.saturating_add(n),
    };
    if f.keep_defaults {
        c.n_levels = 1 + u32::from(f.n_levels % 3);
        return c;
    }
    c.n_features = f.n_features;
    c.scale_factor = f.scale_factor;
    c.n_levels = f.n_levels_any.unwrap_or(u32::from(f.n_levels));
    c.threshold = f.threshold;
    c.min_threshold = f.min_threshold;
    c.nms_radius = f.nms_radius;
    c.border = f.border;
    c.anms = f.anms;
    c.periodic_filter.enabled = f.filter_enabled;
    c.periodic_filter.lattice_min_support = f.lattice_min_support;
    c.periodic_filter.min_contrast = f.min_contrast;
    c.periodic_filter.contrast_radius = f.contrast_radius;
    c.precision = f.precision;
    c.device = f.device;
    c
}

/// A gray image with some structure (so that keypoints exist).
fn pixels(len: usize, fill: u8) -> Vec<u8> {
    (0..len)
        .map(|i| {
            let x = (i % 37) as u8;
            let y = (i / 37) as u8;
            (x ^ y).wrapping_mul(fill | 1).wrapping_add(fill)
        })
        .collect()
}

/// Runs one call and checks its outcome.
fn run(op: &Op, handles: &mut Handles) {
    // SAFETY (for every block below): output pointers are NULL or point to
    // locals; `data` is readable for `claimed_len <= buffer.len()` bytes;
    // arrays hold at least `capacity` elements; handles are anything, which
    // the library must check before following.
    match *op {
        Op::Version => {
            let v = unsafe { CStr::from_ptr(spslam_version()) };
            assert!(!v.is_empty());
        }
        Op::LastError => {
            let _ = unsafe { CStr::from_ptr(spslam_last_error()) };
        }
        Op::ConfigDefault { null_out } => {
            let mut c = std::mem::MaybeUninit::<SpslamConfig>::uninit();
            let out = if null_out {
                ptr::null_mut()
            } else {
                c.as_mut_ptr()
            };
            check_status(unsafe { spslam_config_default(out) }, "config_default");
        }
        Op::ConfigFromOrbSlam3 {
            nfeatures,
            scale_factor,
            nlevels,
            ini_th_fast,
            min_th_fast,
            null_out,
        } => {
            let mut c = std::mem::MaybeUninit::<SpslamConfig>::uninit();
            let out = if null_out {
                ptr::null_mut()
            } else {
                c.as_mut_ptr()
            };
            let status = unsafe {
                spslam_config_from_orb_slam3(
                    nfeatures,
                    scale_factor,
                    nlevels,
                    ini_th_fast,
                    min_th_fast,
                    out,
                )
            };
            check_status(status, "config_from_orb_slam3");
        }
        Op::Create {
            ref config,
            null_config,
            null_out,
        } => {
            let c = c_config(config);
            let config_ptr: *const SpslamConfig = if null_config { ptr::null() } else { &c };
            let mut handle = ptr::null_mut();
            let out = if null_out {
                ptr::null_mut()
            } else {
                &mut handle
            };
            let status = unsafe { spslam_extractor_create(config_ptr, out) };
            check_status(status, "extractor_create");
            if status == SpslamStatus::Ok {
                assert!(!handle.is_null());
                CREATED.fetch_add(1, Ordering::Relaxed);
                handles.revive_extractor(handle);
            } else {
                assert!(handle.is_null());
            }
        }
        Op::DestroyExtractor(choice) => {
            let h = handles.extractor(choice);
            unsafe { spslam_extractor_destroy(h) };
            handles.forget_extractor(h);
        }
        Op::Extract {
            extractor,
            geometry,
            fill,
            null_data,
            null_out,
        } => {
            let (buffer_len, data_len, width, height, stride) = geometry.resolve();
            let buffer = pixels(buffer_len, fill);
            let data = if null_data {
                ptr::null()
            } else {
                buffer.as_ptr()
            };
            let mut features = ptr::null_mut();
            let out = if null_out {
                ptr::null_mut()
            } else {
                &mut features
            };
            let status = unsafe {
                spslam_extract(
                    handles.extractor(extractor),
                    data,
                    data_len,
                    width,
                    height,
                    stride,
                    out,
                )
            };
            check_status(status, "extract");
            if status == SpslamStatus::Ok {
                assert!(!features.is_null());
                handles.revive_features(features);
                // The views must describe readable memory of the stated size.
                let mut view = std::mem::MaybeUninit::<SpslamFeaturesView>::uninit();
                let status = unsafe { spslam_features_view(features, view.as_mut_ptr()) };
                assert_eq!(status, SpslamStatus::Ok);
                let view = unsafe { view.assume_init() };
                EXTRACTED.fetch_add(1, Ordering::Relaxed);
                KEYPOINTS.fetch_add(view.count, Ordering::Relaxed);
                if view.count > 0 {
                    let keypoints =
                        unsafe { std::slice::from_raw_parts(view.keypoints, view.count) };
                    let descriptors = unsafe {
                        std::slice::from_raw_parts(
                            view.descriptors,
                            view.count * view.descriptor_len,
                        )
                    };
                    let (w, h) = (width as f32, height as f32);
                    for k in keypoints {
                        assert!(
                            k.x >= 0.0 && k.x < w && k.y >= 0.0 && k.y < h,
                            "{k:?} outside {w}x{h}"
                        );
                    }
                    assert!(descriptors.iter().all(|v| v.is_finite()));
                }
            } else {
                assert!(features.is_null());
            }
        }
        Op::View { features, null_out } => {
            let mut view = std::mem::MaybeUninit::<SpslamFeaturesView>::uninit();
            let out = if null_out {
                ptr::null_mut()
            } else {
                view.as_mut_ptr()
            };
            check_status(
                unsafe { spslam_features_view(handles.features(features), out) },
                "features_view",
            );
        }
        Op::BinaryView { features, null_out } => {
            let mut view = std::mem::MaybeUninit::<SpslamBinaryView>::uninit();
            let out = if null_out {
                ptr::null_mut()
            } else {
                view.as_mut_ptr()
            };
            let status = unsafe { spslam_features_binary_view(handles.features(features), out) };
            check_status(status, "features_binary_view");
            if status == SpslamStatus::Ok {
                let view = unsafe { view.assume_init() };
                if view.count > 0 {
                    let bytes = unsafe {
                        std::slice::from_raw_parts(view.data, view.count * view.bytes_per_row)
                    };
                    std::hint::black_box(bytes.iter().map(|&b| b as u32).sum::<u32>());
                }
            }
        }
        Op::Count { features, null_out } => {
            let mut n = 0usize;
            let out = if null_out { ptr::null_mut() } else { &mut n };
            check_status(
                unsafe { spslam_features_count(handles.features(features), out) },
                "features_count",
            );
        }
        Op::DestroyFeatures(choice) => {
            let h = handles.features(choice);
            unsafe { spslam_features_destroy(h) };
            handles.forget_features(h);
        }
        Op::DescriptorLen {
            extractor,
            null_out,
        } => {
            let mut n = 0usize;
            let out = if null_out { ptr::null_mut() } else { &mut n };
            let status =
                unsafe { spslam_extractor_descriptor_len(handles.extractor(extractor), out) };
            check_status(status, "extractor_descriptor_len");
        }
        Op::Device {
            extractor,
            null_out,
        } => {
            let mut d = 0i32;
            let out = if null_out { ptr::null_mut() } else { &mut d };
            check_status(
                unsafe { spslam_extractor_device(handles.extractor(extractor), out) },
                "extractor_device",
            );
        }
        Op::Levels {
            extractor,
            null_out,
        } => {
            let mut n = 0usize;
            let out = if null_out { ptr::null_mut() } else { &mut n };
            check_status(
                unsafe { spslam_extractor_levels(handles.extractor(extractor), out) },
                "extractor_levels",
            );
        }
        Op::ScaleTables {
            extractor,
            capacity,
            null_arrays,
        } => {
            let n = capacity as usize;
            let (mut a, mut b, mut c, mut d) =
                (vec![0f32; n], vec![0f32; n], vec![0f32; n], vec![0f32; n]);
            let mut e = vec![0i32; n];
            let or_null = |bit: u8, p: *mut f32| {
                if null_arrays & (1 << bit) != 0 {
                    ptr::null_mut()
                } else {
                    p
                }
            };
            let status = unsafe {
                spslam_extractor_scale_tables(
                    handles.extractor(extractor),
                    n,
                    or_null(0, a.as_mut_ptr()),
                    or_null(1, b.as_mut_ptr()),
                    or_null(2, c.as_mut_ptr()),
                    or_null(3, d.as_mut_ptr()),
                    if null_arrays & 16 != 0 {
                        ptr::null_mut()
                    } else {
                        e.as_mut_ptr()
                    },
                )
            };
            check_status(status, "extractor_scale_tables");
        }
    }
}

fuzz_target!(|ops: Vec<Op>| {
    let mut handles = Handles::default();
    // Bounded so that one input stays about a millisecond or two.
    for op in ops.iter().take(32) {
        run(op, &mut handles);
    }
    drop(handles);
    let _: *const c_char = spslam_last_error();
    let n = INPUTS.fetch_add(1, Ordering::Relaxed) + 1;
    if n.is_multiple_of(1 << 16) && std::env::var_os("SPSLAM_FUZZ_STATS").is_some() {
        eprintln!(
            "[c_abi] {n} inputs: {} extractors created, {} extractions, {} keypoints",
            CREATED.load(Ordering::Relaxed),
            EXTRACTED.load(Ordering::Relaxed),
            KEYPOINTS.load(Ordering::Relaxed)
        );
    }
});
