//! Training examples from the `.npz` dataset: every episode is encoded by
//! the one graph encoder ([`crate::graph`]) when its batch is built, and
//! batches hold episodes of one tree size (no padding while training).

use std::path::Path;

use nalgebra::Vector3;
use rand::seq::SliceRandom;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::dataset::{Episode, SizeData, Split, read_size_file};
use crate::graph::path::{Encoding, PathGraph, PathOutput, encode_forward_path};
use crate::graph::stats::{Running, StatsBuilder};
use crate::graph::{
    Batch, FeatureStats, GraphInput, Task, batch, encode_forward, encode_policy, offsets, rotate_xy,
};
use crate::model::domain::Span;
use crate::seed::derive_seed;
use crate::tree::Tree;

/// Trees whose index in their size file satisfies this are held out for
/// validation (10 %): validation measures generalisation to unseen trees.
pub fn is_validation_tree(tree: usize) -> bool {
    tree % 10 == 9
}

/// The episodes of one split, grouped by tree size.
pub struct Examples {
    pub sizes: Vec<SizeData>,
    /// What graph the model reads ([`Encoding::Path`]: the push's path and
    /// its side branches' first nodes).
    pub encoding: Encoding,
    /// (size index, episode index) of the examples in use.
    pub train: Vec<(usize, usize)>,
    pub validation: Vec<(usize, usize)>,
    /// A path rotation model's loss weighs each branch's turn error by the
    /// square of a length of the branch ([`TurnWeight`]) over this
    /// reference (m², the training examples' mean of that square;
    /// [`Examples::weigh_turns`]); absent: every output row weighs the same.
    pub turn_weight: Option<(TurnWeight, f64)>,
}

/// What a path rotation model's loss weighs each branch's squared turn
/// error by (the square of a length, over its mean in training).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TurnWeight {
    /// Every turn alike (the squared error in radians).
    #[default]
    Uniform,
    /// The turn's reach in the training tree
    /// ([`crate::graph::path::PathGraph::turn_reach`]): the squared
    /// position error the turn causes there.
    Reach,
    /// The branch's radius: by the pipe model, a proxy for how much tree
    /// the branch carries in the tree it grew in, which a crop (cut around
    /// one path) no longer shows.
    Radius,
}

impl std::str::FromStr for TurnWeight {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "uniform" => Ok(Self::Uniform),
            "reach" => Ok(Self::Reach),
            "radius" => Ok(Self::Radius),
            _ => Err(format!(
                "unknown turn weight {s:?} (uniform, reach or radius)"
            )),
        }
    }
}

/// Each graph node's length that `weight` squares (m; 0 for the root and
/// the side nodes); `None` for [`TurnWeight::Uniform`], which weighs every
/// row alike.
fn turn_lengths(weight: TurnWeight, graph: &PathGraph, tree: &Tree) -> Option<Vec<f64>> {
    match weight {
        TurnWeight::Uniform => None,
        TurnWeight::Reach => Some(graph.turn_reach(tree)),
        TurnWeight::Radius => Some(
            (0..graph.input.n)
                .map(|k| match k {
                    k if k > 0 && k < graph.path_len => {
                        tree.branch(graph.nodes[k]).map_or(0.0, |b| b.radius)
                    }
                    _ => 0.0,
                })
                .collect(),
        ),
    }
}

/// Per-axis mean and standard deviation of a 3-vector.
pub type MeanStd = ([f64; 3], [f64; 3]);

/// What the loss compares against, for a batch.
pub struct Targets {
    /// B × N × 3 node displacements p′ − p (forward model).
    pub displacement: Vec<f32>,
    /// B contacted nodes (policy).
    pub contact: Vec<usize>,
    /// B × 3 pushes T (policy).
    pub push: Vec<f32>,
    /// B × N weights of the rows' squared errors (forward model): the
    /// batch's mask, or with [`Examples::turn_weight`] each path branch's
    /// squared length over the scale (0 for the root and the side nodes,
    /// whose rows the decoder never reads).
    pub weight: Vec<f32>,
}

