//! The scale between the two sides of a monocular loop or merge: a
//! monocular map's scale drifts, and a map started after a loss has a
//! scale of its own (ORB-SLAM3's `Sim3Solver` with `mbFixScale` false
//! estimates it with the relative pose; here the pose comes from the
//! side's points, and the scale from the depths both sides give the same
//! keypoints).

use crate::map::{KeyFrameId, Map, MapPointId};
use crate::optim::{LieGroup, Se3, Sim3};

/// Matched pairs needed for a scale; with fewer the sides keep scale 1.
pub const MIN_SCALE_PAIRS: usize = 10;

/// The scale of the query's own side over the other side's: the median,
/// over the query keypoints matched to the other side's points
/// (`matches`, ids in `other_map`), of the keypoint's own point's depth
/// in the query camera (`own_pose`, in `own_map`) over the matched
/// point's depth at the query's pose on the other side (`other_pose`).
/// `None` with fewer than [`MIN_SCALE_PAIRS`] pairs in front of both.
pub(crate) fn side_scale(
    own_map: &Map,
    query: KeyFrameId,
    own_pose: &Se3,
    matches: &[Option<MapPointId>],
    other_map: &Map,
    other_pose: &Se3,
) -> Option<f64> {
    let query = own_map.keyframe(query).ok()?;
    let mut ratios: Vec<f64> = matches
        .iter()
        .enumerate()
        .filter_map(|(i, matched)| {
            let own = own_map
                .map_point(own_map.resolve_point(query.map_point(i)?)?)
                .ok()?;
            let other = other_map
                .map_point(other_map.resolve_point((*matched)?)?)
                .ok()?;
            let z_own = own_pose.transform_point(&own.position).z;
            let z_other = other_pose.transform_point(&other.position).z;
            (z_own > 0.0 && z_other > 0.0).then(|| z_own / z_other)
        })
        .filter(|r| r.is_finite())
        .collect();
    if ratios.len() < MIN_SCALE_PAIRS {
        return None;
    }
    crate::stats::upper_median(&mut ratios)
}

/// The correction `C` of a query keyframe found at `pose_cw` on the other
/// side while its own pose is `own_pose`, the own side's scale being
/// `scale` times the other's: a keyframe `T_kw` of the own side moves to
/// `(T_kw·C)` with its translation brought to the other side's units
/// ([`corrected_pose`]); the query lands exactly on `pose_cw`. With scale
/// 1 it is the rigid `T_qw⁻¹·T_q,other`. `C⁻¹` takes the own side's
/// world to the other's (`X_other = C⁻¹·X_own`).
pub fn scaled_correction(own_pose: &Se3, pose_cw: &Se3, scale: f64) -> Sim3 {
    let other = Sim3::new(pose_cw.rotation, pose_cw.translation * scale, scale);
    Sim3::from_se3(own_pose).inverse().compose(&other)
}

/// Keyframe pose `T_kw` moved by a correction `C` ([`scaled_correction`]):
/// the camera in the other side's world and units.
pub fn corrected_pose(pose_cw: &Se3, correction: &Sim3) -> Se3 {
    Sim3::from_se3(pose_cw)
        .compose(correction)
        .to_se3_unscaled()
}

#[cfg(test)]
mod tests {
    use nalgebra::{UnitQuaternion, Vector3};

    use super::*;

    #[test]
    fn the_query_lands_on_its_pose_and_its_neighbours_keep_their_place_in_the_other_units() {
        let own_q = Se3::new(
            UnitQuaternion::from_euler_angles(0.1, -0.4, 0.2),
            Vector3::new(0.3, -1.0, 2.0),
        );
        let other_q = Se3::new(
            UnitQuaternion::from_euler_angles(-0.2, 0.5, 0.1),
            Vector3::new(4.0, 1.0, -3.0),
        );
        // The own side is 0.4 times the other's (its points 0.4 as deep).
        let scale = 0.4;
        let c = scaled_correction(&own_q, &other_q, scale);
        let q = corrected_pose(&own_q, &c);
        assert!((q.translation - other_q.translation).norm() < 1e-12);
        assert!(q.rotation.angle_to(&other_q.rotation) < 1e-12);
        // A neighbour 1 unit behind the query on the own side is 1/0.4
        // units behind it on the other side.
        let neighbour =
            Se3::new(UnitQuaternion::identity(), Vector3::new(0.0, 0.0, 1.0)).compose(&own_q);
        let moved = corrected_pose(&neighbour, &c);
        let relative = moved.compose(&q.inverse());
        assert!((relative.translation - Vector3::new(0.0, 0.0, 1.0 / scale)).norm() < 1e-12);
        assert!(relative.rotation.angle() < 1e-12);
        // A point seen by the query at depth 2 on the own side is at depth
        // 5 on the other, in the same direction.
        let x_own = own_q
            .inverse()
            .transform_point(&Vector3::new(0.5, -0.2, 2.0));
        let x_other = c.inverse().transform_point(&x_own);
        let seen = other_q.transform_point(&x_other);
        assert!((seen - Vector3::new(0.5, -0.2, 2.0) / scale).norm() < 1e-12);
        // Scale 1: the rigid correction.
        let rigid = scaled_correction(&own_q, &other_q, 1.0);
        let expected = own_q.inverse().compose(&other_q);
        assert!((rigid.translation - expected.translation).norm() < 1e-12);
        assert_eq!(rigid.scale, 1.0);
    }
}
