//! `treemanip eval sizes`: forward models' error and cost against the
//! tree's size ([`treemanip::eval::sizes`]).

use std::path::PathBuf;
use std::time::Instant;

use clap::Args;
use treemanip::eval::learned::Score;
use treemanip::eval::sizes::{
    SizeRow, linear_row, model_row, no_action_row, simulated, test_set, to_markdown,
};
use treemanip::infer::init_backend;
use treemanip::infer::models::{ServedModel, SessionLayout};
use treemanip::tree::collection::TreeShape;
use treemanip::tree::sca::MAX_SCA_NODES;

use crate::trees::{NodeSizes, parse_sizes};

#[derive(Args)]
pub struct EvalSizesArgs {
    /// Directory with the forward models (`forward_path.onnx`,
    /// `forward_gnn.onnx`; whichever are there).
    #[arg(long, default_value = "models")]
    models: PathBuf,
    /// Where `sizes_eval.{md,json,svg}` go.
    #[arg(long, default_value = "docs/results")]
    out: PathBuf,
    /// Tree sizes (orchard trees at every size, SCA trees up to 64).
    #[arg(long, value_parser = parse_sizes, default_value = "10,20,30,60,100,200,300,500")]
    sizes: NodeSizes,
    /// Distinct trees per size and shape.
    #[arg(long, default_value_t = 8)]
    trees: usize,
    /// Pushes per size and shape.
    #[arg(long, default_value_t = 96)]
    episodes: usize,
    /// Base seed of the test trees and pushes (not the training data's 7).
    #[arg(long, default_value_t = 1001)]
    seed: u64,
    /// Timed repetitions of the one-push prediction (a quarter as many of 64).
    #[arg(long, default_value_t = 24)]
    timing_runs: usize,
    /// Native ONNX Runtime library (default: the embedded one, else tract).
    #[arg(long, env = "ORT_DYLIB_PATH")]
    ort_dylib: Option<PathBuf>,
}

pub fn eval_sizes(args: EvalSizesArgs) -> anyhow::Result<()> {
    let started = Instant::now();
    let backend = init_backend(args.ort_dylib.as_deref())?;
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let mut models = Vec::new();
    for (stem, label) in [("forward_path", "path GNN"), ("forward_gnn", "GNN")] {
        let path = args.models.join(format!("{stem}.onnx"));
        if !path.exists() {
            eprintln!("note: {} not found, skipped", path.display());
            continue;
        }
        models.push((
            label,
            ServedModel::load(&path, SessionLayout::shared(cores))?,
        ));
    }
    let mut rows: Vec<SizeRow> = Vec::new();
    let mut sims = Vec::new();
    for shape in [TreeShape::Sca, TreeShape::Orchard] {
        for &n in &args.sizes.0 {
            if shape == TreeShape::Sca && n > MAX_SCA_NODES {
                continue;
            }
            let data = test_set(shape, n, args.trees, args.episodes, args.seed)?;
            let (sim, facts) = simulated(shape, &data);
            for (label, model) in &models {
                if let Some(row) = model_row(label, model, shape, &data, &facts, args.timing_runs)?
                {
                    eprintln!(
                        "{shape:?} N={n} {label}: e_N {:.2} cm, one push {:.2} ms, 64 pushes {:.2} ms",
                        row.error * 100.0,
                        row.one_push_ms.unwrap_or(f64::NAN),
                        row.batch_64_ms.unwrap_or(f64::NAN)
                    );
                    rows.push(row);
                }
            }
            rows.push(linear_row(shape, &data, &facts));
            rows.push(no_action_row(shape, &data, &facts));
            sims.push(sim);
        }
    }
    std::fs::create_dir_all(&args.out)?;
    let markdown = to_markdown(&rows, &sims);
    std::fs::write(args.out.join("sizes_eval.md"), &markdown)?;
    std::fs::write(
        args.out.join("sizes_eval.json"),
        serde_json::to_string_pretty(&serde_json::json!({
            "backend": format!("{backend:?}"),
            "cpu": treemanip::nn::train::checkpoint::cpu_model(),
            "cores": cores,
            "seed": args.seed,
            "trees_per_size": args.trees,
            "episodes_per_size": args.episodes,
            "seconds": started.elapsed().as_secs_f64(),
            "rows": rows,
            "simulate": sims,
            "command": std::env::args().collect::<Vec<_>>().join(" "),
        }))?,
    )?;
    let scores: Vec<Score> = rows
        .iter()
        .map(|r| Score {
            method: format!("{} ({:?} trees)", r.method, r.shape).to_lowercase(),
            n: r.n,
            episodes: r.episodes,
            error: r.error,
            rejected: 0,
        })
        .collect();
    let svg = args.out.join("sizes_eval.svg");
    treemanip::eval::plots::error_by_size_svg(
        &scores,
        "Forward models: e_N against the tree's size (held-out trees)",
        &[],
        &svg,
    )
    .map_err(|e| anyhow::anyhow!("drawing {}: {e}", svg.display()))?;
    println!("{markdown}");
    eprintln!(
        "wrote {}/sizes_eval.{{md,json,svg}} in {:.1} s",
        args.out.display(),
        started.elapsed().as_secs_f64()
    );
    Ok(())
}
