//! `treemanip eval ranks`: the paper's Fig. 8.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, bail};
use clap::Args;
use treemanip::dataset::Split;
use treemanip::dataset::collect::{CollectConfig, collect_size};
use treemanip::eval::plots::{affordance_by_rank_svg, error_by_rank_svg};
use treemanip::eval::ranks::{errors, rank_outcomes, summarise, to_markdown};

use crate::plan::{gnns, load_models};

#[derive(Args)]
pub struct EvalRanksArgs {
    /// Tree size (the paper: 15).
    #[arg(long, default_value_t = 15)]
    n: usize,
    /// Test episodes (the paper: 100).
    #[arg(long, default_value_t = 100)]
    episodes: usize,
    #[command(flatten)]
    data: crate::args::EvalData,
    /// Where to write rank_eval.{md,json} and fig8_*.svg.
    #[arg(long, default_value = "docs/results")]
    out: PathBuf,
}

pub fn eval_ranks(args: EvalRanksArgs) -> anyhow::Result<()> {
    if args.episodes == 0 {
        bail!("--episodes must be at least 1");
    }
    let started = Instant::now();
    let config = CollectConfig {
        seed: args.data.seed,
        ..CollectConfig::default()
    };
    let (data, _) = collect_size(Split::Test, args.n, args.episodes, &config, &|| {})
        .with_context(|| format!("simulating test episodes of {} nodes", args.n))?;
    let set = load_models(&args.data.models_dir)?;
    let (policy, _) = gnns(&set);
    let bar = crate::progress::bar(data.episodes.len() as u64, "episodes");
    let mut outcomes = Vec::new();
    let mut no_action = (0.0, 0.0);
    for episode in &data.episodes {
        let tree = data.tree_of(episode);
        outcomes.push(rank_outcomes(policy, tree, episode)?);
        let (max, mean) = errors(tree.positions(), &episode.final_positions);
        no_action.0 += max;
        no_action.1 += mean;
        bar.inc(1);
    }
    bar.finish_and_clear();
    let k = data.episodes.len() as f64;
    no_action = (no_action.0 / k, no_action.1 / k);
    let rows = summarise(&outcomes);
    std::fs::create_dir_all(&args.out)?;
    let table = to_markdown(&rows, no_action);
    let md = format!(
        "# Executing every rank of the contact policy (the paper's Fig. 8)\n\n`treemanip eval ranks --n {} --episodes {} --seed {}`: test episodes of {} nodes, target = the episode's final shape; every candidate the policy ranks is pushed with its own action in the simulator (arm ignored). Errors are means over episodes of the largest and of the mean node distance to the target. Figures: `fig8_error_by_rank.svg`, `fig8_affordance_by_rank.svg`.\n\n{table}",
        args.n, args.episodes, args.data.seed, args.n
    );
    std::fs::write(args.out.join("rank_eval.md"), &md)?;
    std::fs::write(
        args.out.join("rank_eval.json"),
        serde_json::to_string_pretty(&serde_json::json!({
            "n": args.n, "episodes": args.episodes, "seed": args.data.seed,
            "no_action": { "max_error": no_action.0, "mean_error": no_action.1 },
            "ranks": rows, "outcomes": outcomes,
        }))?,
    )?;
    let title = format!("N = {}, {} test episodes", args.n, args.episodes);
    let figure = args.out.join("fig8_error_by_rank.svg");
    error_by_rank_svg(
        &rows,
        no_action,
        &format!("Error by executed rank, {title}"),
        &figure,
    )
    .map_err(|e| anyhow::anyhow!("cannot draw {}: {e}", figure.display()))?;
    let figure = args.out.join("fig8_affordance_by_rank.svg");
    affordance_by_rank_svg(&rows, &format!("Affordance by rank, {title}"), &figure)
        .map_err(|e| anyhow::anyhow!("cannot draw {}: {e}", figure.display()))?;
    println!("{table}");
    println!(
        "wrote {}/rank_eval.{{md,json}} and fig8_*.svg in {:.1} s",
        args.out.display(),
        started.elapsed().as_secs_f64()
    );
    Ok(())
}
