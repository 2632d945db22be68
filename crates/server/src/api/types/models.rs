//! Which model answered an inference (named in every model-backed answer),
//! and `GET /v1/models`' list of the loaded models with their cards.

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use crate::api::types::schema::{ModelCard, string_enum};

/// Which model answered, and on what.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct ModelInfo {
    #[schema(example = "forward_gnn")]
    pub name: String,
    /// The git commit the model was trained at.
    pub version: String,
    #[schema(schema_with = backend)]
    pub backend: String,
}

/// The inference engine: ONNX Runtime, or tract in a server built with
/// its feature.
pub(crate) fn backend() -> utoipa::openapi::schema::Schema {
    string_enum(&["tract", "onnxruntime"], None)
}

fn task() -> utoipa::openapi::schema::Schema {
    string_enum(&["forward", "policy"], None)
}

/// `GET /v1/models`.
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct ModelsResponse {
    #[schema(schema_with = backend)]
    pub backend: String,
    pub models: Vec<ModelEntry>,
}

/// One loaded model: its name (the file's stem), what it predicts, its
/// file and its card.
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct ModelEntry {
    #[schema(example = "forward_gnn")]
    pub name: String,
    #[schema(schema_with = task)]
    pub task: &'static str,
    #[schema(required = true)]
    pub file: Option<String>,
    #[schema(value_type = ModelCard)]
    pub metadata: serde_json::Value,
}
