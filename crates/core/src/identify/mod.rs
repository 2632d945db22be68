//! Stiffness identification from probe pushes: which branch stiffnesses
//! explain where the tree's nodes went while the gripper held a push.
//!
//! The steady state of a push minimises Σ ½ K_s |θ|² under the contact
//! constraint ([`crate::sim`]), so:
//! - a push at node j depends only on the stiffness of the branches on the
//!   path root → j (the others stay at rest), and only on their *ratios*:
//!   multiplying every K_s by one factor moves no node;
//! - the overall level shows only in forces: a measured contact force
//!   fixes it (`Scale::Absolute`), without one the estimate keeps the
//!   prior's level (`Scale::Relative`).
//!
//! The estimate is the maximum a posteriori of x_b = ln K_s,b under
//! - the prior x ~ N(m, σ² I + σ_g² 1 1ᵀ), m = ln of the tree's stiffness
//!   (the caller's, or the radius formula): each branch off by a
//!   log-normal factor (σ, as the wood and a measured radius vary), and
//!   all of them by one more (σ_g, the wood's modulus);
//! - observed node positions with Gaussian noise of `noise.position` (m)
//!   per coordinate, and a contact force with relative noise `noise.force`.
//!
//! It is found by Levenberg–Marquardt on x with the exact simulator as the
//! observation model and a forward-difference Jacobian (each probe
//! re-solved with one path branch perturbed, warm-started at the probe's
//! current solution, so a column costs a few Newton steps). The posterior
//! covariance is the Laplace approximation (JᵀJ + Σ⁻¹)⁻¹ at the optimum;
//! intervals are its 90 % bands.
//!
//! The documentation beside the code: `docs/identify.md`.

mod fit;
pub mod probes;

use nalgebra::{Point3, Vector3};
use serde::{Deserialize, Serialize};

use crate::sim::{ContactModel, MAX_PUSH_LENGTH, Push};
use crate::tree::{Branch, Tree};

pub use fit::{Posterior, identify, simulate_probe};

/// One probe push, as observed while it was held (before any release).
#[derive(Debug, Clone, PartialEq)]
pub struct Probe {
    pub push: Push,
    pub contact: ContactModel,
    /// Each node's observed position (m), `None` where it was not seen.
    pub observed: Vec<Option<Point3<f64>>>,
    /// The force the gripper applied to the branch (N): the opposite of
    /// what a wrist force/torque sensor reads.
    pub contact_force: Option<Vector3<f64>>,
}

/// Measurement noise (one standard deviation).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Noise {
    /// Per coordinate of an observed node position (m).
    #[serde(default = "Noise::default_position")]
    pub position: f64,
    /// Relative, of a measured contact force's magnitude.
    #[serde(default = "Noise::default_force")]
    pub force: f64,
}

impl Noise {
    fn default_position() -> f64 {
        0.003
    }
    fn default_force() -> f64 {
        0.05
    }
}

impl Default for Noise {
    /// 3 mm per coordinate (a depth camera at about a metre), 5 % of force.
    fn default() -> Self {
        Self {
            position: Self::default_position(),
            force: Self::default_force(),
        }
    }
}

/// The prior's spreads on ln K_s.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Prior {
    /// σ: each branch apart (0.4: a factor 0.67–1.5 at one σ; between
    /// the spreads of 0.3 and 0.5 the evaluation hides, its 90 % intervals
    /// cover 88–94 % of true values there; 0.5 covered 96 % at 0.3).
    #[serde(default = "Prior::default_branch")]
    pub branch_log_sigma: f64,
    /// σ_g: all branches together (1.0: the modulus within a factor e).
    #[serde(default = "Prior::default_global")]
    pub global_log_sigma: f64,
}

impl Prior {
    fn default_branch() -> f64 {
        0.4
    }
    fn default_global() -> f64 {
        1.0
    }
}

