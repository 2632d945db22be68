//! The one shape type: an objective's regions (a fruit, a box, a line of
//! sight), the obstacles the arm must not touch and the arm's own collision
//! geometry are each a [`Shape`] (m, rad), with one parry conversion, one
//! bounding box, one placement in the world and one signed distance.

use nalgebra::{Isometry3, Point3, UnitQuaternion, Vector3};
use parry3d_f64::math::{Pose, Vec3};
use parry3d_f64::query::contact;
use parry3d_f64::shape::{Ball, Capsule, Cuboid, Cylinder};

use crate::geometry::aabb::Aabb;
use crate::geometry::convert::{pose, vec3};
use crate::geometry::segment::{any_perpendicular, closest_points};
use crate::geometry::world_shape::WorldShape;

/// A sphere, a box, a capsule or a cylinder: in the world frame for an
/// objective's regions and the obstacles, in its link's frame for an arm's
/// collision geometry ([`Shape::placed`] moves it, [`Shape::world`] makes it
/// ready for the collision checker).
#[derive(Debug, Clone, PartialEq)]
pub enum Shape {
    Sphere {
        centre: Point3<f64>,
        radius: f64,
    },
    /// Half extents along the axes of its pose.
    Box {
        pose: Isometry3<f64>,
        half_extents: Vector3<f64>,
    },
    /// The points within `radius` of the segment a–b.
    Capsule {
        a: Point3<f64>,
        b: Point3<f64>,
        radius: f64,
    },
    /// Along the local z axis of `pose`.
    Cylinder {
        pose: Isometry3<f64>,
        radius: f64,
        half_length: f64,
    },
}

impl Shape {
    /// A box at `centre` turned by `yaw` (rad) about the vertical: the
    /// boxes of regions and obstacles.
    pub fn turned_box(centre: Point3<f64>, half_extents: Vector3<f64>, yaw: f64) -> Self {
        Shape::Box {
            pose: Isometry3::new(centre.coords, Vector3::z() * yaw),
            half_extents,
        }
    }

    /// The shape's pose: a box's or a cylinder's, a sphere's centre; the
    /// identity for a capsule (its end points carry its place).
    pub fn pose(&self) -> Isometry3<f64> {
        match self {
            Shape::Sphere { centre, .. } => Isometry3::translation(centre.x, centre.y, centre.z),
            Shape::Box { pose, .. } | Shape::Cylinder { pose, .. } => *pose,
            Shape::Capsule { .. } => Isometry3::identity(),
        }
    }

    /// A point inside the shape (its centre).
    pub fn centre(&self) -> Point3<f64> {
        match self {
            Shape::Sphere { centre, .. } => *centre,
            Shape::Box { pose, .. } | Shape::Cylinder { pose, .. } => {
                Point3::from(pose.translation.vector)
            }
            Shape::Capsule { a, b, .. } => nalgebra::center(a, b),
        }
    }

    /// This shape moved by `pose`.
    pub fn placed(&self, pose: &Isometry3<f64>) -> Shape {
        match self {
            Shape::Capsule { a, b, radius } => Shape::Capsule {
                a: pose * a,
                b: pose * b,
                radius: *radius,
            },
            Shape::Sphere { centre, radius } => Shape::Sphere {
                centre: pose * centre,
                radius: *radius,
            },
            Shape::Box {
                pose: at,
                half_extents,
            } => Shape::Box {
                pose: pose * at,
                half_extents: *half_extents,
            },
            Shape::Cylinder {
                pose: at,
                radius,
                half_length,
            } => Shape::Cylinder {
                pose: pose * at,
                radius: *radius,
                half_length: *half_length,
            },
        }
    }

    /// How far the shape reaches from its frame's origin (m).
    pub fn reach(&self) -> f64 {
        match self {
            Shape::Capsule { a, b, radius } => a.coords.norm().max(b.coords.norm()) + radius,
            Shape::Sphere { centre, radius } => centre.coords.norm() + radius,
            Shape::Box { pose, half_extents } => {
                pose.translation.vector.norm() + half_extents.norm()
            }
            Shape::Cylinder {
                pose,
                radius,
                half_length,
            } => {
                pose.translation.vector.norm()
                    + (radius * radius + half_length * half_length).sqrt()
            }
        }
    }

