//! The models a process serves: loaded once from a directory, each with a
//! small pool of sessions so concurrent requests do not queue on one lock,
//! and the two questions the service answers with them (what happens under
//! these pushes; which node to push, and how).

use std::path::{Path, PathBuf};

use nalgebra::{Point3, Vector3};

use super::batcher::{BatchLimits, Batcher, JobControl};
use super::{Backend, InferError, LoadProblem, OnnxModel, init_backend, read_metadata};
use treemanip_core::graph::contract::ModelOutput;
use treemanip_core::graph::path::{Encoding, encode_forward_path};
use treemanip_core::graph::{
    FEATURE_LAYOUT_VERSION, GraphInput, Task, batch, encode_forward, encode_policy,
};
use treemanip_core::model::card::ModelCard;
use treemanip_core::planner::Candidate;
use treemanip_core::tree::Tree;

/// Graphs per inference call; larger requests are split.
pub const MAX_BATCH: usize = 64;

/// How a model's inference is spread over the cores: `count` sessions,
/// each with its batching worker, each running one batch on `threads`
/// threads (ONNX Runtime's intra-op pool; tract runs one thread per
/// session, so there the layout becomes `count × threads` sessions).
///
/// One session on every core is the server's default, for latency:
/// measured on 2 cores (AMD EPYC), the planner's batches of the forward GNN
/// ran 1.6-2× faster per push than on two single-threaded sessions (N = 20,
/// 8 pushes: 2.1 vs 4.1 ms a push), the contact policy's single graph at
/// N = 30 in 8.2 instead of 11.2 ms, and one `/v1/forward` call at N = 30
/// in 11.6 instead of 14.9 ms (p50). Under many concurrent small calls two
/// single-threaded sessions keep more throughput (N = 15, 64 clients: 479
/// against 424 requests/s; N = 30 equal), hence `--session-threads 1`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SessionLayout {
    pub count: usize,
    pub threads: usize,
}

impl SessionLayout {
    /// One session using `cores` threads.
    pub fn shared(cores: usize) -> Self {
        Self {
            count: 1,
            threads: cores.max(1),
        }
    }
}

/// `n` single-threaded sessions.
impl From<usize> for SessionLayout {
    fn from(count: usize) -> Self {
        Self { count, threads: 1 }
    }
}

/// One model file and its sessions, behind a dynamic batcher.
pub struct ServedModel {
    /// File stem: `forward_gnn`, `policy_pointnet`, ...
    pub name: String,
    pub task: Task,
    pub file: PathBuf,
    /// What the model is and what it answers for, from its metadata.
    pub card: ModelCard,
    /// Sessions, each with its batching worker.
    pub sessions: usize,
    batcher: Batcher,
}

impl ServedModel {
    pub fn load(path: &Path, sessions: impl Into<SessionLayout>) -> Result<Self, InferError> {
        Self::load_with(path, sessions, BatchLimits::default())
    }

    /// Loads a model with a session layout (a batching worker per session)
    /// batching requests within `limits`.
    pub fn load_with(
        path: &Path,
        sessions: impl Into<SessionLayout>,
        limits: BatchLimits,
    ) -> Result<Self, InferError> {
        let mut spread: SessionLayout = sessions.into();
        if !matches!(init_backend(None)?, Backend::OnnxRuntime { .. }) {
            spread = (spread.count.max(1) * spread.threads.max(1)).into();
        }
        let bytes = std::fs::read(path).map_err(|e| InferError::Read {
            path: path.to_path_buf(),
            reason: e.to_string(),
        })?;
        let problem = |problem: LoadProblem| InferError::Load {
            path: path.to_path_buf(),
            problem,
        };
        let metadata = read_metadata(&bytes).map_err(|e| problem(LoadProblem::NotOnnx(e)))?;
        let layout = metadata
            .iter()
            .find(|(k, _)| k == "feature_layout_version")
            .map(|(_, v)| v.as_str());
        if layout != Some(FEATURE_LAYOUT_VERSION.to_string().as_str()) {
            return Err(problem(LoadProblem::FeatureLayout {
                found: layout.map(str::to_owned),
                expected: FEATURE_LAYOUT_VERSION,
            }));
        }
        // Before any session is made: a file without a card costs nothing.
        let card = ModelCard::from_metadata(&metadata).map_err(|e| problem(e.into()))?;
        let mut sessions = (0..spread.count.max(1))
            .map(|_| {
                OnnxModel::with_threads(&bytes, metadata.clone(), Some(spread.threads.max(1)))
                    .map_err(|e| match e {
                        InferError::Session(why) => problem(LoadProblem::Session(why)),
                        other => other,
                    })
            })
            .collect::<Result<Vec<_>, _>>()?;
        let task = sessions[0].task();
        for session in &mut sessions {
            canary(session, task, card.encoding)
                .map_err(|e| problem(LoadProblem::Canary(e.to_string())))?;
        }
        let name = path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        Ok(Self {
            card,
            sessions: sessions.len(),
            batcher: Batcher::start(&name, sessions, limits),
            name,
            task,
            file: path.to_path_buf(),
        })
    }

