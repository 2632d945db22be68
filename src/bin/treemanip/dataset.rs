//! `treemanip dataset …`

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, bail};
use clap::{Args, Subcommand};
use serde::{Deserialize, Serialize};
use treemanip::dataset::collect::{CollectConfig, SizeStats, collect_size};
use treemanip::dataset::shard::{FileJob, Shard, assign};
use treemanip::dataset::{Split, read_size_file, write_size_file};
use treemanip::sim::{ContactModel, GRIP_OFFSET, Hold};
use treemanip::tree::StiffnessVariation;
use treemanip::tree::collection::TreeShape;
use treemanip::tree::render::{Arrow, Figure, Layer};

use crate::trees::{NodeSizes, parse_sizes};

#[derive(Subcommand)]
pub enum DatasetCommand {
    /// Simulate push episodes on generated trees and write one .npz per
    /// split and size (default: the paper's split, 51,000 episodes).
    Collect(CollectArgs),
    /// Join the shards of a sharded collection (`collect --shard I/N`) into
    /// one dataset directory: the same files and summary.json as one run.
    Merge(MergeArgs),
    /// Draw episodes of a dataset file as SVG: the tree before (light) and
    /// after (dark) the push, and the push as a red arrow.
    Render(RenderArgs),
}

#[derive(Args)]
pub struct CollectArgs {
    /// Output directory (created if missing).
    #[arg(long)]
    out: PathBuf,
    /// Base seed: trees, pushes and files are a function of it.
    #[arg(long, default_value_t = 7)]
    seed: u64,
    /// Tree sizes of the training split.
    #[arg(long, default_value = "11,13,15,17,19", value_parser = parse_sizes)]
    train_sizes: NodeSizes,
    /// Episodes per training size.
    #[arg(long, default_value_t = 6000)]
    train_episodes: usize,
    /// Tree sizes of the test split.
    #[arg(long, default_value = "10..=30", value_parser = parse_sizes)]
    test_sizes: NodeSizes,
    /// Episodes per test size.
    #[arg(long, default_value_t = 1000)]
    test_episodes: usize,
    /// Distinct trees per split and size.
    #[arg(long, default_value_t = 100)]
    trees_per_size: usize,
    /// Contact model: `slot` or `pinned`.
    #[arg(long, default_value = "slot")]
    contact: ContactModel,
    /// Tree shape: `sca` (the paper's), `orchard` (leader, scaffolds and
    /// laterals at the paper's spacing), `mixed` (both, alternating),
    /// `crop` (N nodes cut around one deep path of a 100-500-node orchard
    /// tree) or `all` (the three in turn).
    #[arg(long, default_value = "sca")]
    shape: TreeShape,
    /// Vary each branch's stiffness away from the radius formula by a
    /// log-normal factor exp(ε), ε ~ N(0, σ²) (0: the paper's data; 0.5 for
    /// stiffness-aware models; see `tree::stiffness`).
    #[arg(long, default_value_t = 0.0)]
    stiffness_sigma: f64,
    /// Multiply each tree's stiffness by one factor, log-uniform in
    /// [1/G, G] (1: none).
    #[arg(long, default_value_t = 1.0)]
    stiffness_global: f64,
    /// Collect only shard INDEX of COUNT (`0/4`): whole files, balanced
    /// over the shards, plus `shard-INDEX-of-COUNT.json`; join the shards
    /// with `dataset merge`.
    #[arg(long, conflicts_with = "shards")]
    shard: Option<Shard>,
    /// Shard count, the index read from JOB_COMPLETION_INDEX (a
    /// Kubernetes Indexed Job's pods).
    #[arg(long)]
    shards: Option<usize>,
}

#[derive(Args)]
pub struct MergeArgs {
    /// The dataset directory to complete (summary.json is written here).
    #[arg(long)]
    out: PathBuf,
    /// Directories holding the shards' files (default: --out itself, as
    /// when every shard wrote to one shared volume).
    #[arg(long = "from")]
    from: Vec<PathBuf>,
}

#[derive(Args)]
pub struct RenderArgs {
    /// A dataset file, e.g. `data/test_N15.npz`.
    file: PathBuf,
    /// Episode indices to draw: `0,1,2` or `0..5`.
    #[arg(long, default_value = "0..4", value_parser = parse_sizes)]
    episodes: NodeSizes,
    /// Output directory for `episode_<k>.svg`.
    #[arg(long)]
    out: PathBuf,
}

/// `summary.json`: a function of the configuration only (no timings), so
/// two runs, or a run and its merged shards, write the same bytes.
#[derive(Clone, Serialize, Deserialize, PartialEq)]
struct Summary {
    generator: String,
    config: CollectConfig,
    train_episodes: usize,
    test_episodes: usize,
    files: Vec<SizeStats>,
}

