//! Does the forward model respect stiffness? On a test split whose trees
//! carry perturbed stiffness (`dataset collect --stiffness-sigma 0.3`):
//!
//! - **true K**: e_N with the tree as the file holds it (the stiffness the
//!   simulator used);
//! - **nominal K**: the same episodes with every branch's stiffness reset
//!   to the radius formula (what a caller who does not know the stiffness
//!   sends); a model that reads K must do worse here;
//! - **global factor**: the largest change of any predicted node position
//!   when every K_s is multiplied by 3 or by 1/3 (the physics does not
//!   change at all; layout 2's κ makes the model blind to it by design).

use nalgebra::{Point3, Vector3};
use serde::Serialize;

use crate::dataset::SizeData;
use crate::graph::{batch, encode_forward};
use crate::identify::with_stiffness;
use crate::infer::{InferError, OnnxModel};
use crate::planner::predict::max_node_error;
use crate::tree::{Tree, Wood};

/// One size's scores (m).
#[derive(Debug, Clone, Serialize)]
pub struct StiffnessScore {
    pub n: usize,
    pub episodes: usize,
    /// e_N given the true stiffness.
    pub true_stiffness: f64,
    /// e_N given the radius formula's stiffness.
    pub nominal_stiffness: f64,
    /// e_N of doing nothing.
    pub no_action: f64,
    /// Largest prediction change under a global factor of 3 or 1/3.
    pub global_factor_shift: f64,
}

fn scaled(tree: &Tree, factor: f64) -> Tree {
    let k: Vec<f64> = tree
        .branches()
        .iter()
        .map(|b| b.map_or(0.0, |b| b.stiffness * factor))
        .collect();
    with_stiffness(tree, &k)
}

fn nominal(tree: &Tree) -> Tree {
    let wood = Wood::default();
    let k: Vec<f64> = tree
        .branches()
        .iter()
        .map(|b| b.map_or(0.0, |b| wood.stiffness(b.radius, b.length)))
        .collect();
    with_stiffness(tree, &k)
}

fn predict(
    model: &mut OnnxModel,
    cases: &[(Tree, usize, Vector3<f64>)],
) -> Result<Vec<Vec<Point3<f64>>>, InferError> {
    let graphs: Vec<_> = cases
        .iter()
        .map(|(t, j, v)| encode_forward(t, *j, v).expect("validated episode"))
        .collect();
    let b = batch(&graphs).expect("non-empty");
    let out = model.run(&b)?;
    Ok(cases
        .iter()
        .enumerate()
        .map(|(k, (t, _, _))| {
            t.positions()
                .iter()
                .enumerate()
                .map(|(j, p)| {
                    let v = &out.vectors[(k * b.n + j) * 3..(k * b.n + j) * 3 + 3];
                    p + Vector3::new(v[0] as f64, v[1] as f64, v[2] as f64)
                })
                .collect()
        })
        .collect())
}

/// Scores the first `limit` episodes of one size file.
pub fn stiffness_scores(
    data: &SizeData,
    model: &mut OnnxModel,
    limit: usize,
    batch_size: usize,
) -> Result<StiffnessScore, InferError> {
    let episodes = &data.episodes[..limit.min(data.episodes.len())];
    let (mut truth, mut formula, mut still, mut shift) = (0.0, 0.0, 0.0, 0.0f64);
    for chunk in episodes.chunks(batch_size.max(1)) {
        let case = |t: Tree, e: &crate::dataset::Episode| (t, e.push.node, e.push.vector);
        let trees: Vec<&Tree> = chunk.iter().map(|e| data.tree_of(e)).collect();
        let given = |f: &dyn Fn(&Tree) -> Tree| -> Vec<_> {
            chunk
                .iter()
                .zip(&trees)
                .map(|(e, t)| case(f(t), e))
                .collect()
        };
        let with_true = predict(model, &given(&|t| t.clone()))?;
        let with_nominal = predict(model, &given(&nominal))?;
        let tripled = predict(model, &given(&|t| scaled(t, 3.0)))?;
        let thirded = predict(model, &given(&|t| scaled(t, 1.0 / 3.0)))?;
        for (k, e) in chunk.iter().enumerate() {
            truth += max_node_error(&with_true[k], &e.final_positions);
            formula += max_node_error(&with_nominal[k], &e.final_positions);
            still += max_node_error(trees[k].positions(), &e.final_positions);
            shift = shift
                .max(max_node_error(&with_true[k], &tripled[k]))
                .max(max_node_error(&with_true[k], &thirded[k]));
        }
    }
    let count = episodes.len().max(1) as f64;
    Ok(StiffnessScore {
        n: data.n,
        episodes: episodes.len(),
        true_stiffness: truth / count,
        nominal_stiffness: formula / count,
        no_action: still / count,
        global_factor_shift: shift,
    })
}

/// The table, in cm (shift in mm), with the mean over sizes last.
pub fn to_markdown(scores: &[StiffnessScore]) -> String {
    let mut out = String::from(
        "| N | episodes | e_N, true K (cm) | e_N, radius-formula K (cm) | No Action (cm) | largest shift under ×3 or ×1/3 on every K (mm) |\n| --- | --- | --- | --- | --- | --- |\n",
    );
    for s in scores {
        out += &format!(
            "| {} | {} | {:.2} | {:.2} | {:.2} | {:.4} |\n",
            s.n,
            s.episodes,
            s.true_stiffness * 100.0,
            s.nominal_stiffness * 100.0,
            s.no_action * 100.0,
            s.global_factor_shift * 1000.0
        );
    }
    let mean = |f: fn(&StiffnessScore) -> f64| {
        scores.iter().map(f).sum::<f64>() / scores.len().max(1) as f64
    };
    out += &format!(
        "| mean | {} | **{:.2}** | **{:.2}** | {:.2} | {:.4} (max) |\n",
        scores.iter().map(|s| s.episodes).sum::<usize>(),
        mean(|s| s.true_stiffness) * 100.0,
        mean(|s| s.nominal_stiffness) * 100.0,
        mean(|s| s.no_action) * 100.0,
        scores
            .iter()
            .map(|s| s.global_factor_shift)
            .fold(0.0, f64::max)
            * 1000.0
    );
    out
}
