//! The Open Inference Protocol (KServe v2, as Triton and KServe serve it)
//! beside the domain API, so that the clients users already run
//! (`tritonclient[http]`, KServe's) work unchanged: server and model
//! metadata, liveness and readiness, and `infer` on raw tensors, named and
//! shaped as [`treemanip_infer::contract`] says. JSON tensor data and Triton's
//! binary tensor data extension are both read; outputs are JSON.

use super::types::v2::{
    InferRequest, InferResponse, LiveResponse, ModelMetadata, ModelReadyResponse, OutputTensor,
    ReadyResponse, ServerMetadata, TensorMetadata,
};
use crate::api::types::error::ModelErrors;
use axum::Json;
use axum::body::Bytes;
use axum::extract::{Path, State};
use axum::http::HeaderMap;
use serde_json::Value;

use super::error::ApiError;
use super::types::schema::ModelName;
use super::{AppState, ModelRef};
use treemanip_infer::contract::{self, DATATYPE, TensorSpec};
use treemanip_infer::models::MAX_BATCH;

/// Open Inference Protocol (KServe v2) server metadata.
#[utoipa::path(get, path = "/v2", tag = "oip",
    responses(
    (status = 200, description = "Server name, version and protocol extensions.", body = ServerMetadata),
))]
pub async fn server_metadata() -> Json<ServerMetadata> {
    Json(ServerMetadata {
        name: "treemanip",
        version: env!("CARGO_PKG_VERSION"),
        extensions: vec!["binary_tensor_data"],
    })
}

/// Open Inference Protocol liveness.
#[utoipa::path(get, path = "/v2/health/live", tag = "oip",
    responses(
    (status = 200, description = "Live.", body = LiveResponse),
))]
pub async fn live() -> Json<LiveResponse> {
    Json(LiveResponse { live: true })
}

/// Open Inference Protocol readiness (the models the domain API needs are
/// loaded).
#[utoipa::path(get, path = "/v2/health/ready", tag = "oip",
    responses(
    (status = 200, description = "Ready.", body = ReadyResponse),
    ModelErrors,
))]
pub async fn ready(State(state): State<AppState>) -> Result<Json<ReadyResponse>, ApiError> {
    for name in super::REQUIRED_MODELS {
        model(&state, name)?;
    }
    Ok(Json(ReadyResponse { ready: true }))
}

/// The served model `name`: 404 if there is no such model, 503 if its file
/// failed to load.
fn model(state: &AppState, name: &str) -> Result<ModelRef, ApiError> {
    let set = state
        .models
        .as_ref()
        .ok_or_else(|| ApiError::not_ready("no models are loaded"))?;
    if set.get(name).is_none() {
        if let Some((_, why)) = set.broken.iter().find(|(n, _)| n == name) {
            return Err(ApiError::not_ready(format!(
                "model {name} failed to load: {why}"
            )));
        }
        return Err(ApiError::not_found(format!("no model named {name:?}")));
    }
    state.model_by_name(name)
}

fn describe(specs: &[TensorSpec]) -> Vec<TensorMetadata> {
    specs
        .iter()
        .map(|s| TensorMetadata {
            name: s.name,
            datatype: DATATYPE,
            shape: s.dims.iter().map(|d| d.oip()).collect(),
        })
        .collect()
}

/// A model's metadata with its real tensor names, shapes (-1 variable) and
/// datatypes.
#[utoipa::path(get, path = "/v2/models/{name}", tag = "oip",
    params(("name" = ModelName, Path)),
    responses(
    (status = 200, description = "Model metadata.", body = ModelMetadata),
    ModelErrors,
))]
pub async fn model_metadata(
    State(state): State<AppState>,
    Path(name): Path<String>,
) -> Result<Json<ModelMetadata>, ApiError> {
    let m = model(&state, &name)?;
    Ok(Json(ModelMetadata {
        name: m.name.clone(),
        versions: vec!["1"],
        platform: "onnx",
        inputs: describe(&contract::inputs(m.task)),
        outputs: describe(&contract::outputs(m.task)),
    }))
}

/// Whether one model is loaded and serving.
#[utoipa::path(get, path = "/v2/models/{name}/ready", tag = "oip",
    params(("name" = ModelName, Path)),
    responses(
    (status = 200, description = "Ready.", body = ModelReadyResponse),
    ModelErrors,
))]
pub async fn model_ready(
    State(state): State<AppState>,
    Path(name): Path<String>,
) -> Result<Json<ModelReadyResponse>, ApiError> {
    let m = model(&state, &name)?;
    Ok(Json(ModelReadyResponse {
        name: m.name.clone(),
        ready: true,
    }))
}

fn bad(message: impl Into<String>) -> ApiError {
    ApiError::invalid_argument(message)
}

/// Row-major values of a JSON `data` field, flat or nested.
fn flatten(value: &Value, out: &mut Vec<f32>, name: &str) -> Result<(), ApiError> {
    match value {
        Value::Array(items) => items.iter().try_for_each(|v| flatten(v, out, name)),
        Value::Number(x) => {
            out.push(x.as_f64().unwrap_or(f64::NAN) as f32);
            Ok(())
        }
        _ => Err(bad(format!("input `{name}`: data must be numbers"))),
    }
}

