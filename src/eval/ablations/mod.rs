//! The paper's Table I: which edge attributes and which connectivity the
//! forward GNN needs. Every variant is trained with the same recipe and the
//! same number of samples seen (the template [`TrainConfig`] with the
//! variant's edge attributes, connectivity and depth), then scored on the
//! test split like `treemanip eval forward` (mean e_N over the test sizes).
//!
//! The study spans sessions: each run is an ordinary resumable checkpoint
//! (`<dir>/<variant>-seed<k>/`), so [`run_study`] picks up the run in
//! progress and goes on until its deadline. A finished run is evaluated
//! once (its `result.json`), and its resumable state (the last weights and
//! the optimiser moments) is deleted, leaving the chosen weights
//! (`best.bpk`) and `state.json` to commit. Once every variant has a result,
//! the two whose errors are closest are trained again with a second seed,
//! to show whether their order is more than noise ([`seed_check`]).

mod report;

use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::{Deserialize, Serialize};

pub use self::report::{to_csv, to_markdown, write_figure};
use crate::dataset::{Split, read_size_file};
use crate::eval::learned::{forward_scores, mean_error};
use crate::infer::OnnxModel;
use crate::nn::gnn::{Connectivity, EdgeAttributes};
use crate::nn::train::checkpoint::{MODEL_FILE, OPTIMIZER_FILE};
use crate::nn::train::{
    ResumeOptions, STATE_FILE, StopReason, TrainConfig, TrainEvent, read_best, read_state, resume,
    train,
};

/// One row of Table I.
#[derive(Debug, Clone, PartialEq)]
pub struct Variant {
    /// Directory name and CSV key, e.g. `attributes-dp-ks`, `branches-10`.
    pub key: String,
    pub edge_attributes: EdgeAttributes,
    pub connectivity: Connectivity,
    pub layers: usize,
    /// The paper's e_N for it (cm).
    pub paper_cm: f64,
    /// A row of the edge-attribute half of the table.
    pub in_attribute_study: bool,
    /// A row of the connectivity half.
    pub in_connectivity_study: bool,
}

impl Variant {
    /// How the table names it: `[Δp, K_s]`, `branches only, 10 layers`.
    pub fn label(&self) -> String {
        let names = self.edge_attributes.names(true);
        let attributes = if names.is_empty() {
            "none".to_owned()
        } else {
            format!("[{}]", names.join(", "))
        };
        let connectivity = match self.connectivity {
            Connectivity::Full => "fully connected",
            Connectivity::Branches => "branches only",
        };
        format!("{attributes}, {connectivity}, {} layers", self.layers)
    }
}

/// The variants of Table I with the paper's numbers. `[Δp, v, K_s]`, fully
/// connected, 5 layers (ours) closes both halves and is trained once.
pub fn table_i() -> Vec<Variant> {
    let attributes = |delta_p, orientation, stiffness| EdgeAttributes {
        delta_p,
        orientation,
        stiffness,
    };
    let mut variants: Vec<Variant> = [
        (attributes(false, false, false), 11.0),
        (attributes(false, true, true), 6.7),
        (attributes(true, true, false), 3.8),
        (attributes(true, false, true), 2.6),
        (attributes(true, true, true), 2.3),
    ]
    .into_iter()
    .map(|(edge_attributes, paper_cm)| Variant {
        key: format!("attributes-{}", edge_attributes.label().replace('+', "-")),
        edge_attributes,
        connectivity: Connectivity::Full,
        layers: 5,
        paper_cm,
        in_attribute_study: true,
        in_connectivity_study: edge_attributes == EdgeAttributes::default(),
    })
    .collect();
    variants.extend(
        [(5, 4.7), (10, 3.9), (15, 4.3), (20, 4.4)].map(|(layers, paper_cm)| Variant {
            key: format!("branches-{layers}"),
            edge_attributes: EdgeAttributes::default(),
            connectivity: Connectivity::Branches,
            layers,
            paper_cm,
            in_attribute_study: false,
            in_connectivity_study: true,
        }),
    );
    variants
}

