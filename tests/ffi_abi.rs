//! The C ABI (`spslam::ffi`) gives exactly what `SuperPointExtractor::extract`
//! gives, on a real KITTI frame, also with a padded row stride and from two
//! threads at once.
//!
//! Needs `make setup` (model + ONNX Runtime) and the data folder
//! (`$SPSLAM_DATA`, default `../shared/data`); when either is missing the test
//! prints SKIPPED and passes, unless `CI=true`, where it fails.

use std::ffi::CStr;
use std::path::PathBuf;
use std::ptr;

use spslam::features::{
    default_model_path, ExtractorConfig, Features, GrayImage, SuperPointExtractor,
};
use spslam::ffi::*;

fn data_dir() -> PathBuf {
    std::env::var_os("SPSLAM_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data"))
}

/// The KITTI frame, or `None` (after printing why) when the inputs are missing.
fn inputs(camera: &str) -> Option<GrayImage> {
    let image = data_dir().join(format!("kitti/sequences/06/{camera}/000000.png"));
    let model = default_model_path();
    let missing: Vec<String> = [&image, &model]
        .iter()
        .filter(|p| !p.is_file())
        .map(|p| p.display().to_string())
        .collect();
    if !missing.is_empty() {
        let message = format!("missing {}", missing.join(", "));
        if std::env::var("CI").is_ok_and(|v| v == "true") {
            panic!("{message} (CI=true)");
        }
        eprintln!("SKIPPED: {message}");
        return None;
    }
    Some(GrayImage::load(&image).expect("cannot load the KITTI frame"))
}

fn last_error() -> String {
    // SAFETY: never NULL; valid until the next call on this thread.
    unsafe { CStr::from_ptr(spslam_last_error()) }
        .to_string_lossy()
        .into_owned()
}

fn orb_slam3_c_config() -> SpslamConfig {
    let mut config = std::mem::MaybeUninit::<SpslamConfig>::uninit();
    // SAFETY: `config` is writable.
    let status = unsafe { spslam_config_from_orb_slam3(1000, 1.2, 8, 20, 7, config.as_mut_ptr()) };
    assert_eq!(status, SpslamStatus::Ok, "{}", last_error());
    // SAFETY: initialised by the successful call.
    unsafe { config.assume_init() }
}

/// An owned C handle, destroyed on drop.
struct Handle(*mut SpslamExtractor);

// SAFETY: the extractor is `Send`; the handle is used by one thread at a time.
unsafe impl Send for Handle {}

impl Handle {
    fn new(config: &SpslamConfig) -> Self {
        let mut raw = ptr::null_mut();
        // SAFETY: valid config (NULL paths) and out pointer.
        let status = unsafe { spslam_extractor_create(config, &mut raw) };
        assert_eq!(status, SpslamStatus::Ok, "{}", last_error());
        assert!(!raw.is_null());
        Handle(raw)
    }

