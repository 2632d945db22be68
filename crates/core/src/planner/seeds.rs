//! Where the push search starts when the objective is not a full target
//! shape (the contact policy was trained only for those): from the tree's
//! geometry. For `clear`, the branches that intrude into a region and their
//! ancestors, pushed away from the region; for `reach`, the node and its
//! ancestors, pushed toward the region; for a weighted shape, the worst
//! listed nodes and their ancestors, pushed toward their targets.

use nalgebra::{Point3, Vector3};

use super::objective::Objective;
use super::predict::{ContactPolicy, PredictError};
use super::search::{MAX_PUSH, MIN_PUSH};
use crate::sim::Push;
use crate::tree::Tree;

/// Length of a seed push when the geometry does not say (m): the middle of
/// the trained range.
const SEED_LENGTH: f64 = 0.10;

/// Up to `max` pushes (distinct contact nodes), most promising first.
pub fn geometric_seeds(tree: &Tree, objective: &Objective, max: usize) -> Vec<Push> {
    // (node whose position should move, direction, how far) in order.
    let goals: Vec<(usize, Vector3<f64>, f64)> = match objective {
        Objective::Clear { .. } => {
            let mut intrusions = objective.scorer().intrusions(tree, tree.positions());
            intrusions.sort_by(|a, b| b.depth.total_cmp(&a.depth));
            intrusions
                .iter()
                .map(|i| (i.node, i.away, i.depth + 0.03))
                .collect()
        }
        Objective::Reach { node, region } => {
            let p = tree.position(*node);
            let to = region.centre() - p;
            vec![(*node, to, to.norm())]
        }
        Objective::Shape { targets, weights } => {
            let mut worst: Vec<(usize, f64)> = (1..tree.len())
                .map(|j| {
                    let w = weights.as_ref().map_or(1.0, |w| w[j]);
                    (j, w * (targets[j] - tree.position(j)).norm())
                })
                .filter(|(_, e)| *e > 0.0)
                .collect();
            worst.sort_by(|a, b| b.1.total_cmp(&a.1));
            worst
                .into_iter()
                .map(|(j, _)| {
                    let to = targets[j] - tree.position(j);
                    (j, to, to.norm())
                })
                .collect()
        }
    };
    let mut seeds: Vec<Push> = Vec::new();
    // Breadth first over the goals: each goal's own node, then the
    // parents, so that several intruding branches all get a seed.
    let paths: Vec<Vec<usize>> = goals
        .iter()
        .map(|(node, _, _)| {
            let mut path = tree.path_to_root(*node);
            path.pop(); // the root is fixed
            path
        })
        .collect();
    let depth = paths.iter().map(Vec::len).max().unwrap_or(0);
    'outer: for level in 0..depth {
        for ((_, direction, distance), path) in goals.iter().zip(&paths) {
            let Some(&contact) = path.get(level) else {
                continue;
            };
            if seeds.iter().any(|s| s.node == contact) {
                continue;
            }
            if let Some(vector) = seed_vector(tree, contact, direction, *distance) {
                seeds.push(Push {
                    node: contact,
                    vector,
                });
                if seeds.len() >= max {
                    break 'outer;
                }
            }
        }
    }
    seeds
}

/// A push at `contact` along `direction` with the part along the contact
/// branch removed (a push along a branch cannot be held), its length
/// `distance` clamped into the trained range.
pub(super) fn seed_vector(
    tree: &Tree,
    contact: usize,
    direction: &Vector3<f64>,
    distance: f64,
) -> Option<Vector3<f64>> {
    let axis = tree.branch_direction(contact)?;
    let across = direction - axis * direction.dot(&axis);
    let d = if across.norm() > 0.2 * direction.norm() {
        across
    } else {
        *direction
    };
    let n = d.norm();
    if !(n.is_finite() && n > 1e-9) {
        return None;
    }
    let length = if distance.is_finite() && distance > 0.0 {
        distance.clamp(MIN_PUSH, MAX_PUSH)
    } else {
        SEED_LENGTH
    };
    Some(d / n * length)
}

/// The policy's ranking as (rank, push).
pub(super) fn ranked(
    policy: &dyn ContactPolicy,
    tree: &Tree,
    targets: &[Point3<f64>],
) -> Result<Vec<(usize, Push)>, PredictError> {
    Ok(policy
        .rank(tree, targets)?
        .iter()
        .map(|c| {
            let push = Push {
                node: c.node,
                vector: Vector3::from(c.push),
            };
            (c.rank, push)
        })
        .collect())
}

/// `a` and `b` taken in turns, each node once.
pub(super) fn interleave(a: &[Push], b: &[Push]) -> Vec<Push> {
    let mut out: Vec<Push> = Vec::new();
    for k in 0..a.len().max(b.len()) {
        for p in [a.get(k), b.get(k)].into_iter().flatten() {
            if !out.iter().any(|q| q.node == p.node) {
                out.push(*p);
            }
        }
    }
    out
}
