//! Equality-constrained minimum-norm problems,
//!
//! ```text
//!     minimise ½|x|²  subject to  c(x) = 0,
//! ```
//!
//! which is what the steady-state push becomes in stiffness-scaled joint
//! coordinates x = √K θ (the elastic energy ½ Σ K|θ|² is then ½|x|²).
//!
//! Sequential quadratic programming: each iteration solves the Newton-KKT
//! system with the exact Lagrangian Hessian I + Σ λ_r ∇²c_r (the curvature
//! of the constraints, obtained by central differences of the analytic
//! λᵀ∂c/∂x, matters for large rotations), by the null-space method so that a
//! Hessian that is indefinite on the constraint tangent space can be
//! regularised there. Steps are globalised with an ℓ1 merit line search and
//! a second-order correction against the Maratos effect. Convergence is
//! quadratic near the solution; the report gives the final residuals.

use std::time::Instant;

use nalgebra::{DMatrix, DVector, SymmetricEigen};

/// c(x) and its Jacobian (rows × n).
pub type Constraints<'a> = dyn Fn(&DVector<f64>) -> (DVector<f64>, DMatrix<f64>) + 'a;

#[derive(Debug, Clone, Copy)]
pub struct SolverOptions {
    pub max_iterations: usize,
    /// Stop when |c|∞ is below this (units of c).
    pub constraint_tolerance: f64,
    /// … and |x + Jᵀλ|∞ is below this, relative to the size of the terms
    /// it sums ([`stationarity_residual`]),
    pub stationarity_tolerance: f64,
    /// … or the Newton step is below this, relative to max(1, |x|∞): the
    /// minimum is found to rounding, whatever the gradient test says.
    pub step_tolerance: f64,
    /// Give up with [`SolveError::OutOfTime`] once this passes: checked
    /// before each iteration and between the Hessian's columns, so a
    /// caller's deadline bounds the work to one Newton step's linear
    /// algebra beyond it (a 512-joint path's 1,536 unknowns take seconds a
    /// step).
    pub deadline: Option<Instant>,
}

impl Default for SolverOptions {
    fn default() -> Self {
        Self {
            max_iterations: 60,
            constraint_tolerance: 1e-12,
            stationarity_tolerance: 1e-11,
            step_tolerance: 1e-12,
            deadline: None,
        }
    }
}

#[derive(Debug, Clone)]
pub struct Solution {
    pub x: DVector<f64>,
    pub lambda: DVector<f64>,
    pub iterations: usize,
    /// |c(x)|∞.
    pub constraint_residual: f64,
    /// [`stationarity_residual`] at the solution.
    pub stationarity_residual: f64,
}

#[derive(Debug, Clone, thiserror::Error)]
pub enum SolveError {
    #[error(
        "no convergence in {iterations} iterations (constraint residual {constraint_residual:.3e}, stationarity {stationarity_residual:.3e})"
    )]
    NotConverged {
        iterations: usize,
        constraint_residual: f64,
        stationarity_residual: f64,
    },
    #[error("the constraints are degenerate (their Jacobian lost rank)")]
    Degenerate,
    #[error("the deadline passed after {iterations} iterations")]
    OutOfTime { iterations: usize },
}

/// `eval(x)` returns c(x) and its Jacobian (rows × n); starts at x = 0.
pub fn solve(
    n: usize,
    eval: &Constraints<'_>,
    opts: &SolverOptions,
) -> Result<Solution, SolveError> {
    solve_from(DVector::zeros(n), eval, opts)
}

