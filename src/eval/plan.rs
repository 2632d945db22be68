//! Evaluating the planner (the paper's Section IV-E, Fig. 10, and this
//! project's action selection): on test episodes of every tree size, the
//! target is the episode's final shape; the planner gets only the tree and
//! the target, ranking with the real contact policy. Its push is then
//! executed in the simulator and the largest node distance left to the
//! target is the score. An episode with no plan counts as No Action.

use std::collections::BTreeMap;
use std::time::Duration;

use nalgebra::{Point3, Vector3};
use serde::Serialize;

use crate::dataset::Episode;
use crate::infer::models::{ServedModel, rank_candidates};
use crate::planner::base::BaseRegion;
use crate::planner::predict::{PhysicsPredictor, max_node_error};
use crate::planner::{
    ContactPolicy, Planner, PredictivePolicy, Predictor, Query, Stance, Strategy,
};
use crate::robot::arm::PAPER_BASE;
use crate::sim::{Push, SimConfig, simulate};
use crate::tree::{FULL_GRAPH_MAX_NODES, Tree};

/// One way of planning that is compared.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Setting {
    pub strategy: Strategy,
    /// With a base region ([`BaseArea`]: by default the paper's, ±0.5 m
    /// around the default base in x and y, 0.1-1.0 m in z) instead of the
    /// fixed default base.
    pub region: bool,
}

impl Setting {
    pub fn name(&self) -> String {
        let strategy = serde_json::to_value(self.strategy)
            .ok()
            .and_then(|v| v.as_str().map(str::to_owned))
            .unwrap_or_default();
        format!(
            "{strategy}/{}",
            if self.region { "region" } else { "fixed" }
        )
    }

    /// Every strategy, fixed base then base region.
    pub fn all() -> Vec<Setting> {
        [false, true]
            .into_iter()
            .flat_map(|region| {
                [Strategy::Paper, Strategy::Model, Strategy::Physics]
                    .into_iter()
                    .map(move |strategy| Setting { strategy, region })
            })
            .collect()
    }
}

/// Where a `region` setting lets the base stand.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum BaseArea {
    /// The paper's: the default base ±0.5 m in x and y
    /// ([`evaluation_region`]), on one side of the trunk. Sized for trees
    /// of 10-30 nodes; a 200-node orchard tree's crown reaches over it.
    #[default]
    Paper,
    /// A square of ± this half width (m) in x and y around the trunk: a
    /// mobile base that drives around the tree, as in an orchard row.
    AroundTree(f64),
}

impl BaseArea {
    /// The region the base may take, 0.1-1.0 m high either way.
    pub fn region(self) -> BaseRegion {
        match self {
            BaseArea::Paper => evaluation_region(),
            BaseArea::AroundTree(w) => BaseRegion {
                min: Vector3::new(-w, -w, 0.1),
                max: Vector3::new(w, w, 1.0),
                yaw: None,
            },
        }
    }

    /// The region in words, for a report.
    pub fn describe(self) -> String {
        match self {
            BaseArea::Paper => "x and y within ±0.5 m of the default base, z 0.1-1.0 m".to_owned(),
            BaseArea::AroundTree(w) => format!(
                "x and y within ±{w} m of the trunk (a base that drives around the tree), z 0.1-1.0 m"
            ),
        }
    }
}

/// The region of the evaluation: the default base ±0.5 m in x and y,
/// 0.1-1.0 m high.
pub fn evaluation_region() -> BaseRegion {
    let base = PAPER_BASE.translation.vector;
    BaseRegion {
        min: Vector3::new(base.x - 0.5, base.y - 0.5, 0.1),
        max: Vector3::new(base.x + 0.5, base.y + 0.5, 1.0),
        yaw: None,
    }
}

#[derive(Debug, Clone, Serialize)]
pub struct EpisodeResult {
    pub n: usize,
    pub planned: bool,
    /// Policy rank of the planned node.
    pub rank: Option<usize>,
    /// Max node error after executing the plan (No Action's without one), m.
    pub executed_error: f64,
    pub no_action_error: f64,
    pub ms: f64,
    /// Outcome of every push the planner looked at.
    pub outcomes: Vec<String>,
}

