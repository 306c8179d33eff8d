//! The camera's rotation from whole images (`spslam::tracking`'s small
//! blurry images): the thumbnail every frame pays for, and the rotation
//! between two thumbnails that a turn the motion model missed, or a lost
//! frame, pays for. KITTI 06's frames 0 and 1 (1226×370) and EuRoC
//! V1_01's first frame (752×480); a missing frame is skipped.
use criterion::{black_box, criterion_group, criterion_main, Criterion};
use nalgebra::UnitQuaternion;
use spslam::features::GrayImage;
use spslam::optim::reprojection::PinholeStereo;
use spslam::tracking::{estimate_rotation, SmallBlurryImage};

#[path = "common/frames.rs"]
mod frames;

fn bench(c: &mut Criterion) {
    let data = frames::data_dir();
    // The thumbnail needs the intrinsics only for its own; any will do.
    let camera = PinholeStereo::new(707.0, 707.0, 601.0, 183.0, 0.0);
    let mut g = c.benchmark_group("image_rotation");
    g.sample_size(30);
    for (name, path) in frames::frames(&data) {
        let Some(image) = path.and_then(|p| GrayImage::load(&p).ok()) else {
            eprintln!("{name}: frame missing, skipped");
            continue;
        };
        g.bench_function(format!("thumbnail_{name}"), |b| {
            b.iter(|| SmallBlurryImage::new(black_box(image.view()), &camera))
        });
    }
    let pair = ["000000.png", "000001.png"]
        .map(|f| GrayImage::load(&data.join("kitti/sequences/06/image_0").join(f)).ok());
    if let [Some(a), Some(b)] = pair {
        let (Some(ta), Some(tb)) = (
            SmallBlurryImage::new(a.view(), &camera),
            SmallBlurryImage::new(b.view(), &camera),
        ) else {
            return;
        };
        g.bench_function("rotation_kitti_frames_0_1", |bench| {
            bench.iter(|| {
                estimate_rotation(black_box(&ta), black_box(&tb), &UnitQuaternion::identity())
            })
        });
    } else {
        eprintln!("KITTI 06 frames 0 and 1 missing: the rotation is not timed");
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
