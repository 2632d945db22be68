//! The JSON of `/v1/plan`'s `objective` and `limits`, checked and turned
//! into [`treemanip_core::planner::Objective`] and [`Limits`]. What the
//! objectives mean is in [`treemanip_core::planner::objective`].

use serde_json::json;

use super::error::ApiError;
use super::shape::{REGION, shape};
use super::validate::{check_contact, targets_at};
use crate::api::types::{LimitsJson, ObjectiveJson};
use treemanip_core::planner::objective::{
    DEFAULT_CLEAR_MARGIN, DEFAULT_MAX_CONTACT_FORCE, DEFAULT_MAX_STRESS,
};
use treemanip_core::planner::{Limits, Objective};
use treemanip_core::tree::Tree;

/// Regions a `clear` objective may list.
pub const MAX_REGIONS: usize = 16;
/// Largest region size (a radius or half extent) and margin accepted (m).
pub const MAX_REGION_SIZE: f64 = REGION.max;

/// The request's objective: `objective`, or the `target_positions`
/// shorthand for a full shape (exactly one of them).
pub fn objective(
    objective: Option<&ObjectiveJson>,
    target_positions: Option<&[Vec<f64>]>,
    tree: &Tree,
) -> Result<Objective, ApiError> {
    match (objective, target_positions) {
        (Some(_), Some(_)) => Err(ApiError::invalid_field(
            "objective",
            "give either `objective` or its shorthand `target_positions`, not both",
        )),
        (None, None) => Err(ApiError::invalid_field(
            "objective",
            "say what the push is for: `objective` (shape, clear or reach) or `target_positions`",
        )),
        (None, Some(t)) => Ok(Objective::shape(targets_at(t, tree, "target_positions")?)),
        (Some(o), None) => from_json(o, tree),
    }
}

fn from_json(json: &ObjectiveJson, tree: &Tree) -> Result<Objective, ApiError> {
    match json {
        ObjectiveJson::Shape {
            target_positions,
            weights,
        } => {
            let targets = targets_at(target_positions, tree, "objective.target_positions")?;
            let weights = match weights {
                None => None,
                Some(w) => {
                    let field = "objective.weights";
                    if w.len() != tree.len() {
                        return Err(ApiError::invalid_field(
                            field,
                            format!(
                                "`{field}` has {} entries but the tree has {} nodes",
                                w.len(),
                                tree.len()
                            ),
                        ));
                    }
                    if let Some(j) = w.iter().position(|v| !(v.is_finite() && *v >= 0.0)) {
                        return Err(ApiError::invalid_field(
                            field,
                            format!("`{field}[{j}]` must be a finite number ≥ 0"),
                        ));
                    }
                    // The root cannot move: weighting only it names no node
                    // a push can serve.
                    if w.iter().skip(1).all(|v| *v == 0.0) {
                        return Err(ApiError::invalid_field(
                            field,
                            format!(
                                "`{field}` weighs no node that can move (every non-root weight is 0)"
                            ),
                        ));
                    }
                    Some(w.clone())
                }
            };
            Ok(Objective::Shape { targets, weights })
        }
        ObjectiveJson::Clear { regions, margin } => {
            if regions.is_empty() || regions.len() > MAX_REGIONS {
                return Err(ApiError::invalid_field(
                    "objective.regions",
                    format!(
                        "`objective.regions` must list 1 to {MAX_REGIONS} regions, not {}",
                        regions.len()
                    ),
                ));
            }
            let margin = match margin {
                None => DEFAULT_CLEAR_MARGIN,
                Some(m) if m.is_finite() && *m >= 0.0 && *m <= MAX_REGION_SIZE => *m,
                Some(m) => {
                    return Err(ApiError::invalid_field(
                        "objective.margin",
                        format!(
                            "`objective.margin` must be between 0 and {MAX_REGION_SIZE} m, not {m}"
                        ),
                    ));
                }
            };
            let regions = regions
                .iter()
                .enumerate()
                .map(|(k, r)| shape(r, &format!("objective.regions[{k}]"), &REGION))
                .collect::<Result<Vec<_>, _>>()?;
            Ok(Objective::Clear { regions, margin })
        }
        ObjectiveJson::Reach { node, region: r } => {
            let node = check_contact(*node, tree, "objective.node")?;
            Ok(Objective::Reach {
                node,
                region: shape(r, "objective.region", &REGION)?,
            })
        }
    }
}

/// The request's limits, defaults filled in.
pub fn limits(json: Option<&LimitsJson>) -> Result<Limits, ApiError> {
    let json = json.cloned().unwrap_or_default();
    let positive = |v: Option<f64>, default: f64, field: &str| match v {
        None => Ok(default),
        Some(v) if v.is_finite() && v > 0.0 => Ok(v),
        Some(v) => Err(ApiError::invalid_field(
            field,
            format!("`{field}` must be a positive number, not {v}"),
        )
        .with_details(json!({ "field": field }))),
    };
    Ok(Limits {
        max_stress: positive(json.max_stress, DEFAULT_MAX_STRESS, "limits.max_stress")?,
        max_contact_force: positive(
            json.max_contact_force,
            DEFAULT_MAX_CONTACT_FORCE,
            "limits.max_contact_force",
        )?,
    })
}
