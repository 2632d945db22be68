//! Choosing the next probe pushes: the ones that most reduce the
//! posterior's uncertainty.
//!
//! Candidates are pushes at the tree's leaves (the longest lever on every
//! joint of their path), in four directions perpendicular to the leaf's
//! branch, of a fixed length (shortened once when the simulator cannot
//! realise it). A candidate's value is its expected information gain
//! about x = ln K_s under the linearised model at the current estimate:
//!
//! IG = ½ (ln det(H + JᵀJ) − ln det H),
//!
//! with H the current posterior precision and J the candidate's whitened
//! position Jacobian. Probes are picked greedily, each adding its JᵀJ to
//! H before the next is scored: a second push along the same path is worth
//! less than the first, which is what spreads the probes over the tree.
//! A global factor is invisible in positions, so these gains are about
//! ratios; a force measured with any probe fixes the level.

use std::sync::atomic::AtomicUsize;

use nalgebra::{DMatrix, Vector3};
use rayon::prelude::*;

use super::fit::Posterior;
use super::{IdentifyConfig, Probe};
use crate::sim::{ContactModel, Push};
use crate::tree::Tree;

/// One proposed probe.
#[derive(Debug, Clone, PartialEq)]
pub struct ProposedProbe {
    pub push: Push,
    pub contact: ContactModel,
    /// Expected information gain (nats) given the probes chosen before it.
    pub information_gain: f64,
}

/// What to propose.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProbeRequest {
    pub count: usize,
    /// Length of each push (m).
    pub push_length: f64,
    pub contact: ContactModel,
}

impl Default for ProbeRequest {
    /// Five 12 cm slot pushes (the paper pushes 5–15 cm).
    fn default() -> Self {
        Self {
            count: 5,
            push_length: 0.12,
            contact: ContactModel::Slot,
        }
    }
}

/// Four push directions perpendicular to the branch ending at `node`.
fn directions(tree: &Tree, node: usize) -> [Vector3<f64>; 4] {
    let d = tree.branch_direction(node).unwrap_or_else(Vector3::z);
    let side = d.cross(&Vector3::z());
    let u = if side.norm() > 1e-6 {
        side.normalize()
    } else {
        Vector3::x()
    };
    let w = d.cross(&u).normalize();
    [u, -u, w, -w]
}

/// ln det of a symmetric positive definite matrix (−∞ when it is not).
fn log_det(m: &DMatrix<f64>) -> f64 {
    m.clone().cholesky().map_or(f64::NEG_INFINITY, |c| {
        2.0 * c.l().diagonal().iter().map(|v| v.ln()).sum::<f64>()
    })
}

/// Up to `request.count` probes for `tree` given `posterior` (the prior,
/// or the result of earlier probes), keeping only pushes `allowed` says
/// the arm can make. Fewer come back when fewer candidates simulate.
pub fn choose_probes(
    tree: &Tree,
    posterior: &Posterior,
    request: &ProbeRequest,
    config: &IdentifyConfig,
    allowed: &(dyn Fn(&Push) -> bool + Sync),
) -> Vec<ProposedProbe> {
    let count = AtomicUsize::new(0);
    let leaves: Vec<usize> = (1..tree.len()).filter(|&j| tree.is_leaf(j)).collect();
    let candidates: Vec<(Push, DMatrix<f64>)> = leaves
        .par_iter()
        .flat_map_iter(|&node| directions(tree, node).map(|d| (node, d)))
        .filter_map(|(node, d)| {
            [1.0, 0.5].iter().find_map(|&scale| {
                let push = Push {
                    node,
                    vector: d * request.push_length * scale,
                };
                if !allowed(&push) {
                    return None;
                }
                let probe = Probe {
                    push,
                    contact: request.contact,
                    observed: tree.positions().iter().map(|p| Some(*p)).collect(),
                    contact_force: None,
                };
                let jac =
                    super::fit::probe_jacobian(tree, &posterior.mean, &probe, config, &count)?;
                Some((push, jac.transpose() * jac))
            })
        })
        .collect();
    let mut precision = posterior
        .covariance
        .clone()
        .try_inverse()
        .unwrap_or_else(|| posterior.prior_precision.clone());
    let mut chosen = Vec::new();
    let mut used = vec![false; candidates.len()];
    for _ in 0..request.count {
        let base = log_det(&precision);
        let best = candidates
            .iter()
            .enumerate()
            .filter(|(k, _)| !used[*k])
            .map(|(k, (_, info))| (k, 0.5 * (log_det(&(&precision + info)) - base)))
            .max_by(|a, b| a.1.total_cmp(&b.1));
        let Some((k, gain)) = best else { break };
        used[k] = true;
        precision += &candidates[k].1;
        chosen.push(ProposedProbe {
            push: candidates[k].0,
            contact: request.contact,
            information_gain: gain,
        });
    }
    chosen
}