/// Open Inference Protocol inference on raw tensors (see GET
/// /v2/models/{name}).
///
/// Inputs are the model's tensors in raw SI features, FP32, as the project's
/// graph encoder writes them (B graphs of N nodes). Feature layout 2: `edges`
/// [B, N, N, 6] holds, for i → j, [Δp = p_j − p_i (m, 3), v (+1 when i is an
/// ancestor of j, else −1), b (1 when i and j are parent and child, else 0),
/// κ = ln K_s − the tree's mean ln K_s for that branch (0 when not a
/// branch)]; `nodes` holds `[c_j]` (forward) or `[p′_j − p_j]` (policy),
/// `global` `[T]` (forward), `mask` 1 for real nodes. Tensor data may be JSON (flat or
/// nested) or, with Triton's binary tensor data extension, raw little-endian
/// bytes after a JSON header of `Inference-Header-Content-Length` bytes.
/// Outputs are JSON.
#[utoipa::path(post, path = "/v2/models/{name}/infer", tag = "oip",
    params(("name" = ModelName, Path)),
    request_body = InferRequest,
    responses(
    (status = 200, description = "Output tensors.", body = InferResponse),
    (status = 400, response = crate::api::types::error::ErrorReply),
    (status = 404, response = crate::api::types::error::ErrorReply),
    (status = 413, response = crate::api::types::error::ErrorReply),
    (status = 422, response = crate::api::types::error::ErrorReply),
    (status = 503, response = crate::api::types::error::ErrorReply),
    (status = 504, response = crate::api::types::error::ErrorReply),
))]
pub async fn infer(
    State(state): State<AppState>,
    Path(name): Path<String>,
    headers: HeaderMap,
    body: Bytes,
) -> Result<Json<InferResponse>, ApiError> {
    let m = model(&state, &name)?;
    let task = m.task;
    // Triton's binary extension: a JSON header of this many bytes, then the
    // tensors' raw bytes in input order.
    let json_len = match headers.get("inference-header-content-length") {
        None => body.len(),
        Some(v) => v
            .to_str()
            .ok()
            .and_then(|v| v.parse::<usize>().ok())
            .filter(|&n| n <= body.len())
            .ok_or_else(|| ApiError::malformed("bad Inference-Header-Content-Length"))?,
    };
    let request: InferRequest = serde_json::from_slice(&body[..json_len])
        .map_err(|e| ApiError::malformed(format!("the inference request is not valid: {e}")))?;
    let mut binary = &body[json_len..];
    let mut tensors = Vec::with_capacity(request.inputs.len());
    for input in &request.inputs {
        if input.datatype != DATATYPE {
            return Err(bad(format!(
                "input `{}` is {}; the models take {DATATYPE}",
                input.name, input.datatype
            )));
        }
        let shape = input.shape.clone();
        let binary_size = input
            .parameters
            .as_ref()
            .and_then(|p| p.get("binary_data_size"))
            .and_then(Value::as_u64);
        let values = match (binary_size, &input.data) {
            (Some(size), _) => {
                let size = size as usize;
                if size > binary.len() || size % 4 != 0 {
                    return Err(bad(format!(
                        "input `{}`: {size} bytes of binary data announced, {} left",
                        input.name,
                        binary.len()
                    )));
                }
                let (head, rest) = binary.split_at(size);
                binary = rest;
                head.chunks_exact(4)
                    .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                    .collect()
            }
            (None, Some(data)) => {
                let mut out = Vec::new();
                flatten(data, &mut out, &input.name)?;
                out
            }
            (None, None) => return Err(bad(format!("input `{}` has no data", input.name))),
        };
        tensors.push((input.name.clone(), shape, values));
    }
    let batch = contract::batch_from_tensors(task, tensors, MAX_BATCH, state.limits.max_nodes)
        .map_err(|e| bad(e.to_string()))?;
    let wanted: Option<Vec<String>> = request
        .outputs
        .map(|o| o.into_iter().map(|o| o.name).collect());
    let specs = contract::outputs(task);
    if let Some(names) = &wanted
        && let Some(unknown) = names.iter().find(|n| !specs.iter().any(|s| s.name == *n))
    {
        return Err(bad(format!("`{unknown}` is not an output of {name}")));
    }
    let model_name = m.name.clone();
    let (b, n) = (batch.batch, batch.n);
    let out = state
        .run_model_work("/v2/models/infer", None, move |control| {
            m.batcher().run(batch, control).map_err(ApiError::from)
        })
        .await?;
    let mut outputs = Vec::new();
    for spec in &specs {
        if wanted
            .as_ref()
            .is_some_and(|w| !w.iter().any(|n| n == spec.name))
        {
            continue;
        }
        let data = match spec.name {
            contract::AFFORDANCE => out.affordance.clone().unwrap_or_default(),
            _ => out.vectors.clone(),
        };
        outputs.push(OutputTensor {
            name: spec.name,
            datatype: DATATYPE,
            shape: spec.shape(b, n),
            data,
        });
    }
    Ok(Json(InferResponse {
        model_name,
        model_version: "1",
        id: request.id,
        outputs,
    }))
}
