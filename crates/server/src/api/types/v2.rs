//! The KServe/Triton open inference protocol (`/v2/models/{name}/infer`):
//! its request and output tensors.

use serde::{Deserialize, Serialize};
use serde_json::Value;

#[derive(Debug, Deserialize)]
pub struct InferRequest {
    #[serde(default)]
    pub id: Option<String>,
    pub inputs: Vec<InputTensor>,
    #[serde(default)]
    pub outputs: Option<Vec<RequestedOutput>>,
    #[serde(default)]
    #[allow(dead_code)] // accepted as the protocol allows; none are used
    pub parameters: Option<Value>,
}

#[derive(Debug, Deserialize)]
pub struct InputTensor {
    pub name: String,
    #[serde(deserialize_with = "crate::api::json::integer::vec_usize")]
    pub shape: Vec<usize>,
    pub datatype: String,
    #[serde(default)]
    pub data: Option<Value>,
    #[serde(default)]
    pub parameters: Option<Value>,
}

#[derive(Debug, Deserialize)]
pub struct RequestedOutput {
    pub name: String,
}

#[derive(Debug, Serialize)]
pub struct OutputTensor {
    pub name: &'static str,
    pub datatype: &'static str,
    pub shape: Vec<usize>,
    pub data: Vec<f32>,
}
