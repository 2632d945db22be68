//! `treemanip train` and `treemanip export`.

use crate::dataset::{dataset_command, dataset_config};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};
use treemanip::graph::path::Encoding;

use anyhow::Context;
use clap::{Args, ValueEnum};
use treemanip::graph::{FEATURE_LAYOUT_VERSION, Task};
use treemanip::model::card::{DomainRecord, ModelCard, TrainingData, TrainingRun};
use treemanip::model::domain;
use treemanip::nn::gnn::{Connectivity, EdgeAttributes};
use treemanip::nn::model::Arch;
use treemanip::nn::train::data::training_span;
use treemanip::nn::train::{
    ResumeOptions, Schedule, StopReason, TrainConfig, TrainEvent, TurnWeight, read_best,
    read_state, resume, train,
};

use crate::progress;
use crate::trees::{NodeSizes, parse_sizes};

#[derive(Clone, Copy, ValueEnum)]
pub enum TaskArg {
    Forward,
    Policy,
}

impl From<TaskArg> for Task {
    fn from(t: TaskArg) -> Task {
        match t {
            TaskArg::Forward => Task::Forward,
            TaskArg::Policy => Task::Policy,
        }
    }
}

#[derive(Clone, Copy, ValueEnum)]
pub enum ArchArg {
    Gnn,
    Pointnet,
}

#[derive(Clone, Copy, ValueEnum)]
pub enum ConnectivityArg {
    Full,
    Branches,
}

#[derive(Clone, Copy, ValueEnum)]
enum ScheduleArg {
    Cosine,
    Plateau,
}

#[derive(Args)]
pub struct TrainArgs {
    /// Which model: the forward model or the contact policy.
    #[arg(value_enum)]
    task: TaskArg,
    #[arg(long, value_enum, default_value = "gnn")]
    arch: ArchArg,
    /// Dataset directory (`treemanip dataset collect --out DIR`).
    #[arg(long)]
    data: PathBuf,
    /// Checkpoint directory (created; must be new unless --resume).
    #[arg(long)]
    out: PathBuf,
    /// Continue the checkpoint in --out exactly where it stopped (every
    /// other setting comes from it; --epochs re-plans, --minutes and
    /// --data still apply).
    #[arg(long)]
    resume: bool,
    /// Training tree sizes (the paper: 11,13,15,17,19).
    #[arg(long, value_parser = parse_sizes, default_value = "11,13,15,17,19")]
    sizes: NodeSizes,
    /// Use at most this many episodes per size.
    #[arg(long)]
    limit_per_size: Option<usize>,
    /// Planned epochs (default 120; the cosine schedule spans them).
    #[arg(long)]
    epochs: Option<usize>,
    /// Wall-clock budget: stop (with a resumable checkpoint) after this many minutes.
    #[arg(long)]
    minutes: Option<f64>,
    #[arg(long, default_value_t = 128)]
    batch_size: usize,
    /// Initial learning rate.
    #[arg(long, default_value_t = 1e-3)]
    lr: f64,
    /// Final learning rate (cosine) or floor (plateau).
    #[arg(long, default_value_t = 1e-5)]
    min_lr: f64,
    /// Learning-rate schedule.
    #[arg(long, value_enum, default_value = "cosine")]
    schedule: ScheduleArg,
    /// Do not turn examples about the vertical axis (on by default).
    #[arg(long)]
    no_rotation: bool,
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// GNN: graph2graph layers.
    #[arg(long, default_value_t = 5)]
    layers: usize,
    /// GNN: embedding width.
    #[arg(long, default_value_t = 128)]
    hidden: usize,
    /// GNN: edge attributes used, e.g. dp+v+ks (all), dp+ks, v+ks, none.
    #[arg(long, default_value = "dp+v+ks")]
    edge_attributes: EdgeAttributes,
    /// GNN: message passing over all node pairs or only along branches.
    #[arg(long, value_enum, default_value = "full")]
    connectivity: ConnectivityArg,
    /// GNN forward model: `full` (the paper: the whole tree in, Δp per
    /// node out), `path_rotation` (the push's root-to-contact path in, each
    /// path branch's turn out, every node placed by forward kinematics; no
    /// size limit; exported as `forward_path`) or `path` (the same graph,
    /// Δp per graph node out: the first path model's).
    #[arg(long, default_value = "full")]
    encoding: Encoding,
    /// GNN: start from this checkpoint directory's best weights
    /// (fine-tuning), carried over to the current feature layout; the
    /// architecture (--layers, --hidden, --connectivity) and normalisation
    /// come from it, --edge-attributes still applies (an ablation may drop
    /// a group the source used).
    #[arg(long)]
    init_from: Option<PathBuf>,
    /// `--encoding path_rotation`: what each path branch's squared turn
    /// error is weighed by: `uniform`, `reach` (how far the turn reaches in
    /// the training tree) or `radius` (the branch's; by the pipe model, how
    /// much tree it carries where it grew), each squared over its mean.
    #[arg(long, default_value = "uniform")]
    turn_weight: TurnWeight,
}

