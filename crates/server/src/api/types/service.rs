//! The service's own endpoints: liveness (`/healthz`) and readiness
//! (`/readyz`).

use std::collections::BTreeMap;

use serde::Serialize;
use utoipa::ToSchema;

use crate::api::types::models::backend;
use crate::api::types::schema::{constant, string_map};

/// The process is up.
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct HealthResponse {
    #[schema(schema_with = ok)]
    pub status: &'static str,
}

fn ok() -> utoipa::openapi::schema::Schema {
    constant("ok")
}

fn ready() -> utoipa::openapi::schema::Schema {
    constant("ready")
}

fn broken() -> utoipa::openapi::schema::Schema {
    string_map("Model files that failed to load (with --skip-broken-models), by name, with why.")
}

/// Every model the endpoints need is loaded.
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct ReadyResponse {
    #[schema(schema_with = ready)]
    pub status: &'static str,
    pub models: Vec<String>,
    #[schema(schema_with = broken)]
    pub broken: BTreeMap<String, String>,
    #[schema(schema_with = backend)]
    pub backend: String,
}
