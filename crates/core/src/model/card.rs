//! A model's card: what the model is, how and on what it was trained, and
//! the inputs it answers for. The exporter writes it into the ONNX file's
//! `metadata_props`, one key per field (structured fields as JSON), and the
//! server reads it back as this type: one definition for both sides.

use serde::{Deserialize, Serialize};
use serde_json::Value;

use super::domain::{Domain, Margin};
use crate::graph::Task;
use crate::graph::path::Encoding;

/// Everything the exporter records about a model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModelCard {
    /// File stem: `forward_gnn`, `policy_pointnet`, ...
    pub name: String,
    pub task: Task,
    /// `gnn` or `pointnet`.
    pub arch: String,
    /// The architecture in words (layers, widths, edge attributes).
    pub architecture: String,
    /// The graph encoding the model reads ([`crate::graph::FEATURE_LAYOUT_VERSION`]).
    pub feature_layout_version: u32,
    /// Input statistics and output scale, applied inside the graph.
    pub normalisation: Value,
    pub training_data: TrainingData,
    /// The command that started training, and every command of the run
    /// (resumptions included).
    pub training_command: String,
    pub training_commands: Vec<String>,
    /// The trainer's configuration, as it recorded it.
    pub training_config: Value,
    /// The training seed.
    pub seed: u64,
    /// The commit the model was exported at.
    pub git_commit: String,
    pub training: TrainingRun,
    /// The validation record of the exported (best) epoch.
    pub validation: Value,
    pub units: String,
    /// The trees and pushes the model answers for.
    pub domain: DomainRecord,
    /// What graph the model reads and what its output means (metadata key
    /// `encoding`; models exported before it existed read the whole tree).
    #[serde(default)]
    pub encoding: Encoding,
}

/// The dataset a model was trained on, and how to make it again.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrainingData {
    pub directory: String,
    pub dataset_seed: Option<u64>,
    /// The command that regenerates the dataset.
    pub regenerate: Option<String>,
    /// Tree sizes N trained on.
    pub sizes: Vec<usize>,
    pub limit_per_size: Option<usize>,
    /// Which trees were held out for validation.
    pub validation: String,
}

/// How long and on what the training ran.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrainingRun {
    pub epochs: usize,
    pub planned_epochs: usize,
    /// Schedule, rates, batch size, clipping, augmentation.
    pub recipe: Value,
    pub minutes: f64,
    pub samples: u64,
    pub samples_per_second: f64,
    pub cpus: Vec<String>,
    /// The epoch whose weights were exported.
    pub best_epoch: Option<usize>,
}

/// The domain as recorded: the widened ranges, the margin that widened
/// them, and the sizes trained on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DomainRecord {
    pub domain: Domain,
    pub margin: Margin,
    pub trained_sizes: Vec<usize>,
}

/// Why a model file's metadata is not a card.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CardError {
    #[error(
        "its metadata has no `{key}` (exported by an older treemanip? export it again with `treemanip export`{hint})"
    )]
    Missing {
        key: &'static str,
        hint: &'static str,
    },
    #[error("its metadata `{key}` is not valid: {reason}")]
    Invalid { key: String, reason: String },
}

/// Fields whose metadata value is a JSON document (the rest are text).
const JSON_KEYS: [&str; 7] = [
    "normalisation",
    "training_data",
    "training_commands",
    "training_config",
    "training",
    "validation",
    "domain",
];

/// The metadata keys, in the order the exporter writes them.
pub const KEYS: [&str; 16] = [
    "name",
    "task",
    "arch",
    "architecture",
    "feature_layout_version",
    "normalisation",
    "training_data",
    "training_command",
    "training_commands",
    "training_config",
    "seed",
    "git_commit",
    "training",
    "validation",
    "units",
    "domain",
];

impl ModelCard {
    /// The card as ONNX `metadata_props`: one key per field, structured
    /// fields as JSON, text and numbers as they read.
    pub fn to_metadata(&self) -> Vec<(String, String)> {
        let Value::Object(fields) = serde_json::to_value(self).expect("a card serialises") else {
            unreachable!("a card is a JSON object")
        };
        KEYS.iter()
            .map(|&key| {
                let value = &fields[key];
                let text = match value {
                    Value::String(s) if !JSON_KEYS.contains(&key) => s.clone(),
                    Value::Number(n) if !JSON_KEYS.contains(&key) => n.to_string(),
                    other => other.to_string(),
                };
                (key.to_owned(), text)
            })
            .chain([("encoding".to_owned(), self.encoding.name().to_owned())])
            .collect()
    }