    /// Runs a batch through the model's queue (batched with other callers'
    /// jobs of the same size) and waits for its rows.
    pub fn run(&self, b: &treemanip_core::graph::Batch) -> Result<ModelOutput, InferError> {
        self.batcher.run(b.clone(), JobControl::default())
    }

    /// The model's queue, for callers that submit several jobs at once or
    /// attach a deadline.
    pub fn batcher(&self) -> &Batcher {
        &self.batcher
    }
}

/// Every session must answer a tiny inference (a three-node tree) with
/// finite outputs of the contract's shapes before it serves: a file that
/// loads but computes garbage (NaN weights, a wrong graph) is refused at
/// start-up instead of answering nonsense. The graph is the one the model
/// reads (`encoding`: the fully connected graph or the push's path).
fn canary(session: &mut OnnxModel, task: Task, encoding: Encoding) -> Result<(), InferError> {
    use treemanip_core::tree::Wood;
    let positions = vec![
        Point3::new(0.0, 0.0, 0.0),
        Point3::new(0.0, 0.0, 0.3),
        Point3::new(0.1, 0.0, 0.5),
    ];
    let parents = vec![None, Some(0), Some(1)];
    let wood = Wood::default();
    let length = |a: usize, b: usize| (positions[b] - positions[a]).norm();
    let branches = vec![
        None,
        Some(wood.branch(0.01, length(0, 1))),
        Some(wood.branch(0.005, length(1, 2))),
    ];
    let tree = Tree::new(positions, parents, branches).expect("the canary tree is valid");
    let graph = match task {
        Task::Forward => {
            let push = Vector3::new(0.0, 0.05, 0.0);
            match encoding {
                Encoding::Full => encode_forward(&tree, 2, &push),
                Encoding::Path | Encoding::PathRotation => {
                    encode_forward_path(&tree, 2, &push).map(|g| g.input)
                }
            }
        }
        Task::Policy => {
            let targets: Vec<_> = tree
                .positions()
                .iter()
                .map(|p| p + Vector3::new(0.0, 0.03, 0.0))
                .collect();
            encode_policy(&tree, &targets)
        }
    }?;
    let b = batch(&[graph])?;
    let out = session.run(&b)?;
    let finite = |v: &[f32]| v.iter().all(|x| x.is_finite());
    if out.vectors.len() != 9 || !finite(&out.vectors) {
        return Err(InferError::Run(format!(
            "expected 3 finite vectors, got {:?}",
            out.vectors
        )));
    }
    if task == Task::Policy
        && !out
            .affordance
            .as_deref()
            .is_some_and(|a| a.len() == 3 && finite(a))
    {
        return Err(InferError::Run(format!(
            "expected 3 finite affordances, got {:?}",
            out.affordance
        )));
    }
    Ok(())
}

/// Every model found in a directory.
pub struct ModelSet {
    pub backend: Backend,
    pub dir: PathBuf,
    pub models: Vec<ServedModel>,
    /// Files that failed to load (name, why), when broken files are
    /// skipped rather than fatal; they show as not ready.
    pub broken: Vec<(String, String)>,
}

impl ModelSet {
    /// Loads every `*.onnx` in `dir` (sorted by name). A file that cannot be
    /// loaded (missing, truncated, another feature layout) is an error that
    /// names it, or, with `skip_broken`, is listed in [`ModelSet::broken`].
    pub fn load_dir(
        dir: &Path,
        library: Option<&Path>,
        sessions: impl Into<SessionLayout>,
        skip_broken: bool,
    ) -> Result<Self, InferError> {
        Self::load_dir_with(dir, library, sessions, skip_broken, BatchLimits::default())
    }

