//! Refusing (or, when asked, flagging) requests outside a model's domain
//! ([`treemanip_core::model::domain`]).

use serde_json::Value;

use super::error::ApiError;
use crate::api::types::Warning;
use crate::api::types::domain::ViolationJson;
use treemanip_core::model::domain::Violation;
use treemanip_core::tree::Tree;
use treemanip_infer::models::ServedModel;

fn details(v: &Violation, model: &ServedModel) -> ViolationJson {
    ViolationJson {
        model: model.name.clone(),
        quantity: v.quantity.to_owned(),
        value: v.value,
        min: v.min,
        max: v.max,
        node: v.node,
    }
}

fn details_json(v: &Violation, model: &ServedModel) -> Value {
    serde_json::to_value(details(v, model)).unwrap_or(Value::Null)
}

/// Checks `tree` and the forward model's pushes (node, |T|) against
/// `model`'s domain. A quantity outside it is a 422 `out_of_domain` naming
/// it, its bound and its node, unless `allow` is set; then it, like every
/// tree size outside the evaluated range, becomes a warning.
pub fn check(
    model: &ServedModel,
    tree: &Tree,
    pushes: &[(usize, f64)],
    allow: bool,
) -> Result<Vec<Warning>, ApiError> {
    let domain = &model.card.domain.domain;
    let mut violations = domain.check_tree(tree);
    violations.extend(
        pushes
            .iter()
            .filter_map(|&(node, length)| domain.check_push(node, length)),
    );
    if !allow && let Some(v) = violations.iter().find(|v| v.refused) {
        let all: Vec<Value> = violations
            .iter()
            .filter(|v| v.refused)
            .map(|v| details_json(v, model))
            .collect();
        let mut d = details_json(v, model);
        d["violations"] = Value::Array(all);
        return Err(ApiError::out_of_domain(format!(
            "{v} (the {} model was trained on such trees only); set `allow_out_of_domain` to get an answer anyway",
            model.name
        ))
        .with_details(d));
    }
    Ok(violations
        .iter()
        .map(|v| Warning {
            code: "out_of_domain".to_owned(),
            message: if v.refused {
                format!("{v}: the answer is extrapolation")
            } else {
                format!(
                    "the tree has {} nodes; the {} model is evaluated on {} to {}",
                    v.value, model.name, v.min, v.max
                )
            },
            details: details(v, model),
        })
        .collect())
}
