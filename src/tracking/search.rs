//! Searches that match map points into the current frame.

use nalgebra::Vector3;

use crate::features::{DescriptorSet, Keypoint};
use crate::map::{KeyFrame, Map, MapPointId};
use crate::matching::{
    match_brute_force_spaced, search_by_projection_filtered, CandidateFilter, MatchParams,
    ProjectedPoint, ProjectionParams, TrainLayout,
};
use crate::optim::LieGroup;

use super::frame::Frame;
use crate::camera::CameraRig;
use crate::error::{MapContext, SlamError};

/// A map point predicted to be visible in the frame.
#[derive(Debug, Clone, Copy)]
pub(crate) struct VisiblePoint {
    pub id: MapPointId,
    pub u: f32,
    pub v: f32,
    /// Projected right-image column.
    pub u_right: f32,
    pub octave: i32,
    /// True when the view is nearly along the point's mean direction.
    pub frontal: bool,
}

/// ORB-SLAM3's `isInFrustum`: the point projects into the image with
/// positive depth, within its scale-invariance range and less than 60° from
/// its mean viewing direction.
pub(crate) fn visible_in_frame(
    map: &Map,
    id: MapPointId,
    frame: &Frame,
    rig: &CameraRig,
) -> Option<VisiblePoint> {
    let p = map.map_point(id).ok()?;
    let uvr = rig.project_in_image(&frame.pose_cw.transform_point(&p.position))?;
    let ray: Vector3<f64> = p.position - frame.camera_center();
    let distance = ray.norm();
    if !p.in_distance_range(distance) {
        return None;
    }
    let view_cos = if p.normal.norm() > 0.0 {
        ray.dot(&p.normal) / distance
    } else {
        1.0
    };
    if view_cos < 0.5 {
        return None;
    }
    let scale_factor = f64::from(frame.scales.scale_factors.get(1).copied().unwrap_or(1.2));
    let octave = p.predict_octave(distance, scale_factor, frame.scales.n_levels());
    Some(VisiblePoint {
        id,
        u: uvr.x as f32,
        v: uvr.y as f32,
        u_right: uvr.z as f32,
        octave: octave as i32,
        frontal: view_cos > 0.998,
    })
}

/// Searches `points` in the frame around their projections; matches go to
/// keypoints with no map point yet. Returns the number of new matches.
pub(crate) fn match_projected(
    frame: &mut Frame,
    map: &Map,
    points: &[VisiblePoint],
    radius: f32,
    octaves: (i32, i32),
    ratio: Option<f32>,
) -> Result<usize, SlamError> {
    let thresholds = frame.distance_thresholds;
    let mut projected = Vec::with_capacity(points.len());
    let mut ids = Vec::with_capacity(points.len());
    for v in points {
        let Ok(p) = map.map_point(v.id) else {
            continue;
        };
        projected.push(ProjectedPoint {
            u: v.u,
            v: v.v,
            predicted_octave: v.octave,
            descriptor: p.descriptor.as_ref(),
            u_right: Some(v.u_right),
        });
        ids.push(v.id);
    }
    let taken: Vec<bool> = frame.map_points.iter().map(Option::is_some).collect();
    let right_u: Vec<Option<f32>> = frame.stereo.iter().map(|s| s.map(|s| s.right_u)).collect();
    let matches = search_by_projection_filtered(
        &projected,
        &frame.features,
        &frame.grid,
        &frame.scales.scale_factors,
        ProjectionParams {
            radius,
            octaves_below: octaves.0,
            octaves_above: octaves.1,
            ratio,
            max_distance: thresholds.high,
            min_rival_distance: frame.descriptor_cell.unwrap_or(0.0),
        },
        CandidateFilter {
            taken: Some(&taken),
            right_u: Some(&right_u),
        },
    )
    .in_stage("search by projection")?;
    let mut added = 0;
    for m in matches {
        if frame.map_points[m.train].is_none() {
            frame.map_points[m.train] = Some(ids[m.query]);
            added += 1;
        }
    }
    Ok(added)
}