pub fn train_cmd(args: TrainArgs) -> anyhow::Result<()> {
    treemanip::nn::train::keep_freed_pages();
    let task: Task = args.task.into();
    let arch = match args.arch {
        ArchArg::Gnn => Arch::Gnn,
        ArchArg::Pointnet => Arch::PointNet,
    };
    let mut config = TrainConfig::paper(task, arch, args.data.clone());
    config.sizes = args.sizes.0.clone();
    config.limit_per_size = args.limit_per_size;
    if let Some(epochs) = args.epochs {
        config.epochs = epochs;
    }
    config.batch_size = args.batch_size;
    config.learning_rate = args.lr;
    config.min_learning_rate = args.min_lr;
    config.schedule = match args.schedule {
        ScheduleArg::Cosine => Schedule::Cosine,
        ScheduleArg::Plateau => Schedule::Plateau,
    };
    config.augment_rotation = !args.no_rotation;
    config.seed = args.seed;
    config.layers = args.layers;
    config.hidden = args.hidden;
    config.edge_attributes = args.edge_attributes;
    config.encoding = args.encoding;
    config.turn_weight = args.turn_weight;
    anyhow::ensure!(
        config.encoding == Encoding::Full || (task == Task::Forward && arch == Arch::Gnn),
        "--encoding path and path_rotation are for the GNN forward model"
    );
    config.connectivity = match args.connectivity {
        ConnectivityArg::Full => Connectivity::Full,
        ConnectivityArg::Branches => Connectivity::Branches,
    };
    if let Some(dir) = &args.init_from {
        anyhow::ensure!(arch == Arch::Gnn, "--init-from carries GNN weights over");
        let source = treemanip::nn::train::finetune::source_state(dir)?;
        anyhow::ensure!(
            source.config.task == task && source.config.arch == arch,
            "{} holds a {} {} model, not a {} {} one",
            dir.display(),
            source.config.task.name(),
            source.config.arch.name(),
            task.name(),
            arch.name()
        );
        config.layers = source.config.layers;
        config.hidden = source.config.hidden;
        config.connectivity = source.config.connectivity;
        config.init_from = Some(dir.clone());
    }
    config.command = std::env::args().collect::<Vec<_>>().join(" ");
    anyhow::ensure!(config.batch_size > 0, "--batch-size must be positive");
    anyhow::ensure!(config.epochs > 0, "--epochs must be positive");
    let deadline = args
        .minutes
        .map(|m| Instant::now() + Duration::from_secs_f64(m.max(0.0) * 60.0));
    let mut bar = progress::bar(0, "batches");
    let mut on_event = |event: TrainEvent| match event {
        TrainEvent::EpochStart {
            epoch,
            batches,
            done,
        } => {
            bar = progress::bar(batches as u64, "batches");
            bar.set_prefix(format!("epoch {epoch}"));
            bar.set_position(done as u64);
        }
        TrainEvent::Step { loss } => {
            bar.inc(1);
            bar.set_message(format!("loss {loss:.4}"));
        }
        TrainEvent::EpochEnd(r) => {
            bar.finish_and_clear();
            let accuracy = r
                .validation_accuracy
                .map(|a| format!(", contact accuracy {:.1} %", 100.0 * a))
                .unwrap_or_default();
            eprintln!(
                "epoch {:>3}: train loss {:.4}, validation loss {:.4}, error {:.2} cm{accuracy} (lr {:.1e}, {:.0} samples/s)",
                r.epoch,
                r.train_loss,
                r.validation_loss,
                100.0 * r.validation_error,
                r.learning_rate,
                r.samples_per_second
            );
        }
    };
    let (state, reason) = if args.resume {
        let options = ResumeOptions {
            epochs: args.epochs,
            data: Some(args.data.clone()),
            command: config.command.clone(),
        };
        resume(&args.out, options, deadline, &mut on_event)?
    } else {
        train(config, &args.out, deadline, &mut on_event)?
    };
    bar.finish_and_clear();
    let best = state
        .best
        .map(|(e, s)| format!("best validation score {s:.5} at epoch {e}"))
        .unwrap_or_else(|| "no epoch finished yet".to_owned());
    match reason {
        StopReason::Finished => eprintln!(
            "finished {} epochs in {:.1} min; {best}",
            state.epoch,
            state.seconds / 60.0
        ),
        StopReason::TimeBudget => eprintln!(
            "time budget reached at epoch {} batch {} ({:.1} min trained); {best}; continue with --resume",
            state.epoch,
            state.batch,
            state.seconds / 60.0
        ),
    }
    Ok(())
}

