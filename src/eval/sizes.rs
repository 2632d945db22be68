//! Error and cost against the tree's size: e_N of each forward model and
//! of No Action on held-out trees of 10 to 500 nodes, the models' inference
//! time for one push and for 64, and the simulator's time for one push.
//!
//! Trees: the paper's Space Colonization trees at the sizes it grows
//! (N ≤ 64) and orchard trees (leader, scaffolds, laterals at the paper's
//! spacing) at every size; paper-style pushes (the dataset's push
//! distribution), the simulator as truth. Seeds are not the training
//! data's (the dataset seed 7 and its trees): these trees were never seen.
//!
//! A model that reads the fully connected graph is run only up to
//! [`FULL_GRAPH_MAX_NODES`]; above it its row is absent, as the server
//! refuses it.

use std::time::Instant;

use nalgebra::{Point3, Vector3};
use serde::Serialize;

use super::plan::percentile;
use crate::dataset::{CollectConfig, Episode, SizeData, Split, collect_size};
use crate::graph::path::{Encoding, PathOutput, encode_forward_path};
use crate::infer::batcher::JobControl;
use crate::infer::models::{ServedModel, predict_displacements};
use crate::planner::objective::DEFAULT_MAX_STRESS;
use crate::sim::loads::PushLoads;
use crate::sim::{SimConfig, simulate};
use crate::tree::collection::TreeShape;
use crate::tree::{FULL_GRAPH_MAX_NODES, Tree};

/// One (model or No Action, shape, size) row.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SizeRow {
    pub method: String,
    pub shape: TreeShape,
    pub n: usize,
    pub episodes: usize,
    /// e_N (m): mean over episodes of the largest node error.
    pub error: f64,
    /// Median time of one push's prediction (ms); None for No Action.
    pub one_push_ms: Option<f64>,
    /// Median time of 64 pushes on one tree in one call (ms).
    pub batch_64_ms: Option<f64>,
    /// e_N of the pushes by how deep the pushed node is ([`DEPTH_BANDS`]).
    pub by_depth: Vec<DepthCell>,
    /// e_N (m) over the pushes that do not break the wood (peak bending
    /// stress within [`DEFAULT_MAX_STRESS`]), and how many those are.
    pub within_stress: Option<f64>,
    pub within_stress_episodes: usize,
}

/// What a row's pushes are grouped by, one per episode of a test set.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PushFacts {
    /// Joints from the root to the pushed node.
    pub depth: usize,
    /// Whether the simulated push stays within [`DEFAULT_MAX_STRESS`] at
    /// every branch. The paper's push distribution (5-12 cm at any node)
    /// asks a large tree for pushes no arm should make: 10 cm near the foot
    /// of a 5 cm leader moves a 200-500-node tree's crown by tens of
    /// centimetres to a metre (`eval sizes`, No Action by depth), and the
    /// wood would break first.
    pub within_stress: bool,
}

/// Bands of the pushed node's depth (joints from the root, both ends
/// included). A push near the root of a large tree carries the most tree:
/// a turn's error there moves a metre or more of branches.
pub const DEPTH_BANDS: [(usize, usize); 6] =
    [(1, 4), (5, 8), (9, 12), (13, 16), (17, 24), (25, 64)];

/// e_N over the pushes whose node's depth is in one band.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DepthCell {
    pub from: usize,
    pub to: usize,
    pub episodes: usize,
    /// e_N (m); None where no push fell in the band.
    pub error: Option<f64>,
}

/// Each band's e_N from (depth, largest node error) per push.
fn depth_cells(errors: &[(usize, f64)]) -> Vec<DepthCell> {
    DEPTH_BANDS
        .iter()
        .map(|&(from, to)| {
            let band: Vec<f64> = errors
                .iter()
                .filter(|(d, _)| (from..=to).contains(d))
                .map(|&(_, e)| e)
                .collect();
            DepthCell {
                from,
                to,
                episodes: band.len(),
                error: (!band.is_empty()).then(|| band.iter().sum::<f64>() / band.len() as f64),
            }
        })
        .collect()
}

/// The simulator's cost at one size.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SimRow {
    pub shape: TreeShape,
    pub n: usize,
    /// Median and 95th percentile of one push's solve (ms).
    pub p50_ms: f64,
    pub p95_ms: f64,
    /// Depth of the pushed node: joints the solve works on (mean).
    pub mean_path: f64,
}

/// Held-out test episodes: `trees` trees of `n` nodes and `episodes` pushes.
pub fn test_set(
    shape: TreeShape,
    n: usize,
    trees: usize,
    episodes: usize,
    seed: u64,
) -> anyhow::Result<SizeData> {
    let config = CollectConfig {
        seed,
        trees_per_size: trees,
        shape,
        ..CollectConfig::default()
    };
    Ok(collect_size(Split::Test, n, episodes, &config, &|| {})?.0)
}

/// The `p` quantile of unsorted samples.
fn quantile(v: &mut [f64], p: f64) -> f64 {
    v.sort_by(f64::total_cmp);
    percentile(v, p)
}

