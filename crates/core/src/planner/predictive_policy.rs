//! A contact policy for trees the learned policy cannot take: rank every
//! node by what a predictor says pushing it would do.
//!
//! The paper's policy GNN reads the fully connected graph (O(N²); trained
//! on 11-19 nodes, run up to [`crate::tree::FULL_GRAPH_MAX_NODES`]). What
//! it approximates is cheap to ask directly of a predictor that costs
//! O(path) a push (the simulator, or a path forward model): push each node
//! toward its own target (the part along its branch removed, the length
//! clamped to the trained range, as [`super::seeds`] does), predict the
//! tree, and rank the nodes by how close the prediction comes to the
//! targets. On a 200-node tree that is 199 predictions, one batch.

use nalgebra::Point3;

use super::predict::{Candidate, ContactPolicy, PredictError, Predictor};
use super::seeds::seed_vector;
use crate::sim::Push;
use crate::tree::Tree;

/// A node is worth a push toward its target only when it is this far from
/// it (m); closer ones are already where they should be.
const MIN_OFFSET: f64 = 0.005;

/// [`ContactPolicy`] by prediction: see the module documentation.
pub struct PredictivePolicy<'a> {
    pub predictor: &'a dyn Predictor,
}

impl ContactPolicy for PredictivePolicy<'_> {
    fn rank(&self, tree: &Tree, targets: &[Point3<f64>]) -> Result<Vec<Candidate>, PredictError> {
        let pushes: Vec<Push> = (1..tree.len())
            .filter_map(|j| {
                let offset = targets[j] - tree.position(j);
                let distance = offset.norm();
                (distance > MIN_OFFSET)
                    .then(|| seed_vector(tree, j, &offset, distance))
                    .flatten()
                    .map(|vector| Push { node: j, vector })
            })
            .collect();
        let predicted = self.predictor.final_positions(tree, &pushes)?;
        // RMS distance to the targets (m); a push the predictor cannot
        // answer ranks last.
        let mut scored: Vec<(f64, &Push)> = pushes
            .iter()
            .zip(&predicted)
            .map(|(push, p)| {
                let residual = p.as_ref().map_or(f64::INFINITY, |p| {
                    let sum: f64 = p
                        .iter()
                        .zip(targets)
                        .map(|(a, b)| (a - b).norm_squared())
                        .sum();
                    (sum / p.len() as f64).sqrt()
                });
                (residual, push)
            })
            .collect();
        scored.sort_by(|a, b| a.0.total_cmp(&b.0));
        // Affordance: a softmax of the residuals on the scale of the best
        // one, so that the list sums to 1 as the policy's does.
        let best = scored.first().map_or(1.0, |s| s.0.max(1e-3));
        let weights: Vec<f64> = scored
            .iter()
            .map(|(r, _)| {
                if r.is_finite() {
                    (-(r - best) / best).exp()
                } else {
                    0.0
                }
            })
            .collect();
        let total: f64 = weights.iter().sum::<f64>().max(1e-300);
        Ok(scored
            .iter()
            .zip(&weights)
            .enumerate()
            .map(|(k, ((_, push), w))| Candidate {
                node: push.node,
                affordance: w / total,
                push: [push.vector.x, push.vector.y, push.vector.z],
                rank: k + 1,
            })
            .collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::planner::predict::PhysicsPredictor;
    use crate::sim::{SimConfig, simulate};
    use crate::tree::{OrchardParams, generate_orchard};
    use nalgebra::Vector3;

    #[test]
    fn the_pushed_node_of_a_simulated_target_ranks_near_the_top() {
        let tree = generate_orchard(150, 4, &OrchardParams::default()).unwrap();
        let mut found = 0;
        let mut tried = 0;
        for node in (5..tree.len()).step_by(13) {
            let axis = tree.branch_direction(node).unwrap();
            let push = axis.cross(&Vector3::z()).normalize() * 0.08;
            let Ok(out) = simulate(&tree, &Push { node, vector: push }, &SimConfig::default())
            else {
                continue;
            };
            tried += 1;
            let ranked = PredictivePolicy {
                predictor: &PhysicsPredictor,
            }
            .rank(&tree, &out.final_positions)
            .unwrap();
            let total: f64 = ranked.iter().map(|c| c.affordance).sum();
            assert!((total - 1.0).abs() < 1e-9, "{total}");
            if ranked.iter().take(3).any(|c| c.node == node) {
                found += 1;
            }
        }
        assert!(tried >= 5, "{tried} pushes simulated");
        assert!(found * 10 >= tried * 7, "{found} of {tried} in the top 3");
    }
}
