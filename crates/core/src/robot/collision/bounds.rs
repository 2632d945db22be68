//! Points and pads that bound a link shape, for the clearance and lever-arm
//! bounds of conservative advancement: a shape lies within `pad` of the
//! segment between its two points.

use nalgebra::Point3;

use crate::robot::model::link_geometry::LinkShape;

/// Distance of `p` from a joint's axis (origin, unit direction, prismatic).
/// Distance of `p` from a joint's axis (a point on it, its direction).
pub(crate) fn from_axis(
    axis: &(Point3<f64>, nalgebra::Vector3<f64>, bool),
    p: &Point3<f64>,
) -> f64 {
    let (o, d, _) = axis;
    let v = p - o;
    (v - d * v.dot(d)).norm()
}

/// Points that bound a shape at `pose`, and how far the shape reaches
/// beyond them (grown by `margin`).
pub(crate) fn bounding_points(
    shape: &LinkShape,
    pose: &nalgebra::Isometry3<f64>,
    margin: f64,
) -> ([Point3<f64>; 2], f64) {
    match shape {
        LinkShape::Capsule(c) => ([pose * c.a, pose * c.b], c.radius + margin),
        LinkShape::Sphere { center, radius } => {
            let c = pose * center;
            ([c, c], radius + margin)
        }
        LinkShape::Box {
            pose: at,
            half_extents,
        } => {
            let c = pose * at * Point3::origin();
            ([c, c], half_extents.norm() + margin)
        }
        LinkShape::Cylinder {
            pose: at,
            radius,
            half_length,
        } => {
            let world = pose * at;
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
