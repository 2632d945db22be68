//! A point's distance from a joint's axis: the lever arm that bounds how
//! fast the joint's rotation moves the point (conservative advancement;
//! the points themselves are [`crate::geometry::shape::Shape::bounding_points`]).

use nalgebra::Point3;

/// Distance of `p` from a joint's axis (a point on it, its direction).
pub(crate) fn from_axis(
    axis: &(Point3<f64>, nalgebra::Vector3<f64>, bool),
    p: &Point3<f64>,
) -> f64 {
    let (o, d, _) = axis;
    let v = p - o;
    (v - d * v.dot(d)).norm()
}