impl Default for Prior {
    fn default() -> Self {
        Self {
            branch_log_sigma: Self::default_branch(),
            global_log_sigma: Self::default_global(),
        }
    }
}

/// Settings of one identification.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IdentifyConfig {
    pub noise: Noise,
    pub prior: Prior,
    /// A branch is `identified` when the posterior σ of its ln K_s
    /// (relative to the tree's level, or absolute with a force) is at most
    /// this: K_s known to about ±15 % at one σ.
    pub identified_log_sigma: f64,
    /// Levenberg–Marquardt iterations at most.
    pub max_iterations: usize,
}

impl Default for IdentifyConfig {
    fn default() -> Self {
        Self {
            noise: Noise::default(),
            prior: Prior::default(),
            identified_log_sigma: 0.15,
            max_iterations: 30,
        }
    }
}

/// How well a branch's stiffness is known after the fit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Status {
    /// Posterior σ of ln K_s ≤ `identified_log_sigma`.
    Identified,
    /// On a probed path, but still uncertain (typically trunk branches,
    /// too stiff to bend measurably).
    Weak,
    /// On no accepted probe's path: the prior, moved only with the level.
    Unobserved,
}

/// Whether the estimate's overall level was measured.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Scale {
    /// A contact force fixed the level.
    Absolute,
    /// Positions fix only ratios; the estimate keeps the prior's level
    /// (its mean ln K_s over branches equals the prior's).
    Relative,
}

/// A probe left out of the fit, and why.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Rejected {
    pub probe: usize,
    /// `hold_switched`, `lost_branch`, or another simulator failure kind
    /// (`crate::sim::SimError::kind`).
    pub reason: String,
    pub message: String,
}

/// How the fit went.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FitReport {
    pub iterations: usize,
    pub converged: bool,
    /// Root mean square of the position residuals at the estimate (m).
    pub position_rms: f64,
    /// The same with the prior's stiffness (m).
    pub prior_position_rms: f64,
    /// Position coordinates and force components used.
    pub observations: usize,
    /// Simulations run.
    pub simulations: usize,
}

/// The result: per node arrays (`None` at the root).
#[derive(Debug, Clone, PartialEq)]
pub struct Identification {
    pub stiffness: Vec<Option<f64>>,
    /// 90 % interval of each K_s (N·m/rad).
    pub interval: Vec<Option<(f64, f64)>>,
    pub status: Vec<Option<Status>>,
    pub scale: Scale,
    /// The tree with the estimate as its stiffness (damping scaled alike).
    pub tree: Tree,
    pub fit: FitReport,
    pub rejected: Vec<Rejected>,
    pub posterior: Posterior,
}

/// A probe that cannot be used, naming it and the field.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("probe {probe}: {field}: {message}")]
pub struct ProbeError {
    pub probe: usize,
    pub field: &'static str,
    pub message: String,
}

/// At most this many probes per request.
pub const MAX_PROBES: usize = 32;

