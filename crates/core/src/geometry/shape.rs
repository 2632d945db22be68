//! The solids of the world around a tree (m, rad, the tree's frame): an
//! objective's regions (a fruit, a box, a line of sight) and the obstacles
//! the arm must not touch are the same [`Shape`], with one parry
//! conversion, one bounding box and one signed distance.

use nalgebra::{Isometry3, Point3, Vector3};
use parry3d_f64::math::{Pose, Vec3};
use parry3d_f64::query::contact;
use parry3d_f64::shape::{Ball, Capsule, Cuboid};
use serde::{Deserialize, Serialize};

use crate::geometry::aabb::Aabb;
use crate::geometry::convert::{pose, vec3};
use crate::geometry::segment::{any_perpendicular, closest_points};
use crate::geometry::world_shape::WorldShape;

/// A sphere, a box turned about the vertical, or a capsule.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Shape {
    Sphere {
        centre: Point3<f64>,
        radius: f64,
    },
    /// A box: its centre, half extents along its own axes, and its pose's
    /// rotation, `yaw` (rad) about the vertical ([`Shape::pose`]).
    Box {
        centre: Point3<f64>,
        half_extents: Vector3<f64>,
        #[serde(default)]
        yaw: f64,
    },
    /// The points within `radius` of the segment a–b.
    Capsule {
        a: Point3<f64>,
        b: Point3<f64>,
        radius: f64,
    },
}

impl Shape {
    /// The shape's pose: a box's centre and yaw, a sphere's centre; the
    /// identity for a capsule (its end points are in the world frame).
    pub fn pose(&self) -> Isometry3<f64> {
        match self {
            Shape::Sphere { centre, .. } => Isometry3::translation(centre.x, centre.y, centre.z),
            Shape::Box { centre, yaw, .. } => Isometry3::new(centre.coords, Vector3::z() * *yaw),
            Shape::Capsule { .. } => Isometry3::identity(),
        }
    }

    /// A point inside the shape (its centre).
    pub fn centre(&self) -> Point3<f64> {
        match self {
            Shape::Sphere { centre, .. } | Shape::Box { centre, .. } => *centre,
            Shape::Capsule { a, b, .. } => nalgebra::center(a, b),
        }
    }

    /// The shape as parry's, with its pose.
    pub fn parry(&self) -> (Box<dyn parry3d_f64::shape::Shape>, Pose) {
        let at = pose(&self.pose());
        match self {
            Shape::Sphere { radius, .. } => (Box::new(Ball::new(*radius)), at),
            Shape::Box { half_extents, .. } => (Box::new(Cuboid::new(vec3(half_extents))), at),
            Shape::Capsule { a, b, radius } => (
                Box::new(Capsule::new(vec3(&a.coords), vec3(&b.coords), *radius)),
                at,
            ),
        }
    }

    /// The axis-aligned box around the shape.
    pub fn aabb(&self) -> Aabb {
        match self {
            Shape::Sphere { centre, radius } => {
                Aabb::of_capsule(&centre.coords, &centre.coords, *radius)
            }
            Shape::Capsule { a, b, radius } => Aabb::of_capsule(&a.coords, &b.coords, *radius),
            Shape::Box {
                centre,
                half_extents,
                ..
            } => {
                let extent =
                    self.pose().rotation.to_rotation_matrix().matrix().abs() * half_extents;
                Aabb {
                    min: centre.coords - extent,
                    max: centre.coords + extent,
                }
            }
        }
    }

    /// The shape ready for the collision checker's queries, with its box.
    /// A sphere is a capsule whose segment is a point (the checker's closed
    /// forms handle it).
    pub fn world(&self) -> (WorldShape, Aabb) {
        let shape = match self {
            Shape::Sphere { centre, radius } => WorldShape::Capsule(Capsule::new(
                vec3(&centre.coords),
                vec3(&centre.coords),
                *radius,
            )),
            Shape::Capsule { a, b, radius } => {
                WorldShape::Capsule(Capsule::new(vec3(&a.coords), vec3(&b.coords), *radius))
            }
            Shape::Box { half_extents, .. } => {
                WorldShape::Box(Cuboid::new(vec3(half_extents)), pose(&self.pose()))
            }
        };
        (shape, self.aabb())
    }

    /// Prepared for many distance queries.
    pub fn prepared(&self) -> PreparedShape {
        let (parry, at) = self.parry();
        PreparedShape {
            shape: self.clone(),
            parry,
            pose: at,
        }
    }
}

/// A [`Shape`] with its parry shape built once, for repeated queries.
pub struct PreparedShape {
    shape: Shape,
    parry: Box<dyn parry3d_f64::shape::Shape>,
    pose: Pose,
}

impl PreparedShape {
    /// Distance from `p` to the shape (0 inside).
    pub fn distance_to_point(&self, p: &Point3<f64>) -> f64 {
        self.parry
            .distance_to_point(&self.pose, vec3(&p.coords), true)
    }

