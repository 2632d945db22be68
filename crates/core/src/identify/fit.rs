//! The maximum a posteriori fit and its Laplace posterior (see the module
//! docs of [`super`]).

use std::sync::atomic::{AtomicUsize, Ordering};

use nalgebra::{DMatrix, DVector, Vector3};
use rayon::prelude::*;

use super::{
    FitReport, Identification, IdentifyConfig, Probe, Rejected, Scale, Status, with_stiffness,
};
use crate::sim::{ContactModel, Hold, PushOutcome, SimConfig, SimError, simulate_from};
use crate::tree::Tree;

/// z of a two-sided 90 % interval.
const Z90: f64 = 1.644_853_626_951_472_2;

/// Forward-difference step on ln K_s (the simulator solves to 1e-12).
const STEP: f64 = 1e-4;

/// The posterior over x = ln K_s of the branches (index b ↔ node b + 1).
#[derive(Debug, Clone, PartialEq)]
pub struct Posterior {
    /// MAP estimate.
    pub mean: DVector<f64>,
    /// Laplace covariance (JᵀJ + Σ⁻¹)⁻¹.
    pub covariance: DMatrix<f64>,
    /// Prior mean and precision Σ⁻¹.
    pub prior_mean: DVector<f64>,
    pub prior_precision: DMatrix<f64>,
}

impl Posterior {
    /// The prior alone (nothing observed yet).
    pub fn prior(tree: &Tree, config: &IdentifyConfig) -> Self {
        let m = prior_mean(tree);
        let p = m.len();
        let (s2, g2) = (
            config.prior.branch_log_sigma.powi(2),
            config.prior.global_log_sigma.powi(2),
        );
        let cov = DMatrix::from_fn(p, p, |i, j| if i == j { s2 + g2 } else { g2 });
        let precision = cov
            .clone()
            .try_inverse()
            .expect("σ²I + σ_g²11ᵀ is positive definite");
        Self {
            mean: m.clone(),
            covariance: cov,
            prior_mean: m,
            prior_precision: precision,
        }
    }

    /// Covariance of x_b − mean(x): what positions can tell.
    pub fn relative_covariance(&self) -> DMatrix<f64> {
        let p = self.mean.len();
        let centre = DMatrix::from_fn(p, p, |i, j| {
            let identity = if i == j { 1.0 } else { 0.0 };
            identity - 1.0 / p as f64
        });
        &centre * &self.covariance * &centre
    }
}

fn prior_mean(tree: &Tree) -> DVector<f64> {
    DVector::from_iterator(
        tree.len() - 1,
        (1..tree.len()).map(|j| tree.branch(j).expect("non-root").stiffness.ln()),
    )
}

/// `tree`'s geometry with K_s = exp(x).
pub(super) fn tree_at(tree: &Tree, x: &DVector<f64>) -> Tree {
    let mut k = vec![0.0; tree.len()];
    for (b, v) in x.iter().enumerate() {
        k[b + 1] = v.exp();
    }
    with_stiffness(tree, &k)
}

/// What the fit knows about one accepted probe.
struct Observed<'a> {
    index: usize,
    probe: &'a Probe,
    /// Branch parameters on its path (b indices).
    path: Vec<usize>,
    rows: usize,
}