/// What the study trains and how it scores.
#[derive(Debug, Clone)]
pub struct StudyConfig {
    /// The recipe every run shares (task forward, GNN): epochs, batch,
    /// schedule, sizes, data. Each run sets its variant's edge attributes,
    /// connectivity and depth, and its seed.
    pub template: TrainConfig,
    /// Where the runs' checkpoints live (`training/ablations`).
    pub dir: PathBuf,
    /// Test sizes scored (the paper: 10…30).
    pub test_sizes: Vec<usize>,
    /// Test episodes per size (the first ones of each file).
    pub per_size: usize,
    /// Graphs per inference call.
    pub eval_batch: usize,
}

/// One trained and scored run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunResult {
    pub key: String,
    pub seed: u64,
    pub label: String,
    /// e_N (m) per test size.
    pub per_size: Vec<(usize, f64)>,
    /// Means over all test sizes, the training sizes and the others (m;
    /// absent when no test size is of that kind).
    pub mean: f64,
    pub mean_trained: Option<f64>,
    pub mean_zero_shot: Option<f64>,
    pub epochs: usize,
    pub samples: u64,
    pub minutes: f64,
    pub best_epoch: Option<usize>,
    pub cpus: Vec<String>,
}

/// A run of the study: a variant and a seed.
#[derive(Debug, Clone, PartialEq)]
pub struct Run {
    pub variant: Variant,
    pub seed: u64,
}

impl Run {
    pub fn dir(&self, study: &Path) -> PathBuf {
        study.join(format!("{}-seed{}", self.variant.key, self.seed))
    }
}

/// Where the study stands.
#[derive(Debug, Clone)]
pub struct StudyStatus {
    pub results: Vec<RunResult>,
    /// Runs not finished yet, in the order they will be trained (the
    /// second-seed runs appear once every variant has a result).
    pub remaining: Vec<Run>,
}

