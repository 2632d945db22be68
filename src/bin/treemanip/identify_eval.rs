//! `treemanip eval identify` and `treemanip eval stiffness`.

use std::path::PathBuf;

use anyhow::Context;
use clap::Args;
use treemanip::dataset::{Split, read_size_file};
use treemanip::eval::identify::{run_study, standard_settings, to_markdown};
use treemanip::tree::Tree;

use crate::progress;
use crate::trees::{NodeSizes, parse_sizes};

#[derive(Args)]
pub struct EvalIdentifyArgs {
    /// Dataset directory whose `test_N<n>.npz` trees are used (their
    /// stiffness is the radius formula's: `dataset collect` without
    /// `--stiffness-sigma`).
    #[arg(long)]
    data: PathBuf,
    #[arg(long, value_parser = parse_sizes, default_value = "10,15,20,25,30")]
    sizes: NodeSizes,
    /// Trees per size.
    #[arg(long, default_value_t = 8)]
    trees_per_size: usize,
    #[arg(long, default_value = "docs/results")]
    out: PathBuf,
    /// File stem of the report in `--out` (`NAME.md`, `.json`, `.svg`).
    #[arg(long, default_value = "identify")]
    name: String,
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Models for the closed-loop study (`policy_gnn.onnx`, `forward_gnn.onnx`).
    #[arg(long, default_value = "models")]
    models: PathBuf,
    /// Trees per size of the closed-loop study (0: skip it).
    #[arg(long, default_value_t = 10)]
    closed_loop_trees_per_size: usize,
}

/// The first `count` trees of each test size file.
pub fn test_trees(
    data: &std::path::Path,
    sizes: &[usize],
    count: usize,
) -> anyhow::Result<Vec<Tree>> {
    let mut trees = Vec::new();
    for &n in sizes {
        let path = data.join(Split::Test.file_name(n));
        let file = read_size_file(&path, Split::Test)
            .map_err(|e| anyhow::anyhow!("reading {}: {e}", path.display()))?;
        trees.extend(file.trees.into_iter().take(count).map(|(_, t)| t));
    }
    Ok(trees)
}

pub fn eval_identify(args: EvalIdentifyArgs) -> anyhow::Result<()> {
    let trees = test_trees(&args.data, &args.sizes.0, args.trees_per_size)?;
    let settings = standard_settings();
    let bar = progress::bar(settings.len() as u64, "settings");
    let mut results = Vec::new();
    for (k, setting) in settings.iter().enumerate() {
        bar.set_message(setting.label());
        let mut one = run_study(&trees, std::slice::from_ref(setting), args.seed + k as u64);
        results.append(&mut one);
        bar.inc(1);
    }
    bar.finish_and_clear();
    let mut table = to_markdown(&results);
    println!("{table}");
    if args.closed_loop_trees_per_size > 0 {
        let set = crate::plan::load_models(&args.models)?;
        let (policy, forward) = (
            set.get("policy_gnn").expect("checked"),
            set.get("forward_gnn").expect("checked"),
        );
        let planner = treemanip::planner::Planner::default();
        let loop_trees = test_trees(&args.data, &args.sizes.0, args.closed_loop_trees_per_size)?;
        table += "\n## Closed loop: `/v1/plan` with the first push's observation\n\nPhysics strategy, the evaluation's base region; the target is where a random paper-style push that passes the arm's reach test moves the true tree; the second plan gets the first push's held positions (3 mm noise) as `observations`, identifies the stiffness from them and plans again from rest, searching the first push again (`treemanip::eval::closed_loop`). `reproduced` keeps the targets the planner on the true stiffness reaches within 2 cm; the others are targets no path or straight push reaches, whatever the stiffness.\n\n";
        table += treemanip::eval::closed_loop::HEADER;
        for sigma in [0.3, 0.5] {
            let bar = progress::bar(loop_trees.len() as u64, "trees");
            bar.set_message(format!("closed loop σ={sigma}"));
            let outcomes = treemanip::eval::closed_loop::run_study(
                &planner,
                policy,
                forward,
                &loop_trees,
                sigma,
                args.seed,
                || bar.inc(1),
            );
            bar.finish_and_clear();
            if std::env::var_os("TREEMANIP_DEBUG_LOOP").is_some() {
                for o in &outcomes {
                    eprintln!("{o:?}");
                }
            }
            let t = treemanip::eval::closed_loop::to_markdown(sigma, &outcomes);
            println!("{t}");
            table += &t;
        }
    }
    std::fs::create_dir_all(&args.out)?;
    let sizes_arg = args
        .sizes
        .0
        .iter()
        .map(|n| n.to_string())
        .collect::<Vec<_>>()
        .join(",");
    let md = format!(
        "# Stiffness identification (`treemanip eval identify`)\n\n{} test-split trees (sizes {:?}, {} each, from `{}`), hidden stiffness K = K_formula·e^ε (every second tree also × a global factor log-uniform in [1/4, 4]); slot contact; seed {}. Regenerate: `treemanip eval identify --data DIR --sizes {} --trees-per-size {} --seed {}{}` with DIR from `{}`.\n\nRatio errors are |ln K̂/K| after removing the common level (mean over the identified branches), on `identified` branches; level errors (with force) are absolute. Coverage: the 90 % intervals of probed branches. Held-out: 5 random paper-style pushes per tree simulated with the estimate and with the radius formula, mean of the largest node error.\n\n{table}",
        trees.len(),
        args.sizes.0,
        args.trees_per_size,
        args.data.display(),
        args.seed,
        sizes_arg,
        args.trees_per_size,
        args.seed,
        [
            (args.name != "identify").then(|| format!(" --name {}", args.name)),
            (args.closed_loop_trees_per_size != 10).then(|| {
                format!(
                    " --closed-loop-trees-per-size {}",
                    args.closed_loop_trees_per_size
                )
            }),
        ]
        .into_iter()
        .flatten()
        .collect::<String>(),
        crate::dataset::dataset_config(&args.data)
            .as_ref()
            .and_then(crate::dataset::dataset_command)
            .unwrap_or_else(|| "treemanip dataset collect --out DIR --seed 7".into()),
    );
    let md_path = args.out.join(format!("{}.md", args.name));
    std::fs::write(&md_path, md).with_context(|| format!("writing {}", md_path.display()))?;
    std::fs::write(
        args.out.join(format!("{}.json", args.name)),
        serde_json::to_string_pretty(&results)?,
    )?;
    treemanip::eval::plots::identify_probes_svg(
        &results,
        &args.out.join(format!("{}.svg", args.name)),
    )
    .map_err(|e| anyhow::anyhow!("drawing {}.svg: {e}", args.name))?;
    eprintln!("wrote {}", md_path.display());
    Ok(())
}