    /// Extracts through the C ABI and copies the result back into `Features`.
    fn extract(&mut self, data: &[u8], width: usize, height: usize, stride: usize) -> Features {
        let mut out = ptr::null_mut();
        // SAFETY: live handle, `data` readable for `data.len()` bytes, valid out pointer.
        let status = unsafe {
            spslam_extract(
                self.0,
                data.as_ptr(),
                data.len(),
                width,
                height,
                stride,
                &mut out,
            )
        };
        assert_eq!(status, SpslamStatus::Ok, "{}", last_error());
        let mut view = std::mem::MaybeUninit::<SpslamFeaturesView>::uninit();
        // SAFETY: `out` is a live result; `view` is writable.
        let status = unsafe { spslam_features_view(out, view.as_mut_ptr()) };
        assert_eq!(status, SpslamStatus::Ok, "{}", last_error());
        // SAFETY: initialised by the successful call.
        let view = unsafe { view.assume_init() };
        let mut features = Features {
            descriptor_len: view.descriptor_len,
            ..Features::default()
        };
        if view.count > 0 {
            // SAFETY: the view's arrays hold `count` keypoints and
            // `count * descriptor_len` floats while `out` lives.
            let (keypoints, descriptors) = unsafe {
                (
                    std::slice::from_raw_parts(view.keypoints, view.count),
                    std::slice::from_raw_parts(view.descriptors, view.count * view.descriptor_len),
                )
            };
            features.keypoints = keypoints
                .iter()
                .map(spslam::features::Keypoint::from)
                .collect();
            features.descriptors = descriptors.to_vec();
        }
        // The binary view: the float rows' sign bits in ORB's layout,
        // checked against a bit-by-bit reference.
        let mut binary = std::mem::MaybeUninit::<SpslamBinaryView>::uninit();
        // SAFETY: `out` is a live result; `binary` is writable.
        let status = unsafe { spslam_features_binary_view(out, binary.as_mut_ptr()) };
        assert_eq!(status, SpslamStatus::Ok, "{}", last_error());
        // SAFETY: initialised by the successful call.
        let binary = unsafe { binary.assume_init() };
        assert_eq!(
            (binary.count, binary.bytes_per_row),
            (view.count, view.descriptor_len.div_ceil(8))
        );
        if binary.count > 0 {
            // SAFETY: `count * bytes_per_row` bytes while `out` lives.
            let bits = unsafe {
                std::slice::from_raw_parts(binary.data, binary.count * binary.bytes_per_row)
            };
            let d = view.descriptor_len;
            for (k, row) in features.descriptors.chunks_exact(d).enumerate() {
                for (dim, &value) in row.iter().enumerate() {
                    let byte = bits[k * binary.bytes_per_row + dim / 8];
                    assert_eq!(
                        byte >> (dim % 8) & 1 == 1,
                        value > 0.0,
                        "keypoint {k}, dimension {dim}"
                    );
                }
            }
        }
        // SAFETY: `out` came from `spslam_extract` and is destroyed once.
        unsafe { spslam_features_destroy(out) };
        features
    }
}

impl Drop for Handle {
    fn drop(&mut self) {
        // SAFETY: created by `spslam_extractor_create`, destroyed once.
        unsafe { spslam_extractor_destroy(self.0) };
    }
}

fn assert_same(a: &Features, b: &Features, what: &str) {
    assert_eq!(
        a.descriptor_len, b.descriptor_len,
        "{what}: descriptor length"
    );
    assert_eq!(a.keypoints, b.keypoints, "{what}: keypoints");
    assert_eq!(a.descriptors, b.descriptors, "{what}: descriptors");
}

