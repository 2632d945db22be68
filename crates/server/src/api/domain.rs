//! Refusing (or, when asked, flagging) requests outside a model's domain
//! ([`treemanip_core::model::domain`]).

use serde_json::Value;

use super::error::ApiError;
use crate::api::types::Warning;
use crate::api::types::domain::ViolationJson;
use treemanip_core::graph::Task;
use treemanip_core::graph::path::Encoding;
use treemanip_core::model::domain::Violation;
use treemanip_core::tree::{FULL_GRAPH_MAX_NODES, Tree};
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

/// A model on the fully connected graph costs O(N²) in time and memory:
/// past [`FULL_GRAPH_MAX_NODES`] it is not run at all (413 naming the limit
/// and the model that has none), `allow_out_of_domain` or not.
pub fn check_size(model: &ServedModel, tree: &Tree) -> Result<(), ApiError> {
    let n = tree.len();
    if model.card.encoding == Encoding::Full && n > FULL_GRAPH_MAX_NODES {
        let alternative = match model.task {
            Task::Forward => {
                "; the forward_path model reads only the push's path and takes any size the server does"
            }
            Task::Policy => {
                "; plan with `strategy: physics` (or a forward_path model), which needs no policy"
            }
        };
        return Err(ApiError::too_large(format!(
            "the tree has {n} nodes; the {} model reads the fully connected graph and takes at most {FULL_GRAPH_MAX_NODES}{alternative}",
            model.name
        ))
        .with_details(serde_json::json!({
            "field": "tree", "nodes": n, "max_nodes": FULL_GRAPH_MAX_NODES, "model": model.name,
        })));
    }
    Ok(())
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
    check_size(model, tree)?;
    let domain = &model.card.domain.domain;
    let mut violations = domain.check_tree(tree);
    violations.extend(
        pushes
            .iter()
            .filter_map(|&(node, length)| domain.check_push(node, length)),
    );
    let mut nodes: Vec<usize> = pushes.iter().map(|&(node, _)| node).collect();
    nodes.sort_unstable();
    nodes.dedup();
    for node in nodes {
        violations.extend(domain.check_path(tree, node));
    }
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
