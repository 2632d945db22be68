//! Trees from scans, evaluated (`treemanip eval scans`): test-split trees
//! scanned synthetically ([`crate::scan::scanner`]) under each condition
//! (viewpoints, depth noise, leaves), the tree extracted from the cloud and
//! scored against the true one ([`crate::scan::score`]), and end to end: a
//! `clear` task planned on the extracted tree (the arm-free oracle search
//! with the simulator and load limits, the clearance margin grown by
//! [`EXTRACTED_MARGIN`]), the push carried out on the true tree in the
//! simulator where a gripper closing at the planned contact would hold it
//! ([`held_at`]), against the same planning on the true tree
//! ([`end_to_end`](mod@end_to_end)).
//!
//! The extraction's parameters were chosen on other trees (seeds 1-8 of
//! the generator, never a test-split seed), so every tree here is held out.

use std::time::Instant;

use nalgebra::Point3;
use serde::Serialize;

use super::plan::percentile;
use crate::dataset::{CollectConfig, Split};
use crate::scan::{
    ExtractParams, Extraction, ScanParams, ScanScore, Skeleton, extract, scan, score,
};
use crate::seed::derive_seed;
use crate::tree::collection::TreeShape;
use crate::tree::collection::tree_set;
use crate::tree::{ScaParams, Tree};

mod end_to_end;
pub use end_to_end::{CONTACT_MATCH, EXTRACTED_MARGIN, EndToEnd, Missed, end_to_end, held_at};

/// One scanning condition.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Condition {
    pub views: usize,
    /// Depth noise σ at the scanning range (m).
    pub noise: f64,
    /// Leaves per twig.
    pub leaves: usize,
    /// Whether the cloud keeps its colours (the extraction then drops
    /// foliage green); without, it has only x, y, z.
    pub colour: bool,
}

impl Condition {
    pub fn label(&self) -> String {
        format!(
            "{} view{}, {:.0} mm{}{}",
            self.views,
            if self.views == 1 { "" } else { "s" },
            self.noise * 1e3,
            if self.leaves > 0 {
                format!(", {} leaves/twig", self.leaves)
            } else {
                String::new()
            },
            if self.colour { ", RGB" } else { "" }
        )
    }
}

/// Leaves per twig in the leafy conditions: a 5 cm leaf every 2-3 cm of a
/// 15-20 cm twig's outer two thirds.
pub const LEAVES_PER_TWIG: usize = 8;

/// The evaluation's grid: 1 and 3 viewpoints, 1-5 mm noise, without
/// leaves, with leaves (x, y, z only), with leaves and colour.
pub fn default_conditions() -> Vec<Condition> {
    let mut out = Vec::new();
    for (leaves, colour) in [
        (0, false),
        (LEAVES_PER_TWIG, false),
        (LEAVES_PER_TWIG, true),
    ] {
        for views in [1, 3] {
            for noise in [0.001, 0.002, 0.003, 0.005] {
                out.push(Condition {
                    views,
                    noise,
                    leaves,
                    colour,
                });
            }
        }
    }
    out
}

/// The test split's trees of each size (as `dataset collect` draws them).
pub fn test_trees(sizes: &[usize], per_size: usize) -> anyhow::Result<Vec<Tree>> {
    let config = CollectConfig::default();
    let base = derive_seed(config.seed, &[Split::Test.seed_part()]);
    let mut out = Vec::new();
    for &n in sizes {
        let set = tree_set(
            n,
            per_size,
            base,
            &ScaParams::default(),
            TreeShape::Sca,
            true,
            |_, _| {},
        )?;
        out.extend(set.into_iter().map(|(_, t)| t));
    }
    Ok(out)
}

/// One tree under one condition.
#[derive(Debug, Clone, Serialize)]
pub struct TreeRow {
    pub n: usize,
    pub points: usize,
    /// Extraction time (s).
    pub seconds: f64,
    pub nodes: usize,
    /// The scores (all zero when the extraction failed).
    pub score: ScanScore,
    /// The extraction's error, if it refused the cloud.
    pub error: Option<String>,
}

impl TreeRow {
    /// `found` scored against `tree`, or the failure `error`.
    pub fn new(tree: &Tree, points: usize, seconds: f64, found: Result<&Skeleton, String>) -> Self {
        let (nodes, score, error) = match found {
            Ok(found) => (found.len(), score(&Skeleton::of_tree(tree), found), None),
            Err(e) => (
                0,
                ScanScore {
                    recall: [0.0; 2],
                    precision: [0.0; 2],
                    radius_error_mm: [f64::NAN; 3],
                    branch_points_matched: 0.0,
                    topology: 0.0,
                },
                Some(e),
            ),
        };
        TreeRow {
            n: tree.len(),
            points,
            seconds,
            nodes,
            score,
            error,
        }
    }
}