#[test]
fn c_abi_equals_the_rust_api_on_kitti() {
    let Some(image) = inputs("image_0") else {
        return;
    };
    let (w, h) = (image.width(), image.height());
    let reference = SuperPointExtractor::new(ExtractorConfig::from_orb_slam3(1000, 1.2, 8, 20, 7))
        .unwrap()
        .extract(image.view())
        .unwrap();
    assert!(reference.len() > 500, "only {} keypoints", reference.len());
    assert_eq!(reference.descriptor_len, 256);

    let config = orb_slam3_c_config();
    let mut handle = Handle::new(&config);
    let contiguous = handle.extract(image.as_slice(), w, h, w);
    assert_same(&reference, &contiguous, "contiguous");

    // The same pixels with a padded stride (as a cv::Mat ROI has).
    let stride = w + 13;
    let mut padded = vec![0xAAu8; stride * (h - 1) + w];
    for y in 0..h {
        padded[y * stride..y * stride + w].copy_from_slice(&image.as_slice()[y * w..(y + 1) * w]);
    }
    let strided = handle.extract(&padded, w, h, stride);
    assert_same(&reference, &strided, "padded stride");

    // The tables match the Rust ones.
    let mut levels = 0usize;
    let mut descriptor_len = 0usize;
    // SAFETY: live handle, writable outputs.
    unsafe {
        assert_eq!(
            spslam_extractor_levels(handle.0, &mut levels),
            SpslamStatus::Ok
        );
        assert_eq!(
            spslam_extractor_descriptor_len(handle.0, &mut descriptor_len),
            SpslamStatus::Ok
        );
    }
    assert_eq!((levels, descriptor_len), (8, 256));
    let mut tables = [[0f32; 8]; 4];
    let mut quotas = [0i32; 8];
    let [s, inv_s, sigma2, inv_sigma2] = &mut tables;
    // SAFETY: live handle, every array holds 8 elements.
    let status = unsafe {
        spslam_extractor_scale_tables(
            handle.0,
            8,
            s.as_mut_ptr(),
            inv_s.as_mut_ptr(),
            sigma2.as_mut_ptr(),
            inv_sigma2.as_mut_ptr(),
            quotas.as_mut_ptr(),
        )
    };
    assert_eq!(status, SpslamStatus::Ok, "{}", last_error());
    let rust = spslam::features::pyramid::ScaleTables::new(1000, 1.2, 8);
    assert_eq!(s.to_vec(), rust.scale_factors);
    assert_eq!(inv_s.to_vec(), rust.inv_scale_factors);
    assert_eq!(sigma2.to_vec(), rust.level_sigma2);
    assert_eq!(inv_sigma2.to_vec(), rust.inv_level_sigma2);
    assert_eq!(
        quotas.iter().map(|&q| q as usize).collect::<Vec<_>>(),
        rust.features_per_level
    );
    // SAFETY: live handle; a capacity below the level count is refused before any write.
    let status = unsafe {
        spslam_extractor_scale_tables(
            handle.0,
            3,
            s.as_mut_ptr(),
            ptr::null_mut(),
            ptr::null_mut(),
            ptr::null_mut(),
            ptr::null_mut(),
        )
    };
    assert_eq!(status, SpslamStatus::InvalidArgument);
    assert!(last_error().contains("capacity"), "{}", last_error());
}

/// ORB-SLAM3 extracts a stereo pair on two threads at once: each extractor
/// gets half the cores (at least one), not ONNX Runtime's thread per core
/// (EVALUATION.md, "Inside ORB-SLAM3: the preload with lite").
#[test]
fn orb_slam3_config_shares_the_cores_between_the_stereo_pair() {
    let cores = std::thread::available_parallelism().map_or(2, |n| n.get());
    let config = orb_slam3_c_config();
    assert_eq!(config.threads as usize, (cores / 2).max(1));
    let mut default = std::mem::MaybeUninit::<SpslamConfig>::uninit();
    // SAFETY: `default` is writable.
    let status = unsafe { spslam_config_default(default.as_mut_ptr()) };
    assert_eq!(status, SpslamStatus::Ok, "{}", last_error());
    // SAFETY: initialised by the successful call.
    assert_eq!(
        unsafe { default.assume_init() }.threads,
        0,
        "the default is ONNX Runtime's choice"
    );
}

#[test]
fn two_handles_on_two_threads_match_sequential_runs() {
    let (Some(left), Some(right)) = (inputs("image_0"), inputs("image_1")) else {
        return;
    };
    let config = orb_slam3_c_config();
    let mut sequential = Handle::new(&config);
    let expect_left =
        sequential.extract(left.as_slice(), left.width(), left.height(), left.width());
    let expect_right = sequential.extract(
        right.as_slice(),
        right.width(),
        right.height(),
        right.width(),
    );
    drop(sequential);

    let (mut a, mut b) = (Handle::new(&config), Handle::new(&config));
    let (got_left, got_right) = std::thread::scope(|scope| {
        let l =
            scope.spawn(|| a.extract(left.as_slice(), left.width(), left.height(), left.width()));
        let r = scope.spawn(|| {
            b.extract(
                right.as_slice(),
                right.width(),
                right.height(),
                right.width(),
            )
        });
        (l.join().unwrap(), r.join().unwrap())
    });
    assert_same(&expect_left, &got_left, "left thread");
    assert_same(&expect_right, &got_right, "right thread");
}

