//! `treemanip eval scans`: trees from synthetic scans of test-split trees,
//! scored against the true trees, and `clear` tasks end to end.

use std::path::PathBuf;

use anyhow::Context;
use clap::Args;
use treemanip::dataset::Split;
use treemanip::eval::scans::{
    EndToEnd, LEAVES_PER_TWIG, PEERS, default_conditions, end_to_end, evaluate_condition,
    independent_rows, peer_row, split_trees, to_markdown, write_clouds,
};
use treemanip::planner::objective::{DEFAULT_MAX_CONTACT_FORCE, DEFAULT_MAX_STRESS, Limits};
use treemanip::scan::Sensor;

use crate::trees::{NodeSizes, parse_sizes};

#[derive(Args)]
pub struct EvalScansArgs {
    /// Tree sizes of the test split.
    #[arg(long, default_value = "10..=30", value_parser = parse_sizes)]
    sizes: NodeSizes,
    /// Trees per size.
    #[arg(long, default_value_t = 2)]
    per_size: usize,
    /// Whose trees: `test` (the report's) or `train` (to develop a change
    /// on without looking at the test split).
    #[arg(long, default_value = "test")]
    split: Split,
    /// `clear` tasks per tree, end to end.
    #[arg(long, default_value_t = 3)]
    tasks_per_tree: usize,
    #[arg(long, default_value_t = 7)]
    seed: u64,
    /// Only the two conditions the goals name (3 views, 2 mm, bare; 1
    /// view, 3 mm, leaves).
    #[arg(long)]
    headline_only: bool,
    /// Write the clouds of the two headline conditions here (binary PLY),
    /// for `scripts/scan-peers`.
    #[arg(long)]
    write_clouds: Option<PathBuf>,
    /// Score the peers' answers found here (`scripts/scan-peers` wrote them
    /// beside the clouds) side by side with ours.
    #[arg(long)]
    peers: Option<PathBuf>,
    /// Also score ours and the peers on the clouds and true cylinders of
    /// an independent scanner found here (`scripts/scan-independent`,
    /// then `scripts/scan-peers` on the same folder).
    #[arg(long)]
    independent: Option<PathBuf>,
    /// Where the table (`scan_eval.md`) and the rows (`scan_eval.json`) go.
    #[arg(long, default_value = "docs/results")]
    out: PathBuf,
}

