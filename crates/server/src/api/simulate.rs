//! `POST /v1/simulate`: the ground truth of a push from our simulator, so
//! any prediction can be checked.

use crate::api::types::error::PostErrors;
use axum::extract::State;
use serde_json::json;

use super::AppState;
use super::error::{ApiError, ErrorCode};
use super::json::ApiJson;
use crate::api::types::{GuardedJson, SimulateRequest, SimulateResponse};
use treemanip_core::sim::guarded::guarded_push;
use treemanip_core::sim::loads::branch_loads;
use treemanip_core::sim::{MAX_PUSH_LENGTH, Push, SimConfig, SimError, simulate as run_sim};

/// Ground truth of a push from the quasi-static simulator.
///
/// The gripper holds the branch ending at `contact_node` and moves by `push`;
/// the answer is where the tree settles, with the solver's report. Pushes the
/// physics rejects (the branch slips out of the slot, the node cannot be
/// carried that far) are 422 push_infeasible. With
/// `stop_at_contact_force` the push is carried out as a guarded move and
/// the answer is the tree where the arm stopped (`guarded`).
#[utoipa::path(post, path = "/v1/simulate", tag = "physics",
    request_body = SimulateRequest,
    responses(
    (status = 200, description = "The steady state.", body = SimulateResponse),
    PostErrors,
))]
pub async fn simulate(
    State(state): State<AppState>,
    ApiJson(request): ApiJson<SimulateRequest>,
) -> Result<axum::Json<SimulateResponse>, ApiError> {
    let tree = request.tree.to_tree(state.limits.max_nodes)?;
    let [x, y, z] = <[f64; 3]>::try_from(request.push.as_slice()).map_err(|_| {
        ApiError::invalid_argument(format!(
            "`push` must have 3 numbers, it has {}",
            request.push.len()
        ))
        .with_details(json!({ "field": "push" }))
    })?;
    let push = Push {
        node: request.contact_node,
        vector: nalgebra::Vector3::new(x, y, z),
    };
    let mut config = SimConfig {
        contact: request.contact.into(),
        ..SimConfig::default()
    };
    let contact = request.contact;
    let guard = match request.stop_at_contact_force {
        Some(f) if !(f.is_finite() && f > 0.0) => {
            return Err(ApiError::invalid_argument(format!(
                "`stop_at_contact_force` must be a positive number of newtons, it is {f}"
            ))
            .with_details(json!({ "field": "stop_at_contact_force" })));
        }
        g => g,
    };
    // The work stops at the deadline: its answer is the timeout the
    // client already got, and the worker is free again.
    let budget = state.limits.request_timeout.as_secs_f64();
    let response = state
        .run_model_work("/v1/simulate", None, move |control| {
            // The solver itself stops at the deadline, plain or guarded: a
            // deep path's solve takes seconds (a 512-joint chain's, 17 s).
            config.solver.deadline = control.deadline;
            let failed = |e: SimError| match e {
                SimError::OutOfTime { .. } => ApiError::timeout(budget),
                e => sim_error(e),
            };
            let (outcome, guarded) = match guard {
                Some(stop_at) => {
                    let g = guarded_push(&tree, &push, &config, stop_at).map_err(failed)?;
                    let guarded = GuardedJson {
                        fraction: g.fraction,
                        stopped: g.stopped,
                    };
                    (g.outcome, Some(guarded))
                }
                None => (run_sim(&tree, &push, &config).map_err(failed)?, None),
            };
            let loads = branch_loads(&tree, &outcome.joint_rotations);
            let xyz = |p: &nalgebra::Point3<f64>| [p.x, p.y, p.z];
            Ok(SimulateResponse {
                displacements: outcome
                    .final_positions
                    .iter()
                    .zip(tree.positions())
                    .map(|(a, b)| {
                        let d = a - b;
                        [d.x, d.y, d.z]
                    })
                    .collect(),
                final_positions: outcome.final_positions.iter().map(xyz).collect(),
                contact,
                contact_force: outcome.report.contact_force,
                branch_moment: loads.bending_moment,
                branch_twist: loads.twisting_moment,
                branch_stress: loads.bending_stress,
                wood_modulus: loads.implied_modulus,
                peak_stress: loads.peak_stress.map(Into::into),
                solver: (&outcome.report).into(),
                guarded,
            })
        })
        .await?;
    Ok(axum::Json(response))
}

/// Bad arguments are 422 `invalid_argument`; pushes the physics rejects are
/// 422 `push_infeasible`, with the simulator's reason.
fn sim_error(err: SimError) -> ApiError {
    let details = json!({ "kind": err.kind() });
    match err {
        SimError::NodeOutOfRange { .. } | SimError::RootContact => {
            ApiError::invalid_argument(err.to_string())
                .with_details(json!({ "field": "contact_node", "kind": err.kind() }))
        }
        SimError::NonFinitePush | SimError::PushTooLong { .. } => {
            ApiError::invalid_argument(format!("{err} (pushes are at most {MAX_PUSH_LENGTH} m)"))
                .with_details(json!({ "field": "push", "kind": err.kind() }))
        }
        _ => ApiError::new(
            ErrorCode::PushInfeasible,
            format!("the push cannot be simulated: {err}"),
        )
        .with_details(details),
    }
}