#[test]
fn bad_images_are_errors_with_messages() {
    if inputs("image_0").is_none() {
        return;
    }
    let mut config = orb_slam3_c_config();
    config.n_levels = 1;
    let handle = Handle::new(&config);
    let pixels = vec![128u8; 64 * 64];
    let mut out = ptr::null_mut();
    struct Case {
        what: &'static str,
        data: *const u8,
        len: usize,
        width: usize,
        height: usize,
        stride: usize,
        expected: SpslamStatus,
        needle: &'static str,
    }
    let case = |what, data, len, width, height, stride, expected, needle| Case {
        what,
        data,
        len,
        width,
        height,
        stride,
        expected,
        needle,
    };
    let p = pixels.as_ptr();
    let cases = [
        case(
            "null data",
            ptr::null(),
            4096,
            64,
            64,
            64,
            SpslamStatus::NullPointer,
            "data",
        ),
        case(
            "zero width",
            p,
            4096,
            0,
            64,
            64,
            SpslamStatus::ImageError,
            "empty",
        ),
        case(
            "zero height",
            p,
            4096,
            64,
            0,
            64,
            SpslamStatus::ImageError,
            "empty",
        ),
        case(
            "stride < width",
            p,
            4096,
            64,
            64,
            32,
            SpslamStatus::ImageError,
            "stride",
        ),
        case(
            "short buffer",
            p,
            4000,
            64,
            64,
            64,
            SpslamStatus::ImageError,
            "needs",
        ),
        case(
            "too small",
            p,
            4096,
            8,
            8,
            8,
            SpslamStatus::ImageError,
            "at least",
        ),
    ];
    for c in cases {
        // SAFETY: `data` is NULL or readable for `len` bytes (len <= 4096); out is writable.
        let status = unsafe {
            spslam_extract(
                handle.0, c.data, c.len, c.width, c.height, c.stride, &mut out,
            )
        };
        assert_eq!(status, c.expected, "{}", c.what);
        assert!(out.is_null(), "{}", c.what);
        let message = last_error();
        assert!(message.contains(c.needle), "{}: {message}", c.what);
    }
    // SAFETY: live handle; NULL out pointer is checked.
    let status =
        unsafe { spslam_extract(handle.0, pixels.as_ptr(), 4096, 64, 64, 64, ptr::null_mut()) };
    assert_eq!(status, SpslamStatus::NullPointer);

    // A missing model is a model error, with the path in the message.
    let mut bad = orb_slam3_c_config();
    bad.model_path = c"/nonexistent/superpoint.onnx".as_ptr();
    let mut raw = ptr::null_mut();
    // SAFETY: valid config and out pointer.
    let status = unsafe { spslam_extractor_create(&bad, &mut raw) };
    assert_eq!(status, SpslamStatus::ModelError);
    assert!(raw.is_null());
    assert!(
        last_error().contains("/nonexistent/superpoint.onnx"),
        "{}",
        last_error()
    );

    // Precision and device values outside their enums are invalid arguments.
    for (field, value, needle) in [
        ("precision", 7, "SPSLAM_PRECISION_INT8"),
        ("device", -1, "SPSLAM_DEVICE_CUDA"),
    ] {
        let mut bad = orb_slam3_c_config();
        if field == "precision" {
            bad.precision = value;
        } else {
            bad.device = value;
        }
        let mut raw = ptr::null_mut();
        // SAFETY: valid config and out pointer.
        let status = unsafe { spslam_extractor_create(&bad, &mut raw) };
        assert_eq!(status, SpslamStatus::InvalidArgument, "{field} = {value}");
        assert!(raw.is_null());
        assert!(last_error().contains(needle), "{}", last_error());
    }

    // CUDA with the CPU build of ONNX Runtime (what `make setup` installs) is
    // a device error that says what to install; on a CUDA build it works and
    // the handle reports the device.
    let mut cuda = orb_slam3_c_config();
    cuda.device = SpslamDevice::Cuda as i32;
    let mut raw = ptr::null_mut();
    // SAFETY: valid config and out pointer.
    let status = unsafe { spslam_extractor_create(&cuda, &mut raw) };
    if spslam::features::model::cuda_offered() {
        if status == SpslamStatus::Ok {
            let handle = Handle(raw);
            let mut device = -1;
            // SAFETY: live handle, writable out pointer.
            let status = unsafe { spslam_extractor_device(handle.0, &mut device) };
            assert_eq!(status, SpslamStatus::Ok);
            assert_eq!(device, SpslamDevice::Cuda as i32);
        } else {
            assert_eq!(status, SpslamStatus::DeviceError, "{}", last_error());
        }
    } else {
        assert_eq!(status, SpslamStatus::DeviceError, "{}", last_error());
        assert!(raw.is_null());
        assert!(last_error().contains("make setup-gpu"), "{}", last_error());
    }
}