/// [`solve`] from a given start (a warm start along a continuation path).
pub fn solve_from(
    start: DVector<f64>,
    eval: &Constraints<'_>,
    opts: &SolverOptions,
) -> Result<Solution, SolveError> {
    let mut x = start;
    let (mut c, mut jac) = eval(&x);
    let mut lambda = least_squares_multipliers(&jac, &x).ok_or(SolveError::Degenerate)?;
    let mut penalty = 1.0f64;
    let mut last = (f64::INFINITY, f64::INFINITY);
    let out_of_time = |iterations| {
        opts.deadline
            .is_some_and(|d| Instant::now() > d)
            .then_some(SolveError::OutOfTime { iterations })
    };
    for iteration in 0..=opts.max_iterations {
        if let Some(e) = out_of_time(iteration) {
            return Err(e);
        }
        let stationarity = stationarity_residual(&x, &jac, &lambda);
        let constraint = c.amax();
        last = (constraint, stationarity);
        if constraint <= opts.constraint_tolerance && stationarity <= opts.stationarity_tolerance {
            return Ok(Solution {
                x,
                lambda,
                iterations: iteration,
                constraint_residual: constraint,
                stationarity_residual: stationarity,
            });
        }
        if iteration == opts.max_iterations {
            break;
        }
        let hessian =
            lagrangian_hessian(&x, &lambda, eval, opts.deadline).ok_or(SolveError::OutOfTime {
                iterations: iteration,
            })?;
        let (step, new_lambda) =
            newton_kkt_step(&x, &c, &jac, &hessian).ok_or(SolveError::Degenerate)?;
        penalty = penalty.max(2.0 * new_lambda.amax() + 1e-3);
        // Converged in x even where the gradient test cannot be met: with
        // λ ≈ 300 the reduced Hessian reaches 1e4, so a stationarity
        // residual of 1e-9 is a Newton correction of 1e-13 m·√K, which
        // rounding then undoes. This was the "did not converge (constraint
        // residual 0)" of stretched pinned holds: the state was the
        // minimum, the test asked for more than f64 can give.
        if constraint <= opts.constraint_tolerance
            && step.amax() <= opts.step_tolerance * x.amax().max(1.0)
        {
            return Ok(Solution {
                x,
                lambda,
                iterations: iteration,
                constraint_residual: constraint,
                stationarity_residual: stationarity,
            });
        }
        let merit =
            |x: &DVector<f64>, c: &DVector<f64>| 0.5 * x.norm_squared() + penalty * c.lp_norm(1);
        // Rounding error of evaluating the merit: a change smaller than this
        // cannot be seen, so a step is judged by Armijo's test only down to
        // it. Near the solution the last Newton steps improve the energy by
        // less than that (|Zᵀx|² ≈ 1e-18 when the projected gradient is
        // 1e-9); demanding a visible decrease rejected them, the search
        // shrank the step to nothing, and the solve stalled a few digits
        // short of the stationarity test.
        let current = merit(&x, &c);
        let noise = 64.0 * f64::EPSILON * current.abs().max(1.0);
        // Directional derivative of the merit along an SQP step (J d = −c).
        let slope = x.dot(&step) - penalty * c.lp_norm(1);
        let mut alpha = 1.0;
        let mut accepted = None;
        for attempt in 0..40 {
            let trial = &x + &step * alpha;
            let (tc, tj) = eval(&trial);
            if merit(&trial, &tc) <= current + 1e-4 * alpha * slope.min(0.0) + noise {
                accepted = Some((trial, tc, tj));
                break;
            }
            if attempt == 0 {
                // Second-order correction: pull the full step back onto the
                // constraints before shortening it.
                if let Some(correction) = min_norm_correction(&jac, &tc) {
                    let corrected = &trial + correction;
                    let (cc, cj) = eval(&corrected);
                    if merit(&corrected, &cc) <= current + 1e-4 * slope.min(0.0) + noise {
                        accepted = Some((corrected, cc, cj));
                        break;
                    }
                }
            }
            alpha *= 0.5;
        }
        let Some((nx, nc, nj)) = accepted else {
            break; // no progress possible along this direction
        };
        x = nx;
        c = nc;
        jac = nj;
        lambda = new_lambda;
    }
    Err(SolveError::NotConverged {
        iterations: opts.max_iterations,
        constraint_residual: last.0,
        stationarity_residual: last.1,
    })
}

/// |x + Jᵀλ|∞ relative to the largest term it sums: max(1, |x|∞,
/// max_i Σ_r |J_ri λ_r|). Rounding leaves about ε·Σ_r |J_ri λ_r| in each
/// component whatever the solver does, and near a stretched-out pinned hold
/// λ grows to 1e4 while x stays O(1): a test relative to |x| alone then asks
/// for more digits than f64 has, and a converged solve was reported as
/// not converged (the "constraint residual 0" discards).
pub fn stationarity_residual(x: &DVector<f64>, jac: &DMatrix<f64>, lambda: &DVector<f64>) -> f64 {
    let residual = x + jac.transpose() * lambda;
    let terms = jac.abs().transpose() * lambda.abs();
    residual.amax() / x.amax().max(terms.amax()).max(1.0)
}

/// Solves (JJᵀ) y = rhs in the least-squares sense, tolerating a
/// rank-deficient J (a straight chain cannot move its tip along itself).
fn solve_normal_equations(jac: &DMatrix<f64>, rhs: &DVector<f64>) -> Option<DVector<f64>> {
    let jjt = jac * jac.transpose();
    let eps = 1e-13 * jjt.amax().max(1e-300);
    jjt.svd(true, true).solve(rhs, eps).ok()
}

