//! Arguments shared by several commands.

use std::path::PathBuf;

use anyhow::Context;
use clap::Args;
use nalgebra::Vector3;
use treemanip::tree::{Tree, urdf};

/// A push on a tree file: `--tree FILE --node J --push DX,DY,DZ`.
#[derive(Args)]
pub struct TreePush {
    /// A tree URDF file.
    #[arg(long)]
    pub tree: PathBuf,
    /// The contacted node (its branch is held by the gripper).
    #[arg(long)]
    pub node: usize,
    /// The gripper's displacement T in metres: `DX,DY,DZ`.
    #[arg(long, value_parser = parse_vector, allow_hyphen_values = true)]
    pub push: Vector3<f64>,
}

impl TreePush {
    pub fn load_tree(&self) -> anyhow::Result<Tree> {
        urdf::read_file(&self.tree)
            .with_context(|| format!("cannot load tree {}", self.tree.display()))
    }
}

/// Exactly `N` comma-separated numbers.
pub fn parse_numbers<const N: usize>(s: &str) -> Result<[f64; N], String> {
    let values: Vec<f64> = s
        .split(',')
        .map(|p| {
            p.trim()
                .parse::<f64>()
                .map_err(|_| format!("`{p}` is not a number"))
        })
        .collect::<Result<_, _>>()?;
    <[f64; N]>::try_from(values).map_err(|v| match N {
        3 => format!(
            "expected three comma-separated numbers, got {} in `{s}`",
            v.len()
        ),
        _ => format!(
            "expected {N} comma-separated numbers, got {} in `{s}`",
            v.len()
        ),
    })
}

pub fn parse_vector(s: &str) -> Result<Vector3<f64>, String> {
    parse_numbers::<3>(s).map(Vector3::from)
}

/// Where an evaluation's episodes and models come from: the test split
/// collected with `--seed` (as `dataset collect` makes it), the ONNX models
/// in `--models-dir`.
#[derive(Args)]
pub struct EvalData {
    /// Dataset seed.
    #[arg(long, default_value_t = 7)]
    pub seed: u64,
    /// Directory of the ONNX models.
    #[arg(long, default_value = "models")]
    pub models_dir: PathBuf,
}