pub fn outcome_name<T: Serialize>(outcome: &T) -> String {
    serde_json::to_value(outcome)
        .ok()
        .and_then(|v| v.as_str().map(str::to_owned))
        .unwrap_or_default()
}

/// The error left after simulating `push`, or `fallback` when the simulator
/// rejects it.
fn executed(tree: &Tree, push: &Push, targets: &[Point3<f64>], fallback: f64) -> f64 {
    simulate(tree, push, &SimConfig::default())
        .map_or(fallback, |o| max_node_error(&o.final_positions, targets))
}

/// Plans `query` with the models as the server uses them: the policy GNN
/// ranks the nodes of trees within its fully connected graph's size, the
/// strategy's predictor (`model`: `forward`; otherwise the simulator) ranks
/// them above ([`PredictivePolicy`]); `forward` predicts and reads loads.
pub fn plan_as_served(
    planner: &Planner,
    query: &Query,
    policy: &ServedModel,
    forward: &ServedModel,
) -> Result<crate::planner::Plan, crate::planner::PlanError> {
    let predictor: &dyn Predictor = match query.strategy {
        Strategy::Model => forward,
        _ => &PhysicsPredictor,
    };
    let ranking = PredictivePolicy { predictor };
    let contact: &dyn ContactPolicy = if query.tree.len() > FULL_GRAPH_MAX_NODES {
        &ranking
    } else {
        policy
    };
    planner.plan(query, contact, Some(forward))
}

/// Plans one episode in one setting; a `region` setting's base stands
/// in `area`.
#[allow(clippy::too_many_arguments)]
pub fn plan_episode(
    planner: &Planner,
    policy: &ServedModel,
    forward: &ServedModel,
    n: usize,
    tree: &Tree,
    episode: &Episode,
    setting: Setting,
    area: BaseArea,
) -> EpisodeResult {
    let targets = episode.final_positions.clone();
    let mut query = Query::new(tree.clone(), targets.clone());
    // The paper's benchmark, as the paper ran it: no load limits (its
    // targets come from unconstrained pushes; `eval tasks` holds pushes to
    // limits).
    query.limits = None;
    query.strategy = setting.strategy;
    query.budget = Duration::from_secs(2);
    if setting.region {
        query.stance = Stance::Region(area.region());
    }
    let no_action_error = max_node_error(tree.positions(), &targets);
    let result = plan_as_served(planner, &query, policy, forward);
    let (plan, ms, outcomes) = match result {
        Ok(p) => (
            p.plan,
            p.total_ms,
            p.attempts
                .iter()
                .map(|a| outcome_name(&a.outcome))
                .collect(),
        ),
        Err(e) => (None, 0.0, vec![format!("error: {e}")]),
    };
    let executed_error = plan.as_ref().map_or(no_action_error, |p| {
        let push = Push {
            node: p.node,
            vector: p.push,
        };
        executed(tree, &push, &targets, no_action_error)
    });
    EpisodeResult {
        n,
        planned: plan.is_some(),
        rank: plan.as_ref().map(|p| p.rank),
        executed_error,
        no_action_error,
        ms,
        outcomes,
    }
}

/// The policy's top push executed with the arm ignored (the ceiling of the
/// paper's method without reachability).
pub fn policy_top_error(policy: &ServedModel, tree: &Tree, episode: &Episode) -> f64 {
    let targets = &episode.final_positions;
    let none = max_node_error(tree.positions(), targets);
    match rank_candidates(policy, tree, targets, &Default::default()) {
        Ok(ranked) if !ranked.is_empty() => {
            let push = Push {
                node: ranked[0].node,
                vector: Vector3::from(ranked[0].push),
            };
            executed(tree, &push, targets, none)
        }
        _ => none,
    }
}