/// A condition's averages over its trees.
#[derive(Debug, Clone, Serialize)]
pub struct ConditionRow {
    pub condition: Condition,
    pub trees: usize,
    pub failed: usize,
    pub points_mean: f64,
    pub recall: [f64; 2],
    pub precision: [f64; 2],
    /// Median over trees of each tree's median radius error, by class.
    pub radius_error_mm: [f64; 3],
    pub branch_points_matched: f64,
    pub topology: f64,
    /// Extraction seconds per 100,000 points, median and 95th percentile.
    pub per_100k_p50: f64,
    pub per_100k_p95: f64,
    /// Extracted nodes per true node.
    pub nodes_ratio: f64,
}

/// The scan of tree `index` under `condition`.
pub fn scan_params(condition: &Condition, seed: u64, index: usize) -> ScanParams {
    ScanParams {
        viewpoints: condition.views,
        noise: condition.noise,
        leaves_per_twig: condition.leaves,
        seed: derive_seed(seed, &[index as u64, condition.views as u64]),
        ..ScanParams::default()
    }
}

/// Scans and extracts every tree under `condition`; the extractions come
/// back beside the rows (for the end-to-end tasks).
pub fn evaluate_condition(
    trees: &[Tree],
    condition: &Condition,
    seed: u64,
) -> (ConditionRow, Vec<Option<Extraction>>) {
    // One tree at a time (each extraction uses both cores), so the times
    // are the extraction's own.
    let mut rows = Vec::new();
    let mut extractions = Vec::new();
    for (i, tree) in trees.iter().enumerate() {
        let mut cloud = match scan(tree, &scan_params(condition, seed, i)) {
            Ok(s) => s.cloud,
            Err(e) => panic!("the evaluation's scan parameters are valid: {e}"),
        };
        if !condition.colour {
            cloud.colors = None;
        }
        let start = Instant::now();
        let result = extract(&cloud, &ExtractParams::default());
        let seconds = start.elapsed().as_secs_f64();
        let row = TreeRow::new(
            tree,
            cloud.len(),
            seconds,
            result
                .as_ref()
                .map(|e| &e.skeleton)
                .map_err(|e| e.to_string()),
        );
        rows.push(row);
        extractions.push(result.ok());
    }
    (summarise(condition, &rows), extractions)
}

fn mean(v: impl Iterator<Item = f64>) -> f64 {
    let (s, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x, n + 1));
    if n == 0 { f64::NAN } else { s / n as f64 }
}

fn median(mut v: Vec<f64>) -> f64 {
    v.retain(|x| x.is_finite());
    v.sort_by(f64::total_cmp);
    percentile(&v, 0.5)
}

pub fn summarise(condition: &Condition, rows: &[TreeRow]) -> ConditionRow {
    let mut per_100k: Vec<f64> = rows
        .iter()
        .map(|r| r.seconds / r.points.max(1) as f64 * 1e5)
        .collect();
    per_100k.sort_by(f64::total_cmp);
    ConditionRow {
        condition: *condition,
        trees: rows.len(),
        failed: rows.iter().filter(|r| r.error.is_some()).count(),
        points_mean: mean(rows.iter().map(|r| r.points as f64)),
        recall: [0, 1].map(|k| mean(rows.iter().map(|r| r.score.recall[k]))),
        precision: [0, 1].map(|k| mean(rows.iter().map(|r| r.score.precision[k]))),
        radius_error_mm: [0, 1, 2]
            .map(|k| median(rows.iter().map(|r| r.score.radius_error_mm[k]).collect())),
        branch_points_matched: mean(rows.iter().map(|r| r.score.branch_points_matched)),
        topology: mean(rows.iter().map(|r| r.score.topology)),
        per_100k_p50: percentile(&per_100k, 0.5),
        per_100k_p95: percentile(&per_100k, 0.95),
        nodes_ratio: mean(rows.iter().map(|r| r.nodes as f64 / r.n as f64)),
    }
}

/// The results as a markdown table.
pub fn to_markdown(rows: &[ConditionRow]) -> String {
    let mut s = String::from(
        "| condition | trees | points | recall 0.5 r / 1.0 r | precision 0.5 r / 1.0 r | radius error (mm): all / r ≥ 5 mm / r ≥ 10 mm | branch points | right parent | s per 100k points p50 / p95 | nodes / true |\n| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |\n",
    );
    for r in rows {
        s += &format!(
            "| {} | {}{} | {:.0} | {:.3} / {:.3} | {:.3} / {:.3} | {:.2} / {:.2} / {:.2} | {:.2} | {:.2} | {:.3} / {:.3} | {:.2} |\n",
            r.condition.label(),
            r.trees,
            if r.failed > 0 {
                format!(" ({} refused)", r.failed)
            } else {
                String::new()
            },
            r.points_mean,
            r.recall[0],
            r.recall[1],
            r.precision[0],
            r.precision[1],
            r.radius_error_mm[0],
            r.radius_error_mm[1],
            r.radius_error_mm[2],
            r.branch_points_matched,
            r.topology,
            r.per_100k_p50,
            r.per_100k_p95,
            r.nodes_ratio
        );
    }
    s
}

