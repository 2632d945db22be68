//! A shape placed in the world, ready for queries: capsules (endpoints in
//! world coordinates), boxes and cylinders with their poses; whether two
//! touch and how far apart they are, in closed form where one exists.

use parry3d_f64::math::Pose;
use parry3d_f64::query::intersection_test;
use parry3d_f64::shape::{Capsule, Cuboid, Cylinder, Shape};

use crate::geometry::aabb::Aabb;
use crate::geometry::segment::closest_points;
use crate::geometry::segment_box::segment_box_distance_squared;

/// The arm's shapes in the world at one configuration, with their bounding
/// boxes (on the stack: computed for every pose checked).
pub type WorldShapes = smallvec::SmallVec<[(WorldShape, Aabb); 16]>;

/// A shape in the world, ready for queries.
#[derive(Debug, Clone)]
pub enum WorldShape {
    /// Endpoints are in world coordinates; the pose is the identity.
    Capsule(Capsule),
    Box(Cuboid, Pose),
    /// parry's cylinder runs along its local y axis.
    Cylinder(Cylinder, Pose),
}

impl WorldShape {
    pub fn as_query(&self) -> (Pose, &dyn Shape) {
        match self {
            WorldShape::Capsule(c) => (Pose::IDENTITY, c),
            WorldShape::Box(b, p) => (*p, b),
            WorldShape::Cylinder(c, p) => (*p, c),
        }
    }
}

/// Whether two shapes touch: closed forms for capsule pairs and capsule–box
/// pairs ([`crate::geometry::segment_box`]), parry's default dispatcher for two boxes.
pub fn intersects(a: &WorldShape, b: &WorldShape) -> bool {
    match (a, b) {
        (WorldShape::Capsule(c1), WorldShape::Capsule(c2)) => {
            capsules_intersect(&Pose::IDENTITY, c1, &Pose::IDENTITY, c2)
        }
        (WorldShape::Capsule(c), WorldShape::Box(cuboid, pose))
        | (WorldShape::Box(cuboid, pose), WorldShape::Capsule(c)) => {
            segment_box_distance_squared(c.segment.a, c.segment.b, cuboid, pose)
                <= c.radius * c.radius
        }
        _ => {
            let ((pa, sa), (pb, sb)) = (a.as_query(), b.as_query());
            intersection_test(&pa, sa, &pb, sb).map_or(true, |r| r.intersecting)
        }
    }
}

/// Two capsules touch when their segments are within the sum of the radii:
/// parry's closed-form segment-segment closest points, where its general
/// dispatcher would run GJK on the two support maps (most of a
/// configuration's checks are capsule pairs: arm links, branches, self).
pub fn capsules_intersect(pa: &Pose, c1: &Capsule, pb: &Pose, c2: &Capsule) -> bool {
    let (s1, s2) = (c1.segment.transformed(pa), c2.segment.transformed(pb));
    let (p1, p2) = closest_points(s1.a, s1.b, s2.a, s2.b);
    let gap = p1 - p2;
    let reach = c1.radius + c2.radius;
    gap.length_squared() <= reach * reach
}

/// Distance between two shapes (0 when they touch or overlap): closed form
/// for two capsules and for a capsule and a box ([`crate::geometry::segment_box`]),
/// parry's GJK for two boxes.
pub fn distance(a: &WorldShape, b: &WorldShape) -> f64 {
    match (a, b) {
        (WorldShape::Capsule(c1), WorldShape::Capsule(c2)) => {
            let (s1, s2) = (&c1.segment, &c2.segment);
            let (p1, p2) = closest_points(s1.a, s1.b, s2.a, s2.b);
            let gap = (p1 - p2).length();
            (gap - c1.radius - c2.radius).max(0.0)
        }
        (WorldShape::Capsule(c), WorldShape::Box(cuboid, pose))
        | (WorldShape::Box(cuboid, pose), WorldShape::Capsule(c)) => {
            let gap = segment_box_distance_squared(c.segment.a, c.segment.b, cuboid, pose).sqrt();
            (gap - c.radius).max(0.0)
        }
        _ => {
            let ((pa, sa), (pb, sb)) = (a.as_query(), b.as_query());
            parry3d_f64::query::distance(&pa, sa, &pb, sb).map_or(0.0, |d| d.distance.max(0.0))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::convert::pose;
    use nalgebra::{Isometry3, Vector3};
    use parry3d_f64::math::Vec3;
    use rand::{RngExt, SeedableRng};

    /// The closed form agrees with parry's general (GJK) test on random
    /// capsule pairs, near-touching ones included, under random poses.
    #[test]
    fn capsule_fast_path_matches_parry() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let point = |rng: &mut rand_chacha::ChaCha8Rng| {
            Vec3::new(
                rng.random_range(-0.3..0.3),
                rng.random_range(-0.3..0.3),
                rng.random_range(-0.3..0.3),
            )
        };
        let (mut touching, mut apart) = (0, 0);
        for k in 0..20_000 {
            let c1 = Capsule::new(
                point(&mut rng),
                point(&mut rng),
                rng.random_range(0.005..0.1),
            );
            let c2 = Capsule::new(
                point(&mut rng),
                point(&mut rng),
                rng.random_range(0.005..0.1),
            );
            let pose_of = |rng: &mut rand_chacha::ChaCha8Rng| {
                if k % 2 == 0 {
                    Pose::IDENTITY
                } else {
                    pose(&Isometry3::new(
                        Vector3::new(rng.random_range(-0.1..0.1), 0.05, 0.0),
                        Vector3::new(rng.random_range(-1.0..1.0), 0.3, -0.2),
                    ))
                }
            };
            let (pa, pb) = (pose_of(&mut rng), pose_of(&mut rng));
            let gjk = intersection_test(&pa, &c1, &pb, &c2).unwrap().intersecting;
            // Within 1e-9 m of touching, either answer is right.
            let clearance = parry3d_f64::query::distance(&pa, &c1, &pb, &c2)
                .unwrap()
                .distance;
            if capsules_intersect(&pa, &c1, &pb, &c2) != gjk {
                assert!(
                    clearance < 1e-9 && !gjk,
                    "pair {k}: clearance {clearance}, gjk {gjk}"
                );
            }
            if gjk { touching += 1 } else { apart += 1 }
        }
        assert!(
            touching > 1000 && apart > 1000,
            "{touching} touching, {apart} apart"
        );
    }
}