impl Observed<'_> {
    fn config(&self) -> SimConfig {
        SimConfig {
            contact: self.probe.contact,
            ..SimConfig::default()
        }
    }

    /// Whitened residuals of a simulated outcome.
    fn residual(&self, out: &PushOutcome, config: &IdentifyConfig) -> DVector<f64> {
        let mut r = Vec::with_capacity(self.rows);
        for (sim, obs) in out.final_positions.iter().zip(&self.probe.observed) {
            if let Some(obs) = obs {
                r.extend((sim - obs).iter().map(|d| d / config.noise.position));
            }
        }
        if let Some(f) = self.probe.contact_force {
            let scale = config.noise.force * f.norm();
            let sim = Vector3::from(out.report.contact_force);
            r.extend((sim - f).iter().map(|d| d / scale));
        }
        DVector::from_vec(r)
    }

    /// Simulates the probe on `tree`; a slot hold that slid to a fork (or
    /// any failure) is an error: the map from stiffness to positions is
    /// not smooth there.
    fn simulate(
        &self,
        tree: &Tree,
        warm: Option<&[Vector3<f64>]>,
        count: &AtomicUsize,
    ) -> Result<PushOutcome, Rejected> {
        count.fetch_add(1, Ordering::Relaxed);
        let out =
            simulate_from(tree, &self.probe.push, &self.config(), warm).map_err(|e| Rejected {
                probe: self.index,
                reason: e.kind().into(),
                message: e.to_string(),
            })?;
        if self.probe.contact == ContactModel::Slot && out.report.hold != Hold::OnAxis {
            return Err(Rejected {
                probe: self.index,
                reason: "hold_switched".into(),
                message: "the slot slid along the branch to a fork and caught there: the hold switched, so the probe says little about stiffness and is left out".into(),
            });
        }
        Ok(out)
    }
}

/// One evaluation of every accepted probe at x.
struct State {
    x: DVector<f64>,
    outcomes: Vec<PushOutcome>,
    residuals: Vec<DVector<f64>>,
    cost: f64,
}

fn evaluate(
    tree: &Tree,
    probes: &[Observed],
    x: DVector<f64>,
    warm: Option<&[PushOutcome]>,
    prior: &Posterior,
    config: &IdentifyConfig,
    count: &AtomicUsize,
) -> Result<State, Rejected> {
    let at = tree_at(tree, &x);
    let outcomes = probes
        .par_iter()
        .enumerate()
        .map(|(k, p)| {
            let w = warm.map(|w| w[k].joint_rotations.as_slice());
            p.simulate(&at, w, count)
        })
        .collect::<Result<Vec<_>, _>>()?;
    let residuals: Vec<DVector<f64>> = probes
        .iter()
        .zip(&outcomes)
        .map(|(p, o)| p.residual(o, config))
        .collect();
    let d = &x - &prior.prior_mean;
    let cost = 0.5 * residuals.iter().map(|r| r.norm_squared()).sum::<f64>()
        + 0.5 * (d.transpose() * &prior.prior_precision * &d)[(0, 0)];
    Ok(State {
        x,
        outcomes,
        residuals,
        cost,
    })
}

/// Jacobian of the stacked whitened residuals by forward differences.
fn jacobian(
    tree: &Tree,
    probes: &[Observed],
    state: &State,
    config: &IdentifyConfig,
    count: &AtomicUsize,
) -> DMatrix<f64> {
    let p = state.x.len();
    let rows: usize = probes.iter().map(|o| o.rows).sum();
    let jobs: Vec<(usize, usize)> = probes
        .iter()
        .enumerate()
        .flat_map(|(k, o)| o.path.iter().map(move |&b| (k, b)))
        .collect();
    let columns: Vec<(usize, usize, Option<DVector<f64>>)> = jobs
        .par_iter()
        .map(|&(k, b)| {
            let probe = &probes[k];
            let warm = Some(state.outcomes[k].joint_rotations.as_slice());
            let column = [STEP, -STEP].iter().find_map(|&h| {
                let mut x = state.x.clone();
                x[b] += h;
                let out = probe.simulate(&tree_at(tree, &x), warm, count).ok()?;
                Some((probe.residual(&out, config) - &state.residuals[k]) / h)
            });
            (k, b, column)
        })
        .collect();
    let mut offsets = Vec::with_capacity(probes.len());
    let mut at = 0;
    for o in probes {
        offsets.push(at);
        at += o.rows;
    }
    let mut jac = DMatrix::zeros(rows, p);
    for (k, b, column) in columns {
        if let Some(c) = column {
            jac.view_mut((offsets[k], b), (c.len(), 1)).copy_from(&c);
        }
    }
    jac
}