    /// Reads a card from ONNX `metadata_props`; a missing or malformed key
    /// is named in the error.
    pub fn from_metadata(metadata: &[(String, String)]) -> Result<Self, CardError> {
        let mut fields = serde_json::Map::new();
        for key in KEYS {
            let text = metadata
                .iter()
                .find(|(k, _)| k == key)
                .map(|(_, v)| v.as_str())
                .ok_or(CardError::Missing {
                    key,
                    hint: if key == "domain" {
                        ", or add it with `treemanip domain`"
                    } else {
                        ""
                    },
                })?;
            let invalid = |reason: String| CardError::Invalid {
                key: key.to_owned(),
                reason,
            };
            let value = if JSON_KEYS.contains(&key) {
                serde_json::from_str(text).map_err(|e| invalid(e.to_string()))?
            } else if matches!(key, "feature_layout_version" | "seed") {
                let n: u64 = text
                    .trim()
                    .parse()
                    .map_err(|_| invalid(format!("{text:?} is not a whole number")))?;
                Value::from(n)
            } else {
                Value::String(text.to_owned())
            };
            fields.insert(key.to_owned(), value);
        }
        if let Some((_, text)) = metadata.iter().find(|(k, _)| k == "encoding") {
            fields.insert("encoding".to_owned(), Value::String(text.clone()));
        }
        // The error names the field at fault: its top-level key is the
        // metadata key.
        serde_path_to_error::deserialize(Value::Object(fields)).map_err(|e| {
            let key = e
                .path()
                .iter()
                .next()
                .map_or_else(|| "metadata".to_owned(), |segment| segment.to_string());
            CardError::Invalid {
                key,
                reason: e.into_inner().to_string(),
            }
        })
    }

    /// The longest push the model answers for (m): the top of its domain's
    /// push range (twice the longest trained push).
    pub fn max_push(&self) -> f64 {
        self.domain.domain.push_length.max
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::domain::{EVALUATED_NODES, Interval};

    fn card() -> ModelCard {
        let range = |min, max| Interval { min, max };
        let domain = Domain {
            tree_height: range(0.4, 2.5),
            branch_length: range(0.05, 0.7),
            branch_radius: range(0.003, 0.02),
            stiffness_log_ratio: range(-4.0, 3.0),
            push_length: range(0.025, 0.3),
            nodes: EVALUATED_NODES,
            encoding: Encoding::Full,
        };
        ModelCard {
            name: "forward_gnn".into(),
            task: Task::Forward,
            arch: "gnn".into(),
            architecture: "gnn: 5 layers".into(),
            feature_layout_version: 2,
            normalisation: serde_json::json!({"inputs": {"edge_mean": [0.0]}}),
            training_data: TrainingData {
                directory: "data".into(),
                dataset_seed: Some(7),
                regenerate: Some("treemanip dataset collect --out DIR --seed 7".into()),
                sizes: vec![11, 13],
                limit_per_size: None,
                validation: "trees with index ≡ 9 (mod 10)".into(),
            },
            training_command: "treemanip train forward".into(),
            training_commands: vec!["treemanip train forward".into()],
            training_config: serde_json::json!({"seed": 0}),
            seed: 0,
            // All digits: must stay text, not become a number.
            git_commit: "1234567".into(),
            training: TrainingRun {
                epochs: 2,
                planned_epochs: 2,
                recipe: serde_json::json!({"batch_size": 128}),
                minutes: 1.5,
                samples: 1000,
                samples_per_second: 11.1,
                cpus: vec!["AMD EPYC".into()],
                best_epoch: Some(1),
            },
            validation: Value::Null,
            units: "SI: metres, N·m/rad".into(),
            domain: DomainRecord {
                domain,
                margin: Margin::STANDARD,
                trained_sizes: vec![11, 13],
            },
            encoding: Encoding::Full,
        }
    }

    #[test]
    fn a_card_survives_the_metadata_round_trip() {
        let card = card();
        let metadata = card.to_metadata();
        let keys: Vec<&str> = metadata.iter().map(|(k, _)| k.as_str()).collect();
        assert_eq!(keys[..KEYS.len()], KEYS);
        assert_eq!(keys[KEYS.len()..], ["encoding"]);
        let text = |key: &str| &metadata.iter().find(|(k, _)| k == key).unwrap().1;
        // Text fields as text, numbers as their digits, documents as JSON.
        assert_eq!(text("git_commit"), "1234567");
        assert_eq!(text("seed"), "0");
        assert_eq!(text("task"), "forward");
        assert!(text("domain").starts_with('{'));
        assert_eq!(ModelCard::from_metadata(&metadata).unwrap(), card);
        assert!((card.max_push() - 0.3).abs() < 1e-12);
        // A path model says so; a file from before the key reads as full.
        let path = ModelCard {
            encoding: Encoding::Path,
            ..card.clone()
        };
        assert_eq!(ModelCard::from_metadata(&path.to_metadata()).unwrap(), path);
        let old: Vec<_> = metadata
            .iter()
            .filter(|(k, _)| k != "encoding")
            .cloned()
            .collect();
        assert_eq!(
            ModelCard::from_metadata(&old).unwrap().encoding,
            Encoding::Full
        );
    }

    #[test]
    fn a_missing_or_broken_key_is_named() {
        let metadata = card().to_metadata();
        let without = |key: &str| -> Vec<(String, String)> {
            metadata.iter().filter(|(k, _)| k != key).cloned().collect()
        };
        let err = ModelCard::from_metadata(&without("domain")).unwrap_err();
        assert!(
            matches!(err, CardError::Missing { key: "domain", .. }),
            "{err}"
        );
        assert!(
            err.to_string().contains("`domain`") && err.to_string().contains("treemanip domain")
        );
        let err = ModelCard::from_metadata(&without("seed")).unwrap_err();
        assert!(err.to_string().contains("`seed`"), "{err}");
        let mut broken = metadata.clone();
        for (k, v) in &mut broken {
            if k == "training_data" {
                *v = r#"{"sizes": "many"}"#.into();
            }
        }
        let err = ModelCard::from_metadata(&broken).unwrap_err();
        assert!(
            matches!(&err, CardError::Invalid { key, .. } if key == "training_data"),
            "{err}"
        );
    }
}