    /// Signed distance from the capsule a–b of `radius` (negative: depth of
    /// overlap) and the unit direction from the shape toward the capsule.
    /// Spheres and capsules are a segment (or point) grown by a radius, as
    /// branches are, so their signed distance is exact and has no
    /// degenerate case (a fruit centred on a branch's axis); boxes use
    /// parry's contact query.
    pub fn signed_distance(
        &self,
        a: &Point3<f64>,
        b: &Point3<f64>,
        radius: f64,
    ) -> (f64, Vector3<f64>) {
        let (a, b) = (vec3(&a.coords), vec3(&b.coords));
        let grown = |core_a: Vec3, core_b: Vec3, core_radius: f64| {
            let (on_branch, on_core) = closest_points(a, b, core_a, core_b);
            let gap = on_branch - on_core;
            let away = if gap.length() > 1e-12 {
                gap.normalize()
            } else {
                any_perpendicular(b - a)
            };
            (gap.length() - core_radius - radius, away)
        };
        let (dist, away) = match &self.shape {
            Shape::Sphere { centre, radius: r } => {
                grown(vec3(&centre.coords), vec3(&centre.coords), *r)
            }
            Shape::Capsule {
                a: p,
                b: q,
                radius: r,
            } => grown(vec3(&p.coords), vec3(&q.coords), *r),
            Shape::Box { centre, .. } => {
                let capsule = Capsule::new(a, b, radius);
                match contact(
                    &Pose::IDENTITY,
                    &capsule,
                    &self.pose,
                    &*self.parry,
                    f64::MAX,
                )
                .ok()
                .flatten()
                {
                    // normal1 points from the branch toward the shape.
                    Some(c) => (c.dist, -c.normal1),
                    None => {
                        let c = vec3(&centre.coords);
                        let (on_branch, _) = closest_points(a, b, c, c);
                        (0.0, (on_branch - c).normalize_or(Vec3::Z))
                    }
                }
            }
        };
        (dist, Vector3::new(away.x, away.y, away.z))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(x: f64, y: f64, z: f64) -> Point3<f64> {
        Point3::new(x, y, z)
    }

    /// Signed distances against closed forms: a branch beside a sphere, a
    /// capsule, and above a turned box; an overlap is negative.
    #[test]
    fn signed_distances_match_closed_forms() {
        let (a, b, r) = (p(0.0, -1.0, 0.0), p(0.0, 1.0, 0.0), 0.01);
        let sphere = Shape::Sphere {
            centre: p(0.3, 0.2, 0.0),
            radius: 0.05,
        };
        let (d, away) = sphere.prepared().signed_distance(&a, &b, r);
        assert!((d - (0.3 - 0.05 - 0.01)).abs() < 1e-12, "{d}");
        assert!((away - Vector3::new(-1.0, 0.0, 0.0)).norm() < 1e-12);
        let capsule = Shape::Capsule {
            a: p(0.0, 0.0, 0.2),
            b: p(0.0, 0.0, 1.0),
            radius: 0.02,
        };
        let (d, _) = capsule.prepared().signed_distance(&a, &b, r);
        assert!((d - (0.2 - 0.02 - 0.01)).abs() < 1e-12, "{d}");
        let turned = Shape::Box {
            centre: p(0.0, 0.0, 0.5),
            half_extents: Vector3::new(0.1, 0.3, 0.2),
            yaw: 0.7,
        };
        let (d, away) = turned.prepared().signed_distance(&a, &b, r);
        // parry's contact query (GJK/EPA) is exact to its tolerance.
        assert!((d - (0.5 - 0.2 - 0.01)).abs() < 1e-6, "{d}");
        assert!(
            (away - Vector3::new(0.0, 0.0, -1.0)).norm() < 1e-6,
            "{away}"
        );
        let (d, _) = sphere
            .prepared()
            .signed_distance(&p(0.3, -1.0, 0.0), &p(0.3, 1.0, 0.0), r);
        assert!((d + 0.06).abs() < 1e-12, "overlap {d}");
    }

    /// The bounding box holds the shape: the turned box's corners, and
    /// the points a distance query says are inside.
    #[test]
    fn the_bounding_box_holds_the_shape() {
        let turned = Shape::Box {
            centre: p(0.2, -0.1, 0.4),
            half_extents: Vector3::new(0.1, 0.3, 0.2),
            yaw: -0.4,
        };
        let aabb = turned.aabb();
        let pose = turned.pose();
        for corner in 0..8 {
            let local = Vector3::new(
                if corner & 1 == 0 { -0.1 } else { 0.1 },
                if corner & 2 == 0 { -0.3 } else { 0.3 },
                if corner & 4 == 0 { -0.2 } else { 0.2 },
            );
            let w = pose * Point3::from(local);
            for k in 0..3 {
                assert!(w[k] >= aabb.min[k] - 1e-12 && w[k] <= aabb.max[k] + 1e-12);
            }
        }
        let prepared = turned.prepared();
        assert_eq!(prepared.distance_to_point(&turned.centre()), 0.0);
        assert!((prepared.distance_to_point(&p(0.2, -0.1, 0.9)) - 0.3).abs() < 1e-12);
    }
}
