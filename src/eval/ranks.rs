//! The paper's Fig. 8: how good is the policy's ranking? On test episodes
//! (target = the episode's final shape), every candidate the policy ranks
//! is executed in the simulator with its own push, the arm ignored, and
//! its error to the target recorded by rank: the largest and the mean node
//! distance. A ranking that works has errors rising with rank and the
//! affordance mass on the first ranks.

use nalgebra::Vector3;
use rayon::prelude::*;
use serde::Serialize;

use crate::dataset::Episode;
use crate::infer::models::{ServedModel, rank_candidates};
use crate::sim::{Push, SimConfig, simulate};
use crate::tree::Tree;

/// One ranked candidate of one episode, executed.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct RankedOutcome {
    pub rank: usize,
    pub node: usize,
    pub affordance: f64,
    /// Largest node distance to the target after the push (m); the push
    /// rejected by the simulator (branch lost) leaves the tree as it was.
    pub max_error: f64,
    /// Mean node distance to the target after the push (m).
    pub mean_error: f64,
    /// Whether the simulator accepted the push.
    pub feasible: bool,
}

/// Largest and mean distance between matching points.
pub fn errors(a: &[nalgebra::Point3<f64>], b: &[nalgebra::Point3<f64>]) -> (f64, f64) {
    let d: Vec<f64> = a.iter().zip(b).map(|(p, q)| (p - q).norm()).collect();
    let max = d.iter().copied().fold(0.0, f64::max);
    (max, d.iter().sum::<f64>() / d.len().max(1) as f64)
}

/// Every candidate of one episode, by rank (1 first).
pub fn rank_outcomes(
    policy: &ServedModel,
    tree: &Tree,
    episode: &Episode,
) -> Result<Vec<RankedOutcome>, crate::infer::InferError> {
    let targets = &episode.final_positions;
    let ranked = rank_candidates(policy, tree, targets, &Default::default())?;
    let none = errors(tree.positions(), targets);
    Ok(ranked
        .par_iter()
        .map(|c| {
            let push = Push {
                node: c.node,
                vector: Vector3::from(c.push),
            };
            let outcome = simulate(tree, &push, &SimConfig::default());
            let (max_error, mean_error) = outcome
                .as_ref()
                .map_or(none, |o| errors(&o.final_positions, targets));
            RankedOutcome {
                rank: c.rank,
                node: c.node,
                affordance: c.affordance,
                max_error,
                mean_error,
                feasible: outcome.is_ok(),
            }
        })
        .collect())
}

/// One rank over all episodes.
#[derive(Debug, Clone, Serialize)]
pub struct RankSummary {
    pub rank: usize,
    pub episodes: usize,
    /// Mean over episodes (m).
    pub max_error: f64,
    pub mean_error: f64,
    pub affordance_mean: f64,
    pub affordance_p10: f64,
    pub affordance_p50: f64,
    pub affordance_p90: f64,
    /// Share of episodes whose push at this rank the simulator accepted.
    pub feasible: f64,
}

/// Per-rank means and affordance quantiles over `episodes` (each a list of
/// outcomes by rank).
pub fn summarise(episodes: &[Vec<RankedOutcome>]) -> Vec<RankSummary> {
    let ranks = episodes.iter().map(Vec::len).max().unwrap_or(0);
    (1..=ranks)
        .map(|rank| {
            let at: Vec<&RankedOutcome> = episodes
                .iter()
                .filter_map(|e| e.iter().find(|o| o.rank == rank))
                .collect();
            let k = at.len().max(1) as f64;
            let mut affordance: Vec<f64> = at.iter().map(|o| o.affordance).collect();
            affordance.sort_by(f64::total_cmp);
            let q = |p: f64| crate::eval::plan::percentile(&affordance, p);
            RankSummary {
                rank,
                episodes: at.len(),
                max_error: at.iter().map(|o| o.max_error).sum::<f64>() / k,
                mean_error: at.iter().map(|o| o.mean_error).sum::<f64>() / k,
                affordance_mean: affordance.iter().sum::<f64>() / k,
                affordance_p10: q(0.1),
                affordance_p50: q(0.5),
                affordance_p90: q(0.9),
                feasible: at.iter().filter(|o| o.feasible).count() as f64 / k,
            }
        })
        .collect()
}

/// The table of [`summarise`]'s rows, errors in cm.
pub fn to_markdown(rows: &[RankSummary], no_action: (f64, f64)) -> String {
    let mut s = String::from(
        "| rank | episodes | max error (cm) | mean error (cm) | affordance mean | p10 | p50 | p90 | push feasible |\n|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        s += &format!(
            "| {} | {} | {:.2} | {:.2} | {:.3} | {:.3} | {:.3} | {:.3} | {:.0} % |\n",
            r.rank,
            r.episodes,
            100.0 * r.max_error,
            100.0 * r.mean_error,
            r.affordance_mean,
            r.affordance_p10,
            r.affordance_p50,
            r.affordance_p90,
            100.0 * r.feasible
        );
    }
    s += &format!(
        "| no action | | {:.2} | {:.2} | | | | | |\n",
        100.0 * no_action.0,
        100.0 * no_action.1
    );
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    fn outcome(rank: usize, affordance: f64, max_error: f64) -> RankedOutcome {
        RankedOutcome {
            rank,
            node: rank,
            affordance,
            max_error,
            mean_error: max_error / 2.0,
            feasible: max_error < 0.5,
        }
    }

    #[test]
    fn ranks_are_averaged_over_episodes() {
        let episodes = vec![
            vec![outcome(1, 0.7, 0.01), outcome(2, 0.3, 0.05)],
            vec![outcome(1, 0.5, 0.03), outcome(2, 0.5, 0.9)],
        ];
        let rows = summarise(&episodes);
        assert_eq!(rows.len(), 2);
        assert!((rows[0].max_error - 0.02).abs() < 1e-12);
        assert!((rows[1].mean_error - 0.2375).abs() < 1e-12);
        assert!((rows[0].affordance_mean - 0.6).abs() < 1e-12);
        assert!((rows[1].feasible - 0.5).abs() < 1e-12);
        assert!(to_markdown(&rows, (0.1, 0.05)).contains("| 2 | 2 | 47.50 |"));
    }
}