    /// [`Self::load_dir`] with the batching limits of every model.
    pub fn load_dir_with(
        dir: &Path,
        library: Option<&Path>,
        sessions: impl Into<SessionLayout>,
        skip_broken: bool,
        limits: BatchLimits,
    ) -> Result<Self, InferError> {
        let backend = init_backend(library)?;
        let sessions = sessions.into();
        let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
            .map_err(|e| InferError::Read {
                path: dir.to_path_buf(),
                reason: e.to_string(),
            })?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|x| x == "onnx"))
            .collect();
        files.sort();
        let mut models = Vec::new();
        let mut broken = Vec::new();
        for path in &files {
            match ServedModel::load_with(path, sessions, limits) {
                Ok(model) => models.push(model),
                Err(e) if skip_broken => {
                    let name = path
                        .file_stem()
                        .map(|s| s.to_string_lossy().into_owned())
                        .unwrap_or_default();
                    broken.push((name, e.to_string()));
                }
                Err(e) => return Err(e),
            }
        }
        Ok(Self {
            backend,
            dir: dir.to_path_buf(),
            models,
            broken,
        })
    }

    pub fn get(&self, name: &str) -> Option<&ServedModel> {
        self.models.iter().find(|m| m.name == name)
    }

    /// The model that answers a task by default: for the forward model the
    /// path GNN where it is loaded (no size limit, error flat in the
    /// tree's size), else the paper's GNN; the GNN for the policy.
    pub fn default_for(&self, task: Task) -> Option<&ServedModel> {
        default_name(task).iter().find_map(|name| self.get(name))
    }
}

impl ModelSet {
    /// The forward model for a tree of `nodes` nodes: the paper's GNN up to
    /// the largest size its card says it is evaluated on (30 nodes, the
    /// paper's sizes, where the planner's evaluations were made with it;
    /// the held path model is now the more accurate there too,
    /// `models/README.md`), the path model for every other size, whichever
    /// is loaded otherwise.
    pub fn forward_for(&self, nodes: usize) -> Option<&ServedModel> {
        // Smaller trees too: the GNN's error shrinks with the size.
        let gnn = self
            .get("forward_gnn")
            .filter(|m| m.card.encoding == Encoding::Full && nodes <= m.card.domain.domain.nodes.1);
        gnn.or_else(|| self.default_for(Task::Forward))
    }
}

/// The names [`ModelSet::default_for`] tries, in order.
pub fn default_name(task: Task) -> &'static [&'static str] {
    match task {
        Task::Forward => &["forward_path", "forward_gnn"],
        Task::Policy => &["policy_gnn"],
    }
}

/// Predicted displacements Δp (m) per node, for each (contact node, push):
/// the fully connected graph's output as it is, or for a path model each
/// push's path graph (a few to a few dozen nodes, whatever the tree's
/// size) placed on the whole tree by forward kinematics.
pub fn predict_displacements(
    model: &ServedModel,
    tree: &Tree,
    actions: &[(usize, Vector3<f64>)],
    control: &JobControl,
) -> Result<Vec<Vec<Vector3<f64>>>, InferError> {
    let _timer = InferenceTimer::start(model);
    let vector = |v: &[f32]| Vector3::new(v[0] as f64, v[1] as f64, v[2] as f64);
    match model.card.encoding.path_output() {
        None => {
            let graphs = actions
                .iter()
                .map(|(node, push)| encode_forward(tree, *node, push))
                .collect::<Result<Vec<_>, _>>()?;
            let rows = run_in_chunks(model, graphs, control)?;
            Ok(rows
                .iter()
                .map(|r| r.chunks_exact(3).map(vector).collect())
                .collect())
        }
        Some(output) => {
            let paths = actions
                .iter()
                .map(|(node, push)| encode_forward_path(tree, *node, push))
                .collect::<Result<Vec<_>, _>>()?;
            let graphs: Vec<GraphInput> = paths.iter().map(|p| p.input.clone()).collect();
            let rows = run_in_chunks(model, graphs, control)?;
            Ok(paths
                .iter()
                .zip(&rows)
                .map(|(path, r)| {
                    path.held_positions(output, tree, r)
                        .iter()
                        .zip(tree.positions())
                        .map(|(a, b)| a - b)
                        .collect()
                })
                .collect())
        }
    }
}

/// Each graph's output rows (3 numbers per node), in the order given.
/// Chunks of at most [`MAX_BATCH`] graphs (fewer for large ones, see
/// [`super::batcher::MAX_PAIRS`]) are queued together, so the model's
/// sessions run them in parallel; a small call is split so that every
/// session gets a share (a planner's search round runs on all cores).
/// Graphs of different sizes (a path model's) are sorted by size and
/// chunked by [`size_chunks`], since a chunk is padded to its largest graph
/// and costs the square of it: 64 path graphs of a 500-node tree are 31
/// nodes at the median and 61 at most.
fn run_in_chunks(
    model: &ServedModel,
    graphs: Vec<GraphInput>,
    control: &JobControl,
) -> Result<Vec<Vec<f32>>, InferError> {
    let count = graphs.len();
    let most = MAX_BATCH.min(count.div_ceil(model.sessions.max(1))).max(1);
    let mut indexed: Vec<(usize, GraphInput)> = graphs.into_iter().enumerate().collect();
    indexed.sort_by_key(|(_, g)| g.n);
    let (order, sorted): (Vec<usize>, Vec<GraphInput>) = indexed.into_iter().unzip();
    let pending = size_chunks(sorted.iter().map(|g| g.n), most, super::batcher::MAX_PAIRS)
        .into_iter()
        .map(|range| {
            let chunk = &sorted[range];
            let b = batch(chunk)?;
            Ok((chunk, b.n, model.batcher.submit(b, control.clone())))
        })
        .collect::<Result<Vec<_>, InferError>>()?;
    let mut out = vec![Vec::new(); count];
    let mut at = order.iter();
    for (chunk, n, answer) in pending {
        let y = answer.wait()?;
        for (k, g) in chunk.iter().enumerate() {
            let slot = *at.next().expect("one slot per graph");
            out[slot] = y.vectors[k * n * 3..(k * n + g.n) * 3].to_vec();
        }
    }
    Ok(out)
}

