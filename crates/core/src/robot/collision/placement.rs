//! A link's collision shape placed in the world, as the queries take it.

use nalgebra::{Isometry3, Point3, Vector3};
use parry3d_f64::shape::{Capsule, Cuboid, Cylinder};

use crate::geometry::aabb::Aabb;
use crate::geometry::convert::{pose, vec3};
use crate::geometry::world_shape::WorldShape;
use crate::robot::model::link_geometry::LinkShape;

/// A link's shape placed at the link's world pose `p`, grown by `margin`,
/// with its (exact) bounding box.
pub(crate) fn world_shape(
    shape: &LinkShape,
    p: &Isometry3<f64>,
    margin: f64,
) -> (WorldShape, Aabb) {
    let capsule = |a: Point3<f64>, b: Point3<f64>, radius: f64| {
        let (wa, wb) = ((p * a).coords, (p * b).coords);
        let r = radius + margin;
        (
            WorldShape::Capsule(Capsule::new(vec3(&wa), vec3(&wb), r)),
            Aabb::of_capsule(&wa, &wb, r),
        )
    };
    match shape {
        LinkShape::Capsule(c) => capsule(c.a, c.b, c.radius),
        LinkShape::Sphere { center, radius } => capsule(*center, *center, *radius),
        LinkShape::Box {
            pose: at,
            half_extents,
        } => {
            let half_extents = &half_extents.add_scalar(margin);
            let world = p * at;
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
        LinkShape::Cylinder {
            pose: at,
            radius,
            half_length,
        } => {
            let (radius, half_length) = (radius + margin, half_length + margin);
            let world = p * at;
            let axis = world.rotation * Vector3::z();
            // A disc of radius r across unit axis d reaches r √(1 − d_k²)
            // along world axis k.
            let extent =
                axis.abs() * half_length + axis.map(|d| radius * (1.0 - d * d).max(0.0).sqrt());
            let c = world.translation.vector;
            // parry's cylinder is along y: turn y onto the local z.
            let turned = world
                * nalgebra::UnitQuaternion::from_axis_angle(
                    &Vector3::x_axis(),
                    std::f64::consts::FRAC_PI_2,
                );
            (
                WorldShape::Cylinder(Cylinder::new(half_length, radius), pose(&turned)),
                Aabb {
                    min: c - extent,
                    max: c + extent,
                },
            )
        }
    }
}