#[derive(Args)]
pub struct TrainFoliageArgs {
    #[arg(long, default_value_t = 7)]
    seed: u64,
    #[arg(long, default_value_t = 12)]
    epochs: usize,
    /// Hidden width of the perceptron.
    #[arg(long, default_value_t = 32)]
    hidden: usize,
    /// At most this many cubes from each training scan.
    #[arg(long, default_value_t = 4000)]
    per_scan: usize,
    /// Stages after the first, each looking again with the stage before's
    /// calls of the cubes around.
    #[arg(long, default_value_t = 1)]
    context_stages: usize,
    #[arg(long, default_value = "models/foliage.json")]
    out: PathBuf,
}

pub fn train_foliage_cmd(args: TrainFoliageArgs) -> anyhow::Result<()> {
    use treemanip::nn::train::foliage::{FoliageConfig, train_foliage};
    let command = format!(
        "treemanip train-foliage --seed {} --epochs {} --hidden {} --per-scan {} --context-stages {} --out {}",
        args.seed,
        args.epochs,
        args.hidden,
        args.per_scan,
        args.context_stages,
        args.out.display()
    );
    let config = FoliageConfig {
        seed: args.seed,
        epochs: args.epochs,
        hidden: args.hidden,
        per_scan: args.per_scan,
        context_stages: args.context_stages,
        batch: 1024,
        learning_rate: 1e-3,
        command,
    };
    let started = std::time::Instant::now();
    let classifier = train_foliage(&config, |stage, epoch, loss| {
        eprintln!("stage {stage} epoch {epoch}: loss {loss:.4}");
    })?;
    eprintln!(
        "{} cubes, {:.0} s; held out (test split, one leafy view, 3 mm): leaf points found {:.3}, bark points lost {:.3}",
        classifier.card.examples,
        started.elapsed().as_secs_f64(),
        classifier.card.held_out_leaf_found,
        classifier.card.held_out_bark_lost
    );
    std::fs::write(&args.out, serde_json::to_string(&classifier)? + "\n")?;
    eprintln!("wrote {}", args.out.display());
    Ok(())
}

#[derive(Args)]
pub struct ExportArgs {
    /// Checkpoint directories (`treemanip train --out DIR`); each one's best
    /// weights become `<task>_<arch>.onnx`.
    #[arg(required = true)]
    checkpoints: Vec<PathBuf>,
    /// Output directory.
    #[arg(long, default_value = "models")]
    out: PathBuf,
}

fn git_commit() -> String {
    std::process::Command::new("git")
        .args(["rev-parse", "HEAD"])
        .output()
        .ok()
        .filter(|o| o.status.success())
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_owned())
        .unwrap_or_else(|| "unknown".to_owned())
}

pub fn export_cmd(args: ExportArgs) -> anyhow::Result<()> {
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    for dir in &args.checkpoints {
        let path = export_one(dir, &args.out)?;
        println!("{}", path.display());
    }
    Ok(())
}

/// The recorded command with the program shown as `treemanip`, wherever
/// the binary was run from.
fn command_line(recorded: &str) -> String {
    match recorded.split_once(' ') {
        Some((_, rest)) => format!("treemanip {rest}"),
        None => recorded.to_owned(),
    }
}