/// `shard-I-of-N.json`: one shard's part of the summary, and the whole
/// collection's file list, so `merge` can check that nothing is missing.
#[derive(Serialize, Deserialize)]
struct ShardSummary {
    shard: Shard,
    jobs: Vec<FileJob>,
    summary: Summary,
}

pub fn run(cmd: DatasetCommand) -> anyhow::Result<()> {
    match cmd {
        DatasetCommand::Collect(args) => collect(args),
        DatasetCommand::Merge(args) => merge(args),
        DatasetCommand::Render(args) => render(args),
    }
}

fn shard_of(args: &CollectArgs) -> anyhow::Result<Option<Shard>> {
    match (args.shard, args.shards) {
        (Some(shard), _) => Ok(Some(shard)),
        (None, None) => Ok(None),
        (None, Some(count)) => {
            let index = std::env::var("JOB_COMPLETION_INDEX")
                .context("--shards needs JOB_COMPLETION_INDEX (or give --shard INDEX/COUNT)")?;
            let index: usize = index
                .parse()
                .with_context(|| format!("JOB_COMPLETION_INDEX={index:?} is not an index"))?;
            Ok(Some(Shard::new(index, count).map_err(anyhow::Error::msg)?))
        }
    }
}

fn collect(args: CollectArgs) -> anyhow::Result<()> {
    let config = CollectConfig {
        seed: args.seed,
        trees_per_size: args.trees_per_size,
        contact: args.contact,
        shape: args.shape,
        stiffness: StiffnessVariation {
            branch_log_sigma: args.stiffness_sigma,
            global_factor: args.stiffness_global,
        },
        ..CollectConfig::default()
    };
    config
        .stiffness
        .validate()
        .map_err(|e| anyhow::anyhow!("--stiffness-sigma/--stiffness-global: {e}"))?;
    let shard = shard_of(&args)?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create {}", args.out.display()))?;
    let all: Vec<FileJob> = args
        .train_sizes
        .0
        .iter()
        .map(|&n| (Split::Train, n, args.train_episodes))
        .chain(
            args.test_sizes
                .0
                .iter()
                .map(|&n| (Split::Test, n, args.test_episodes)),
        )
        .filter(|job| job.2 > 0)
        .map(|(split, n, episodes)| FileJob { split, n, episodes })
        .collect();
    if all.is_empty() {
        bail!("nothing to collect: every split has 0 episodes");
    }
    let mine: Vec<FileJob> = match shard {
        None => all.clone(),
        Some(shard) => all
            .iter()
            .zip(assign(&all, shard.count))
            .filter(|&(_, s)| s == shard.index)
            .map(|(j, _)| *j)
            .collect(),
    };
    let total: usize = mine.iter().map(|j| j.episodes).sum();
    let bar = crate::progress::bar(total as u64, "episodes");
    let start = Instant::now();
    let mut files = Vec::new();
    for job in &mine {
        let name = job.split.file_name(job.n);
        bar.set_message(name.clone());
        let (data, stats) = collect_size(job.split, job.n, job.episodes, &config, &|| bar.inc(1))
            .with_context(|| format!("collecting {name}"))?;
        write_size_file(&data, &args.out.join(&name))?;
        files.push(stats);
    }
    bar.finish_and_clear();
    let seconds = start.elapsed().as_secs_f64();
    let summary = Summary {
        generator: concat!("treemanip ", env!("CARGO_PKG_VERSION")).to_owned(),
        config,
        train_episodes: args.train_episodes,
        test_episodes: args.test_episodes,
        files,
    };
    print_summary(&summary);
    println!(
        "{total} episodes in {seconds:.1} s ({:.0} kept episodes/s)",
        total as f64 / seconds
    );
    let written = match shard {
        None => write_json(&args.out.join("summary.json"), &summary)?,
        Some(shard) => {
            if summary.files.is_empty() {
                println!("shard {shard} has no file to collect (more shards than files)");
            }
            write_json(
                &args.out.join(shard.file_name()),
                &ShardSummary {
                    shard,
                    jobs: all,
                    summary,
                },
            )?
        }
    };
    println!(
        "wrote {} files and {} to {}",
        mine.len(),
        written,
        args.out.display()
    );
    Ok(())
}

/// Writes `value` as pretty JSON; returns the file's name.
fn write_json(path: &std::path::Path, value: &impl Serialize) -> anyhow::Result<String> {
    std::fs::write(path, serde_json::to_string_pretty(value)? + "\n")
        .with_context(|| format!("cannot write {}", path.display()))?;
    Ok(path
        .file_name()
        .map(|f| f.to_string_lossy().into_owned())
        .unwrap_or_default())
}

