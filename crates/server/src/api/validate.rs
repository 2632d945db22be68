//! Request validation shared by the handlers: fields that must be finite
//! 3-vectors, nodes that can be pushed, pushes the forward model answers
//! for, target shapes, joint configurations, deadlines. Each error names
//! the field at fault (`details.field`).

use nalgebra::{Point3, Vector3};
use serde_json::json;
use treemanip_core::tree::Tree;

use super::error::ApiError;

/// Farthest a base or obstacle may be from the tree root (m).
pub const MAX_DISTANCE: f64 = 5.0;

/// A request's `timeout_ms`, checked.
pub fn request_timeout(value: Option<f64>) -> Result<Option<std::time::Duration>, ApiError> {
    match value {
        None => Ok(None),
        Some(ms) if ms.is_finite() && ms > 0.0 => {
            Ok(Some(std::time::Duration::from_secs_f64(ms.min(1e9) / 1e3)))
        }
        Some(_) => Err(
            ApiError::invalid_argument("`timeout_ms` must be a positive number")
                .with_details(json!({ "field": "timeout_ms" })),
        ),
    }
}

/// A 3-vector field, finite.
pub fn vector3(values: &[f64], field: &str) -> Result<Vector3<f64>, ApiError> {
    let [x, y, z] = <[f64; 3]>::try_from(values).map_err(|_| {
        ApiError::invalid_argument(format!(
            "`{field}` must have 3 numbers, it has {}",
            values.len()
        ))
        .with_details(json!({ "field": field }))
    })?;
    let v = Vector3::new(x, y, z);
    if !v.iter().all(|c| c.is_finite()) {
        return Err(
            ApiError::invalid_argument(format!("`{field}` must be finite"))
                .with_details(json!({ "field": field })),
        );
    }
    Ok(v)
}

/// A push no longer than `max_push` (m), the longest the forward model
/// answers for (its card's domain: twice the longest trained push). Past
/// that its answers would be pure extrapolation, so not even
/// `allow_out_of_domain` asks for them.
pub fn check_push(
    push: Vector3<f64>,
    field: &str,
    max_push: f64,
) -> Result<Vector3<f64>, ApiError> {
    if push.norm() > max_push {
        return Err(ApiError::invalid_argument(format!(
            "`{field}` is {:.3} m long; the forward model answers for pushes up to {max_push:.3} m (twice the longest push it was trained on)",
            push.norm()
        ))
        .with_details(json!({ "field": field })));
    }
    Ok(push)
}

pub fn check_contact(node: usize, tree: &Tree, field: &str) -> Result<usize, ApiError> {
    if node == 0 || node >= tree.len() {
        return Err(ApiError::invalid_argument(format!(
            "`{field}` is {node}; it must name a non-root node, 1 to {}",
            tree.len() - 1
        ))
        .with_details(json!({ "field": field, "node": node })));
    }
    Ok(node)
}

/// Target positions: one finite 3-vector per node.
pub fn targets(values: &[Vec<f64>], tree: &Tree) -> Result<Vec<Point3<f64>>, ApiError> {
    targets_at(values, tree, "target_positions")
}

/// [`targets`] for a request field named `field`.
pub fn targets_at(
    values: &[Vec<f64>],
    tree: &Tree,
    field: &str,
) -> Result<Vec<Point3<f64>>, ApiError> {
    if values.len() != tree.len() {
        return Err(ApiError::invalid_argument(format!(
            "`{field}` has {} entries but the tree has {} nodes",
            values.len(),
            tree.len()
        ))
        .with_details(json!({ "field": field, "expected": tree.len(), "got": values.len() })));
    }
    values
        .iter()
        .enumerate()
        .map(|(j, v)| vector3(v, &format!("{field}[{j}]")).map(Point3::from))
        .collect()
}

/// Whether `angle` is a heading the API takes: finite, within ±2π rad
/// (base yaw, roll and pitch, a base region's yaw range).
pub fn within_turn(angle: f64) -> bool {
    angle.is_finite() && angle.abs() <= std::f64::consts::TAU
}

/// A joint configuration of `arm` given in `field`: one finite value per
/// joint (rad, or m for a prismatic joint), each within its joint's limits.
pub fn joints(
    values: &[f64],
    field: &str,
    arm: &treemanip_core::robot::Arm,
) -> Result<treemanip_core::robot::model::joint_vector::JointVector, ApiError> {
    if values.len() != arm.dof() {
        return Err(ApiError::invalid_field(
            field,
            format!(
                "`{field}` must have {} joint values for `{}`, it has {}",
                arm.dof(),
                arm.name(),
                values.len()
            ),
        ));
    }
    for (k, (v, j)) in values.iter().zip(arm.joints()).enumerate() {
        if !(v.is_finite() && j.lower <= *v && *v <= j.upper) {
            return Err(ApiError::invalid_field(
                field,
                format!(
                    "`{field}[{k}]` = {v} is outside joint `{}`'s limits [{}, {}]",
                    j.name, j.lower, j.upper
                ),
            ));
        }
    }
    Ok(treemanip_core::robot::model::joint_vector::JointVector::from_slice(values))
}

/// A point within [`MAX_DISTANCE`] of the root.
pub fn near_point(values: &[f64], field: &str) -> Result<Point3<f64>, ApiError> {
    let v = vector3(values, field)?;
    if v.norm() > MAX_DISTANCE {
        return Err(ApiError::invalid_field(
            field,
            format!("`{field}` is more than {MAX_DISTANCE} m from the tree root"),
        ));
    }
    Ok(Point3::from(v))
}
