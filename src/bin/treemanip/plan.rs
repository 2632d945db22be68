//! `treemanip plan` and `treemanip eval plan`.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, bail};
use clap::Args;
use nalgebra::{Isometry3, Vector3};
use serde::Serialize;
use treemanip::dataset::Split;
use treemanip::dataset::collect::{CollectConfig, collect_size};
use treemanip::eval::plan::{ORACLE_GREEDY, evaluate, summarise};
use treemanip::eval::plots::rank_histogram_svg;
use treemanip::robot::collision::CollisionModel;
use treemanip::robot::plan::{PlanOptions, PushCandidate, plan_push};
use treemanip::robot::{Ur5, ur5};

use crate::args::{TreePush, parse_numbers, parse_vector};
use crate::trees::{NodeSizes, parse_sizes};

#[derive(Args)]
pub struct PlanArgs {
    #[command(flatten)]
    target: TreePush,
    /// Start joint configuration (rad), six comma-separated values.
    /// Default: the paper's home pose.
    #[arg(long, value_parser = parse_numbers::<6>, allow_hyphen_values = true)]
    start: Option<[f64; 6]>,
    /// Arm base position `X,Y,Z` (m), identity orientation. Default: the
    /// paper's (−0.5, 0, 0.1).
    #[arg(long, value_parser = parse_vector, allow_hyphen_values = true)]
    base: Option<Vector3<f64>>,
    /// RRT* seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Print the whole plan (trajectory included) as JSON.
    #[arg(long)]
    json: bool,
}

#[derive(Serialize)]
struct PlanJson<'a> {
    status: &'static str,
    joint_names: [&'static str; 6],
    #[serde(flatten)]
    report: &'a treemanip::robot::plan::PlanReport,
}

pub fn plan(args: PlanArgs) -> anyhow::Result<()> {
    let tree = args.target.load_tree()?;
    let base = args
        .base
        .map_or_else(ur5::default_base, |b| Isometry3::translation(b.x, b.y, b.z));
    let model = CollisionModel::new(Ur5::default().with_base(base));
    let mut options = PlanOptions::default();
    options.rrt.seed = args.seed;
    let start = args.start.unwrap_or(ur5::HOME);
    let candidate = PushCandidate {
        node: args.target.node,
        push: args.target.push,
    };
    let report = plan_push(&model, &tree, &[candidate], &start, &options).context("cannot plan")?;
    if args.json {
        let json = PlanJson {
            status: if report.plan.is_some() {
                "planned"
            } else {
                "no_plan"
            },
            joint_names: ur5::JOINT_NAMES,
            report: &report,
        };
        println!("{}", serde_json::to_string_pretty(&json)?);
        return Ok(());
    }
    for a in &report.attempts {
        println!(
            "candidate {} (node {}): {:?} in {:.1} ms",
            a.rank, a.node, a.outcome, a.ms
        );
    }
    match &report.plan {
        Some(p) => {
            let end = p.trajectory.last().map_or(0.0, |t| t.t);
            let push_start = p.trajectory[p.push_start_index].t;
            println!(
                "planned: {} trajectory points, approach {:.2} s, push {:.2} s (starts at index {}), planning {:.1} ms",
                p.trajectory.len(),
                push_start,
                end - push_start,
                p.push_start_index,
                report.total_ms
            );
        }
        None => println!("no plan ({:.1} ms)", report.total_ms),
    }
    Ok(())
}

#[derive(Args)]
pub struct EvalPlanArgs {
    /// Tree sizes.
    #[arg(long, default_value = "10..=30", value_parser = parse_sizes)]
    sizes: NodeSizes,
    /// Episodes per size (test split, as `dataset collect` makes them).
    #[arg(long, default_value_t = 100)]
    per_size: usize,
    /// Dataset seed.
    #[arg(long, default_value_t = 7)]
    seed: u64,
    /// Where to write plan_eval.json, plan_eval.csv and plan_rank_histogram.svg.
    #[arg(long, default_value = "docs/results")]
    out: PathBuf,
}

pub fn eval_plan(args: EvalPlanArgs) -> anyhow::Result<()> {
    if args.per_size == 0 {
        bail!("--per-size must be at least 1");
    }
    let started = Instant::now();
    let config = CollectConfig {
        seed: args.seed,
        ..CollectConfig::default()
    };
    let mut data = Vec::new();
    for &n in &args.sizes.0 {
        let (size, _) = collect_size(Split::Test, n, args.per_size, &config, &|| {})
            .with_context(|| format!("simulating test episodes of {n} nodes"))?;
        data.push(size);
    }
    let episodes: Vec<_> = data
        .iter()
        .flat_map(|d| d.episodes.iter().map(move |e| (d.n, d.tree_of(e), e)))
        .collect();
    let model = CollisionModel::new(Ur5::default());
    let bar = crate::progress::bar(episodes.len() as u64, "episodes");
    let results = evaluate(
        &model,
        &episodes,
        &ur5::HOME,
        &PlanOptions::default(),
        &|| bar.inc(1),
    );
    bar.finish_and_clear();
    let summary = summarise(&results);
    std::fs::create_dir_all(&args.out)?;
    std::fs::write(
        args.out.join("plan_eval.json"),
        serde_json::to_string_pretty(&summary)?,
    )?;
    let mut csv = String::from("n,episodes,planned,success_rate,median_ms\n");
    for (n, total, ok, rate, ms) in &summary.per_size {
        csv.push_str(&format!("{n},{total},{ok},{rate:.4},{ms:.2}\n"));
    }
    std::fs::write(args.out.join("plan_eval.csv"), csv)?;
    let figure = args.out.join("plan_rank_histogram.svg");
    rank_histogram_svg(
        &summary.rank_histogram,
        summary.episodes,
        &format!(
            "Algorithm 1: planned rank, {} episodes, {:.1} % planned",
            summary.episodes,
            100.0 * summary.success_rate
        ),
        &figure,
        15,
    )
    .map_err(|e| anyhow::anyhow!("cannot draw {}: {e}", figure.display()))?;

    println!("candidate ranking: {ORACLE_GREEDY}");
    println!(
        "{:>4} {:>9} {:>8} {:>9} {:>10}",
        "N", "episodes", "planned", "success", "median ms"
    );
    for (n, total, ok, rate, ms) in &summary.per_size {
        println!(
            "{n:>4} {total:>9} {ok:>8} {:>8.1}% {ms:>10.1}",
            100.0 * rate
        );
    }
    println!(
        "all: {}/{} planned ({:.1} %, paper 82.9 %); planning time p50 {:.1} ms, p95 {:.1} ms, max {:.1} ms",
        summary.planned,
        summary.episodes,
        100.0 * summary.success_rate,
        summary.ms_p50,
        summary.ms_p95,
        summary.ms_max
    );
    let top = summary.rank_histogram.get(&1).copied().unwrap_or(0);
    println!(
        "planned at rank 1: {:.1} % of episodes (paper 22.9 % with its learned policy); outcomes of tried candidates: {:?}",
        100.0 * top as f64 / summary.episodes as f64,
        summary.outcomes
    );
    println!(
        "wrote {}/plan_eval.{{json,csv}} and {} in {:.1} s",
        args.out.display(),
        figure.display(),
        started.elapsed().as_secs_f64()
    );
    Ok(())
}
