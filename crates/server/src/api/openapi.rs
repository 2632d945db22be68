//! The OpenAPI document, derived with `utoipa` from the wire types in
//! [`crate::api::types`] and the `#[utoipa::path]` of each handler, served
//! at `GET /openapi.yaml`. The repository keeps a copy, `openapi.yaml`, so
//! that reviewers read API changes in diffs; a test fails when the two
//! differ, and `treemanip-server --print-openapi > openapi.yaml` rewrites
//! it.

use std::sync::OnceLock;

use axum::http::header;
use axum::response::IntoResponse;
use utoipa::openapi::schema::{AdditionalProperties, Schema};
use utoipa::openapi::{OpenApi as Document, RefOr};
use utoipa::{Modify, OpenApi};

use crate::api::from_points;
use crate::api::identify;
use crate::api::plan;
use crate::api::predict;
use crate::api::robots;
use crate::api::scene;
use crate::api::service;
use crate::api::simulate;
use crate::api::types::error::{ErrorReply, ErrorResponse};
use crate::api::types::schema::{ModelName, OpenApiDocument};
use crate::api::v2;
use crate::api::viewer;

const DESCRIPTION: &str = "\
Predicts how a tree deforms when a gripper pushes one of its nodes, \
proposes pushes, and plans an arm's motion for them, after \"Towards \
Robotic Tree Manipulation: Leveraging Graph Representations\".
Units are SI: metres, radians, N·m/rad. Models are the ONNX files in the \
server's models directory (GET /v1/models lists them with their model \
cards); they run on ONNX Runtime, embedded in the server or given as a \
library (a server built with the `tract` feature falls back to tract).
Every POST endpoint is a pure function of its body: it changes no state, so \
a client or load balancer may safely send a request again, to the same or \
another replica, after a connection failure, an empty answer, 502 or 503 \
(deploy/README.md).
";

#[derive(OpenApi)]
#[openapi(
    info(title = "treemanip", description = DESCRIPTION),
    paths(
        service::healthz,
        service::readyz,
        service::render_metrics,
        serve,
        robots::robots,
        service::list_models,
        predict::forward,
        predict::policy,
        plan::plan,
        simulate::simulate,
        identify::identify,
        identify::propose,
        scene::tree_from_urdf,
        scene::example_tree,
        from_points::from_points,
        scene::link_poses,
        viewer::index,
        v2::server_metadata,
        v2::live,
        v2::ready,
        v2::model_metadata,
        v2::model_ready,
        v2::infer,
    ),
    components(responses(ErrorReply), schemas(ModelName, ErrorResponse)),
    modifiers(&ClosedVariants),
)]
struct ApiDoc;

/// `deny_unknown_fields` on a tagged enum (a shape, an objective) refuses
/// unknown members in every variant, which the derive does not carry into
/// the variants' schemas: close them here.
struct ClosedVariants;

impl Modify for ClosedVariants {
    fn modify(&self, doc: &mut Document) {
        let Some(components) = doc.components.as_mut() else {
            return;
        };
        for name in ["Shape", "Objective"] {
            if let Some(RefOr::T(Schema::OneOf(one_of))) = components.schemas.get_mut(name) {
                for variant in &mut one_of.items {
                    if let RefOr::T(Schema::Object(object)) = variant {
                        object.additional_properties =
                            Some(Box::new(AdditionalProperties::FreeForm(false)));
                    }
                }
            }
        }
    }
}

/// The document as YAML, generated once.
pub fn yaml() -> &'static str {
    static YAML: OnceLock<String> = OnceLock::new();
    YAML.get_or_init(|| {
        ApiDoc::openapi()
            .to_yaml()
            .expect("the OpenAPI document serializes")
    })
}

/// The document as JSON (for tests that look into it).
pub fn document() -> serde_json::Value {
    serde_json::to_value(ApiDoc::openapi()).expect("the OpenAPI document serializes")
}

/// This document.
#[utoipa::path(get, path = "/openapi.yaml", tag = "service", responses(
    (status = 200, description = "The OpenAPI description (a YAML mapping, this document).",
     body = OpenApiDocument, content_type = "application/yaml"),
))]
pub async fn serve() -> impl IntoResponse {
    ([(header::CONTENT_TYPE, "application/yaml")], yaml())
}
