/// One keypoint, with OpenCV's `cv::KeyPoint` fields and ORB-SLAM3's meaning.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Keypoint {
    /// Column in level-0 pixel coordinates.
    pub x: f32,
    /// Row in level-0 pixel coordinates.
    pub y: f32,
    /// Diameter of the meaningful neighbourhood in level-0 pixels
    /// (ORB-SLAM3: `PATCH_SIZE * scale_factor[octave]`, with PATCH_SIZE = 31).
    pub size: f32,
    /// Orientation in degrees [0, 360) from the intensity centroid, as ORB-SLAM3's `IC_Angle`.
    pub angle: f32,
    /// Detector score (keypoint probability).
    pub response: f32,
    /// Pyramid level the keypoint was detected on.
    pub octave: i32,
}

/// Wall-clock time spent in each stage of one extraction, in milliseconds.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct StageTimings {
    /// Pyramid building, padding and conversion to float.
    pub preprocess_ms: f64,
    /// ONNX Runtime inference.
    pub inference_ms: f64,
    /// Threshold, periodic-artefact filter, NMS and border removal.
    pub decode_nms_ms: f64,
    /// ANMS (or top-N) selection.
    pub anms_ms: f64,
    /// Descriptor sampling, orientation and the output assembly.
    pub descriptors_ms: f64,
    /// Sum of the stages.
    pub total_ms: f64,
}

/// The result of one extraction: keypoints and a row-major descriptor block.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Features {
    /// Keypoints, in level order then by decreasing ANMS rank.
    pub keypoints: Vec<Keypoint>,
    /// `keypoints.len() * descriptor_len` floats, row i is keypoint i's unit-L2 descriptor.
    pub descriptors: Vec<f32>,
    /// Floats per descriptor (256 for SuperPoint; read from the model).
    pub descriptor_len: usize,
    /// Time per stage.
    pub timings: StageTimings,
}

impl Features {
    /// Number of keypoints.
    pub fn len(&self) -> usize {
        self.keypoints.len()
    }

    /// True when there is no keypoint.
    pub fn is_empty(&self) -> bool {
        self.keypoints.is_empty()
    }

    /// The descriptor of keypoint `i`, or `None` when out of range.
    pub fn descriptor(&self, i: usize) -> Option<&[f32]> {
        let start = i.checked_mul(self.descriptor_len)?;
        self.descriptors.get(start..start + self.descriptor_len)
    }
}
