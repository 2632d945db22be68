//! Evaluating Algorithm 1 (the paper's Section IV-E, Fig. 10): on test
//! episodes of every tree size, does the planner find an executable push,
//! for which candidate rank, and how long does it take?
//!
//! Until a trained contact policy exists, candidates are ranked by an
//! oracle-plus-Greedy stand-in: rank 1 is the episode's ground-truth
//! contact and push, then the other nodes in decreasing distance to their
//! targets, each pushed by p′_j − p_j. Every report says which ranking it
//! used.

use std::collections::BTreeMap;

use rayon::prelude::*;
use serde::Serialize;

use crate::dataset::Episode;
use crate::robot::collision::CollisionModel;
use crate::robot::plan::{Outcome, PlanOptions, PushCandidate, plan_push};
use crate::robot::rrt::Config;
use crate::tree::Tree;

/// How candidates were ranked.
pub const ORACLE_GREEDY: &str = "ground-truth contact first, then Greedy (farthest from target, push p'_j - p_j); no trained policy yet";

/// The stand-in candidate list for one episode.
pub fn oracle_greedy_candidates(tree: &Tree, episode: &Episode) -> Vec<PushCandidate> {
    let mut candidates = vec![PushCandidate {
        node: episode.push.node,
        push: episode.push.vector,
    }];
    let offset = |j: usize| episode.final_positions[j] - tree.position(j);
    let mut others: Vec<usize> = (1..tree.len())
        .filter(|&j| j != episode.push.node && offset(j).norm() > 1e-3)
        .collect();
    others.sort_by(|&a, &b| {
        offset(b)
            .norm()
            .total_cmp(&offset(a).norm())
            .then(a.cmp(&b))
    });
    candidates.extend(others.into_iter().map(|j| PushCandidate {
        node: j,
        push: offset(j),
    }));
    candidates
}

#[derive(Debug, Clone, Serialize)]
pub struct EpisodePlan {
    pub n: usize,
    /// Rank of the planned candidate, if any.
    pub rank: Option<usize>,
    pub ms: f64,
    pub outcomes: Vec<Outcome>,
}

/// Plans every episode (in parallel); `trees` and `episodes` pair up.
pub fn evaluate(
    model: &CollisionModel,
    episodes: &[(usize, &Tree, &Episode)],
    start: &Config,
    options: &PlanOptions,
    progress: &(dyn Fn() + Sync),
) -> Vec<EpisodePlan> {
    episodes
        .par_iter()
        .map(|&(n, tree, episode)| {
            let candidates = oracle_greedy_candidates(tree, episode);
            let result = plan_push(model, tree, &candidates, start, options);
            progress();
            match result {
                Ok(report) => EpisodePlan {
                    n,
                    rank: report.plan.as_ref().map(|p| p.rank),
                    ms: report.total_ms,
                    outcomes: report.attempts.iter().map(|a| a.outcome).collect(),
                },
                Err(_) => EpisodePlan {
                    n,
                    rank: None,
                    ms: 0.0,
                    outcomes: Vec::new(),
                },
            }
        })
        .collect()
}

#[derive(Debug, Clone, Serialize)]
pub struct PlanSummary {
    pub ranking: &'static str,
    pub episodes: usize,
    pub planned: usize,
    pub success_rate: f64,
    /// Planned episodes by the rank of the candidate that was planned.
    pub rank_histogram: BTreeMap<usize, usize>,
    pub ms_p50: f64,
    pub ms_p95: f64,
    pub ms_max: f64,
    /// Attempt outcomes over all tried candidates.
    pub outcomes: BTreeMap<String, usize>,
    /// (N, episodes, planned, success rate, median ms)
    pub per_size: Vec<(usize, usize, usize, f64, f64)>,
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    sorted[((sorted.len() - 1) as f64 * p).round() as usize]
}

pub fn summarise(results: &[EpisodePlan]) -> PlanSummary {
    let mut times: Vec<f64> = results.iter().map(|r| r.ms).collect();
    times.sort_by(f64::total_cmp);
    let planned = results.iter().filter(|r| r.rank.is_some()).count();
    let mut rank_histogram = BTreeMap::new();
    let mut outcomes = BTreeMap::new();
    for r in results {
        if let Some(rank) = r.rank {
            *rank_histogram.entry(rank).or_default() += 1;
        }
        for o in &r.outcomes {
            if *o != Outcome::Skipped {
                *outcomes
                    .entry(
                        serde_json::to_value(o)
                            .ok()
                            .and_then(|v| v.as_str().map(str::to_owned))
                            .unwrap_or_default(),
                    )
                    .or_default() += 1;
            }
        }
    }
    let mut sizes: Vec<usize> = results.iter().map(|r| r.n).collect();
    sizes.sort_unstable();
    sizes.dedup();
    let per_size = sizes
        .iter()
        .map(|&n| {
            let of: Vec<&EpisodePlan> = results.iter().filter(|r| r.n == n).collect();
            let ok = of.iter().filter(|r| r.rank.is_some()).count();
            let mut t: Vec<f64> = of.iter().map(|r| r.ms).collect();
            t.sort_by(f64::total_cmp);
            (
                n,
                of.len(),
                ok,
                ok as f64 / of.len() as f64,
                percentile(&t, 0.5),
            )
        })
        .collect();
    PlanSummary {
        ranking: ORACLE_GREEDY,
        episodes: results.len(),
        planned,
        success_rate: planned as f64 / results.len().max(1) as f64,
        rank_histogram,
        ms_p50: percentile(&times, 0.5),
        ms_p95: percentile(&times, 0.95),
        ms_max: times.last().copied().unwrap_or(f64::NAN),
        outcomes,
        per_size,
    }
}