impl Targets {
    /// The targets of examples `range` of a batch padded to `n` nodes.
    pub fn rows(&self, range: std::ops::Range<usize>, n: usize) -> Targets {
        Targets {
            displacement: self.displacement[range.start * n * 3..range.end * n * 3].to_vec(),
            contact: self.contact[range.clone()].to_vec(),
            push: self.push[range.start * 3..range.end * 3].to_vec(),
            weight: self.weight[range.start * n..range.end * n].to_vec(),
        }
    }
}

impl Examples {
    /// Loads `train_N{n}.npz` for each size; `limit` caps the episodes per
    /// size (first ones in file order, for quick runs and tests).
    pub fn load(
        dir: &Path,
        sizes: &[usize],
        limit: Option<usize>,
        encoding: Encoding,
    ) -> anyhow::Result<Self> {
        let mut out = Examples {
            encoding,
            sizes: Vec::new(),
            train: Vec::new(),
            validation: Vec::new(),
            turn_weight: None,
        };
        for &n in sizes {
            let path = dir.join(Split::Train.file_name(n));
            let data = read_size_file(&path, Split::Train)
                .map_err(|e| anyhow::anyhow!("reading {}: {e}", path.display()))?;
            let s = out.sizes.len();
            let count = limit.unwrap_or(usize::MAX).min(data.episodes.len());
            for (e, episode) in data.episodes.iter().enumerate().take(count) {
                if is_validation_tree(episode.tree) {
                    out.validation.push((s, e));
                } else {
                    out.train.push((s, e));
                }
            }
            out.sizes.push(data);
        }
        anyhow::ensure!(
            !out.train.is_empty(),
            "no training episodes in {}",
            dir.display()
        );
        anyhow::ensure!(
            !out.validation.is_empty(),
            "no validation episodes (trees with index ≡ 9 mod 10) in {}",
            dir.display()
        );
        Ok(out)
    }

    fn episode(&self, (s, e): (usize, usize)) -> (&SizeData, &Episode) {
        let data = &self.sizes[s];
        (data, &data.episodes[e])
    }

    /// The encoded model input of one example and, for the forward model,
    /// what it learns: Δp (m) per graph node (empty for the policy). A
    /// path graph is built once for both.
    pub fn example(&self, task: Task, id: (usize, usize)) -> (GraphInput, Vec<f32>) {
        let (input, rows, _) = self.encoded(task, id, false);
        (input, rows)
    }

    /// [`Examples::example`] and, with `weighed` for a path model whose
    /// turns are weighed ([`Examples::turn_weight`]), each graph node's
    /// weight, from the same path graph.
    fn encoded(
        &self,
        task: Task,
        id: (usize, usize),
        weighed: bool,
    ) -> (GraphInput, Vec<f32>, Option<Vec<f32>>) {
        let (data, episode) = self.episode(id);
        let tree = data.tree_of(episode);
        let (node, push) = (episode.push.node, &episode.push.vector);
        let valid = "dataset episodes are validated when read";
        match (task, self.encoding.path_output()) {
            (Task::Policy, _) => (
                encode_policy(tree, &episode.final_positions).expect(valid),
                Vec::new(),
                None,
            ),
            (Task::Forward, Some(output)) => {
                let graph = encode_forward_path(tree, node, push).expect(valid);
                let rows = graph.targets(output, tree, &episode.final_positions);
                let weights = self
                    .turn_weight
                    .filter(|_| weighed)
                    .and_then(|(weight, scale)| {
                        let lengths = turn_lengths(weight, &graph, tree)?;
                        Some(lengths.iter().map(|r| (r * r / scale) as f32).collect())
                    });
                (graph.input, rows, weights)
            }
            (Task::Forward, None) => (
                encode_forward(tree, node, push).expect(valid),
                offsets(&episode.final_positions, tree.positions()),
                None,
            ),
        }
    }