fn export_one(dir: &Path, out: &Path) -> anyhow::Result<PathBuf> {
    let state = read_state(dir)?;
    anyhow::ensure!(
        state.config.arch == Arch::PointNet
            || state.config.feature_layout == FEATURE_LAYOUT_VERSION,
        "{} was trained on feature layout {} and the server reads layout {}: fine-tune it with `treemanip train ... --init-from {}` and export that run",
        dir.display(),
        state.config.feature_layout,
        FEATURE_LAYOUT_VERSION,
        dir.display()
    );
    let weights = read_best(dir)?;
    let best_epoch = state.best.map(|b| b.0);
    let best_record = state
        .history
        .iter()
        .find(|r| Some(r.epoch) == best_epoch)
        .cloned();
    let stats = match &weights {
        treemanip::nn::model::ModelWeights::Gnn(w) => &w.stats,
        treemanip::nn::model::ModelWeights::PointNet(w) => &w.stats,
    };
    let (out_mean, out_std) = weights.output_scale();
    let dataset = dataset_config(&state.config.data);
    let card = ModelCard {
        name: weights.stem(),
        task: weights.task(),
        arch: weights.arch().name().into(),
        architecture: weights.describe(),
        feature_layout_version: FEATURE_LAYOUT_VERSION,
        normalisation: serde_json::json!({"inputs": stats, "output_mean": out_mean, "output_std": out_std}),
        training_data: TrainingData {
            directory: state.config.data.display().to_string(),
            dataset_seed: dataset.as_ref().and_then(|c| c["seed"].as_u64()),
            regenerate: dataset.as_ref().and_then(dataset_command),
            sizes: state.config.sizes.clone(),
            limit_per_size: state.config.limit_per_size,
            validation: "trees with index ≡ 9 (mod 10) in each size file".into(),
        },
        training_command: command_line(&state.config.command),
        training_commands: state.commands.iter().map(|c| command_line(c)).collect(),
        training_config: serde_json::to_value(&state.config)?,
        seed: state.config.seed,
        git_commit: git_commit(),
        training: TrainingRun {
            epochs: state.epoch,
            planned_epochs: state.config.epochs,
            recipe: serde_json::json!({
                "schedule": state.config.schedule,
                "learning_rate": state.config.learning_rate,
                "min_learning_rate": state.config.min_learning_rate,
                "batch_size": state.config.batch_size,
                "grad_clip": state.config.grad_clip,
                "augment_rotation": state.config.augment_rotation,
            }),
            minutes: state.seconds / 60.0,
            samples: state.samples,
            samples_per_second: state.samples as f64 / state.seconds.max(1e-9),
            cpus: state.cpus.clone(),
            best_epoch,
        },
        validation: serde_json::to_value(&best_record)?,
        units: "SI: metres, N·m/rad".into(),
        domain: domain_record(&state.config.data, &state.config.sizes, weights.encoding())?,
        encoding: weights.encoding(),
    };
    let bytes = weights.to_onnx(&card.to_metadata());
    let path = out.join(format!("{}.onnx", weights.stem()));
    std::fs::write(&path, bytes).with_context(|| format!("writing {}", path.display()))?;
    Ok(path)
}

#[derive(Args)]
pub struct DomainArgs {
    /// ONNX models to annotate (rewritten in place).
    #[arg(required = true)]
    models: Vec<PathBuf>,
    /// The dataset they were trained on (`treemanip dataset collect`).
    #[arg(long)]
    data: PathBuf,
}

/// The domain of a model trained on `sizes` of `data`, as its card records it.
fn domain_record(data: &Path, sizes: &[usize], encoding: Encoding) -> anyhow::Result<DomainRecord> {
    let span = training_span(data, sizes)?;
    let mut domain = span.domain(domain::Margin::STANDARD, domain::EVALUATED_NODES);
    if encoding.is_path() {
        // No size limit: the model reads the path, whatever the tree.
        domain.nodes = (treemanip::tree::MIN_NODES, treemanip::tree::MAX_NODES);
        domain.encoding = encoding;
    }
    Ok(DomainRecord {
        domain,
        margin: domain::Margin::STANDARD,
        trained_sizes: sizes.to_vec(),
    })
}

pub fn domain_cmd(args: DomainArgs) -> anyhow::Result<()> {
    for path in &args.models {
        let bytes = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
        let metadata = treemanip::infer::read_metadata(&bytes)
            .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
        let config: serde_json::Value = metadata
            .iter()
            .find(|(k, _)| k == "training_config")
            .and_then(|(_, v)| serde_json::from_str(v).ok())
            .with_context(|| format!("{}: no training_config in its metadata", path.display()))?;
        let sizes: Vec<usize> = serde_json::from_value(config["sizes"].clone())
            .with_context(|| format!("{}: training_config has no sizes", path.display()))?;
        let entry = (
            "domain".to_owned(),
            serde_json::to_string(&domain_record(
                &args.data,
                &sizes,
                serde_json::from_value(config["encoding"].clone()).unwrap_or_default(),
            )?)?,
        );
        let out = treemanip::nn::onnx::with_metadata(&bytes, std::slice::from_ref(&entry))
            .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
        std::fs::write(path, out).with_context(|| format!("writing {}", path.display()))?;
        println!("{}: {}", path.display(), entry.1);
    }
    Ok(())
}