/// λ minimising |x + Jᵀλ|: the multipliers that best explain x.
///
/// Solved as a least-squares problem in Jᵀ itself (SVD), not through the
/// normal equations JJᵀλ = −Jx: those square J's condition number, and at
/// pinned holds on nearly straight chains (cond J ≈ 1e3 and |λ| ≈ 300) the
/// rounding error they leave in λ kept the stationarity residual near
/// 1e-9, above the stopping test, so converged solves were reported as
/// not converged.
fn least_squares_multipliers(jac: &DMatrix<f64>, x: &DVector<f64>) -> Option<DVector<f64>> {
    let jt = jac.transpose();
    let eps = 1e-13 * jt.amax().max(1e-300);
    jt.svd(true, true).solve(&-x, eps).ok()
}

/// −J⁺c: the smallest move that cancels c to first order (as far as the
/// Jacobian's range allows).
fn min_norm_correction(jac: &DMatrix<f64>, c: &DVector<f64>) -> Option<DVector<f64>> {
    solve_normal_equations(jac, c).map(|y| -(jac.transpose() * y))
}

/// I + Σ λ_r ∇²c_r, the curvature term by central differences of Jᵀλ.
fn lagrangian_hessian(
    x: &DVector<f64>,
    lambda: &DVector<f64>,
    eval: &Constraints,
    deadline: Option<Instant>,
) -> Option<DMatrix<f64>> {
    let n = x.len();
    let mut h = DMatrix::identity(n, n);
    for i in 0..n {
        if i % 64 == 0 && deadline.is_some_and(|d| Instant::now() > d) {
            return None;
        }
        let step = 1e-5 * x[i].abs().max(1.0);
        let mut plus = x.clone();
        plus[i] += step;
        let mut minus = x.clone();
        minus[i] -= step;
        let gp = eval(&plus).1.transpose() * lambda;
        let gm = eval(&minus).1.transpose() * lambda;
        let column = (gp - gm) / (2.0 * step);
        for r in 0..n {
            h[(r, i)] += column[r];
        }
    }
    Some((&h + h.transpose()) * 0.5)
}

/// Null-space solution of the Newton-KKT system
/// [H Jᵀ; J 0] [d; λ] = [−x; −c], with H regularised on the tangent space
/// until it is positive definite there. Returns the step and new multipliers.
fn newton_kkt_step(
    x: &DVector<f64>,
    c: &DVector<f64>,
    jac: &DMatrix<f64>,
    hessian: &DMatrix<f64>,
) -> Option<(DVector<f64>, DVector<f64>)> {
    let n = x.len();
    let normal = min_norm_correction(jac, c)?;
    // Tangent basis: eigenvectors of JᵀJ with (numerically) zero eigenvalue.
    // Rank-revealing, so a Jacobian that lost rank still gets a full basis.
    let eig = SymmetricEigen::new(jac.transpose() * jac);
    let tolerance = 1e-12 * eig.eigenvalues.amax().max(1e-300);
    let tangent_columns: Vec<usize> = (0..n)
        .filter(|&i| eig.eigenvalues[i] <= tolerance)
        .collect();
    let tangent_dim = tangent_columns.len();
    let z = DMatrix::from_fn(n, tangent_dim, |r, col| {
        eig.eigenvectors[(r, tangent_columns[col])]
    });
    let gradient = x + hessian * &normal;
    let reduced_rhs = -(z.transpose() * &gradient);
    // Modified Newton on the tangent space: eigenvalues of the reduced
    // Hessian are made positive (|e|, floored), which leaves a positive
    // definite reduced Hessian — the usual case near a minimum — untouched.
    let reduced = SymmetricEigen::new(z.transpose() * hessian * &z);
    let scale = reduced.eigenvalues.amax().max(1.0);
    let projected = reduced.eigenvectors.transpose() * reduced_rhs;
    let scaled = DVector::from_fn(tangent_dim, |i, _| {
        projected[i] / reduced.eigenvalues[i].abs().max(1e-10 * scale)
    });
    let tangent = &reduced.eigenvectors * scaled;
    let step = normal + &z * tangent;
    // Multipliers from the first KKT row: Jᵀλ = −(x + H d).
    let residual = x + hessian * &step;
    let lambda = least_squares_multipliers(jac, &residual)?;
    Some((step, lambda))
}
