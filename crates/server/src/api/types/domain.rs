//! `domain`: the warning an answer carries when a tree lies outside a model's domain.

use serde::{Deserialize, Serialize};
use serde_json::Value;

/// A note on an answer that was given anyway.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Warning {
    /// `out_of_domain`.
    pub code: String,
    pub message: String,
    pub details: Value,
}