/// Destroyed and foreign handles are reported (`SPSLAM_STATUS_INVALID_HANDLE`)
/// instead of followed, and a second destroy is a no-op with a message.
#[test]
fn destroyed_and_foreign_handles_are_reported() {
    if inputs("image_0").is_none() {
        return;
    }
    let mut config = orb_slam3_c_config();
    config.n_levels = 1;
    let mut extractor = ptr::null_mut();
    // SAFETY: valid config and out pointer.
    assert_eq!(
        unsafe { spslam_extractor_create(&config, &mut extractor) },
        SpslamStatus::Ok
    );
    let pixels = vec![128u8; 64 * 64];
    let mut features = ptr::null_mut();
    // SAFETY: live handle, 4096 readable bytes, writable out pointer.
    let status =
        unsafe { spslam_extract(extractor, pixels.as_ptr(), 4096, 64, 64, 64, &mut features) };
    assert_eq!(status, SpslamStatus::Ok, "{}", last_error());
    let mut count = 0usize;
    // SAFETY: every pointer below is either live, or checked by the library
    // before it is followed (the point of this test); outputs are writable.
    unsafe {
        assert_eq!(
            spslam_features_count(features, &mut count),
            SpslamStatus::Ok
        );
        spslam_features_destroy(features);
        assert_eq!(last_error(), "");
        assert_eq!(
            spslam_features_count(features, &mut count),
            SpslamStatus::InvalidHandle
        );
        assert!(
            last_error().contains("`features` is not a live handle"),
            "{}",
            last_error()
        );
        spslam_features_destroy(features);
        assert!(
            last_error().contains("spslam_features_destroy"),
            "{}",
            last_error()
        );
        let mut view = std::mem::MaybeUninit::<SpslamFeaturesView>::uninit();
        assert_eq!(
            spslam_features_view(features, view.as_mut_ptr()),
            SpslamStatus::InvalidHandle
        );

        spslam_extractor_destroy(extractor);
        let mut levels = 0usize;
        assert_eq!(
            spslam_extractor_levels(extractor, &mut levels),
            SpslamStatus::InvalidHandle
        );
        let status = spslam_extract(extractor, pixels.as_ptr(), 4096, 64, 64, 64, &mut features);
        assert_eq!(status, SpslamStatus::InvalidHandle);
        assert!(features.is_null());
        spslam_extractor_destroy(extractor);
        assert!(
            last_error().contains("not a live handle"),
            "{}",
            last_error()
        );

        // A pointer this library never returned: a features result passed as
        // an extractor, and a made-up address.
        let foreign = 0x1000usize as *mut SpslamExtractor;
        assert_eq!(
            spslam_extractor_levels(foreign, &mut levels),
            SpslamStatus::InvalidHandle
        );
        let bogus = pixels.as_ptr() as *const SpslamFeatures;
        assert_eq!(
            spslam_features_count(bogus, &mut count),
            SpslamStatus::InvalidHandle
        );
    }
}