    /// A path model's error on example `id` (m): the largest over every
    /// node of the tree when its answer `rows` (3 numbers per graph node,
    /// padding after them ignored) is placed on it.
    pub fn tree_error(&self, output: PathOutput, id: (usize, usize), rows: &[f32]) -> f64 {
        let (data, episode) = self.episode(id);
        let tree = data.tree_of(episode);
        let graph = encode_forward_path(tree, episode.push.node, &episode.push.vector)
            .expect("dataset episodes are validated when read");
        graph
            .held_positions(output, tree, &rows[..3 * graph.input.n])
            .iter()
            .zip(&episode.final_positions)
            .map(|(a, b)| (a - b).norm())
            .fold(0.0, f64::max)
    }

    /// Weighs a path rotation model's turn errors by `weight` (squared),
    /// over its mean square over the training examples' path branches
    /// (every 10th example); [`TurnWeight::Uniform`] weighs every row alike.
    pub fn weigh_turns(&mut self, weight: TurnWeight) {
        if weight == TurnWeight::Uniform {
            self.turn_weight = None;
            return;
        }
        let (sum, count) = self
            .train
            .iter()
            .step_by(10)
            .flat_map(|&id| {
                let (data, episode) = self.episode(id);
                let tree = data.tree_of(episode);
                let graph = encode_forward_path(tree, episode.push.node, &episode.push.vector)
                    .expect("dataset episodes are validated when read");
                turn_lengths(weight, &graph, tree).unwrap_or_default()
            })
            .filter(|&r| r > 0.0)
            .fold((0.0, 0usize), |(s, c), r| (s + r * r, c + 1));
        self.turn_weight = Some((weight, sum / count.max(1) as f64));
    }

    /// A padded batch and its targets.
    pub fn batch(&self, task: Task, ids: &[(usize, usize)]) -> (Batch, Targets) {
        self.batch_rotated(task, ids, &[])
    }

    /// A padded batch and its targets, example k turned by `angles[k]` about
    /// the vertical axis through its root (inputs and targets alike; see
    /// [`GraphInput::rotate_about_vertical`]). An empty `angles` turns
    /// nothing.
    pub fn batch_rotated(
        &self,
        task: Task,
        ids: &[(usize, usize)],
        angles: &[f64],
    ) -> (Batch, Targets) {
        assert!(angles.is_empty() || angles.len() == ids.len());
        let mut graphs = Vec::with_capacity(ids.len());
        let mut rows = Vec::with_capacity(ids.len());
        let mut weights = Vec::with_capacity(ids.len());
        for (k, &id) in ids.iter().enumerate() {
            let (mut g, r, w) = self.encoded(task, id, true);
            if let Some(&angle) = angles.get(k) {
                g.rotate_about_vertical(angle);
            }
            graphs.push(g);
            rows.push(r);
            weights.push(w);
        }
        let batch = batch(&graphs).expect("non-empty batch of one task");
        let n = batch.n;
        let mut targets = Targets {
            displacement: vec![0.0; ids.len() * n * 3],
            contact: Vec::with_capacity(ids.len()),
            push: Vec::with_capacity(ids.len() * 3),
            weight: batch.mask.clone(),
        };
        for (k, (&id, rows)) in ids.iter().zip(&rows).enumerate() {
            let (_, episode) = self.episode(id);
            if let Some(w) = &weights[k] {
                let row = &mut targets.weight[k * n..(k + 1) * n];
                row.fill(0.0);
                row[..w.len()].copy_from_slice(w);
            }
            targets.displacement[k * n * 3..k * n * 3 + rows.len()].copy_from_slice(rows);
            targets.contact.push(episode.push.node);
            let t: Vector3<f64> = episode.push.vector;
            targets.push.extend([t.x as f32, t.y as f32, t.z as f32]);
            if let Some(&angle) = angles.get(k) {
                let (sin, cos) = angle.sin_cos();
                let d = &mut targets.displacement[k * n * 3..(k + 1) * n * 3];
                d.chunks_exact_mut(3).for_each(|v| rotate_xy(v, sin, cos));
                rotate_xy(&mut targets.push[k * 3..k * 3 + 3], sin, cos);
            }
        }
        (batch, targets)
    }