    /// Two points and a pad such that the shape, moved by `at` and grown
    /// by `margin`, lies within `pad` of the segment between the points:
    /// what conservative advancement bounds a moving shape by.
    pub fn bounding_points(&self, at: &Isometry3<f64>, margin: f64) -> ([Point3<f64>; 2], f64) {
        match self {
            Shape::Capsule { a, b, radius } => ([at * a, at * b], radius + margin),
            Shape::Sphere { centre, radius } => {
                let c = at * centre;
                ([c, c], radius + margin)
            }
            Shape::Box { pose, half_extents } => {
                let c = at * pose * Point3::origin();
                ([c, c], half_extents.norm() + margin)
            }
            Shape::Cylinder {
                pose,
                radius,
                half_length,
            } => {
                let world = at * pose;
                (
                    [
                        world * Point3::new(0.0, 0.0, -half_length),
                        world * Point3::new(0.0, 0.0, *half_length),
                    ],
                    radius + margin,
                )
            }
        }
    }

    /// The shape moved by `at` and grown by `margin`, ready for the
    /// collision checker's queries, with its (exact) bounding box. A
    /// sphere is a capsule whose segment is a point (the checker's closed
    /// forms handle it).
    pub fn world(&self, at: &Isometry3<f64>, margin: f64) -> (WorldShape, Aabb) {
        let capsule = |a: Point3<f64>, b: Point3<f64>, radius: f64| {
            let (wa, wb) = ((at * a).coords, (at * b).coords);
            let r = radius + margin;
            (
                WorldShape::Capsule(Capsule::new(vec3(&wa), vec3(&wb), r)),
                Aabb::of_capsule(&wa, &wb, r),
            )
        };
        match self {
            Shape::Capsule { a, b, radius } => capsule(*a, *b, *radius),
            Shape::Sphere { centre, radius } => capsule(*centre, *centre, *radius),
            Shape::Box {
                pose: local,
                half_extents,
            } => {
                let half_extents = &half_extents.add_scalar(margin);
                let world = at * local;
                let extent = world.rotation.to_rotation_matrix().matrix().abs() * half_extents;
                let c = world.translation.vector;
                (
                    WorldShape::Box(Cuboid::new(vec3(half_extents)), pose(&world)),
                    Aabb {
                        min: c - extent,
                        max: c + extent,
                    },
                )
            }
            Shape::Cylinder {
                pose: local,
                radius,
                half_length,
            } => {
                let (radius, half_length) = (radius + margin, half_length + margin);
                let world = at * local;
                let axis = world.rotation * Vector3::z();
                // A disc of radius r across unit axis d reaches r √(1 − d_k²)
                // along world axis k.
                let extent =
                    axis.abs() * half_length + axis.map(|d| radius * (1.0 - d * d).max(0.0).sqrt());
                let c = world.translation.vector;
                (
                    WorldShape::Cylinder(
                        Cylinder::new(half_length, radius),
                        pose(&y_onto_z(&world)),
                    ),
                    Aabb {
                        min: c - extent,
                        max: c + extent,
                    },
                )
            }
        }
    }

    /// The axis-aligned box around the shape.
    pub fn aabb(&self) -> Aabb {
        self.world(&Isometry3::identity(), 0.0).1
    }

    /// The shape as parry's, with its pose in the shape's frame (parry's
    /// cylinder stands along its y axis, ours along z: the pose turns it).
    pub fn parry_in_frame(&self) -> (Isometry3<f64>, Box<dyn parry3d_f64::shape::Shape>) {
        match self {
            Shape::Sphere { radius, .. } => (self.pose(), Box::new(Ball::new(*radius))),
            Shape::Box { pose, half_extents } => (*pose, Box::new(Cuboid::new(vec3(half_extents)))),
            Shape::Capsule { a, b, radius } => (
                Isometry3::identity(),
                Box::new(Capsule::new(vec3(&a.coords), vec3(&b.coords), *radius)),
            ),
            Shape::Cylinder {
                pose,
                radius,
                half_length,
            } => (
                y_onto_z(pose),
                Box::new(Cylinder::new(*half_length, *radius)),
            ),
        }
    }

    /// The shape as parry's, with its pose.
    pub fn parry(&self) -> (Box<dyn parry3d_f64::shape::Shape>, Pose) {
        let (at, shape) = self.parry_in_frame();
        (shape, pose(&at))
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

/// `pose` turned so that parry's cylinder, along its local y, lies along
/// the pose's z.
fn y_onto_z(pose: &Isometry3<f64>) -> Isometry3<f64> {
    let z_to_y = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::FRAC_PI_2);
    pose * Isometry3::from_parts(Default::default(), z_to_y)
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
            Shape::Box { .. } | Shape::Cylinder { .. } => {
                let centre = self.shape.centre();
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
        let turned = Shape::turned_box(p(0.0, 0.0, 0.5), Vector3::new(0.1, 0.3, 0.2), 0.7);
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
        let turned = Shape::turned_box(p(0.2, -0.1, 0.4), Vector3::new(0.1, 0.3, 0.2), -0.4);
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