/// One row of the table.
#[derive(Debug, Clone, Serialize)]
pub struct SettingSummary {
    pub method: String,
    pub episodes: usize,
    /// Share of episodes with a plan (NaN for the rows without an arm).
    pub planned: f64,
    /// Share whose executed error is below No Action's.
    pub helpful: f64,
    /// Mean executed max node error (m).
    pub executed_error: f64,
    pub ms_p50: f64,
    pub ms_p95: f64,
    pub rank_histogram: BTreeMap<usize, usize>,
    pub outcomes: BTreeMap<String, usize>,
}

/// The `p` quantile of sorted values (nearest rank).
pub fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    sorted[((sorted.len() - 1) as f64 * p).round() as usize]
}

pub fn summarise(method: &str, results: &[EpisodeResult]) -> SettingSummary {
    let count = results.len().max(1) as f64;
    let mut times: Vec<f64> = results.iter().map(|r| r.ms).collect();
    times.sort_by(f64::total_cmp);
    let mut rank_histogram = BTreeMap::new();
    let mut outcomes = BTreeMap::new();
    for r in results {
        if let Some(rank) = r.rank {
            *rank_histogram.entry(rank).or_default() += 1;
        }
        for o in &r.outcomes {
            if o != "skipped" {
                *outcomes.entry(o.clone()).or_default() += 1;
            }
        }
    }
    SettingSummary {
        method: method.to_owned(),
        episodes: results.len(),
        planned: results.iter().filter(|r| r.planned).count() as f64 / count,
        helpful: results
            .iter()
            .filter(|r| r.executed_error < r.no_action_error - 1e-9)
            .count() as f64
            / count,
        executed_error: results.iter().map(|r| r.executed_error).sum::<f64>() / count,
        ms_p50: percentile(&times, 0.5),
        ms_p95: percentile(&times, 0.95),
        rank_histogram,
        outcomes,
    }
}

/// A share as a table cell in percent, `–` for NaN (not applicable).
pub fn percent_cell(v: f64) -> String {
    if v.is_nan() {
        "–".to_owned()
    } else {
        format!("{:.1}", 100.0 * v)
    }
}

/// Milliseconds as a table cell, `–` for NaN.
pub fn ms_cell(v: f64) -> String {
    if v.is_nan() {
        "–".to_owned()
    } else {
        format!("{v:.0}")
    }
}

/// The table as Markdown (errors in cm, times in ms).
pub fn to_markdown(rows: &[SettingSummary]) -> String {
    let mut out = String::from(
        "| method | episodes | planned % | helpful % | executed error (cm) | plan ms p50 | p95 | outcomes of the pushes looked at |\n|---|---|---|---|---|---|---|---|\n",
    );
    let (pct, ms) = (percent_cell, ms_cell);
    for r in rows {
        let outcomes: Vec<String> = r.outcomes.iter().map(|(k, v)| format!("{k} {v}")).collect();
        out.push_str(&format!(
            "| {} | {} | {} | {} | {:.2} | {} | {} | {} |\n",
            r.method,
            r.episodes,
            pct(r.planned),
            pct(r.helpful),
            100.0 * r.executed_error,
            ms(r.ms_p50),
            ms(r.ms_p95),
            outcomes.join(", ")
        ));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The paper's region stands beside the trunk on one side; the area
    /// around the tree reaches every side of it, as high as the paper's.
    #[test]
    fn the_area_around_the_tree_surrounds_the_trunk() {
        let paper = BaseArea::Paper.region();
        assert_eq!(paper, evaluation_region());
        assert!(paper.max.x <= 0.0 + 1e-12, "{paper:?}");
        let around = BaseArea::AroundTree(2.0).region();
        for (x, y) in [(1.5, 0.0), (-1.5, 0.0), (0.0, 1.5), (0.0, -1.5)] {
            let p = Vector3::new(x, y, 0.5);
            assert!(
                p >= around.min && p <= around.max,
                "{p:?} outside {around:?}"
            );
        }
        assert_eq!((around.min.z, around.max.z), (paper.min.z, paper.max.z));
        assert!(
            BaseArea::AroundTree(2.0)
                .describe()
                .contains("±2 m of the trunk")
        );
    }
}
