//! EuRoC camera calibration from `camX/sensor.yaml`.

use std::path::Path;

use nalgebra::{Matrix3, Matrix4};

use super::error::{DatasetError, Result};
use super::yaml::YamlDoc;

/// A pinhole camera with radial-tangential distortion and its pose on the body.
#[derive(Debug, Clone, PartialEq)]
pub struct CameraCalibration {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Focal length in x (pixels).
    pub fx: f64,
    /// Focal length in y (pixels).
    pub fy: f64,
    /// Principal point x (pixels).
    pub cx: f64,
    /// Principal point y (pixels).
    pub cy: f64,
    /// Radial-tangential distortion `[k1, k2, p1, p2]` (OpenCV order).
    pub distortion: [f64; 4],
    /// Sensor-to-body transform `T_BS` (maps camera points into the body frame).
    pub t_bs: Matrix4<f64>,
}

impl CameraCalibration {
    /// Reads an EuRoC camera `sensor.yaml` (`resolution`, `intrinsics`
    /// `[fu, fv, cu, cv]`, `distortion_model` radial-tangential,
    /// `distortion_coefficients`, `T_BS` as `rows`/`cols`/`data`).
    pub fn from_sensor_yaml(path: &Path) -> Result<Self> {
        let doc = YamlDoc::from_file(path)?;
        let (model, line) = doc.text("camera_model")?;
        if model != "pinhole" {
            return Err(DatasetError::row(
                path,
                line,
                format!("camera_model `{model}` is not supported (only pinhole)"),
            ));
        }
        let (model, line) = doc.text("distortion_model")?;
        if !matches!(model, "radial-tangential" | "radtan" | "plumb_bob") {
            return Err(DatasetError::row(
                path,
                line,
                format!("distortion_model `{model}` is not supported (only radial-tangential)"),
            ));
        }
        let resolution = doc.numbers("resolution", 2)?;
        let (width, height) = (pixels(&doc, resolution[0])?, pixels(&doc, resolution[1])?);
        let k = doc.numbers("intrinsics", 4)?;
        let d = doc.numbers("distortion_coefficients", 4)?;
        let t_bs = transform(&doc, "T_BS")?;
        Ok(Self {
            width,
            height,
            fx: k[0],
            fy: k[1],
            cx: k[2],
            cy: k[3],
            distortion: [d[0], d[1], d[2], d[3]],
            t_bs,
        })
    }

    /// The 3×3 camera matrix `K`.
    pub fn camera_matrix(&self) -> Matrix3<f64> {
        Matrix3::new(
            self.fx, 0.0, self.cx, //
            0.0, self.fy, self.cy, //
            0.0, 0.0, 1.0,
        )
    }
}

/// A positive whole number of pixels.
fn pixels(doc: &YamlDoc, v: f64) -> Result<u32> {
    if v >= 1.0 && v.fract() == 0.0 && v <= f64::from(u32::MAX) {
        Ok(v as u32)
    } else {
        let (_, line) = doc.text("resolution")?;
        Err(DatasetError::row(
            doc.path(),
            line,
            format!("resolution: {v} is not a positive whole number of pixels"),
        ))
    }
}

/// A 4×4 matrix given as `KEY: {rows: 4, cols: 4, data: [16 numbers]}`, row-major.
fn transform(doc: &YamlDoc, key: &str) -> Result<Matrix4<f64>> {
    for dim in ["rows", "cols"] {
        let full = format!("{key}.{dim}");
        if doc.integer(&full)? != 4 {
            let (value, line) = doc.text(&full)?;
            return Err(DatasetError::row(
                doc.path(),
                line,
                format!("{full} is {value}, expected 4"),
            ));
        }
    }
    let data = doc.numbers(&format!("{key}.data"), 16)?;
    Ok(Matrix4::from_row_slice(&data))
}