/// What the caller hears about.
pub enum StudyEvent<'a> {
    RunStart {
        run: &'a Run,
        index: usize,
        total: usize,
    },
    Train(TrainEvent<'a>),
    Evaluated(&'a RunResult),
}

const RESULT_FILE: &str = "result.json";

fn read_result(dir: &Path) -> Option<RunResult> {
    serde_json::from_str(&std::fs::read_to_string(dir.join(RESULT_FILE)).ok()?).ok()
}

/// The two variants (first seed) whose mean errors are closest, once every
/// variant has a result: they are run again with the next seed.
pub fn seed_check(results: &[RunResult], variants: &[Variant], seed: u64) -> Option<[String; 2]> {
    let first: Vec<&RunResult> = variants
        .iter()
        .map(|v| results.iter().find(|r| r.key == v.key && r.seed == seed))
        .collect::<Option<_>>()?;
    let mut best: Option<(f64, [String; 2])> = None;
    for (i, a) in first.iter().enumerate() {
        for b in &first[i + 1..] {
            let gap = (a.mean - b.mean).abs();
            if best.as_ref().is_none_or(|(g, _)| gap < *g) {
                best = Some((gap, [a.key.clone(), b.key.clone()]));
            }
        }
    }
    best.map(|(_, keys)| keys)
}

/// Every run of the study in order, with what is finished.
pub fn status(config: &StudyConfig) -> StudyStatus {
    let variants = table_i();
    let seed = config.template.seed;
    let mut runs: Vec<Run> = variants
        .iter()
        .map(|v| Run {
            variant: v.clone(),
            seed,
        })
        .collect();
    let results_of = |runs: &[Run]| -> Vec<RunResult> {
        runs.iter()
            .filter_map(|r| read_result(&r.dir(&config.dir)))
            .collect()
    };
    if let Some(keys) = seed_check(&results_of(&runs), &variants, seed) {
        runs.extend(
            variants
                .iter()
                .filter(|v| keys.contains(&v.key))
                .map(|v| Run {
                    variant: v.clone(),
                    seed: seed + 1,
                }),
        );
    }
    let results = results_of(&runs);
    let remaining = runs
        .into_iter()
        .filter(|r| {
            !results
                .iter()
                .any(|x| x.key == r.variant.key && x.seed == r.seed)
        })
        .collect();
    StudyStatus { results, remaining }
}

/// Trains and scores the runs still to do, in order, until `deadline`.
pub fn run_study(
    config: &StudyConfig,
    deadline: Option<Instant>,
    on_event: &mut dyn FnMut(StudyEvent),
) -> anyhow::Result<StudyStatus> {
    loop {
        let status = status(config);
        let total = status.results.len() + status.remaining.len();
        let Some(run) = status.remaining.first() else {
            return Ok(status);
        };
        if deadline.is_some_and(|d| Instant::now() >= d) {
            return Ok(status);
        }
        on_event(StudyEvent::RunStart {
            run,
            index: status.results.len(),
            total,
        });
        let dir = run.dir(&config.dir);
        let mut forward = |e: TrainEvent| on_event(StudyEvent::Train(e));
        let (state, reason) = if dir.join(STATE_FILE).exists() {
            same_budget(&read_state(&dir)?.config, &config.template, &dir)?;
            let options = ResumeOptions {
                data: Some(config.template.data.clone()),
                command: config.template.command.clone(),
                ..ResumeOptions::default()
            };
            resume(&dir, options, deadline, &mut forward)?
        } else {
            let template = &config.template;
            let train_config = TrainConfig {
                edge_attributes: run.variant.edge_attributes,
                connectivity: run.variant.connectivity,
                layers: run.variant.layers,
                seed: run.seed,
                ..template.clone()
            };
            train(train_config, &dir, deadline, &mut forward)?
        };
        if reason == StopReason::TimeBudget {
            return Ok(self::status(config));
        }
        let result = evaluate(config, run, &dir, &state)?;
        on_event(StudyEvent::Evaluated(&result));
        crate::nn::train::checkpoint::write_json(&dir.join(RESULT_FILE), &result)?;
        // Finished: only the chosen weights and the record are kept.
        for file in [MODEL_FILE, OPTIMIZER_FILE] {
            let _ = std::fs::remove_file(dir.join(file));
        }
    }
}

/// A run in progress must go on under the study's budget and recipe: a
/// different `--epochs` (say) in a later session would make the rows
/// incomparable.
fn same_budget(run: &TrainConfig, study: &TrainConfig, dir: &Path) -> anyhow::Result<()> {
    let recipe = |c: &TrainConfig| {
        (
            c.epochs,
            c.batch_size,
            c.sizes.clone(),
            c.limit_per_size,
            c.hidden,
            c.learning_rate.to_bits(),
            c.schedule,
            c.augment_rotation,
        )
    };
    anyhow::ensure!(
        recipe(run) == recipe(study),
        "{} was started with another budget or recipe ({} epochs, batch {}, sizes {:?}, limit {:?}, hidden {}); continue the study with the settings it started with",
        dir.display(),
        run.epochs,
        run.batch_size,
        run.sizes,
        run.limit_per_size,
        run.hidden
    );
    Ok(())
}

/// Scores a finished run's chosen weights on the test split, through the
/// same ONNX export and evaluation as the shipped models.
fn evaluate(
    config: &StudyConfig,
    run: &Run,
    dir: &Path,
    state: &crate::nn::train::TrainState,
) -> anyhow::Result<RunResult> {
    let weights = read_best(dir)?;
    let bytes = weights.to_onnx(&[]);
    let mut models = vec![(
        run.variant.key.clone(),
        OnnxModel::from_bytes(&bytes, Vec::new())?,
    )];
    let mut scores = Vec::new();
    for &n in &config.test_sizes {
        let path = config.template.data.join(Split::Test.file_name(n));
        let data = read_size_file(&path, Split::Test)
            .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
        scores.extend(
            forward_scores(&data, &mut models, config.per_size, config.eval_batch)?
                .into_iter()
                .filter(|s| s.method == run.variant.key),
        );
    }
    let key = &run.variant.key;
    let trained = &state.config.sizes;
    let among = |which: &dyn Fn(usize) -> bool| {
        scores
            .iter()
            .any(|s| which(s.n))
            .then(|| mean_error(&scores, key, which))
    };
    Ok(RunResult {
        key: key.clone(),
        seed: run.seed,
        label: run.variant.label(),
        per_size: scores.iter().map(|s| (s.n, s.error)).collect(),
        mean: mean_error(&scores, key, |_| true),
        mean_trained: among(&|n| trained.contains(&n)),
        mean_zero_shot: among(&|n| !trained.contains(&n)),
        epochs: state.epoch,
        samples: state.samples,
        minutes: state.seconds / 60.0,
        best_epoch: state.best.map(|b| b.0),
        cpus: state.cpus.clone(),
    })
}
