//! `domain`: the warning an answer carries when a tree lies outside a model's domain.

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use crate::api::types::schema::string_enum;

/// A note on an answer that was given anyway.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct Warning {
    #[schema(schema_with = warning_code)]
    pub code: String,
    pub message: String,
    pub details: ViolationJson,
}

fn warning_code() -> utoipa::openapi::schema::Schema {
    string_enum(&["out_of_domain"], None)
}

/// One quantity of a request outside a model's domain: its value, the
/// domain's bounds and the node it was measured at.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
#[schema(as = Violation)]
pub struct ViolationJson {
    /// The model whose domain it is.
    pub model: String,
    /// What is out of domain (described in the schema).
    #[schema(schema_with = quantity)]
    pub quantity: String,
    pub value: f64,
    pub min: f64,
    pub max: f64,
    #[schema(required = true)]
    pub node: Option<usize>,
}

fn quantity() -> utoipa::openapi::schema::Schema {
    string_enum(
        &[
            "tree_height",
            "branch_length",
            "branch_radius",
            "stiffness_log_ratio",
            "push_length",
            "nodes",
        ],
        Some(
            "stiffness_log_ratio is κ = ln K_s − the tree's mean ln K_s at `node` (dimensionless); a global factor on every K_s is never out of domain.",
        ),
    )
}