/// Checks probes against the tree before anything is simulated. An
/// observation "that cannot come from this tree" is one that stretches a
/// branch: branches are rigid, so two observed ends of one branch are
/// its length apart up to the noise (5 σ each way, plus 1 mm).
pub fn validate_probes(tree: &Tree, probes: &[Probe], noise: &Noise) -> Result<(), ProbeError> {
    let n = tree.len();
    for (k, p) in probes.iter().enumerate() {
        let err = |field, message: String| ProbeError {
            probe: k,
            field,
            message,
        };
        if p.push.node == 0 || p.push.node >= n {
            return Err(err(
                "contact_node",
                format!("must be a non-root node, 1..{}", n - 1),
            ));
        }
        if !p.push.vector.iter().all(|v| v.is_finite()) {
            return Err(err("push", "must be finite".into()));
        }
        let length = p.push.vector.norm();
        if length == 0.0 || length > MAX_PUSH_LENGTH {
            return Err(err(
                "push",
                format!("length {length} m is outside (0, {MAX_PUSH_LENGTH}] m"),
            ));
        }
        if p.observed.len() != n {
            return Err(err(
                "observed_positions",
                format!("{} entries for a tree of {n} nodes", p.observed.len()),
            ));
        }
        if let Some(j) = p
            .observed
            .iter()
            .position(|o| o.is_some_and(|o| !o.iter().all(|c| c.is_finite())))
        {
            return Err(err(
                "observed_positions",
                format!("node {j}'s position is not finite"),
            ));
        }
        if p.observed.iter().all(Option::is_none) {
            return Err(err("observed_positions", "no node was observed".into()));
        }
        if let Some(f) = p.contact_force {
            let m = f.norm();
            if !m.is_finite() || m == 0.0 {
                return Err(err(
                    "contact_force",
                    "must be finite and non-zero (leave it out when not measured)".into(),
                ));
            }
        }
        let tolerance = 10.0 * noise.position + 0.001;
        if let Some(o) = p.observed[0]
            && (o - tree.position(0)).norm() > tolerance
        {
            return Err(err(
                "observed_positions",
                format!(
                    "the root is fixed, but node 0 is observed {:.4} m from it",
                    (o - tree.position(0)).norm()
                ),
            ));
        }
        for (j, b) in tree.branches_iter() {
            let parent = tree.parent(j).expect("non-root");
            if let (Some(a), Some(c)) = (p.observed[parent], p.observed[j]) {
                let stretch = ((c - a).norm() - b.length).abs();
                if stretch > tolerance {
                    return Err(err(
                        "observed_positions",
                        format!(
                            "nodes {parent} and {j} are observed {:.4} m apart, but the branch between them is {:.4} m long (branches are rigid): these observations cannot come from this tree",
                            (c - a).norm(),
                            b.length
                        ),
                    ));
                }
            }
        }
    }
    Ok(())
}

/// `tree` with branch j's stiffness set to `stiffness[j]` (damping scaled
/// by the same factor); entries for the root are ignored.
pub fn with_stiffness(tree: &Tree, stiffness: &[f64]) -> Tree {
    let branches: Vec<Option<Branch>> = tree
        .branches()
        .iter()
        .zip(stiffness)
        .map(|(b, &k)| {
            b.map(|b| Branch {
                stiffness: k,
                damping: b.damping * k / b.stiffness,
                ..b
            })
        })
        .collect();
    Tree::new(tree.positions().to_vec(), tree.parents().to_vec(), branches)
        .expect("positive finite stiffness keeps a valid tree valid")
}

/// A probe as a sensor would report it on the tree `truth`: the held
/// positions of every node and (with `force`) the contact force, with
/// Gaussian noise of `noise` drawn from `rng`. For evaluation and tests;
/// `None` when the push does not simulate.
pub fn observe<R: rand::Rng + ?Sized>(
    truth: &Tree,
    push: Push,
    contact: ContactModel,
    noise: &Noise,
    force: bool,
    rng: &mut R,
) -> Option<Probe> {
    use crate::seed::standard_normal;
    let probe = Probe {
        push,
        contact,
        observed: Vec::new(),
        contact_force: None,
    };
    let out = simulate_probe(truth, &probe).ok()?;
    let mut jitter = |v: f64, sd: f64| v + sd * standard_normal(rng);
    let observed = out
        .final_positions
        .iter()
        .enumerate()
        .map(|(j, p)| {
            // The root is fixed and known.
            Some(if j == 0 {
                *p
            } else {
                Point3::new(
                    jitter(p.x, noise.position),
                    jitter(p.y, noise.position),
                    jitter(p.z, noise.position),
                )
            })
        })
        .collect();
    let contact_force = force.then(|| {
        let f = Vector3::from(out.report.contact_force);
        let sd = noise.force * f.norm();
        Vector3::new(jitter(f.x, sd), jitter(f.y, sd), jitter(f.z, sd))
    });
    Some(Probe {
        observed,
        contact_force,
        ..probe
    })
}