fn max_error(a: &[Point3<f64>], b: &[Point3<f64>]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(p, q)| (p - q).norm())
        .fold(0.0, f64::max)
}

/// Episode indices grouped by their tree, in tree order.
fn by_tree(data: &SizeData) -> Vec<(usize, Vec<usize>)> {
    let mut groups: Vec<(usize, Vec<usize>)> = Vec::new();
    for (k, e) in data.episodes.iter().enumerate() {
        match groups.iter_mut().find(|(t, _)| *t == e.tree) {
            Some((_, list)) => list.push(k),
            None => groups.push((e.tree, vec![k])),
        }
    }
    groups
}

/// A model's row on one test set; `None` when the model does not take trees
/// of this size.
pub fn model_row(
    name: &str,
    model: &ServedModel,
    shape: TreeShape,
    data: &SizeData,
    facts: &[PushFacts],
    timing_runs: usize,
) -> anyhow::Result<Option<SizeRow>> {
    if model.card.encoding == Encoding::Full && data.n > FULL_GRAPH_MAX_NODES {
        return Ok(None);
    }
    let control = JobControl::default();
    let mut errors = vec![0.0; data.episodes.len()];
    for (t, episodes) in by_tree(data) {
        let tree = &data.trees[t].1;
        let actions: Vec<(usize, Vector3<f64>)> = episodes
            .iter()
            .map(|&k| (data.episodes[k].push.node, data.episodes[k].push.vector))
            .collect();
        let predicted = predict_displacements(model, tree, &actions, &control)?;
        for (&k, d) in episodes.iter().zip(&predicted) {
            let placed: Vec<Point3<f64>> =
                tree.positions().iter().zip(d).map(|(p, d)| p + d).collect();
            errors[k] = max_error(&placed, &data.episodes[k].final_positions);
        }
    }
    // Timing on the first tree: one push, then 64 (its pushes repeated).
    let first = &data.episodes[0];
    let tree = data.tree_of(first);
    let mut one = Vec::with_capacity(timing_runs);
    for k in 0..timing_runs {
        let e = &data.episodes[k % data.episodes.len()];
        let action = [(e.push.node, e.push.vector)];
        let started = Instant::now();
        predict_displacements(model, data.tree_of(e), &action, &control)?;
        one.push(started.elapsed().as_secs_f64() * 1e3);
    }
    let same_tree: Vec<(usize, Vector3<f64>)> = data
        .episodes
        .iter()
        .filter(|e| e.tree == first.tree)
        .map(|e| (e.push.node, e.push.vector))
        .cycle()
        .take(64)
        .collect();
    let mut many = Vec::new();
    for _ in 0..timing_runs.div_ceil(4).max(3) {
        let started = Instant::now();
        predict_displacements(model, tree, &same_tree, &control)?;
        many.push(started.elapsed().as_secs_f64() * 1e3);
    }
    Ok(Some(SizeRow {
        one_push_ms: Some(quantile(&mut one, 0.5)),
        batch_64_ms: Some(quantile(&mut many, 0.5)),
        ..scored(name, shape, data, facts, &errors)
    }))
}

/// A row's error columns from each episode's largest node error, in the
/// test set's episode order.
fn scored(
    method: &str,
    shape: TreeShape,
    data: &SizeData,
    facts: &[PushFacts],
    errors: &[f64],
) -> SizeRow {
    let mean = |e: &[f64]| (!e.is_empty()).then(|| e.iter().sum::<f64>() / e.len() as f64);
    let within: Vec<f64> = errors
        .iter()
        .zip(facts)
        .filter(|(_, f)| f.within_stress)
        .map(|(&e, _)| e)
        .collect();
    let by_depth: Vec<(usize, f64)> = facts
        .iter()
        .map(|f| f.depth)
        .zip(errors.iter().copied())
        .collect();
    SizeRow {
        method: method.to_owned(),
        shape,
        n: data.n,
        episodes: data.episodes.len(),
        error: mean(errors).unwrap_or(0.0),
        one_push_ms: None,
        batch_64_ms: None,
        by_depth: depth_cells(&by_depth),
        within_stress: mean(&within),
        within_stress_episodes: within.len(),
    }
}

/// No Action: the tree left as it is.
pub fn no_action_row(shape: TreeShape, data: &SizeData, facts: &[PushFacts]) -> SizeRow {
    baseline_row("No Action", shape, data, facts, |tree, _| {
        tree.positions().to_vec()
    })
}

/// The linearised push alone ([`crate::sim::linear`]): the path model's
/// starting point, what its all-zero answer places.
pub fn linear_row(shape: TreeShape, data: &SizeData, facts: &[PushFacts]) -> SizeRow {
    baseline_row("Linearised", shape, data, facts, |tree, e| {
        let graph =
            encode_forward_path(tree, e.push.node, &e.push.vector).expect("validated episode");
        graph.positions(PathOutput::Rotation, tree, &vec![0.0; 3 * graph.input.n])
    })
}