fn merge(args: MergeArgs) -> anyhow::Result<()> {
    let sources = if args.from.is_empty() {
        vec![args.out.clone()]
    } else {
        args.from.clone()
    };
    // Every shard summary in the sources, with the directory holding it.
    let mut shards: Vec<(PathBuf, ShardSummary)> = Vec::new();
    for dir in &sources {
        let entries =
            std::fs::read_dir(dir).with_context(|| format!("cannot read {}", dir.display()))?;
        for entry in entries {
            let path = entry?.path();
            let name = path.file_name().unwrap_or_default().to_string_lossy();
            if name.starts_with("shard-") && name.ends_with(".json") {
                let text = std::fs::read_to_string(&path)?;
                let shard: ShardSummary = serde_json::from_str(&text)
                    .with_context(|| format!("{} is not a shard summary", path.display()))?;
                shards.push((dir.clone(), shard));
            }
        }
    }
    let Some((_, first)) = shards.first() else {
        bail!("no shard-*.json in {sources:?}: run `dataset collect --shard I/N` first");
    };
    let count = first.shard.count;
    let jobs = first.jobs.clone();
    for (dir, s) in &shards {
        if s.shard.count != count
            || s.jobs != jobs
            || s.summary.config != first.summary.config
            || s.summary.train_episodes != first.summary.train_episodes
            || s.summary.test_episodes != first.summary.test_episodes
        {
            bail!(
                "{}/{} belongs to another collection than shard {} (different settings or count)",
                dir.display(),
                s.shard.file_name(),
                first.shard
            );
        }
    }
    for index in 0..count {
        match shards
            .iter()
            .filter(|(_, s)| s.shard.index == index)
            .count()
        {
            1 => {}
            0 => bail!("shard {index}/{count} is missing"),
            k => bail!("shard {index}/{count} appears {k} times"),
        }
    }
    std::fs::create_dir_all(&args.out)?;
    // The files in the one-run order, each copied from its shard's
    // directory when that is not --out.
    let mut files = Vec::new();
    for job in &jobs {
        let (dir, stats) = shards
            .iter()
            .find_map(|(dir, s)| {
                s.summary
                    .files
                    .iter()
                    .find(|f| f.split == job.split && f.n == job.n)
                    .map(|f| (dir, f))
            })
            .with_context(|| format!("no shard collected {}", job.split.file_name(job.n)))?;
        let name = job.split.file_name(job.n);
        let (from, to) = (dir.join(&name), args.out.join(&name));
        if !from.exists() {
            bail!(
                "{} is missing (its shard's summary lists it)",
                from.display()
            );
        }
        if from != to {
            std::fs::copy(&from, &to)
                .with_context(|| format!("copying {} to {}", from.display(), to.display()))?;
        }
        files.push(stats.clone());
    }
    let summary = Summary {
        files,
        ..first.summary.clone()
    };
    write_json(&args.out.join("summary.json"), &summary)?;
    print_summary(&summary);
    println!(
        "merged {count} shards ({} files) into {}",
        jobs.len(),
        args.out.display()
    );
    Ok(())
}

fn print_summary(summary: &Summary) {
    println!(
        "{:<13} {:>7} {:>9} {:>8} {:>10} {:>8} {:>12} {:>12} {:>7}",
        "file",
        "kept",
        "discarded",
        "lost",
        "out_reach",
        "fork",
        "no-action m",
        "max disp m",
        "iters"
    );
    for s in &summary.files {
        println!(
            "{:<13} {:>7} {:>9} {:>8} {:>10} {:>8} {:>12.4} {:>12.4} {:>7.2}",
            format!("{}_N{}", s.split.name(), s.n),
            s.kept,
            s.discarded_total(),
            s.discarded.get("lost_branch").unwrap_or(&0),
            s.discarded.get("out_of_reach").unwrap_or(&0),
            s.caught_at_fork,
            s.no_action_error,
            s.max_displacement,
            s.mean_iterations
        );
    }
    let kept: usize = summary.files.iter().map(|s| s.kept).sum();
    let discarded: usize = summary.files.iter().map(|s| s.discarded_total()).sum();
    println!(
        "{kept} episodes kept, {discarded} pushes discarded ({:.1} %)",
        100.0 * discarded as f64 / (kept + discarded).max(1) as f64,
    );
}

