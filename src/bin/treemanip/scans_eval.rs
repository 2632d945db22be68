//! `treemanip eval scans`: trees from synthetic scans of test-split trees,
//! scored against the true trees, and `clear` tasks end to end.

use std::path::PathBuf;

use anyhow::Context;
use clap::Args;
use treemanip::eval::scans::{
    EndToEnd, LEAVES_PER_TWIG, default_conditions, end_to_end, evaluate_condition, peer_row,
    test_trees, to_markdown, write_clouds,
};
use treemanip::planner::objective::{DEFAULT_MAX_CONTACT_FORCE, DEFAULT_MAX_STRESS, Limits};

use crate::trees::{NodeSizes, parse_sizes};

#[derive(Args)]
pub struct EvalScansArgs {
    /// Tree sizes of the test split.
    #[arg(long, default_value = "10..=30", value_parser = parse_sizes)]
    sizes: NodeSizes,
    /// Trees per size.
    #[arg(long, default_value_t = 2)]
    per_size: usize,
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
    /// Score a peer's answers found here (`scripts/scan-peers` wrote them
    /// beside the clouds) side by side with ours.
    #[arg(long)]
    peers: Option<PathBuf>,
    /// Where the table (`scan_eval.md`) and the rows (`scan_eval.json`) go.
    #[arg(long, default_value = "docs/results")]
    out: PathBuf,
}

pub fn eval_scans(args: EvalScansArgs) -> anyhow::Result<()> {
    let started = std::time::Instant::now();
    let trees = test_trees(&args.sizes.0, args.per_size)?;
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
        // End to end also with colour, for the leafy headline.
        let leafy_rgb = headline && condition.colour;
        let headline = headline && !condition.colour;
        if args.headline_only && !headline && !leafy_rgb {
            continue;
        }
        if let Some(dir) = &args.write_clouds
            && headline
        {
            write_clouds(&trees, &condition, args.seed, dir)?;
        }
        let (row, extractions) = evaluate_condition(&trees, &condition, args.seed);
        if let Some(dir) = &args.peers
            && let Some(peer) = peer_row(&trees, &condition, dir)?
        {
            peers.push((row.clone(), peer));
        }
        eprintln!(
            "{}: recall {:.3}, precision {:.3} (1.0 r), radius {:.2} mm, {:.3} s per 100k points",
            condition.label(),
            row.recall[1],
            row.precision[1],
            row.radius_error_mm[1],
            row.per_100k_p50
        );
        if (headline || leafy_rgb) && args.tasks_per_tree > 0 {
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
        "# Trees from scans\n\nRegenerate: `treemanip eval scans --sizes {}..={} --per-size {} --tasks-per-tree {} --seed {}` ({} test-split trees; {:.0} s on this machine).\n\nSynthetic scans (`treemanip trees scan`): viewpoints 1.5 m from the trunk at half the tree's height, 40,000 surface samples per viewpoint before occlusion, depth noise σ at that range growing with the square of range; leaves are 5 cm discs near the twigs; every point has its colour (bark brown, leaf green) under varied light, kept only in the RGB conditions, where the extraction drops foliage-green points. Scores as in `crates/core/src/scan/score.rs` (Smart-Tree's recall and precision at t × the true radius).\n\n",
        args.sizes.0.first().copied().unwrap_or(0),
        args.sizes.0.last().copied().unwrap_or(0),
        args.per_size,
        args.tasks_per_tree,
        args.seed,
        trees.len(),
        started.elapsed().as_secs_f64()
    );
    md += &to_markdown(&rows);
    if !ends.is_empty() {
        md += "\n## End to end: `clear` tasks\n\nA fruit-sized sphere across a random branch; the push planned on the extracted tree (the arm-free search with the simulator, load limits 40 MPa and the default contact force, the clearance margin grown by 1 cm for the extracted geometry's uncertainty) is carried out on the true tree where a gripper closing at the planned contact holds it (the nearest true branch, within 5 cm, split there by a rigid joint), and compared with the push planned on the true tree.\n\n| condition | tasks | solved planning on the true tree | of those, solved planning on the extracted tree | share | solved from the extracted tree (all) | over the limits on the true tree | no usable tree | missed: no push / no branch there / not cleared / over a limit |\n| --- | --- | --- | --- | --- | --- | --- | --- | --- |\n";
        for (label, e) in &ends {
            md += &format!(
                "| {label} | {} | {} | {} | {:.1} % | {} | {} | {} | {} / {} / {} / {} |\n",
                e.tasks,
                e.true_solved,
                e.extracted_solved,
                100.0 * e.extracted_solved as f64 / e.true_solved.max(1) as f64,
                e.extracted_solved_any,
                e.over_limit,
                e.no_tree,
                e.missed.no_push,
                e.missed.no_branch,
                e.missed.not_cleared,
                e.missed.over_limit
            );
        }
    }
    if !peers.is_empty() {
        md += "\n## Side by side: PyTLidar 1.1.2 (TreeQSM's port) on the same clouds\n\n`scripts/scan-peers DIR` on the clouds `--write-clouds DIR` wrote, scored by the same code; PyTLidar's time is its repeat run (numba compiled), ours the extraction's.\n\n";
        let mut rows = Vec::new();
        for (ours, peer) in &peers {
            rows.push(ours.clone());
            rows.push(peer.clone());
        }
        let table = to_markdown(&rows);
        // Label alternate rows: ours, then the peer's.
        let mut k = 0;
        for line in table.lines() {
            if line.starts_with("| ")
                && !line.starts_with("| condition")
                && !line.starts_with("| ---")
            {
                let who = if k % 2 == 0 { "treemanip" } else { "PyTLidar" };
                md += &line.replacen("| ", &format!("| {who}: "), 1);
                k += 1;
            } else {
                md += line;
            }
            md += "\n";
        }
    }
    std::fs::create_dir_all(&args.out)?;
    let path = args.out.join("scan_eval.md");
    std::fs::write(&path, &md).with_context(|| format!("cannot write {}", path.display()))?;
    let json = serde_json::json!({ "conditions": rows, "end_to_end": ends });
    std::fs::write(
        args.out.join("scan_eval.json"),
        serde_json::to_string_pretty(&json)?,
    )?;
    println!("{md}");
    Ok(())
}
