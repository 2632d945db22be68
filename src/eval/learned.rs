//! The paper's evaluation of the learned models (Section IV, Fig. 7):
//! e_N, the mean over a size's test episodes of the tree's maximum node
//! position error, for each method and tree size.
//!
//! - Forward model: predicted p + Δp against the simulated p′; No Action
//!   predicts that nothing moves.
//! - Contact policy: the arg-max affordance node's predicted push is
//!   **executed in the simulator** and the resulting tree is compared with
//!   the target p′. Greedy pushes the node farthest from its target by
//!   p′_j − p_j; Random does the same for a uniformly drawn node; No Action
//!   leaves the tree still. A push the simulator rejects (the gripper would
//!   lose the branch, say) leaves the tree still, and is counted.
//!
//! Models are run through ONNX ([`OnnxModel`]): what is evaluated is what
//! ships.

use nalgebra::Point3;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::Serialize;

use crate::dataset::{Episode, SizeData};
use crate::graph::{Task, batch, encode_forward, encode_policy};
use crate::infer::{InferError, OnnxModel};
use crate::seed::derive_seed;
use crate::sim::{Push, SimConfig, simulate};
use crate::tree::Tree;

/// One method's score on one tree size.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Score {
    pub method: String,
    pub n: usize,
    pub episodes: usize,
    /// e_N (m).
    pub error: f64,
    /// Policy methods: pushes the simulator rejected.
    pub rejected: usize,
}

fn max_error(a: &[Point3<f64>], b: &[Point3<f64>]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(p, q)| (p - q).norm())
        .fold(0.0, f64::max)
}

/// Episodes evaluated for a size: the first `limit` in file order.
fn episodes(data: &SizeData, limit: usize) -> &[Episode] {
    &data.episodes[..limit.min(data.episodes.len())]
}

/// Forward models and No Action on one size file.
pub fn forward_scores(
    data: &SizeData,
    models: &mut [(String, OnnxModel)],
    limit: usize,
    batch_size: usize,
) -> Result<Vec<Score>, InferError> {
    let eps = episodes(data, limit);
    let mut scores = Vec::new();
    for (name, model) in models.iter_mut() {
        let mut sum = 0.0;
        for chunk in eps.chunks(batch_size.max(1)) {
            let graphs: Vec<_> = chunk
                .iter()
                .map(|e| {
                    encode_forward(data.tree_of(e), e.push.node, &e.push.vector)
                        .expect("validated episode")
                })
                .collect();
            let b = batch(&graphs).expect("non-empty");
            let out = model.run(&b)?;
            for (k, e) in chunk.iter().enumerate() {
                let tree = data.tree_of(e);
                let predicted: Vec<Point3<f64>> = tree
                    .positions()
                    .iter()
                    .enumerate()
                    .map(|(j, p)| {
                        let v = &out.vectors[(k * b.n + j) * 3..(k * b.n + j) * 3 + 3];
                        p + nalgebra::Vector3::new(v[0] as f64, v[1] as f64, v[2] as f64)
                    })
                    .collect();
                sum += max_error(&predicted, &e.final_positions);
            }
        }
        scores.push(Score {
            method: name.clone(),
            n: data.n,
            episodes: eps.len(),
            error: sum / eps.len().max(1) as f64,
            rejected: 0,
        });
    }
    scores.push(no_action(data, eps));
    Ok(scores)
}

fn no_action(data: &SizeData, eps: &[Episode]) -> Score {
    let sum: f64 = eps
        .iter()
        .map(|e| max_error(data.tree_of(e).positions(), &e.final_positions))
        .sum();
    Score {
        method: "No Action".to_owned(),
        n: data.n,
        episodes: eps.len(),
        error: sum / eps.len().max(1) as f64,
        rejected: 0,
    }
}

/// The error after executing `push` on `tree`, and whether it was rejected.
fn executed(tree: &Tree, push: Push, target: &[Point3<f64>], sim: &SimConfig) -> (f64, bool) {
    match simulate(tree, &push, sim) {
        Ok(out) => (max_error(&out.final_positions, target), false),
        Err(_) => (max_error(tree.positions(), target), true),
    }
}

/// The push that moves node j onto its target.
fn push_to_target(tree: &Tree, target: &[Point3<f64>], j: usize) -> Push {
    Push {
        node: j,
        vector: target[j] - tree.position(j),
    }
}

fn score_pushes(
    method: &str,
    data: &SizeData,
    eps: &[Episode],
    pushes: &[Push],
    sim: &SimConfig,
) -> Score {
    let results: Vec<(f64, bool)> = eps
        .par_iter()
        .zip(pushes)
        .map(|(e, p)| executed(data.tree_of(e), *p, &e.final_positions, sim))
        .collect();
    Score {
        method: method.to_owned(),
        n: data.n,
        episodes: eps.len(),
        error: results.iter().map(|r| r.0).sum::<f64>() / eps.len().max(1) as f64,
        rejected: results.iter().filter(|r| r.1).count(),
    }
}