/// The file stem of tree `index`'s cloud under `condition`.
pub fn cloud_stem(condition: &Condition, index: usize) -> String {
    format!(
        "v{}_n{:.0}_l{}{}_{index:03}",
        condition.views,
        condition.noise * 1e3,
        condition.leaves,
        if condition.colour { "c" } else { "" }
    )
}

/// Writes every tree's cloud under `condition` as binary PLY into `dir`
/// (for peers to read: `scripts/scan-peers`).
pub fn write_clouds(
    trees: &[Tree],
    condition: &Condition,
    seed: u64,
    dir: &std::path::Path,
) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir)?;
    for (i, tree) in trees.iter().enumerate() {
        let mut cloud = scan(tree, &scan_params(condition, seed, i))
            .map_err(anyhow::Error::msg)?
            .cloud;
        if !condition.colour {
            cloud.colors = None;
        }
        let path = dir.join(format!("{}.ply", cloud_stem(condition, i)));
        let mut file = std::io::BufWriter::new(std::fs::File::create(&path)?);
        crate::scan::io::ply::write(&cloud, &mut file)?;
    }
    Ok(())
}

/// A peer's answer for one cloud (`*.pytlidar.json`).
#[derive(Debug, serde::Deserialize)]
struct PeerAnswer {
    points: usize,
    seconds: Option<f64>,
    cylinders: Option<Cylinders>,
    error: Option<String>,
}

#[derive(Debug, serde::Deserialize)]
struct Cylinders {
    start: Vec<[f64; 3]>,
    axis: Vec<[f64; 3]>,
    length: Vec<f64>,
    radius: Vec<f64>,
    parent: Vec<i64>,
}

/// Cylinders with parents as a skeleton: a node at each cylinder's end,
/// hanging from its parent cylinder's end (through a node at its own
/// start when that is more than 1 mm away); root cylinders hang from the
/// nearest node before them, the first from a node at its start.
fn cylinders_skeleton(c: &Cylinders) -> Option<Skeleton> {
    let n = c.start.len();
    if n == 0 || [c.axis.len(), c.length.len(), c.radius.len(), c.parent.len()] != [n; 4] {
        return None;
    }
    let start = |k: usize| Point3::from(c.start[k]);
    let end = |k: usize| start(k) + nalgebra::Vector3::from(c.axis[k]) * c.length[k];
    let mut s = Skeleton {
        positions: vec![start(0)],
        parents: vec![None],
        radius: vec![c.radius[0]],
    };
    let mut end_node = vec![usize::MAX; n];
    for k in 0..n {
        let from = match usize::try_from(c.parent[k]).ok().filter(|&p| p < n) {
            Some(p) if end_node[p] != usize::MAX => end_node[p],
            _ => (0..s.len())
                .min_by(|&a, &b| {
                    (s.positions[a] - start(k))
                        .norm()
                        .total_cmp(&(s.positions[b] - start(k)).norm())
                })
                .unwrap_or(0),
        };
        let mut at = from;
        if (s.positions[from] - start(k)).norm() > 0.001 {
            s.positions.push(start(k));
            s.parents.push(Some(from));
            s.radius.push(c.radius[k]);
            at = s.len() - 1;
        }
        s.positions.push(end(k));
        s.parents.push(Some(at));
        s.radius.push(c.radius[k]);
        end_node[k] = s.len() - 1;
    }
    Some(s)
}

/// The peer's answers in `dir` for `condition`, scored like ours; `None`
/// when the directory holds none for it.
pub fn peer_row(
    trees: &[Tree],
    condition: &Condition,
    dir: &std::path::Path,
) -> anyhow::Result<Option<ConditionRow>> {
    let mut rows = Vec::new();
    for (i, tree) in trees.iter().enumerate() {
        let path = dir.join(format!("{}.pytlidar.json", cloud_stem(condition, i)));
        let Ok(text) = std::fs::read_to_string(&path) else {
            continue;
        };
        let answer: PeerAnswer = serde_json::from_str(&text)?;
        let found = answer.cylinders.as_ref().and_then(cylinders_skeleton);
        let failure = answer.error.unwrap_or_else(|| "no cylinders".into());
        rows.push(TreeRow::new(
            tree,
            answer.points,
            answer.seconds.unwrap_or(f64::NAN),
            found.as_ref().ok_or(failure),
        ));
    }
    Ok((!rows.is_empty()).then(|| summarise(condition, &rows)))
}