/// A method without a model, untimed: the mean over the episodes of the
/// largest node error of the positions `predict` gives.
fn baseline_row(
    method: &str,
    shape: TreeShape,
    data: &SizeData,
    facts: &[PushFacts],
    predict: impl Fn(&Tree, &Episode) -> Vec<Point3<f64>>,
) -> SizeRow {
    let errors: Vec<f64> = data
        .episodes
        .iter()
        .map(|e| max_error(&predict(data.tree_of(e), e), &e.final_positions))
        .collect();
    scored(method, shape, data, facts, &errors)
}

/// Each episode's push simulated once (one thread): the simulator's time
/// per push, and each push's [`PushFacts`] from its outcome (the loads
/// read outside the timing).
pub fn simulated(shape: TreeShape, data: &SizeData) -> (SimRow, Vec<PushFacts>) {
    let mut times = Vec::with_capacity(data.episodes.len());
    let mut facts = Vec::with_capacity(data.episodes.len());
    for e in &data.episodes {
        let tree = data.tree_of(e);
        let started = Instant::now();
        let outcome = simulate(tree, &e.push, &SimConfig::default());
        times.push(started.elapsed().as_secs_f64() * 1e3);
        facts.push(PushFacts {
            depth: tree.depth(e.push.node),
            within_stress: outcome.is_ok_and(|out| {
                PushLoads::of_outcome(tree, &out).peak_stress <= DEFAULT_MAX_STRESS
            }),
        });
    }
    let path: usize = facts.iter().map(|f| f.depth).sum();
    let row = SimRow {
        shape,
        n: data.n,
        p50_ms: quantile(&mut times.clone(), 0.5),
        p95_ms: quantile(&mut times, 0.95),
        mean_path: path as f64 / data.episodes.len().max(1) as f64,
    };
    (row, facts)
}

/// The rows as a Markdown report.
pub fn to_markdown(rows: &[SizeRow], sims: &[SimRow]) -> String {
    let mut out = String::from(
        "| trees | N | method | episodes | e_N (cm) | e_N / e_20 | within stress: e_N (cm), pushes | e_N / e_20 | one push p50 (ms) | 64 pushes p50 (ms) |\n| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |\n",
    );
    let ms = |v: Option<f64>| v.map_or("-".to_owned(), |v| format!("{v:.2}"));
    for r in rows {
        let at20 = rows
            .iter()
            .find(|q| q.method == r.method && q.shape == r.shape && q.n == 20);
        let ratio = at20.map_or("-".to_owned(), |q| format!("{:.2}", r.error / q.error));
        let within = r.within_stress.map_or("-".to_owned(), |e| {
            format!("{:.2}, {}", e * 100.0, r.within_stress_episodes)
        });
        let within_ratio = match (r.within_stress, at20.and_then(|q| q.within_stress)) {
            (Some(e), Some(e20)) => format!("{:.2}", e / e20),
            _ => "-".to_owned(),
        };
        out += &format!(
            "| {:?} | {} | {} | {} | {:.2} | {} | {} | {} | {} | {} |\n",
            r.shape,
            r.n,
            r.method,
            r.episodes,
            r.error * 100.0,
            ratio,
            within,
            within_ratio,
            ms(r.one_push_ms),
            ms(r.batch_64_ms)
        )
        .to_lowercase()
        .replace("no action", "No Action")
        .replace("gnn", "GNN");
    }
    out += "\nBy the pushed node's depth (joints from the root): e_N in cm (pushes).\n\n| trees | N | method |";
    for (from, to) in DEPTH_BANDS {
        out += &format!(" {from}-{to} |");
    }
    out += "\n| --- | --- | --- |";
    out += &" --- |".repeat(DEPTH_BANDS.len());
    out += "\n";
    for r in rows {
        let cells: String = r
            .by_depth
            .iter()
            .map(|c| match c.error {
                Some(e) => format!(" {:.2} ({}) |", e * 100.0, c.episodes),
                None => " - |".to_owned(),
            })
            .collect();
        out += &format!("| {:?} | {} | {} |{cells}\n", r.shape, r.n, r.method)
            .to_lowercase()
            .replace("no action", "No Action")
            .replace("gnn", "GNN");
    }
    out += "\n| trees | N | simulate p50 (ms) | p95 (ms) | mean path (joints) |\n| --- | --- | --- | --- | --- |\n";
    for s in sims {
        out += &format!(
            "| {:?} | {} | {:.2} | {:.2} | {:.1} |\n",
            s.shape, s.n, s.p50_ms, s.p95_ms, s.mean_path
        )
        .to_lowercase();
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each push counts in the one band holding its depth; a band without
    /// pushes has no error rather than a zero one.
    #[test]
    fn pushes_fall_in_the_band_of_their_depth() {
        let cells = depth_cells(&[(1, 0.01), (4, 0.03), (5, 0.10), (30, 0.5)]);
        assert_eq!(cells.len(), DEPTH_BANDS.len());
        assert_eq!((cells[0].episodes, cells[0].error), (2, Some(0.02)));
        assert_eq!((cells[1].episodes, cells[1].error), (1, Some(0.10)));
        assert_eq!((cells[2].episodes, cells[2].error), (0, None));
        assert_eq!((cells[5].from, cells[5].episodes), (25, 1));
    }
}