/// Contact policies, Greedy, Random and No Action on one size file.
pub fn policy_scores(
    data: &SizeData,
    models: &mut [(String, OnnxModel)],
    limit: usize,
    batch_size: usize,
    seed: u64,
) -> Result<Vec<Score>, InferError> {
    let eps = episodes(data, limit);
    let sim = SimConfig::default();
    let mut scores = Vec::new();
    for (name, model) in models.iter_mut() {
        let mut pushes = Vec::with_capacity(eps.len());
        for chunk in eps.chunks(batch_size.max(1)) {
            let graphs: Vec<_> = chunk
                .iter()
                .map(|e| encode_policy(data.tree_of(e), &e.final_positions).expect("validated"))
                .collect();
            let b = batch(&graphs).expect("non-empty");
            let out = model.run(&b)?;
            let affordance = out.affordance.as_ref().expect("a policy model");
            for (k, e) in chunk.iter().enumerate() {
                let n = data.tree_of(e).len();
                let row = &affordance[k * b.n..k * b.n + n];
                let node = (1..n)
                    .max_by(|&a, &c| row[a].total_cmp(&row[c]))
                    .unwrap_or(1);
                let v = &out.vectors[(k * b.n + node) * 3..(k * b.n + node) * 3 + 3];
                pushes.push(Push {
                    node,
                    vector: nalgebra::Vector3::new(v[0] as f64, v[1] as f64, v[2] as f64),
                });
            }
        }
        scores.push(score_pushes(name, data, eps, &pushes, &sim));
    }
    let greedy: Vec<Push> = eps
        .iter()
        .map(|e| {
            let tree = data.tree_of(e);
            let j = (1..tree.len())
                .max_by(|&a, &b| {
                    let da = (e.final_positions[a] - tree.position(a)).norm();
                    let db = (e.final_positions[b] - tree.position(b)).norm();
                    da.total_cmp(&db)
                })
                .unwrap_or(1);
            push_to_target(tree, &e.final_positions, j)
        })
        .collect();
    scores.push(score_pushes("Greedy", data, eps, &greedy, &sim));
    let mut rng = ChaCha8Rng::seed_from_u64(derive_seed(seed, &[data.n as u64, 0x7a4d]));
    let random: Vec<Push> = eps
        .iter()
        .map(|e| {
            let tree = data.tree_of(e);
            let j = rng.random_range(1..tree.len());
            push_to_target(tree, &e.final_positions, j)
        })
        .collect();
    scores.push(score_pushes("Random", data, eps, &random, &sim));
    scores.push(no_action(data, eps));
    Ok(scores)
}

/// Methods in first-seen order.
pub fn methods(scores: &[Score]) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    for s in scores {
        if !out.contains(&s.method) {
            out.push(s.method.clone());
        }
    }
    out
}

fn sizes(scores: &[Score]) -> Vec<usize> {
    let mut n: Vec<usize> = scores.iter().map(|s| s.n).collect();
    n.sort_unstable();
    n.dedup();
    n
}

fn lookup<'a>(scores: &'a [Score], method: &str, n: usize) -> Option<&'a Score> {
    scores.iter().find(|s| s.method == method && s.n == n)
}

/// Mean e_N over the given sizes.
pub fn mean_error(scores: &[Score], method: &str, among: impl Fn(usize) -> bool) -> f64 {
    let v: Vec<f64> = scores
        .iter()
        .filter(|s| s.method == method && among(s.n))
        .map(|s| s.error)
        .collect();
    v.iter().sum::<f64>() / v.len().max(1) as f64
}

/// CSV: n, episodes, then one column per method (metres).
pub fn to_csv(scores: &[Score]) -> String {
    let ms = methods(scores);
    let mut out = format!("n,episodes,{}\n", ms.join(","));
    for n in sizes(scores) {
        let episodes = scores.iter().find(|s| s.n == n).map_or(0, |s| s.episodes);
        let cells: Vec<String> = ms
            .iter()
            .map(|m| lookup(scores, m, n).map_or(String::new(), |s| format!("{:.5}", s.error)))
            .collect();
        out.push_str(&format!("{n},{episodes},{}\n", cells.join(",")));
    }
    out
}

/// Markdown table in centimetres, with the mean over all sizes, over the
/// training sizes and over the zero-shot sizes.
pub fn to_markdown(scores: &[Score], trained: &[usize]) -> String {
    let ms = methods(scores);
    let mut out = format!(
        "| N | {} |\n|---|{}\n",
        ms.join(" | "),
        "---|".repeat(ms.len())
    );
    for n in sizes(scores) {
        let mark = if trained.contains(&n) { "*" } else { "" };
        let cells: Vec<String> = ms
            .iter()
            .map(|m| {
                lookup(scores, m, n).map_or(String::new(), |s| {
                    if s.rejected > 0 {
                        format!("{:.2} ({} rej.)", 100.0 * s.error, s.rejected)
                    } else {
                        format!("{:.2}", 100.0 * s.error)
                    }
                })
            })
            .collect();
        out.push_str(&format!("| {n}{mark} | {} |\n", cells.join(" | ")));
    }
    let row = |label: &str, f: &dyn Fn(usize) -> bool| {
        let cells: Vec<String> = ms
            .iter()
            .map(|m| format!("**{:.2}**", 100.0 * mean_error(scores, m, f)))
            .collect();
        format!("| {label} | {} |\n", cells.join(" | "))
    };
    out.push_str(&row("mean", &|_| true));
    out.push_str(&row("mean, trained sizes", &|n| trained.contains(&n)));
    out.push_str(&row("mean, zero-shot sizes", &|n| !trained.contains(&n)));
    out.push_str("\nErrors in cm (e_N: mean over episodes of the tree's largest node error); * = size seen in training.\n");
    out
}

/// The task's methods in the paper's order, for plots.
pub fn task_title(task: Task) -> &'static str {
    match task {
        Task::Forward => "Forward model: e_N per tree size",
        Task::Policy => "Contact policy (executed in simulation): e_N per tree size",
    }
}