/// Matches the frame's descriptors against the given points' descriptors
/// (ratio + mutual), for the loop detector's candidate groups, whose points
/// come from several keyframes. Returns `(keypoint index, point)` pairs.
pub(crate) fn match_descriptors(
    frame: &Frame,
    map: &Map,
    points: &[MapPointId],
    ratio: f32,
) -> Result<Vec<(usize, MapPointId)>, SlamError> {
    let seen: Vec<(MapPointId, Option<&Keypoint>)> = points.iter().map(|&p| (p, None)).collect();
    match_seen(frame, map, &seen, ratio)
}

/// A keyframe's points, each with the keypoint that observes it there: what
/// [`match_descriptors_in_view`] takes for a keyframe.
pub(crate) fn keyframe_points_in_view(kf: &KeyFrame) -> Vec<(MapPointId, &Keypoint)> {
    let keypoints = &kf.measurements.keypoints;
    kf.observed_points()
        .filter_map(|(i, p)| Some((p, keypoints.get(i)?)))
        .collect()
}

/// [`match_descriptors`] for points seen in one view (a keyframe or the
/// last frame; each with the keypoint that observes it there), for tracking
/// the reference keyframe or the last frame and for relocalisation. The
/// ratio test does not pit two of the view's points less than the
/// extractor's descriptor cell apart against each other (see
/// [`TrainLayout`]), as the search by projection does not.
pub(crate) fn match_descriptors_in_view(
    frame: &Frame,
    map: &Map,
    points: &[(MapPointId, &Keypoint)],
    ratio: f32,
) -> Result<Vec<(usize, MapPointId)>, SlamError> {
    let seen: Vec<(MapPointId, Option<&Keypoint>)> =
        points.iter().map(|&(p, k)| (p, Some(k))).collect();
    match_seen(frame, map, &seen, ratio)
}

/// The one descriptor match of tracking and loop closing: the points'
/// descriptors against the frame's, with the rival test of
/// [`match_descriptors_in_view`] where every point has its keypoint and the
/// extractor has a descriptor cell.
fn match_seen(
    frame: &Frame,
    map: &Map,
    points: &[(MapPointId, Option<&Keypoint>)],
    ratio: f32,
) -> Result<Vec<(usize, MapPointId)>, SlamError> {
    let kind = frame.features.descriptors.kind();
    let mut ids = Vec::with_capacity(points.len());
    let mut positions = Vec::with_capacity(points.len());
    let mut rival_distances = Vec::with_capacity(points.len());
    let cell = frame.descriptor_cell.unwrap_or(0.0);
    let mut spaced = cell > 0.0;
    let mut set = match kind {
        crate::features::DescriptorKind::Float { dim } => DescriptorSet::Float {
            dim,
            data: Vec::with_capacity(points.len() * dim),
        },
        crate::features::DescriptorKind::Binary => DescriptorSet::Binary {
            data: Vec::with_capacity(points.len()),
        },
    };
    for &(id, keypoint) in points {
        let Ok(p) = map.map_point(id) else { continue };
        match (&mut set, p.descriptor.as_ref()) {
            (DescriptorSet::Float { dim, data }, crate::features::DescriptorRef::Float(row))
                if row.len() == *dim =>
            {
                data.extend_from_slice(row);
            }
            (DescriptorSet::Binary { data }, crate::features::DescriptorRef::Binary(row)) => {
                data.push(*row);
            }
            _ => continue,
        }
        ids.push(id);
        match keypoint {
            Some(k) => {
                let scale = frame.scales.scale_at(k.octave).unwrap_or(1.0);
                positions.push([k.x, k.y]);
                rival_distances.push(cell * scale);
            }
            None => spaced = false,
        }
    }
    if ids.is_empty() {
        return Ok(Vec::new());
    }
    let thresholds = frame.distance_thresholds;
    let layout = spaced.then_some(TrainLayout {
        positions: &positions,
        min_rival_distance: &rival_distances,
    });
    let matches = match_brute_force_spaced(
        &frame.features.descriptors,
        &set,
        MatchParams {
            ratio: Some(ratio),
            max_distance: thresholds.high,
            mutual: true,
        },
        layout,
    )
    .in_stage("descriptor matching")?;
    Ok(matches.iter().map(|m| (m.query, ids[m.train])).collect())
}
