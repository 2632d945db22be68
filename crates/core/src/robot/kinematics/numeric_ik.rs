//! Inverse kinematics for any serial chain ([`crate::robot::model::urdf_chain::Chain`]):
//! damped least squares (Levenberg-Marquardt) on the tip's pose error, the
//! joints clamped into their limits after every step, restarted from random
//! configurations inside the limits when a start does not converge (as
//! TRAC-IK restarts KDL's solver). The first start is the reference
//! configuration, and for a redundant chain (7 joints) every step also
//! moves toward the reference in the Jacobian's null space, so the answer
//! is the solution near the reference rather than any.
//!
//! A start that stalls, its squared error down by less than
//! [`STALL_PROGRESS`] over [`STALL_WINDOW`] iterations, is abandoned: in
//! plans, most starts fail (a pose out of reach, or a local minimum against
//! a joint limit) and end tens of centimetres away, and running each to
//! its iteration cap made the failures most of a plan's time. A start that
//! converges does so in a few iterations, or keeps descending.

use nalgebra::{DVector, Isometry3, Matrix6, Vector3, Vector6};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use crate::robot::model::urdf_chain::{Chain, random_configuration};

/// Iterations over which a start must make progress.
pub const STALL_WINDOW: usize = 10;
/// The least relative fall of the squared error over [`STALL_WINDOW`]
/// iterations (1 %): below it the start has stalled.
pub const STALL_PROGRESS: f64 = 0.01;

/// Tolerances and budgets.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IkOptions {
    /// Position tolerance of the tip (m).
    pub position_tolerance: f64,
    /// Orientation tolerance of the tip (rad).
    pub orientation_tolerance: f64,
    /// Iterations per start.
    pub iterations: usize,
    /// Starts in all (the reference first).
    pub restarts: usize,
    /// Gain of the null-space pull toward the reference (redundant chains).
    pub null_space_gain: f64,
    pub seed: u64,
}

impl Default for IkOptions {
    fn default() -> Self {
        Self {
            position_tolerance: 1e-5,
            orientation_tolerance: 1e-4,
            iterations: 100,
            restarts: 100,
            null_space_gain: 0.05,
            seed: 1,
        }
    }
}

/// The pose error (translation, rotation vector) from `current` to
/// `target`, both in the base frame.
fn pose_error(current: &Isometry3<f64>, target: &Isometry3<f64>) -> Vector6<f64> {
    let dp: Vector3<f64> = target.translation.vector - current.translation.vector;
    let dr = (target.rotation * current.rotation.inverse()).scaled_axis();
    Vector6::new(dp.x, dp.y, dp.z, dr.x, dr.y, dr.z)
}

/// A joint configuration putting the tip at `target` (base frame), near
/// `reference`, or `None` when no start converges.
pub fn solve(
    chain: &Chain,
    target: &Isometry3<f64>,
    reference: &[f64],
    options: &IkOptions,
) -> Option<Vec<f64>> {
    let n = chain.dof();
    if reference.len() != n {
        return None;
    }
    let limits = chain.limits();
    let clamp = |q: &mut DVector<f64>| {
        for (k, (lo, hi)) in limits.iter().enumerate() {
            q[k] = q[k].clamp(*lo, *hi);
        }
    };
    let mut rng = ChaCha8Rng::seed_from_u64(options.seed);
    let reference = DVector::from_column_slice(reference);
    let mut held = vec![false; n];
    let mut step = DVector::zeros(n);
    for start in 0..options.restarts.max(1) {
        let mut q = if start == 0 {
            reference.clone()
        } else {
            DVector::from_vec(random_configuration(chain, &mut rng))
        };
        clamp(&mut q);
        let mut lambda = 1e-3;
        let (pose, mut jac) = chain.jacobian(q.as_slice());
        let mut error = pose_error(&pose, target);
        let mut cost = error.norm_squared();
        // The squared error at the last STALL_WINDOW iterations (a ring).
        let mut recent = [f64::INFINITY; STALL_WINDOW];
        for iteration in 0..options.iterations {
            if error.fixed_rows::<3>(0).norm() < options.position_tolerance
                && error.fixed_rows::<3>(3).norm() < options.orientation_tolerance
            {
                return Some(q.as_slice().to_vec());
            }
            let slot = iteration % STALL_WINDOW;
            if cost > (1.0 - STALL_PROGRESS) * recent[slot] {
                break;
            }
            recent[slot] = cost;
            // Δq = Jᵀ (J Jᵀ + λ² I)⁻¹ e, and for a redundant chain a pull
            // toward the reference in the null space of J. A joint at a
            // limit that the step would push past is held there and the
            // step solved again without it (an active set): clamping alone
            // stalls the solver on poses whose solutions lie near limits.
            // Built column by column on 6-vectors (J is stored by columns):
            // the solver's time is most of a plan's on numerical-IK arms.
            let column = |k: usize| Vector6::from_column_slice(&jac.as_slice()[6 * k..6 * k + 6]);
            held.fill(false);
            step.fill(0.0);
            for _ in 0..n.min(4) {
                // J Jᵀ + λ² I over the free joints (6 × 6, symmetric
                // positive definite).
                let mut jjt = Matrix6::from_diagonal_element(lambda * lambda);
                for k in (0..n).filter(|&k| !held[k]) {
                    let c = column(k);
                    jjt += c * c.transpose();
                }
                let Some(cholesky) = jjt.cholesky() else {
                    break;
                };
                let y = cholesky.solve(&error);
                for k in 0..n {
                    step[k] = if held[k] { 0.0 } else { column(k).dot(&y) };
                }
                if n > 6 {
                    // (I − J⁺J) v = v − Jᵀ (J Jᵀ + λ² I)⁻¹ J v, with the
                    // held joints left where they are.
                    let mut jv = Vector6::zeros();
                    for k in (0..n).filter(|&k| !held[k]) {
                        jv += column(k) * ((reference[k] - q[k]) * options.null_space_gain);
                    }
                    let z = cholesky.solve(&jv);
                    for k in (0..n).filter(|&k| !held[k]) {
                        step[k] +=
                            (reference[k] - q[k]) * options.null_space_gain - column(k).dot(&z);
                    }
                }
                let mut changed = false;
                for (k, (lo, hi)) in limits.iter().enumerate() {
                    let pushes_out = (q[k] <= *lo + 1e-12 && step[k] < 0.0)
                        || (q[k] >= *hi - 1e-12 && step[k] > 0.0);
                    if pushes_out && !held[k] {
                        held[k] = true;
                        changed = true;
                    }
                }
                if !changed {
                    break;
                }
            }
            let mut candidate = &q + &step;
            clamp(&mut candidate);
            let (p, j) = chain.jacobian(candidate.as_slice());
            let err = pose_error(&p, target);
            let c = err.norm_squared();
            if c < cost {
                q = candidate;
                jac = j;
                error = err;
                cost = c;
                lambda = (lambda * 0.5).max(1e-6);
            } else {
                lambda = (lambda * 4.0).min(10.0);
            }
        }
        if error.fixed_rows::<3>(0).norm() < options.position_tolerance
            && error.fixed_rows::<3>(3).norm() < options.orientation_tolerance
        {
            return Some(q.as_slice().to_vec());
        }
    }
    None
}