#[derive(Args)]
pub struct EvalLearnedArgs {
    /// Directory with the ONNX models (`<task>_gnn.onnx`, `<task>_pointnet.onnx`).
    #[arg(long, default_value = "models")]
    models: PathBuf,
    /// Dataset directory with `test_N<n>.npz` (`<n>` the tree size).
    #[arg(long)]
    data: PathBuf,
    /// Where the table (CSV, Markdown, JSON) and the figure (SVG) go.
    #[arg(long, default_value = "docs/results")]
    out: PathBuf,
    #[arg(long, value_parser = parse_sizes, default_value = "10..=30")]
    sizes: NodeSizes,
    /// Test episodes per size (the paper: 1000).
    #[arg(long, default_value_t = 1000)]
    per_size: usize,
    /// Graphs per inference call.
    #[arg(long, default_value_t = 32)]
    batch_size: usize,
    /// Native ONNX Runtime library (default: $ORT_DYLIB_PATH, else tract).
    #[arg(long, env = "ORT_DYLIB_PATH")]
    ort_dylib: Option<PathBuf>,
    /// Seed of the Random baseline.
    #[arg(long, default_value_t = 0)]
    seed: u64,
}

pub fn eval_learned(task: Task, args: EvalLearnedArgs) -> anyhow::Result<()> {
    use treemanip::dataset::{Split, read_size_file};
    use treemanip::eval::learned::{
        forward_scores, mean_error, policy_scores, task_title, to_csv, to_markdown,
    };
    use treemanip::infer::{OnnxModel, init_backend};
    let backend = init_backend(args.ort_dylib.as_deref())?;
    let mut models = Vec::new();
    let mut trained: Vec<usize> = Vec::new();
    for (arch, label) in [("gnn", "GNN"), ("pointnet", "PointNet")] {
        let path = args.models.join(format!("{}_{arch}.onnx", task.name()));
        if !path.exists() {
            eprintln!("note: {} not found, skipped", path.display());
            continue;
        }
        let model = OnnxModel::load(&path)?;
        anyhow::ensure!(
            model.task() == task,
            "{} is not a {} model",
            path.display(),
            task.name()
        );
        if let Ok(card) = ModelCard::from_metadata(&model.metadata) {
            trained.extend(card.training_data.sizes);
        }
        models.push((label.to_owned(), model));
    }
    trained.sort_unstable();
    trained.dedup();
    eprintln!("backend: {backend:?}; models: {}", models.len());
    let bar = progress::bar(args.sizes.0.len() as u64, "sizes");
    let started = Instant::now();
    let mut scores = Vec::new();
    for &n in &args.sizes.0 {
        let path = args.data.join(Split::Test.file_name(n));
        let data = read_size_file(&path, Split::Test)
            .map_err(|e| anyhow::anyhow!("reading {}: {e}", path.display()))?;
        let s = match task {
            Task::Forward => forward_scores(&data, &mut models, args.per_size, args.batch_size)?,
            Task::Policy => policy_scores(
                &data,
                &mut models,
                args.per_size,
                args.batch_size,
                args.seed,
            )?,
        };
        bar.set_message(format!("N={n}"));
        bar.inc(1);
        scores.extend(s);
    }
    bar.finish_and_clear();
    std::fs::create_dir_all(&args.out)?;
    let stem = format!("{}_eval", task.name());
    std::fs::write(args.out.join(format!("{stem}.csv")), to_csv(&scores))?;
    let markdown = to_markdown(&scores, &trained);
    std::fs::write(args.out.join(format!("{stem}.md")), &markdown)?;
    std::fs::write(
        args.out.join(format!("{stem}.json")),
        serde_json::to_string_pretty(&serde_json::json!({
            "task": task.name(),
            "backend": format!("{backend:?}"),
            "episodes_per_size": args.per_size,
            "trained_sizes": trained,
            "seconds": started.elapsed().as_secs_f64(),
            "scores": scores,
        }))?,
    )?;
    let svg = args.out.join(format!("{stem}.svg"));
    treemanip::eval::plots::error_by_size_svg(&scores, task_title(task), &trained, &svg)
        .map_err(|e| anyhow::anyhow!("drawing {}: {e}", svg.display()))?;
    println!("{markdown}");
    for m in treemanip::eval::learned::methods(&scores) {
        eprintln!(
            "{m}: mean e_N {:.2} cm",
            100.0 * mean_error(&scores, &m, |_| true)
        );
    }
    eprintln!(
        "wrote {}/{stem}.{{csv,md,json,svg}} in {:.1} s",
        args.out.display(),
        started.elapsed().as_secs_f64()
    );
    Ok(())
}