fn stacked(state: &State) -> DVector<f64> {
    let rows: usize = state.residuals.iter().map(|r| r.len()).sum();
    DVector::from_iterator(rows, state.residuals.iter().flat_map(|r| r.iter().copied()))
}

/// Root mean square of the position residuals, in metres.
fn position_rms(probes: &[Observed], state: &State, config: &IdentifyConfig) -> f64 {
    let (mut sum, mut count) = (0.0, 0usize);
    for (o, r) in probes.iter().zip(&state.residuals) {
        let positions = o.rows
            - if o.probe.contact_force.is_some() {
                3
            } else {
                0
            };
        sum += r.rows(0, positions).norm_squared();
        count += positions;
    }
    (sum / count.max(1) as f64).sqrt() * config.noise.position
}

/// Identifies the stiffness of `tree`'s branches from `probes` (checked
/// first with [`super::validate_probes`]). Probes whose simulation fails or
/// whose slot hold switches at the prior are left out and reported; with
/// none left, the result is the prior, every branch `unobserved`.
pub fn identify(tree: &Tree, probes: &[Probe], config: &IdentifyConfig) -> Identification {
    let count = AtomicUsize::new(0);
    let prior = Posterior::prior(tree, config);
    let prior_tree = tree_at(tree, &prior.prior_mean);
    let mut rejected = Vec::new();
    let mut accepted = Vec::new();
    for (index, probe) in probes.iter().enumerate() {
        let observed = Observed::new(index, probe, tree);
        match observed.simulate(&prior_tree, None, &count) {
            Ok(_) => accepted.push(observed),
            Err(why) => rejected.push(why),
        }
    }
    let mut state = evaluate(
        tree,
        &accepted,
        prior.prior_mean.clone(),
        None,
        &prior,
        config,
        &count,
    )
    .expect("every accepted probe simulates at the prior");
    let prior_rms = position_rms(&accepted, &state, config);
    let mut mu = 1e-3;
    let (mut iterations, mut converged) = (0, accepted.is_empty());
    while !converged && iterations < config.max_iterations {
        iterations += 1;
        let jac = jacobian(tree, &accepted, &state, config, &count);
        let r = stacked(&state);
        let d = &state.x - &prior.prior_mean;
        let gradient = jac.transpose() * &r + &prior.prior_precision * d;
        let hessian = jac.transpose() * &jac + &prior.prior_precision;
        let mut improved = false;
        while mu < 1e10 {
            let mut damped = hessian.clone();
            for i in 0..damped.nrows() {
                damped[(i, i)] += mu * hessian[(i, i)];
            }
            let Some(step) = damped.cholesky().map(|c| c.solve(&(-&gradient))) else {
                mu *= 10.0;
                continue;
            };
            let trial = evaluate(
                tree,
                &accepted,
                &state.x + &step,
                Some(&state.outcomes),
                &prior,
                config,
                &count,
            );
            match trial {
                Ok(trial) if trial.cost <= state.cost => {
                    let gain = state.cost - trial.cost;
                    converged = step.amax() < 1e-5 || gain <= 1e-9 * state.cost.max(1e-12);
                    state = trial;
                    mu = (mu / 3.0).max(1e-9);
                    improved = true;
                    break;
                }
                _ => mu *= 4.0,
            }
        }
        if !improved {
            converged = true;
        }
    }
    let jac = jacobian(tree, &accepted, &state, config, &count);
    let precision = jac.transpose() * &jac + &prior.prior_precision;
    let covariance = precision
        .clone()
        .try_inverse()
        .unwrap_or_else(|| prior.covariance.clone());
    let posterior = Posterior {
        mean: state.x.clone(),
        covariance,
        prior_mean: prior.prior_mean.clone(),
        prior_precision: prior.prior_precision.clone(),
    };
    let absolute = accepted.iter().any(|o| o.probe.contact_force.is_some());
    let p = posterior.mean.len();
    let (estimate, spread) = if absolute {
        (posterior.mean.clone(), posterior.covariance.clone())
    } else {
        let shift = prior.prior_mean.mean() - posterior.mean.mean();
        (
            posterior.mean.add_scalar(shift),
            posterior.relative_covariance(),
        )
    };
    let mut on_path = vec![false; p];
    for o in &accepted {
        for &b in &o.path {
            on_path[b] = true;
        }
    }
    let n = tree.len();
    let (mut stiffness, mut interval, mut status) = (vec![None; n], vec![None; n], vec![None; n]);
    let mut k = vec![0.0; n];
    for b in 0..p {
        let sd = spread[(b, b)].max(0.0).sqrt();
        let x = estimate[b];
        k[b + 1] = x.exp();
        stiffness[b + 1] = Some(x.exp());
        interval[b + 1] = Some(((x - Z90 * sd).exp(), (x + Z90 * sd).exp()));
        status[b + 1] = Some(if !on_path[b] {
            Status::Unobserved
        } else if sd <= config.identified_log_sigma {
            Status::Identified
        } else {
            Status::Weak
        });
    }
    let observations = accepted.iter().map(|o| o.rows).sum();
    Identification {
        stiffness,
        interval,
        status,
        scale: if absolute {
            Scale::Absolute
        } else {
            Scale::Relative
        },
        tree: with_stiffness(tree, &k),
        fit: FitReport {
            iterations,
            converged,
            position_rms: position_rms(&accepted, &state, config),
            prior_position_rms: prior_rms,
            observations,
            simulations: count.load(Ordering::Relaxed),
        },
        rejected,
        posterior,
    }
}

