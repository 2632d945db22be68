//! Which model answered an inference: named in every model-backed answer.

/// Which model answered, and on what.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct ModelInfo {
    pub name: String,
    /// The git commit the model was trained at.
    pub version: String,
    /// `tract` or `onnxruntime`.
    pub backend: String,
}