pub fn eval_scans(args: EvalScansArgs) -> anyhow::Result<()> {
    let started = std::time::Instant::now();
    let trees = split_trees(args.split, &args.sizes.0, args.per_size)?;
    let limits = Limits {
        max_stress: DEFAULT_MAX_STRESS,
        max_contact_force: DEFAULT_MAX_CONTACT_FORCE,
    };
    let mut rows = Vec::new();
    let mut ends: Vec<(String, EndToEnd)> = Vec::new();
    let mut peers = Vec::new();
    for condition in default_conditions() {
        let headline = (condition.views == 3 && condition.noise == 0.002 && condition.leaves == 0)
            || (condition.views == 1
                && condition.noise == 0.003
                && condition.leaves == LEAVES_PER_TWIG);
        // End to end also with colour, told a camera made the cloud, and
        // not told where the scanner stood, for the leafy headline; clouds
        // written and peers read for the plain headlines only.
        let variant = headline
            && (condition.colour || condition.sensor == Sensor::Camera || !condition.placed);
        let headline = headline && !variant;
        if args.headline_only && !headline && !variant {
            continue;
        }
        if let Some(dir) = &args.write_clouds
            && headline
        {
            write_clouds(&trees, &condition, args.seed, dir)?;
        }
        let (row, extractions) = evaluate_condition(&trees, &condition, args.seed);
        // Peers take no viewpoints: their rows are read once per cloud,
        // beside ours told where the scanner stood.
        if let Some(dir) = &args.peers
            && condition.placed
        {
            let mut answered = Vec::new();
            for peer in PEERS {
                answered.extend(peer_row(&trees, &condition, dir, peer)?);
            }
            if !answered.is_empty() {
                let mut ours = row.clone();
                ours.label = format!("treemanip: {}", ours.label);
                peers.push(ours);
                peers.extend(answered);
            }
        }
        eprintln!(
            "{}: recall {:.3}, precision {:.3} (1.0 r), radius {:.2} mm, {:.3} s per 100k points",
            condition.label(),
            row.recall[1],
            row.precision[1],
            row.radius_error_mm[1],
            row.per_100k_p50
        );
        if (headline || variant) && args.tasks_per_tree > 0 {
            let e = end_to_end(
                &trees,
                &extractions,
                args.tasks_per_tree,
                &limits,
                args.seed,
            );
            eprintln!("  end to end: {e:?}");
            ends.push((condition.label(), e));
        }
        rows.push(row);
    }
    let mut md = format!(
        "# Trees from scans\n\nRegenerate: `treemanip eval scans --sizes {}..={} --per-size {} --tasks-per-tree {} --seed {}{}` ({} {}-split trees; {:.0} s on this machine). DIR holds the clouds an earlier run's `--write-clouds DIR` wrote, with `scripts/scan-peers DIR`'s answers; IND what `scripts/scan-independent IND` and then `scripts/scan-peers IND` wrote.\n\nSynthetic scans (`treemanip trees scan`): viewpoints 1.5 m from the trunk at half the tree's height, 40,000 surface samples per viewpoint before occlusion, depth noise σ at that range growing with the square of range; leaves are 5 cm discs near the twigs; every point has its colour (bark brown, leaf green) under varied light, kept only in the RGB conditions, where the extraction drops foliage-green points. Scores as in `crates/core/src/scan/score.rs` (Smart-Tree's recall and precision at t × the true radius).\n\n",
        args.sizes.0.first().copied().unwrap_or(0),
        args.sizes.0.last().copied().unwrap_or(0),
        args.per_size,
        args.tasks_per_tree,
        args.seed,
        [
            args.headline_only.then(|| " --headline-only".to_owned()),
            args.peers.as_ref().map(|_| " --peers DIR".to_owned()),
            args.independent
                .as_ref()
                .map(|_| " --independent IND".to_owned()),
            (args.split == Split::Train).then(|| " --split train".to_owned()),
        ]
        .into_iter()
        .flatten()
        .collect::<String>(),
        trees.len(),
        args.split.name(),
        started.elapsed().as_secs_f64()
    );
    md += &to_markdown(&rows);
    if !ends.is_empty() {
        md += "\n## End to end: `clear` tasks\n\nA fruit-sized sphere across a random branch; the push planned on the extracted tree (the arm-free search with the simulator, load limits 40 MPa and the default contact force, the clearance margin grown by 1 cm for the extracted geometry's uncertainty and 10 % of the stress limit kept in reserve for its radii's) is carried out on the true tree where a gripper closing at the planned contact holds it (the nearest true branch, within 5 cm, split there by a rigid joint; within 1 cm of a node, at that node: a fork is held at the fork) as a guarded move that stops where the wrist's force first reaches the plan's guard (`Limits::guard_force`: the contact-force limit, or lower where the push's own stress per newton says a stiffer tree would pass the stress limit first; `sim::guarded`), and compared with the push planned on the true tree (no reserve). Over the limits: as carried out (guarded), and the same pushes carried to their end whatever the force.\n\n| condition | tasks | solved planning on the true tree | of those, solved planning on the extracted tree | share | solved from the extracted tree (all) | over the limits on the true tree: guarded / to the end | stopped by the guard | no usable tree | missed: no push / no branch there / not cleared / over a limit |\n| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |\n";
        for (label, e) in &ends {
            md += &format!(
                "| {label} | {} | {} | {} | {:.1} % | {} | {} / {} | {} | {} | {} / {} / {} / {} |\n",
                e.tasks,
                e.true_solved,
                e.extracted_solved,
                100.0 * e.extracted_solved as f64 / e.true_solved.max(1) as f64,
                e.extracted_solved_any,
                e.over_limit,
                e.over_limit_unguarded,
                e.guard_stopped,
                e.no_tree,
                e.missed.no_push,
                e.missed.no_branch,
                e.missed.not_cleared,
                e.missed.over_limit
            );
        }
    }
    if !peers.is_empty() {
        md += &format!(
            "\n## Side by side: {} on the same clouds\n\n`scripts/scan-peers DIR` on the clouds `--write-clouds DIR` wrote, scored by the same code; a peer's time is its repeat run (compiled kernels), ours the extraction's. sylva-rs's parameters are `SYLVA_PARAMS` in `scripts/scan-peers` (its defaults are for forest trees); pc-skeletor fits no radius.\n\n",
            PEERS.map(|p| p.name).join(", ")
        );
        md += &to_markdown(&peers);
    }
    let independent = match &args.independent {
        Some(dir) => independent_rows(dir, &PEERS)?,
        None => Vec::new(),
    };
    if !independent.is_empty() {
        md += &format!(
            "\n## An independent scanner: sylva-rs's trees and beam-model scans\n\n`scripts/scan-independent DIR` (sylva-rs 0.3.0's `synthetic.tree_model`: broadleaf, eucalypt, savanna and conifer archetypes, 5 cm stems, 2.5 m tall, twigs to 4 mm; `synthetic.scan` with a RIEGL VZ-400i's beam, {:.0} mm range noise, 1 or 3 viewpoints 1.5 m out), then `scripts/scan-peers DIR`; scored against the models' own cylinders. Seeds 1-3 (scan_peers) were used to choose some of the extraction's constants; seeds 4-6 (scan_independent_held_out) were not.\n\n",
            treemanip::eval::scans::INDEPENDENT_NOISE * 1e3
        );
        md += &to_markdown(&independent);
    }
    std::fs::create_dir_all(&args.out)?;
    let path = args.out.join("scan_eval.md");
    std::fs::write(&path, &md).with_context(|| format!("cannot write {}", path.display()))?;
    let json = serde_json::json!({
        "conditions": rows,
        "end_to_end": ends,
        "peers": peers,
        "independent": independent,
    });
    std::fs::write(
        args.out.join("scan_eval.json"),
        serde_json::to_string_pretty(&json)?,
    )?;
    println!("{md}");
    Ok(())
}
