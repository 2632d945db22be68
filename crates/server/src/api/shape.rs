//! The one shape schema of the wire: `objective.regions`, `objective.region`
//! and `obstacles` are each a [`ShapeJson`] (a sphere, a box, a capsule or
//! a cylinder; m, rad), checked by one validator into
//! [`treemanip_core::geometry::shape::Shape`]; the links' shapes of
//! `/v1/robot/link-poses` are answered in the same schema.

use nalgebra::{Isometry3, Quaternion, UnitQuaternion};
use treemanip_core::geometry::shape::Shape;

use super::error::ApiError;
use super::validate::{MAX_DISTANCE, near_point, vector3};
use crate::api::types::ShapeJson;

/// How large a shape may be where it is used, and whether a refusal
/// quotes the value.
#[derive(Debug, Clone, Copy)]
pub struct SizeRule {
    /// The largest radius or half extent (m).
    pub max: f64,
    /// Whether the message ends with the value refused.
    pub quote_value: bool,
}

/// A region of an objective: a fruit, a box, a line of sight (at most 2 m).
pub const REGION: SizeRule = SizeRule {
    max: 2.0,
    quote_value: true,
};

/// An obstacle: a post, a wire, a neighbouring stem (within the 5 m any
/// point may lie from the root). Its messages never quoted the value, and
/// answers stay as they were.
pub const OBSTACLE: SizeRule = SizeRule {
    max: MAX_DISTANCE,
    quote_value: false,
};

fn size(value: f64, field: &str, rule: &SizeRule) -> Result<f64, ApiError> {
    if value.is_finite() && value > 0.0 && value <= rule.max {
        return Ok(value);
    }
    let max = rule.max;
    let message = if rule.quote_value {
        format!("`{field}` must be positive and at most {max} m, not {value}")
    } else {
        format!("`{field}` must be positive and at most {max} m")
    };
    Err(ApiError::invalid_field(field, message))
}

/// `[qx, qy, qz, qw]` at `field`: four finite numbers, not all zero,
/// normalised.
fn unit_quaternion(q: &[f64], field: &str) -> Result<UnitQuaternion<f64>, ApiError> {
    let ok = q.len() == 4 && q.iter().all(|x| x.is_finite());
    let norm = q.iter().map(|x| x * x).sum::<f64>().sqrt();
    if !ok || norm <= 1e-9 {
        return Err(ApiError::invalid_field(
            field,
            format!(
                "`{field}` must be a quaternion [qx, qy, qz, qw] of finite numbers, not all zero"
            ),
        ));
    }
    Ok(UnitQuaternion::from_quaternion(Quaternion::new(
        q[3], q[0], q[1], q[2],
    )))
}

/// `json` at `field` (e.g. `objective.regions[2]`), checked: points within
/// reach of the root, sizes positive and within `rule`, a finite yaw or a
/// rotation (a box takes one of them).
pub fn shape(json: &ShapeJson, field: &str, rule: &SizeRule) -> Result<Shape, ApiError> {
    Ok(match json {
        ShapeJson::Sphere { centre, radius } => Shape::Sphere {
            centre: near_point(centre, &format!("{field}.centre"))?,
            radius: size(*radius, &format!("{field}.radius"), rule)?,
        },
        ShapeJson::Box {
            centre,
            half_extents,
            yaw,
            rotation,
        } => {
            let h = vector3(half_extents, &format!("{field}.half_extents"))?;
            for k in 0..3 {
                size(h[k], &format!("{field}.half_extents"), rule)?;
            }
            if !yaw.is_finite() {
                return Err(ApiError::invalid_field(
                    &format!("{field}.yaw"),
                    format!("`{field}.yaw` must be finite"),
                ));
            }
            let centre = near_point(centre, &format!("{field}.centre"))?;
            match rotation {
                None => Shape::turned_box(centre, h, *yaw),
                Some(_) if *yaw != 0.0 => {
                    return Err(ApiError::invalid_field(
                        &format!("{field}.rotation"),
                        format!("give `{field}.yaw` or `{field}.rotation`, not both"),
                    ));
                }
                Some(q) => Shape::Box {
                    pose: Isometry3::from_parts(
                        centre.coords.into(),
                        unit_quaternion(q, &format!("{field}.rotation"))?,
                    ),
                    half_extents: h,
                },
            }
        }
        ShapeJson::Cylinder {
            centre,
            rotation,
            radius,
            half_length,
        } => {
            let centre = near_point(centre, &format!("{field}.centre"))?;
            let rotation = match rotation {
                Some(q) => unit_quaternion(q, &format!("{field}.rotation"))?,
                None => UnitQuaternion::identity(),
            };
            Shape::Cylinder {
                pose: Isometry3::from_parts(centre.coords.into(), rotation),
                radius: size(*radius, &format!("{field}.radius"), rule)?,
                half_length: size(*half_length, &format!("{field}.half_length"), rule)?,
            }
        }
        ShapeJson::Capsule { a, b, radius } => Shape::Capsule {
            a: near_point(a, &format!("{field}.a"))?,
            b: near_point(b, &format!("{field}.b"))?,
            radius: size(*radius, &format!("{field}.radius"), rule)?,
        },
    })
}
