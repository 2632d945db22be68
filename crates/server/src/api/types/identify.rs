//! `/v1/identify` and `/v1/identify/probes`: probes, requests and answers.

use serde::{Deserialize, Serialize};
use treemanip_core::identify::probes::ProbeRequest;
use treemanip_core::identify::{FitReport, Noise, Prior, Rejected, Scale, Status};
use utoipa::ToSchema;

use crate::api::types::robots::RobotJson;
use crate::api::types::schema::{Interval, Vec3};
use crate::api::types::simulate::ContactJson;
use crate::api::types::tree::TreeJson;

#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct IdentifyRequest {
    /// The tree; its `stiffness`, when given, is the prior mean (else the
    /// radius formula).
    pub tree: TreeJson,
    #[schema(min_items = 1, max_items = 32)]
    pub probes: Vec<ProbeJson>,
    /// Measurement noise (defaults: 3 mm, 5 % of force).
    #[serde(default)]
    pub noise: Option<NoiseJson>,
    /// Prior spreads on ln K_s (defaults: 0.4 per branch, 1.0 overall).
    #[serde(default)]
    pub prior: Option<PriorJson>,
}

#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct ProbesRequest {
    pub tree: TreeJson,
    /// Probes already observed: the proposal starts from what they taught.
    #[serde(default)]
    #[schema(max_items = 32)]
    pub probes: Vec<ProbeJson>,
    /// How many probes to propose.
    #[serde(
        default = "default_count",
        deserialize_with = "crate::api::json::integer::usize"
    )]
    #[schema(minimum = 1, maximum = 20, default = default_count)]
    pub count: usize,
    /// Length of each proposed push (m).
    #[serde(default = "default_push_length")]
    #[schema(exclusive_minimum = 0.0, maximum = 1.0, default = default_push_length)]
    pub push_length: f64,
    #[serde(default)]
    pub contact: ContactJson,
    /// Measurement noise (defaults: 3 mm, 5 % of force).
    #[serde(default)]
    pub noise: Option<NoiseJson>,
    /// Prior spreads on ln K_s (defaults: 0.4 per branch, 1.0 overall).
    #[serde(default)]
    pub prior: Option<PriorJson>,
    /// Where the arm stands (as `/v1/plan` takes it): only pushes it can
    /// make are proposed. Without it, every push is a candidate.
    #[serde(default)]
    pub robot: Option<RobotJson>,
}

#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
#[schema(as = ProposedProbe)]
pub struct ProposedProbeJson {
    pub contact_node: usize,
    #[schema(value_type = Vec3)]
    pub push: [f64; 3],
    pub contact: ContactJson,
    /// Expected information gain about ln K_s (nats), given the probes
    /// proposed before it.
    pub information_gain: f64,
    /// Variance it is expected to remove from the predicted positions of
    /// the paper's pushes (m², summed over coordinates, averaged over
    /// pushes), given the probes proposed before it: what it is chosen by.
    pub prediction_variance_reduction: f64,
}

#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct ProbesResponse {
    pub probes: Vec<ProposedProbeJson>,
}

/// One observed probe push: a push the arm made and held, with where the
/// tree's nodes were seen while it was held.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(as = Probe)]
pub struct ProbeJson {
    /// A non-root node.
    #[serde(deserialize_with = "crate::api::json::integer::usize")]
    #[schema(minimum = 1, maximum = 9007199254740991_u64)]
    pub contact_node: usize,
    /// Gripper displacement T (m).
    #[schema(value_type = Vec3)]
    pub push: Vec<f64>,
    #[serde(default)]
    pub contact: ContactJson,
    /// One entry per node (m), null where the node was not seen; observed
    /// while the push was held.
    #[schema(value_type = Vec<Option<Vec3>>, max_items = 512)]
    pub observed_positions: Vec<Option<Vec<f64>>>,
    /// The force the gripper applied to the branch (N), non-zero, as
    /// `/v1/simulate` reports `contact_force`; a wrist sensor reads the
    /// opposite sign.
    #[serde(default)]
    #[schema(value_type = Option<Vec3>)]
    pub contact_force: Option<Vec<f64>>,
}

/// The estimate, per node (null at the root).
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct IdentifyResponse {
    /// Estimated K_s (N·m/rad).
    pub stiffness: Vec<Option<f64>>,
    /// 90 % interval of each K_s (N·m/rad).
    #[schema(value_type = Vec<Option<Interval>>)]
    pub interval: Vec<Option<[f64; 2]>>,
    pub status: Vec<Option<StatusJson>>,
    /// `absolute` when a contact force fixed the level; `relative`: the
    /// estimate keeps the prior's level (its mean ln K_s).
    pub scale: ScaleJson,
    /// The request's tree with the estimate as its `stiffness`, ready for
    /// the other endpoints.
    pub tree: TreeJson,
    pub fit: FitReportJson,
    pub rejected: Vec<RejectedJson>,
}

