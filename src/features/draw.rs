//! Drawing keypoints on an image, for the CLI and the demo.

use std::path::Path;

use opencv::core::{Mat, Point, Scalar, Vector};

use super::{FeatureError, GrayImageView, Keypoint};

/// Writes `image` in colour with each keypoint drawn as a circle of its
/// octave's size (colour by octave) and a dot at its position.
pub fn write_keypoint_image(
    image: GrayImageView<'_>,
    keypoints: &[Keypoint],
    path: &Path,
) -> Result<(), FeatureError> {
    let gray = image.to_owned_image().to_mat()?;
    let mut colour = Mat::default();
    opencv::imgproc::cvt_color_def(&gray, &mut colour, opencv::imgproc::COLOR_GRAY2BGR)?;
    const PALETTE: [(f64, f64, f64); 8] = [
        (0.0, 255.0, 0.0),
        (0.0, 200.0, 255.0),
        (255.0, 128.0, 0.0),
        (255.0, 0.0, 255.0),
        (0.0, 0.0, 255.0),
        (255.0, 255.0, 0.0),
        (128.0, 0.0, 255.0),
        (255.0, 255.0, 255.0),
    ];
    for kp in keypoints {
        let (b, g, r) = PALETTE[kp.octave.unsigned_abs() as usize % PALETTE.len()];
        let colour_of = Scalar::new(b, g, r, 0.0);
        let centre = Point::new(kp.x.round() as i32, kp.y.round() as i32);
        let radius = (kp.size / 31.0 * 3.0).round().max(2.0) as i32;
        opencv::imgproc::circle(
            &mut colour,
            centre,
            radius,
            colour_of,
            1,
            opencv::imgproc::LINE_AA,
            0,
        )?;
        opencv::imgproc::circle(
            &mut colour,
            centre,
            0,
            colour_of,
            -1,
            opencv::imgproc::LINE_8,
            0,
        )?;
    }
    let name = path.to_str().ok_or_else(|| FeatureError::ImageRead {
        path: path.to_path_buf(),
        reason: "path is not valid UTF-8".into(),
    })?;
    let written = opencv::imgcodecs::imwrite(name, &colour, &Vector::new())?;
    if !written {
        return Err(FeatureError::OpenCv(format!(
            "could not write {name} (unknown extension or unwritable folder)"
        )));
    }
    Ok(())
}
