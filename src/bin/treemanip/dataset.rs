//! `treemanip dataset …`

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, bail};
use clap::{Args, Subcommand};
use serde::Serialize;
use treemanip::dataset::collect::{CollectConfig, SizeStats, collect_size};
use treemanip::dataset::{Split, read_size_file, write_size_file};
use treemanip::sim::{ContactModel, GRIP_OFFSET, Hold};
use treemanip::tree::render::{Arrow, Figure, Layer};

use crate::trees::{NodeSizes, parse_sizes};

#[derive(Subcommand)]
pub enum DatasetCommand {
    /// Simulate push episodes on generated trees and write one .npz per
    /// split and size (default: the paper's split, 51,000 episodes).
    Collect(CollectArgs),
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

#[derive(Serialize)]
struct Summary {
    generator: &'static str,
    config: CollectConfig,
    train_episodes: usize,
    test_episodes: usize,
    files: Vec<SizeStats>,
    seconds: f64,
    kept_per_second: f64,
}

pub fn run(cmd: DatasetCommand) -> anyhow::Result<()> {
    match cmd {
        DatasetCommand::Collect(args) => collect(args),
        DatasetCommand::Render(args) => render(args),
    }
}

fn collect(args: CollectArgs) -> anyhow::Result<()> {
    let config = CollectConfig {
        seed: args.seed,
        trees_per_size: args.trees_per_size,
        contact: args.contact,
        ..CollectConfig::default()
    };
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create {}", args.out.display()))?;
    let jobs: Vec<(Split, usize, usize)> = args
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
        .collect();
    let total: usize = jobs.iter().map(|j| j.2).sum();
    if total == 0 {
        bail!("nothing to collect: every split has 0 episodes");
    }
    let bar = crate::progress::bar(total as u64, "episodes");
    let start = Instant::now();
    let mut files = Vec::new();
    for (split, n, episodes) in jobs {
        bar.set_message(split.file_name(n));
        let (data, stats) = collect_size(split, n, episodes, &config, &|| bar.inc(1))
            .with_context(|| format!("collecting {}", split.file_name(n)))?;
        let path = args.out.join(split.file_name(n));
        write_size_file(&data, &path)?;
        files.push(stats);
    }
    bar.finish_and_clear();
    let seconds = start.elapsed().as_secs_f64();
    let summary = Summary {
        generator: concat!("treemanip ", env!("CARGO_PKG_VERSION")),
        config,
        train_episodes: args.train_episodes,
        test_episodes: args.test_episodes,
        kept_per_second: total as f64 / seconds,
        files,
        seconds,
    };
    std::fs::write(
        args.out.join("summary.json"),
        serde_json::to_string_pretty(&summary)?,
    )?;
    print_summary(&summary);
    println!(
        "wrote {} files and summary.json to {}",
        summary.files.len(),
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
        "{kept} episodes kept, {discarded} pushes discarded ({:.1} %), {:.1} s, {:.0} kept episodes/s",
        100.0 * discarded as f64 / (kept + discarded).max(1) as f64,
        summary.seconds,
        summary.kept_per_second
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
                if episode.hold == Hold::AtNode {
                    " (held at the node)"
                } else {
                    ""
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
        };
        let path = args.out.join(format!("episode_{k}.svg"));
        std::fs::write(&path, figure.to_svg())?;
        println!("wrote {}", path.display());
    }
    Ok(())
}
