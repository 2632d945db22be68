//! What a client needs to draw a scene with the server's own geometry:
//! `POST /v1/trees/urdf` (a tree URDF → tree JSON, through the same parser
//! as the CLI), `GET /v1/trees/example` (a Space Colonization tree from
//! the dataset's generator) and `POST /v1/robot/link-poses` (the arm's link
//! frames and collision shapes along a trajectory, from the same
//! kinematics the planner uses). The viewer (`GET /viewer`) draws with
//! these; so can any client, with no second URDF parser or kinematics.

use crate::api::types::error::PostErrors;
use axum::extract::{RawQuery, State};
use nalgebra::{Isometry3, Point3};
use serde::Deserialize;
use serde_json::json;

use super::AppState;
use super::error::ApiError;
use super::json::ApiJson;
use super::tree_json::tree_error;
use treemanip_core::planner::base::BasePose;

use crate::api::types::scene::ExampleQuery;
use crate::api::types::{
    LinkJson, LinkPosesRequest, LinkPosesResponse, ShapeJson, TreeJson, TreeResponse, UrdfRequest,
};
use treemanip_core::tree::FULL_GRAPH_MAX_NODES;
use treemanip_core::tree::collection::TreeShape;
use treemanip_core::tree::sca::{MIN_GENERATED_NODES, ScaError, ScaParams};
use treemanip_core::tree::urdf::{UrdfError, from_urdf_str};

/// Configurations one `/v1/robot/link-poses` call may ask for.
pub const MAX_CONFIGURATIONS: usize = 2048;
/// Example trees are generated with this many nodes unless asked otherwise.
pub const DEFAULT_EXAMPLE_NODES: usize = 15;

/// A tree URDF (as `treemanip` writes it) as tree JSON.
///
/// Parses the URDF with the same reader as the CLI and answers the tree in
/// the JSON every other endpoint takes. Documents that are not URDF, or not a
/// tree's URDF, are 422 with the parser's message.
#[utoipa::path(post, path = "/v1/trees/urdf", tag = "trees",
    request_body = UrdfRequest,
    responses(
    (status = 200, description = "The tree.", body = TreeResponse),
    PostErrors,
))]
pub async fn tree_from_urdf(
    State(state): State<AppState>,
    ApiJson(request): ApiJson<UrdfRequest>,
) -> Result<axum::Json<TreeResponse>, ApiError> {
    let max_nodes = state.limits.max_nodes;
    state
        .run_blocking("/v1/trees/urdf", move || {
            let tree = from_urdf_str(&request.urdf).map_err(|e| match e {
                UrdfError::Tree(e) => tree_error(e),
                e => {
                    ApiError::invalid_argument(e.to_string()).with_details(json!({"field": "urdf"}))
                }
            })?;
            // Same validation as a tree sent as JSON (node count, shape).
            let json = TreeJson::from_tree(&tree);
            json.to_tree(max_nodes)?;
            Ok(axum::Json(TreeResponse {
                nodes: tree.len(),
                tree: json,
                seed: None,
            }))
        })
        .await
}

/// `nodes` and `seed` from the query string (both optional).
fn example_query(query: Option<&str>, max_nodes: usize) -> Result<(usize, u64), ApiError> {
    #[derive(Deserialize)]
    #[serde(deny_unknown_fields)]
    struct Params {
        nodes: Option<String>,
        seed: Option<String>,
    }
    let params: Params = serde_urlencoded::from_str(query.unwrap_or("")).map_err(|e| {
        ApiError::invalid_argument(format!(
            "query: {e} (accepted: `nodes`, `seed`, e.g. `?nodes=15&seed=3`)"
        ))
    })?;
    let max = max_nodes.min(treemanip_core::tree::MAX_NODES);
    let nodes = match params.nodes.as_deref() {
        None => DEFAULT_EXAMPLE_NODES.min(max),
        Some(s) => match s.parse::<usize>() {
            Ok(n) if (MIN_GENERATED_NODES..=max).contains(&n) => n,
            _ => {
                return Err(ApiError::invalid_argument(format!(
                    "`nodes` must be an integer from {MIN_GENERATED_NODES} to {max}, got `{s}`"
                ))
                .with_details(json!({"field": "nodes", "min": MIN_GENERATED_NODES, "max": max})));
            }
        },
    };
    let seed = match params.seed.as_deref() {
        None => 0,
        Some(s) => s.parse::<u64>().map_err(|_| {
            ApiError::invalid_argument(format!(
                "`seed` must be a non-negative integer below 2^64, got `{s}`"
            ))
            .with_details(json!({"field": "seed"}))
        })?,
    };
    Ok((nodes, seed))
}