    /// Input statistics, output (Δp or T) statistics and node-position
    /// (p_j − p_0) statistics over the training examples only.
    pub fn statistics(&self, task: Task) -> (FeatureStats, MeanStd, MeanStd) {
        let mut inputs = StatsBuilder::new(task);
        let mut outputs = Running::new(3);
        let mut position = Running::new(3);
        for &id in &self.train {
            let (g, rows) = self.example(task, id);
            inputs.add(&g);
            for j in 0..g.n {
                position.push(&g.edge(0, j)[..3]);
            }
            let (_, episode) = self.episode(id);
            match task {
                Task::Forward => {
                    for j in 0..g.n {
                        outputs.push(&rows[3 * j..3 * j + 3]);
                    }
                }
                Task::Policy => {
                    let t = episode.push.vector;
                    outputs.push(&[t.x as f32, t.y as f32, t.z as f32]);
                }
            }
        }
        let three = |r: &Running| {
            let (m, s) = r.finish();
            ([m[0], m[1], m[2]], [s[0], s[1], s[2]])
        };
        (inputs.finish(), three(&outputs), three(&position))
    }

    /// The batches of one epoch: examples shuffled within each tree size,
    /// cut into batches, batch order shuffled. A function of (seed, epoch)
    /// only, so a resumed run replays the same order.
    pub fn epoch_batches(&self, seed: u64, epoch: usize, size: usize) -> Vec<Vec<(usize, usize)>> {
        let mut rng = ChaCha8Rng::seed_from_u64(derive_seed(seed, &[epoch as u64, 0xba7c]));
        let mut out = Vec::new();
        for s in 0..self.sizes.len() {
            let mut ids: Vec<(usize, usize)> =
                self.train.iter().copied().filter(|id| id.0 == s).collect();
            ids.shuffle(&mut rng);
            out.extend(ids.chunks(size).map(|c| c.to_vec()));
        }
        out.shuffle(&mut rng);
        out
    }

    /// The augmentation angles of one training batch (rad, uniform in
    /// [0, 2π)): a function of (seed, epoch, batch) only, drawn afresh each
    /// epoch, replayed exactly on resume.
    pub fn rotation_angles(seed: u64, epoch: usize, batch: usize, count: usize) -> Vec<f64> {
        let mut rng =
            ChaCha8Rng::seed_from_u64(derive_seed(seed, &[epoch as u64, batch as u64, 0x2074]));
        (0..count)
            .map(|_| rng.random_range(0.0..std::f64::consts::TAU))
            .collect()
    }

    /// Validation examples in batches of one size each.
    pub fn validation_batches(&self, size: usize) -> Vec<Vec<(usize, usize)>> {
        let mut out = Vec::new();
        for s in 0..self.sizes.len() {
            let ids: Vec<(usize, usize)> = self
                .validation
                .iter()
                .copied()
                .filter(|id| id.0 == s)
                .collect();
            out.extend(ids.chunks(size).map(|c| c.to_vec()));
        }
        out
    }
}

/// The span of the training trees (index ≢ 9 mod 10, the validation
/// trees excluded as in training) and pushes of `sizes` in dataset `dir`.
pub fn training_span(dir: &Path, sizes: &[usize]) -> anyhow::Result<Span> {
    let mut span = Span::default();
    for &n in sizes {
        let path = dir.join(Split::Train.file_name(n));
        let data = read_size_file(&path, Split::Train)
            .map_err(|e| anyhow::anyhow!("reading {}: {e}", path.display()))?;
        for (index, (_, tree)) in data.trees.iter().enumerate() {
            if !is_validation_tree(index) {
                span.add_tree(tree);
            }
        }
        for episode in &data.episodes {
            if !is_validation_tree(episode.tree) {
                span.add_push(episode.push.vector.norm());
            }
        }
    }
    anyhow::ensure!(
        span.push_length.min <= span.push_length.max,
        "no training episodes in {}",
        dir.display()
    );
    Ok(span)
}
