//! Closest points of two segments: the one query behind every capsule's
//! distance (branch to region, link to link, link to branch), parry's
//! closed form.

use parry3d_f64::math::Vec3;
use parry3d_f64::query::details::closest_points_segment_segment_with_locations_nD;
use parry3d_f64::shape::Segment;

/// The closest points of segments a–b and c–d (on a–b, on c–d).
pub fn closest_points(a: Vec3, b: Vec3, c: Vec3, d: Vec3) -> (Vec3, Vec3) {
    let (l1, l2) = closest_points_segment_segment_with_locations_nD((&a, &b), (&c, &d));
    (
        Segment::new(a, b).point_at(&l1),
        Segment::new(c, d).point_at(&l2),
    )
}

/// A unit vector perpendicular to `axis` (any one).
pub fn any_perpendicular(axis: Vec3) -> Vec3 {
    let helper = if axis.x.abs() < 0.9 { Vec3::X } else { Vec3::Y };
    let p = axis.cross(helper);
    if p.length() > 1e-12 {
        p.normalize()
    } else {
        Vec3::X
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crossing_skew_segments_meet_at_their_common_perpendicular() {
        let (p, q) = closest_points(
            Vec3::new(-1.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.3, -1.0, 0.5),
            Vec3::new(0.3, 1.0, 0.5),
        );
        assert!((p - Vec3::new(0.3, 0.0, 0.0)).length() < 1e-12);
        assert!((q - Vec3::new(0.3, 0.0, 0.5)).length() < 1e-12);
    }

    #[test]
    fn parallel_and_degenerate_segments_have_a_closest_pair() {
        // A point (a ball's core) against a segment: the foot of the
        // perpendicular, clamped to the segment.
        let c = Vec3::new(2.0, 0.4, 0.0);
        let (p, q) = closest_points(Vec3::ZERO, Vec3::new(1.0, 0.0, 0.0), c, c);
        assert!((p - Vec3::new(1.0, 0.0, 0.0)).length() < 1e-12 && q == c);
        let (p, q) = closest_points(
            Vec3::ZERO,
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 0.2, 0.0),
            Vec3::new(1.0, 0.2, 0.0),
        );
        assert!(((p - q).length() - 0.2).abs() < 1e-12);
        let n = any_perpendicular(Vec3::new(0.0, 0.0, 2.0));
        assert!((n.length() - 1.0).abs() < 1e-12 && n.z.abs() < 1e-12);
    }
}