#[derive(Args)]
pub struct EvalStiffnessArgs {
    /// Directory with `forward_gnn.onnx`.
    #[arg(long, default_value = "models")]
    models: PathBuf,
    /// Dataset with perturbed stiffness (`dataset collect --stiffness-sigma 0.3`).
    #[arg(long)]
    data: PathBuf,
    #[arg(long, value_parser = parse_sizes, default_value = "10..=30")]
    sizes: NodeSizes,
    #[arg(long, default_value_t = 1000)]
    per_size: usize,
    #[arg(long, default_value = "docs/results")]
    out: PathBuf,
    /// Native ONNX Runtime library (default: $ORT_DYLIB_PATH, else tract).
    #[arg(long, env = "ORT_DYLIB_PATH")]
    ort_dylib: Option<PathBuf>,
}

pub fn eval_stiffness(args: EvalStiffnessArgs) -> anyhow::Result<()> {
    use treemanip::eval::stiffness::{stiffness_scores, to_markdown};
    use treemanip::infer::{OnnxModel, init_backend};
    init_backend(args.ort_dylib.as_deref())?;
    let path = args.models.join("forward_gnn.onnx");
    let mut model = OnnxModel::load(&path)?;
    let bar = progress::bar(args.sizes.0.len() as u64, "sizes");
    let mut scores = Vec::new();
    for &n in &args.sizes.0 {
        let file = args.data.join(Split::Test.file_name(n));
        let data = read_size_file(&file, Split::Test)
            .map_err(|e| anyhow::anyhow!("reading {}: {e}", file.display()))?;
        scores.push(stiffness_scores(&data, &mut model, args.per_size, 32)?);
        bar.inc(1);
    }
    bar.finish_and_clear();
    let table = to_markdown(&scores);
    println!("{table}");
    std::fs::create_dir_all(&args.out)?;
    let md = format!(
        "# Forward model and stiffness (`treemanip eval stiffness`)\n\n`{}` on the test split of `{}` (perturbed stiffness: `{}`), {} episodes per size.\n\n{table}",
        path.display(),
        args.data.display(),
        crate::dataset::dataset_config(&args.data)
            .as_ref()
            .and_then(crate::dataset::dataset_command)
            .unwrap_or_else(|| "no summary.json".into()),
        args.per_size
    );
    std::fs::write(args.out.join("stiffness.md"), md)?;
    Ok(())
}