impl<'a> Observed<'a> {
    fn new(index: usize, probe: &'a Probe, tree: &Tree) -> Self {
        let rows = 3 * probe.observed.iter().flatten().count()
            + if probe.contact_force.is_some() { 3 } else { 0 };
        Self {
            index,
            probe,
            path: tree
                .path_to_root(probe.push.node)
                .into_iter()
                .filter(|&j| j != 0)
                .map(|j| j - 1)
                .collect(),
            rows,
        }
    }
}

/// What one probe at x tells about the stiffnesses: JᵀJ of its whitened
/// residual Jacobian, which is zero outside the joints on the pushed node's
/// path (the only joints a push bends), so it is kept on those alone.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct PathInformation {
    /// Branch indices b of the path's joints.
    pub joints: Vec<usize>,
    /// JᵀJ restricted to `joints` (k × k).
    pub matrix: DMatrix<f64>,
}

/// The information of one probe at x (`None` when the probe does not
/// simulate there, or its hold switches).
pub(super) fn probe_information(
    tree: &Tree,
    x: &DVector<f64>,
    probe: &Probe,
    config: &IdentifyConfig,
    count: &AtomicUsize,
) -> Option<PathInformation> {
    let observed = [Observed::new(0, probe, tree)];
    let out = observed[0].simulate(&tree_at(tree, x), None, count).ok()?;
    let state = State {
        x: x.clone(),
        residuals: vec![observed[0].residual(&out, config)],
        outcomes: vec![out],
        cost: 0.0,
    };
    let jac = jacobian(tree, &observed, &state, config, count).select_columns(&observed[0].path);
    Some(PathInformation {
        matrix: jac.transpose() * jac,
        joints: observed[0].path.clone(),
    })
}

/// A probe's simulated outcome on `tree`, for callers that synthesise
/// observations (evaluation, tests).
pub fn simulate_probe(tree: &Tree, probe: &Probe) -> Result<PushOutcome, SimError> {
    simulate_from(
        tree,
        &probe.push,
        &SimConfig {
            contact: probe.contact,
            ..SimConfig::default()
        },
        None,
    )
}
