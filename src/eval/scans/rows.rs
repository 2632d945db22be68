//! The rows of the scan evaluation: a scanning condition, one tree's
//! scores under it, a condition's averages and the markdown table, shared
//! by our own extraction, the peers and the independent scans.

use nalgebra::Point3;
use serde::Serialize;

use crate::eval::plan::percentile;
use crate::scan::{
    ExtractParams, Extraction, PointCloud, ScanScore, Sensor, Skeleton, extract, score,
};

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
    /// What the extraction is told made the cloud.
    pub sensor: Sensor,
    /// Whether the extraction is told where the scanner stood (its
    /// `viewpoints`), as a robot knows its camera's pose.
    pub placed: bool,
}

impl Condition {
    pub fn label(&self) -> String {
        format!(
            "{} view{}, {:.0} mm{}{}{}{}",
            self.views,
            if self.views == 1 { "" } else { "s" },
            self.noise * 1e3,
            if self.leaves > 0 {
                format!(", {} leaves/twig", self.leaves)
            } else {
                String::new()
            },
            if self.colour { ", RGB" } else { "" },
            match self.sensor {
                Sensor::Unknown => String::new(),
                Sensor::Camera => ", `sensor: camera`".to_owned(),
                Sensor::Laser { beam_radius } =>
                    format!(", `sensor: laser`, beam radius {:.1} mm", beam_radius * 1e3),
            },
            if self.placed {
                ""
            } else {
                ", viewpoint unknown"
            }
        )
    }
}

/// Leaves per twig in the leafy conditions: a 5 cm leaf every 2-3 cm of a
/// 15-20 cm twig's outer two thirds.
pub const LEAVES_PER_TWIG: usize = 8;

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
    /// Extracts the tree in `cloud` with the default parameters but
    /// `sensor`, timed, and scores it against `truth`; the extraction
    /// comes back beside the row.
    pub fn extracted(
        truth: &Skeleton,
        cloud: &PointCloud,
        sensor: Sensor,
        viewpoints: &[Point3<f64>],
    ) -> (Self, Option<Extraction>) {
        let start = std::time::Instant::now();
        let params = ExtractParams {
            sensor,
            viewpoints: viewpoints.to_vec(),
            ..ExtractParams::default()
        };
        let result = extract(cloud, &params);
        let seconds = start.elapsed().as_secs_f64();
        let row = Self::new(
            truth,
            cloud.len(),
            seconds,
            result
                .as_ref()
                .map(|e| &e.skeleton)
                .map_err(|e| e.to_string()),
        );
        (row, result.ok())
    }

    /// `found` scored against the true geometry `truth`, or the failure
    /// `error`.
    pub fn new(
        truth: &Skeleton,
        points: usize,
        seconds: f64,
        found: Result<&Skeleton, String>,
    ) -> Self {
        let (nodes, score, error) = match found {
            Ok(found) => (found.len(), score(truth, found), None),
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
            n: truth.len(),
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
    /// What the row is: the condition's label, or who answered on which
    /// clouds.
    pub label: String,
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
        label: condition.label(),
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
            "| {} | {}{} | {:.0} | {:.3} / {:.3} | {:.3} / {:.3} | {} | {:.2} | {:.2} | {:.3} / {:.3} | {:.2} |\n",
            r.label,
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
            if r.radius_error_mm.iter().all(|e| e.is_nan()) {
                "none fitted".to_owned()
            } else {
                format!(
                    "{:.2} / {:.2} / {:.2}",
                    r.radius_error_mm[0], r.radius_error_mm[1], r.radius_error_mm[2]
                )
            },
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
        "v{}_n{:.0}_l{}{}{}_{index:03}",
        condition.views,
        condition.noise * 1e3,
        condition.leaves,
        if condition.colour { "c" } else { "" },
        match condition.sensor {
            Sensor::Unknown => "",
            Sensor::Camera => "k",
            Sensor::Laser { .. } => "b",
        }
    )
}
