//! The KServe/Triton open inference protocol (`/v2/...`): server and model
//! metadata, liveness and readiness, and `infer`'s request and output
//! tensors.

use serde::{Deserialize, Serialize};
use serde_json::Value;
use utoipa::ToSchema;

use crate::api::types::schema::{AnyJson, string_enum};

fn fp32() -> utoipa::openapi::schema::Schema {
    string_enum(&["FP32"], None)
}

/// `GET /v2`: the server's name, version and protocol extensions.
#[derive(Debug, Serialize, ToSchema)]
#[schema(as = OipServerMetadata)]
pub struct ServerMetadata {
    pub name: &'static str,
    pub version: &'static str,
    pub extensions: Vec<&'static str>,
}

/// `GET /v2/health/live`.
#[derive(Debug, Serialize, ToSchema)]
#[schema(as = OipLive)]
pub struct LiveResponse {
    pub live: bool,
}

/// `GET /v2/health/ready`.
#[derive(Debug, Serialize, ToSchema)]
#[schema(as = OipReady)]
pub struct ReadyResponse {
    pub ready: bool,
}

/// `GET /v2/models/{name}/ready`.
#[derive(Debug, Serialize, ToSchema)]
#[schema(as = OipModelReady)]
pub struct ModelReadyResponse {
    pub name: String,
    pub ready: bool,
}

/// A tensor's name, datatype and shape (-1: variable).
#[derive(Debug, Serialize, ToSchema)]
#[schema(as = OipTensorMetadata)]
pub struct TensorMetadata {
    pub name: &'static str,
    #[schema(schema_with = fp32)]
    pub datatype: &'static str,
    pub shape: Vec<i64>,
}

/// `GET /v2/models/{name}`: the model's real tensors.
#[derive(Debug, Serialize, ToSchema)]
#[schema(as = OipModelMetadata)]
pub struct ModelMetadata {
    pub name: String,
    pub versions: Vec<&'static str>,
    pub platform: &'static str,
    pub inputs: Vec<TensorMetadata>,
    pub outputs: Vec<TensorMetadata>,
}

/// `POST /v2/models/{name}/infer`.
#[derive(Debug, Deserialize, ToSchema)]
#[schema(as = OipInferRequest)]
pub struct InferRequest {
    #[serde(default)]
    pub id: Option<String>,
    #[schema(max_items = 8)]
    pub inputs: Vec<InputTensor>,
    #[serde(default)]
    pub outputs: Option<Vec<RequestedOutput>>,
    #[serde(default)]
    #[allow(dead_code)] // accepted as the protocol allows; none are used
    #[schema(value_type = Option<Object>)]
    pub parameters: Option<Value>,
}

/// An input tensor: its name, shape and datatype, and its data (JSON, flat
/// or nested; or raw bytes with the binary tensor data extension).
#[derive(Debug, Deserialize, ToSchema)]
#[schema(as = OipInputTensor)]
pub struct InputTensor {
    pub name: String,
    #[serde(deserialize_with = "crate::api::json::integer::vec_usize")]
    #[schema(max_items = 4, minimum = 0, maximum = 4096)]
    pub shape: Vec<usize>,
    pub datatype: String,
    #[serde(default)]
    #[schema(value_type = Option<Vec<AnyJson>>)]
    pub data: Option<Value>,
    #[serde(default)]
    #[schema(value_type = Option<Object>)]
    pub parameters: Option<Value>,
}

/// An output the client asks for (all of them when `outputs` is absent).
#[derive(Debug, Deserialize, ToSchema)]
#[schema(as = OipRequestedOutput)]
pub struct RequestedOutput {
    pub name: String,
    #[serde(default)]
    #[allow(dead_code)] // accepted as the protocol allows; none are used
    #[schema(value_type = Option<Object>)]
    pub parameters: Option<Value>,
}

/// An output tensor, its data row-major.
#[derive(Debug, Serialize, ToSchema)]
#[schema(as = OipOutputTensor)]
pub struct OutputTensor {
    pub name: &'static str,
    #[schema(schema_with = fp32)]
    pub datatype: &'static str,
    pub shape: Vec<usize>,
    pub data: Vec<f32>,
}

/// `POST /v2/models/{name}/infer`'s answer.
#[derive(Debug, Serialize, ToSchema)]
#[schema(as = OipInferResponse)]
pub struct InferResponse {
    pub model_name: String,
    pub model_version: &'static str,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub id: Option<String>,
    pub outputs: Vec<OutputTensor>,
}