/// Consecutive ranges of graphs, sizes ascending, each as long as its
/// padded batch (its count × its largest size squared) stays within
/// `max_pairs` node pairs and `most` graphs: small graphs share a batch,
/// large ones run a few at a time, and none is padded far beyond its size.
fn size_chunks(
    sizes: impl IntoIterator<Item = usize>,
    most: usize,
    max_pairs: usize,
) -> Vec<std::ops::Range<usize>> {
    let mut chunks: Vec<std::ops::Range<usize>> = Vec::new();
    for (k, n) in sizes.into_iter().enumerate() {
        match chunks.last_mut() {
            // The batcher's own rule for how many graphs of this size a
            // batch holds; sorted ascending, `n` is the chunk's largest.
            Some(last) if last.len() < super::batcher::graphs_per_batch(n, most, max_pairs) => {
                last.end = k + 1;
            }
            _ => chunks.push(k..k + 1),
        }
    }
    chunks
}

/// All non-root nodes ranked by affordance (renormalised over them, so
/// the root, which cannot be pushed, is never a candidate).
pub fn rank_candidates(
    model: &ServedModel,
    tree: &Tree,
    targets: &[Point3<f64>],
    control: &JobControl,
) -> Result<Vec<Candidate>, InferError> {
    let _timer = InferenceTimer::start(model);
    let g = encode_policy(tree, targets)?;
    let b = batch(std::slice::from_ref(&g))?;
    let y = model.batcher.run(b, control.clone())?;
    let affordance = y.affordance.ok_or_else(|| InferError::NotAPolicy {
        model: model.name.clone(),
    })?;
    let n = tree.len();
    let total: f64 = (1..n).map(|j| affordance[j] as f64).sum();
    let mut candidates: Vec<Candidate> = (1..n)
        .map(|j| Candidate {
            node: j,
            affordance: if total > 0.0 {
                affordance[j] as f64 / total
            } else {
                1.0 / (n - 1) as f64
            },
            push: [
                y.vectors[j * 3] as f64,
                y.vectors[j * 3 + 1] as f64,
                y.vectors[j * 3 + 2] as f64,
            ],
            rank: 0,
        })
        .collect();
    candidates.sort_by(|a, b| {
        b.affordance
            .total_cmp(&a.affordance)
            .then(a.node.cmp(&b.node))
    });
    for (k, c) in candidates.iter_mut().enumerate() {
        c.rank = k + 1;
    }
    Ok(candidates)
}

/// Records how long one call into a model took (queueing, batching and
/// running), as `treemanip_inference_seconds{model}`, whoever made the call:
/// a `/v1/forward` or `/v1/policy` request, or the planner's push search.
struct InferenceTimer<'a> {
    model: &'a ServedModel,
    started: std::time::Instant,
}

impl<'a> InferenceTimer<'a> {
    fn start(model: &'a ServedModel) -> Self {
        Self {
            model,
            started: std::time::Instant::now(),
        }
    }
}

impl Drop for InferenceTimer<'_> {
    fn drop(&mut self) {
        metrics::histogram!("treemanip_inference_seconds", "model" => self.model.name.clone())
            .record(self.started.elapsed().as_secs_f64());
    }
}

#[cfg(test)]
mod tests {
    use super::size_chunks;

    /// Small graphs share a chunk up to the pair budget; a larger one
    /// starts its own, and one over the budget still runs, alone.
    #[test]
    fn chunks_hold_sorted_graphs_within_the_pair_and_count_limits() {
        let sizes = [5, 5, 10, 10, 10, 30, 31, 40];
        assert_eq!(size_chunks(sizes, 64, 1000), vec![0..5, 5..6, 6..7, 7..8]);
        assert_eq!(
            size_chunks(sizes, 2, 1000),
            vec![0..2, 2..4, 4..5, 5..6, 6..7, 7..8]
        );
        assert!(size_chunks([], 64, 1000).is_empty());
    }
}