/// A generated tree: Space Colonization (the paper's trees) up to 64 nodes,
/// an orchard tree (a central leader with scaffolds and laterals at the
/// paper's node spacing) above.
///
/// The same generators and parameters as `treemanip trees generate`
/// (`--shape sca` / `--shape orchard`); the same `nodes` and `seed` always
/// give the same tree.
#[utoipa::path(get, path = "/v1/trees/example", tag = "trees",
    params(ExampleQuery),
    responses(
    (status = 200, description = "The tree and its seed.", body = TreeResponse),
    (status = 422, response = crate::api::types::error::ErrorReply),
    (status = 503, response = crate::api::types::error::ErrorReply),
    (status = 504, response = crate::api::types::error::ErrorReply),
))]
pub async fn example_tree(
    State(state): State<AppState>,
    RawQuery(query): RawQuery,
) -> Result<axum::Json<TreeResponse>, ApiError> {
    let (nodes, seed) = example_query(query.as_deref(), state.limits.max_nodes)?;
    state
        .run_blocking("/v1/trees/example", move || {
            let shape = if nodes > FULL_GRAPH_MAX_NODES {
                TreeShape::Orchard
            } else {
                TreeShape::Sca
            };
            let tree = shape
                .generate(nodes, seed, 0, &ScaParams::default())
                .map_err(|e| match e {
                    ScaError::GaveUp { .. } => {
                        ApiError::invalid_argument(format!("{e}; try another seed"))
                            .with_details(json!({"field": "seed"}))
                    }
                    e => ApiError::internal(e.to_string()),
                })?;
            Ok(axum::Json(TreeResponse {
                nodes: tree.len(),
                tree: TreeJson::from_tree(&tree),
                seed: Some(seed),
            }))
        })
        .await
}

fn pose7(iso: &Isometry3<f64>) -> [f64; 7] {
    let t = iso.translation.vector;
    let q = iso.rotation.coords; // (i, j, k, w)
    [t.x, t.y, t.z, q.x, q.y, q.z, q.w]
}

/// The arm's link frames and collision shapes along a trajectory.
///
/// Forward kinematics of the planner's own arm model (`robot`, default the
/// server's default robot, with its pusher tool): every link's world pose for
/// each joint configuration (e.g. a `/v1/plan` trajectory's `q`), and each
/// link's collision shapes in its frame, in the one shape schema that
/// regions and obstacles use (capsules, spheres, boxes and cylinders with a
/// `rotation` quaternion), so a client draws exactly what the planner
/// checks for collisions. Poses are `[x, y, z, qx, qy, qz, qw]` (m, unit
/// quaternion); links are in the order of `links`.
#[utoipa::path(post, path = "/v1/robot/link-poses", tag = "planning",
    request_body = LinkPosesRequest,
    responses(
    (status = 200, description = "Links, their shapes, and their poses per configuration.", body = LinkPosesResponse),
    PostErrors,
))]
pub async fn link_poses(
    State(state): State<AppState>,
    ApiJson(request): ApiJson<LinkPosesRequest>,
) -> Result<axum::Json<LinkPosesResponse>, ApiError> {
    let base = match &request.base {
        None => None,
        Some(b) => {
            let p: Point3<f64> = super::validate::near_point(&b.position, "base.position")?;
            for (name, v) in [("yaw", b.yaw), ("roll", b.roll), ("pitch", b.pitch)] {
                if !super::validate::within_turn(v) {
                    return Err(ApiError::invalid_argument(format!(
                        "`base.{name}` must be finite, within ±2π rad"
                    ))
                    .with_details(json!({"field": format!("base.{name}")})));
                }
            }
            Some(BasePose {
                position: [p.x, p.y, p.z],
                yaw: b.yaw,
                roll: b.roll,
                pitch: b.pitch,
            })
        }
    };
    let n = request.configurations.len();
    if n == 0 || n > MAX_CONFIGURATIONS {
        return Err(ApiError::invalid_argument(format!(
            "`configurations` must list 1 to {MAX_CONFIGURATIONS} joint configurations, it has {n}"
        ))
        .with_details(json!({"field": "configurations", "max": MAX_CONFIGURATIONS})));
    }
    let planner = state.robots.get(request.robot.as_deref(), "robot")?;
    let base = base.unwrap_or_else(|| BasePose::of(&planner.robot().default_base()));
    let configurations = request
        .configurations
        .iter()
        .enumerate()
        .map(|(k, q)| super::validate::joints(q, &format!("configurations[{k}]"), planner.robot()))
        .collect::<Result<Vec<_>, _>>()?;
    state
        .run_blocking("/v1/robot/link-poses", move || {
            let robot = planner.robot().clone().with_base(base.isometry());
            let links = robot
                .link_shapes()
                .enumerate()
                .map(|(i, (name, shapes))| LinkJson {
                    name: name.to_owned(),
                    parent: robot.link_parent(i),
                    shapes: shapes.iter().map(ShapeJson::from).collect(),
                })
                .collect();
            let poses = configurations
                .iter()
                .map(|q| robot.link_poses(q).iter().map(pose7).collect())
                .collect();
            Ok(axum::Json(LinkPosesResponse {
                base: base.into(),
                robot: robot.name().to_owned(),
                joint_names: robot.joint_names().map(str::to_owned).collect(),
                links,
                poses,
            }))
        })
        .await
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::api::error::ErrorCode;

    #[test]
    fn example_query_defaults_and_bounds() {
        assert_eq!(example_query(None, 64).unwrap(), (15, 0));
        assert_eq!(example_query(Some("nodes=20&seed=9"), 64).unwrap(), (20, 9));
        assert_eq!(example_query(Some("seed=3"), 10).unwrap(), (10, 3));
        for bad in ["nodes=3", "nodes=65", "nodes=x", "seed=-1", "colour=red"] {
            let err = example_query(Some(bad), 64).unwrap_err();
            assert_eq!(err.code, ErrorCode::InvalidArgument, "{bad}");
        }
    }
}