fn render(args: RenderArgs) -> anyhow::Result<()> {
    let name = args
        .file
        .file_name()
        .map(|f| f.to_string_lossy().into_owned())
        .unwrap_or_default();
    let split = if name.starts_with("train") {
        Split::Train
    } else {
        Split::Test
    };
    let data = read_size_file(&args.file, split)?;
    std::fs::create_dir_all(&args.out)?;
    for &k in &args.episodes.0 {
        let Some(episode) = data.episodes.get(k) else {
            bail!(
                "{name} has {} episodes; there is no episode {k}",
                data.episodes.len()
            );
        };
        let tree = data.tree_of(episode);
        let node = episode.push.node;
        let axis = tree.branch_direction(node).expect("non-root contact");
        let grip = tree.position(node) - axis * GRIP_OFFSET;
        let figure = Figure {
            title: format!(
                "{name} episode {k}: node {node} pushed {:.1} cm{}",
                100.0 * episode.push.vector.norm(),
                match episode.hold {
                    Hold::AtNode => " (held at the node)",
                    Hold::AtBase => " (held at the base fork)",
                    Hold::OnAxis => "",
                }
            ),
            layers: vec![
                Layer {
                    colour: "#c9b79c".to_owned(),
                    label_nodes: false,
                    ..Layer::rest(tree)
                },
                Layer {
                    positions: episode.final_positions.clone(),
                    ..Layer::rest(tree)
                },
            ],
            arrows: vec![Arrow {
                from: grip,
                to: grip + episode.push.vector,
                colour: "#d62728".to_owned(),
            }],
            ..Figure::default()
        };
        let path = args.out.join(format!("episode_{k}.svg"));
        std::fs::write(&path, figure.to_svg())?;
        println!("wrote {}", path.display());
    }
    Ok(())
}

/// The `config` that `dataset collect` recorded in the directory's
/// summary.json, with the sizes and episode counts of its files added
/// (`train_sizes`, `test_sizes`, `train_episodes`, `test_episodes`).
pub(crate) fn dataset_config(dir: &std::path::Path) -> Option<serde_json::Value> {
    let text = std::fs::read_to_string(dir.join("summary.json")).ok()?;
    let mut v: serde_json::Value = serde_json::from_str(&text).ok()?;
    let mut config = v.get_mut("config")?.take();
    for split in ["train", "test"] {
        let sizes: Vec<u64> = v["files"]
            .as_array()
            .into_iter()
            .flatten()
            .filter(|f| f["split"] == split)
            .filter_map(|f| f["n"].as_u64())
            .collect();
        config[format!("{split}_sizes")] = serde_json::json!(sizes);
        config[format!("{split}_episodes")] = v[format!("{split}_episodes")].clone();
    }
    Some(config)
}

/// The `dataset collect` command that regenerates the data recorded by
/// `config` (see [`dataset_config`]): the seed and every option that
/// differs from the default (stiffness perturbations, contact, trees per
/// size, shape, sizes and episodes).
pub(crate) fn dataset_command(config: &serde_json::Value) -> Option<String> {
    let mut command = format!(
        "treemanip dataset collect --out DIR --seed {}",
        config["seed"].as_u64()?
    );
    let sigma = config["stiffness"]["branch_log_sigma"]
        .as_f64()
        .unwrap_or(0.0);
    if sigma != 0.0 {
        command += &format!(" --stiffness-sigma {sigma}");
    }
    let global = config["stiffness"]["global_factor"].as_f64().unwrap_or(1.0);
    if global != 1.0 {
        command += &format!(" --stiffness-global {global}");
    }
    if let Some(contact) = config["contact"].as_str().filter(|c| *c != "slot") {
        command += &format!(" --contact {contact}");
    }
    if let Some(n) = config["trees_per_size"].as_u64().filter(|n| *n != 100) {
        command += &format!(" --trees-per-size {n}");
    }
    if let Some(shape) = config["shape"].as_str().filter(|s| *s != "sca") {
        command += &format!(" --shape {shape}");
    }
    // The sizes and episode counts where they are not the defaults.
    let defaults = [
        ("train", vec![11, 13, 15, 17, 19], 6000),
        ("test", (10..=30).collect::<Vec<u64>>(), 1000),
    ];
    for (split, sizes, episodes) in defaults {
        let recorded: Vec<u64> = config[format!("{split}_sizes")]
            .as_array()
            .into_iter()
            .flatten()
            .filter_map(|n| n.as_u64())
            .collect();
        if !recorded.is_empty() && recorded != sizes {
            let list: Vec<String> = recorded.iter().map(u64::to_string).collect();
            command += &format!(" --{split}-sizes {}", list.join(","));
        }
        if let Some(e) = config[format!("{split}_episodes")]
            .as_u64()
            .filter(|e| *e != episodes)
        {
            command += &format!(" --{split}-episodes {e}");
        }
    }
    Some(command)
}