fn default_count() -> usize {
    ProbeRequest::default().count
}

fn default_push_length() -> f64 {
    ProbeRequest::default().push_length
}

/// Measurement noise, one standard deviation: `position` per coordinate
/// of an observed node (m, default 3 mm), `force` relative to a measured
/// contact force (default 5 %).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(as = Noise)]
pub struct NoiseJson {
    /// Per coordinate (m).
    #[serde(default = "default_noise_position")]
    #[schema(exclusive_minimum = 0.0, maximum = 0.1, default = default_noise_position)]
    pub position: f64,
    /// Relative to the force's magnitude.
    #[serde(default = "default_noise_force")]
    #[schema(exclusive_minimum = 0.0, maximum = 1.0, default = default_noise_force)]
    pub force: f64,
}

fn default_noise_position() -> f64 {
    Noise::default().position
}

fn default_noise_force() -> f64 {
    Noise::default().force
}

impl From<NoiseJson> for Noise {
    fn from(n: NoiseJson) -> Self {
        Noise {
            position: n.position,
            force: n.force,
        }
    }
}

/// The prior's spreads on ln K_s: each branch apart (default 0.4) and all
/// branches together (default 1.0).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(as = StiffnessPrior)]
pub struct PriorJson {
    #[serde(default = "default_branch_log_sigma")]
    #[schema(exclusive_minimum = 0.0, maximum = 5.0, default = default_branch_log_sigma)]
    pub branch_log_sigma: f64,
    #[serde(default = "default_global_log_sigma")]
    #[schema(exclusive_minimum = 0.0, maximum = 5.0, default = default_global_log_sigma)]
    pub global_log_sigma: f64,
}

fn default_branch_log_sigma() -> f64 {
    Prior::default().branch_log_sigma
}

fn default_global_log_sigma() -> f64 {
    Prior::default().global_log_sigma
}

impl From<PriorJson> for Prior {
    fn from(p: PriorJson) -> Self {
        Prior {
            branch_log_sigma: p.branch_log_sigma,
            global_log_sigma: p.global_log_sigma,
        }
    }
}

/// How well a branch's stiffness is known after the fit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
#[schema(as = BranchStatus)]
pub enum StatusJson {
    Identified,
    Weak,
    Unobserved,
}

impl From<Status> for StatusJson {
    fn from(s: Status) -> Self {
        match s {
            Status::Identified => StatusJson::Identified,
            Status::Weak => StatusJson::Weak,
            Status::Unobserved => StatusJson::Unobserved,
        }
    }
}

/// Whether the estimate's overall level was measured (`absolute`, with a
/// force) or kept at the prior's (`relative`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
#[schema(as = Scale)]
pub enum ScaleJson {
    Absolute,
    Relative,
}

impl From<Scale> for ScaleJson {
    fn from(s: Scale) -> Self {
        match s {
            Scale::Absolute => ScaleJson::Absolute,
            Scale::Relative => ScaleJson::Relative,
        }
    }
}

/// A probe left out of the fit, and why.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
#[schema(as = RejectedProbe)]
pub struct RejectedJson {
    pub probe: usize,
    /// `hold_switched`, `lost_branch`, `out_of_reach`, `over_rotated`,
    /// `not_converged` or `degenerate`.
    pub reason: String,
    pub message: String,
}

impl From<&Rejected> for RejectedJson {
    fn from(r: &Rejected) -> Self {
        Self {
            probe: r.probe,
            reason: r.reason.clone(),
            message: r.message.clone(),
        }
    }
}

/// How the fit went: iterations, convergence, the position residuals (m)
/// at the estimate and at the prior, observations and simulations used.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
#[schema(as = FitReport)]
pub struct FitReportJson {
    /// Levenberg–Marquardt iterations of the fit.
    pub iterations: usize,
    /// Whether the fit met its tolerance within its iterations.
    pub converged: bool,
    /// The rms position residual at the estimate (m).
    pub position_rms: f64,
    /// The same with the prior's stiffness (m).
    pub prior_position_rms: f64,
    /// Observed position coordinates and force components fitted.
    pub observations: usize,
    /// Simulations the fit ran.
    pub simulations: usize,
}

impl From<&FitReport> for FitReportJson {
    fn from(f: &FitReport) -> Self {
        Self {
            iterations: f.iterations,
            converged: f.converged,
            position_rms: f.position_rms,
            prior_position_rms: f.prior_position_rms,
            observations: f.observations,
            simulations: f.simulations,
        }
    }
}
