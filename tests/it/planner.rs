//! The planning layer on random trees: every returned trajectory is within
//! the joint limits and collision-free, its push is a straight line of
//! |T| plus the approach margin at constant tool orientation, for every
//! strategy, both stances, and with obstacles.

use std::path::Path;
use std::time::Duration;

use nalgebra::{Point3, Vector3};
use treemanip::geometry::shape::Shape;
use treemanip::infer::models::{ModelSet, ServedModel};
use treemanip::planner::predict::max_node_error;
use treemanip::planner::{Plan, Planner, Query, Stance, Strategy};
use treemanip::robot::Arm;
use treemanip::robot::arm::tool_line::APPROACH_OFFSET;
use treemanip::robot::collision::{Allowed, CollisionModel, Hit, TreeObstacles};
use treemanip::robot::kinematics::dh::JOINT_LIMITS;
use treemanip::robot::motion::push_motion::Outcome;
use treemanip::sim::{Push, SimConfig, simulate};
use treemanip::tree::Tree;

use crate::common::episode;

pub(crate) fn models() -> ModelSet {
    ModelSet::load_dir(Path::new("models"), None, 1, false).expect("the committed models load")
}

/// The GNN contact policy and forward model of `set`.
pub(crate) fn policy_and_forward(set: &ModelSet) -> (&ServedModel, &ServedModel) {
    (
        set.get("policy_gnn").unwrap(),
        set.get("forward_gnn").unwrap(),
    )
}

/// What the gripper may touch at the pre-contact pose: the contacted
/// branch and the branches leaving its node.
fn near_contact(tree: &Tree, node: usize) -> Allowed {
    Allowed {
        gripper_branches: std::iter::once(node)
            .chain(tree.children(node).iter().copied())
            .collect(),
    }
}

/// The controller's trajectory: velocity-continuous, within every joint's
/// velocity and acceleration limit by finite differences of the positions
/// alone, the approach collision-free (its blended samples too), and the
/// push exactly straight at constant orientation and constant speed in its
/// middle, by the URDF chain's forward kinematics (code apart from the
/// UR5 model the planner uses).
fn check_execution(plan: &Plan, query: &Query) {
    use treemanip::robot::model::urdf_chain::Chain;
    use treemanip::robot::ur5::URDF;
    let Some(p) = &plan.plan else { return };
    let e = &p.execution;
    let points = &e.joint_trajectory.points;
    let t: Vec<f64> = points.iter().map(|p| p.time_from_start.as_secs()).collect();
    assert!(t.windows(2).all(|w| w[1] > w[0]), "time increases");
    assert_eq!(points[0].positions, plan.start.to_vec());
    assert!(points[0].velocities.iter().all(|v| *v == 0.0));
    crate::robot_arms::check_limits("ur5", &Arm::default(), &e.joint_trajectory);
    let chain = Chain::from_urdf_str(URDF, Some("base_link"), Some("tool")).unwrap();
    let base = plan.base.isometry();
    let tool = |k: usize| base * chain.tip_pose(&points[k].positions);
    let push: Vec<_> = (e.push_start_point..=e.push_end_point).map(tool).collect();
    crate::robot_arms::assert_straight_push("ur5", &push, p.push.norm() + APPROACH_OFFSET, 1e-6);
    // Constant tool speed in the middle of the push.
    let mid = (e.push_start_point + e.push_end_point) / 2;
    let speed = (tool(mid + 1).translation.vector - tool(mid).translation.vector).norm()
        / (t[mid + 1] - t[mid]);
    assert!(
        (speed - query.execution.push_speed).abs() < 1e-3 || speed < query.execution.push_speed,
        "{speed} m/s"
    );
    // Hold, release and retreat end where the approach began.
    assert!(t[e.push_end_point + 1] - t[e.push_end_point] >= query.execution.hold_s - 1e-9);
    assert_eq!(points.last().unwrap().positions, plan.start.to_vec());
    // The approach, blended or not, clears the tree and the obstacles.
    let arm = CollisionModel::new(Arm::default().with_base(base));
    let rest = TreeObstacles::new(&query.tree).with_obstacles(&query.obstacles);
    let near = near_contact(&query.tree, p.node);
    for point in &points[..=e.push_start_point] {
        let q: [f64; 6] = point.positions.clone().try_into().unwrap();
        assert_eq!(arm.check(&q, &rest, &near), None, "approach collides");
    }
}

/// Checks everything a returned plan promises.
fn check_plan(plan: &Plan, query: &Query) {
    check_execution(plan, query);
    let Some(p) = &plan.plan else { return };
    let tree = &query.tree;
    for point in &p.trajectory {
        for (i, q) in point.q.iter().enumerate() {
            let (lo, hi) = JOINT_LIMITS[i];
            assert!(
                *q >= lo - 1e-9 && *q <= hi + 1e-9,
                "joint {i} at {q} outside its limits"
            );
        }
    }
    assert!(
        p.trajectory.windows(2).all(|w| w[1].t > w[0].t),
        "time increases"
    );
    assert_eq!(
        p.trajectory[0].q, plan.start,
        "the trajectory begins at the start"
    );
    let arm = CollisionModel::new(Arm::default().with_base(plan.base.isometry()));
    let rest = TreeObstacles::new(tree).with_obstacles(&query.obstacles);
    let near = near_contact(tree, p.node);
    for point in &p.trajectory[..=p.push_start_index] {
        assert_eq!(arm.check(&point.q, &rest, &near), None, "approach collides");
    }
    // The push: constant orientation, a straight line along T of length
    // |T| + the approach margin.
    let push: Vec<_> = p.trajectory[p.push_start_index..]
        .iter()
        .map(|point| arm.robot.tool_pose(&point.q))
        .collect();
    let travel = crate::robot_arms::assert_straight_push(
        "ur5",
        &push,
        p.push.norm() + APPROACH_OFFSET,
        1e-6,
    );
    assert!((travel.normalize() - p.push.normalize()).norm() < 1e-6);
    for point in &p.trajectory[p.push_start_index..] {
        // The arm (not the gripper) never touches the tree or an obstacle.
        if let Some(hit) = arm.check(
            &point.q,
            &rest,
            &Allowed {
                gripper_branches: tree.subtree(p.node),
            },
        ) {
            assert!(
                matches!(hit, Hit::Branch { .. }),
                "push hits something fixed: {hit:?}"
            );
        }
    }
}

fn query(tree: &Tree, targets: &[Point3<f64>], strategy: Strategy, region: bool) -> Query {
    let mut q = Query::new(tree.clone(), targets.to_vec());
    q.strategy = strategy;
    q.budget = Duration::from_secs(3);
    if region {
        q.stance = Stance::Region(treemanip::eval::plan::evaluation_region());
    }
    q
}

#[test]
fn every_strategy_and_stance_returns_valid_plans_that_help() {
    let set = models();
    let (policy, forward) = policy_and_forward(&set);
    let planner = Planner::default();
    let mut planned = 0;
    let mut helped = 0;
    // The paper's Algorithm 1 executes the policy's push unchecked; the
    // searched strategies never execute a push predicted not to help.
    let (mut paper_planned, mut paper_helped) = (0, 0);
    for (n, seed) in [(10usize, 3u64), (14, 5), (12, 11)] {
        let (tree, targets) = episode(n, seed);
        for strategy in [Strategy::Paper, Strategy::Model, Strategy::Physics] {
            for region in [false, true] {
                let q = query(&tree, &targets, strategy, region);
                let plan = planner.plan(&q, policy, Some(forward)).unwrap();
                check_plan(&plan, &q);
                assert_eq!(plan.strategy, strategy);
                if let Some(p) = &plan.plan {
                    let paper = strategy == Strategy::Paper;
                    if paper {
                        paper_planned += 1;
                    } else {
                        planned += 1;
                    }
                    let push = Push {
                        node: p.node,
                        vector: p.push,
                    };
                    let after = simulate(&tree, &push, &SimConfig::default())
                        .map(|o| max_node_error(&o.final_positions, &targets))
                        .unwrap_or(plan.no_action_error);
                    if after < plan.no_action_error {
                        if paper {
                            paper_helped += 1;
                        } else {
                            helped += 1;
                        }
                    }
                    if strategy != Strategy::Paper {
                        let predicted = plan.predicted_error.expect("searched plans predict");
                        assert!(predicted < plan.no_action_error);
                    }
                } else {
                    assert!(plan.attempts.iter().all(|a| a.outcome != Outcome::Planned));
                }
            }
        }
    }
    // 12 searched plans asked for: most find a push, and most of those
    // help; the paper's pick helps in at least half of its plans.
    assert!(planned >= 8, "only {planned} of 12 searched plans planned");
    assert!(
        paper_helped * 2 >= paper_planned && paper_planned >= 4,
        "paper: {paper_helped} of {paper_planned} plans helped"
    );
    assert!(
        helped * 10 >= planned * 8,
        "{helped} of {planned} plans helped"
    );
}

#[test]
fn physics_search_is_no_worse_than_the_papers_pick_with_a_base_region() {
    let set = models();
    let (policy, forward) = policy_and_forward(&set);
    let planner = Planner::default();
    let (tree, targets) = episode(12, 21);
    let error = |strategy| {
        let plan = planner
            .plan(
                &query(&tree, &targets, strategy, true),
                policy,
                Some(forward),
            )
            .unwrap();
        plan.plan.map_or(plan.no_action_error, |p| {
            let push = Push {
                node: p.node,
                vector: p.push,
            };
            simulate(&tree, &push, &SimConfig::default()).map_or(plan.no_action_error, |o| {
                max_node_error(&o.final_positions, &targets)
            })
        })
    };
    let (physics, paper) = (error(Strategy::Physics), error(Strategy::Paper));
    assert!(
        physics <= paper + 1e-3,
        "physics {physics} vs paper {paper}"
    );
}

/// A tilted mount (the base rolled, pitched and turned): the plan keeps
/// the base as given, and its trajectory is valid and pushes straight in
/// the tree's frame (`check_plan` runs the forward kinematics from the
/// plan's base).
#[test]
fn a_tilted_base_plans_in_the_trees_frame() {
    let set = models();
    let (policy, forward) = policy_and_forward(&set);
    let planner = Planner::default();
    let tilted = treemanip::planner::base::BasePose {
        position: [-0.5, 0.0, 0.1],
        yaw: 0.2,
        roll: 0.15,
        pitch: -0.1,
    };
    let mut planned = 0;
    for (n, seed) in [
        (10usize, 3u64),
        (12, 11),
        (14, 5),
        (10, 7),
        (11, 2),
        (12, 4),
    ] {
        let (tree, targets) = episode(n, seed);
        let mut q = query(&tree, &targets, Strategy::Physics, false);
        q.stance = Stance::Fixed(tilted.isometry());
        // As the shape benchmark: no load limits.
        q.limits = None;
        let plan = planner.plan(&q, policy, Some(forward)).unwrap();
        let b = plan.base;
        assert!(
            (Vector3::from(b.position) - Vector3::from(tilted.position)).norm() < 1e-12
                && (b.roll - tilted.roll).abs() < 1e-12
                && (b.pitch - tilted.pitch).abs() < 1e-12
                && (b.yaw - tilted.yaw).abs() < 1e-12,
            "{b:?}"
        );
        check_plan(&plan, &q);
        if let Some(p) = &plan.plan {
            // The push runs along the planned push in the tree's frame: the
            // chain's tool, placed by the tilted base.
            let e = &p.execution;
            let points = &e.joint_trajectory.points;
            let chain = treemanip::robot::model::urdf_chain::Chain::from_urdf_str(
                treemanip::robot::ur5::URDF,
                Some("base_link"),
                Some("tool"),
            )
            .unwrap();
            let tool = |k: usize| {
                (tilted.isometry() * chain.tip_pose(&points[k].positions))
                    .translation
                    .vector
            };
            let travel = tool(e.push_end_point) - tool(e.push_start_point);
            assert!(travel.normalize().dot(&p.push.normalize()) > 1.0 - 1e-9);
            planned += 1;
        }
    }
    assert!(planned >= 1, "no tilted plan at all");
}

#[test]
fn obstacles_are_respected_and_named() {
    let set = models();
    let (policy, forward) = policy_and_forward(&set);
    let planner = Planner::default();
    let (tree, targets) = episode(10, 4);
    let mut q = query(&tree, &targets, Strategy::Physics, false);
    let plan = planner.plan(&q, policy, Some(forward)).unwrap();
    let p = plan.plan.as_ref().expect("the open scene plans");
    // A stake (20 cm, 4 cm radius) through where the wrist passed along
    // the approach, from halfway on: the first such place that leaves the
    // start free (an obstacle on the start is the wall's case below).
    let arm = CollisionModel::new(Arm::default().with_base(plan.base.isometry()));
    let post_at = |k: usize| {
        let at = arm.robot.tool_pose(&p.trajectory[k].q).translation.vector;
        Shape::Capsule {
            a: Point3::new(at.x, at.y, at.z - 0.1),
            b: Point3::new(at.x, at.y, at.z + 0.1),
            radius: 0.04,
        }
    };
    let with = |post: &Shape| TreeObstacles::new(&tree).with_obstacles(std::slice::from_ref(post));
    // Away from the start and from the pre-contact pose with a margin, so
    // that the stake blocks the way and not its ends.
    let contact = &p.trajectory[p.push_start_index].q;
    let (k, post) = (p.push_start_index / 4..p.push_start_index)
        .map(|k| (k, post_at(k)))
        .find(|(_, post)| {
            [(&plan.start, 0.02), (contact, 0.08)]
                .iter()
                .all(|(q, margin)| {
                    let hit = arm.check_with_margin(q, &with(post), &Allowed::default(), *margin);
                    !matches!(hit, Some(Hit::Obstacle { .. }))
                })
        })
        .expect("some place along the approach is away from the start and the contact");
    assert!(
        matches!(
            arm.check(&p.trajectory[k].q, &with(&post), &Allowed::default()),
            Some(Hit::Obstacle { .. })
        ),
        "the stake blocks the first plan"
    );
    q.obstacles = vec![post.clone()];
    let around = planner.plan(&q, policy, Some(forward)).unwrap();
    assert!(
        around.plan.is_some(),
        "plans around the stake: {:?}",
        around.attempts
    );
    check_plan(&around, &q);
    // A wall over the whole workspace makes the start collide, by name.
    let wall = Shape::turned_box(
        Point3::new(-0.5, 0.0, 0.5),
        Vector3::new(0.3, 0.3, 0.3),
        0.3,
    );
    let walled_in = TreeObstacles::new(&tree).with_obstacles(&[post, wall.clone()]);
    let hit = CollisionModel::new(Arm::default()).check(
        &treemanip::robot::ur5::HOME,
        &walled_in,
        &Allowed::default(),
    );
    assert!(
        matches!(hit, Some(Hit::Obstacle { index: 1, .. })),
        "{hit:?}"
    );
    q.obstacles = vec![wall];
    assert!(planner.plan(&q, policy, Some(forward)).is_err());
}

/// `treemanip eval ranks` (the paper's Fig. 8) on a few episodes: every
/// rank is executed, the policy's first choice beats doing nothing, and
/// the figures are written.
#[test]
fn eval_ranks_executes_every_rank() {
    let out = crate::common::temp_dir("ranks");
    let run = crate::common::treemanip(&[
        "eval",
        "ranks",
        "--n",
        "10",
        "--episodes",
        "6",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("rank_eval.json")).unwrap())
            .unwrap();
    let ranks = json["ranks"].as_array().unwrap();
    assert_eq!(
        ranks.len(),
        9,
        "every non-root node of a 10-node tree is ranked"
    );
    assert!(ranks.iter().all(|r| r["episodes"] == 6));
    let first = ranks[0]["max_error"].as_f64().unwrap();
    let none = json["no_action"]["max_error"].as_f64().unwrap();
    assert!(
        first < 0.5 * none,
        "rank 1 leaves {first} m, no action {none} m"
    );
    let affordance: Vec<f64> = ranks
        .iter()
        .map(|r| r["affordance_mean"].as_f64().unwrap())
        .collect();
    assert!(
        affordance.windows(2).all(|w| w[0] >= w[1] - 1e-12),
        "{affordance:?}"
    );
    for figure in ["fig8_error_by_rank.svg", "fig8_affordance_by_rank.svg"] {
        let svg = std::fs::read_to_string(out.join(figure)).unwrap();
        assert!(svg.contains("<svg") && svg.contains("rank"), "{figure}");
    }
    std::fs::remove_dir_all(&out).ok();
}

#[test]
fn the_default_search_budget_follows_the_graphs_size_and_bounds_predictions() {
    use treemanip::planner::default_evaluations;
    // A prediction costs in proportion to N(N-1): fewer pushes for bigger
    // trees (up to the fully connected models' limit), more with a base
    // region, within 16..=96.
    assert_eq!(default_evaluations(15, false), 60);
    assert_eq!(default_evaluations(30, false), 16);
    assert_eq!(default_evaluations(10, true), 96);
    assert_eq!(default_evaluations(30, true), 48);
    for region in [false, true] {
        for n in 3..63 {
            let (a, b) = (
                default_evaluations(n, region),
                default_evaluations(n + 1, region),
            );
            assert!(b <= a && (16..=96).contains(&b));
        }
    }
    // Above the fully connected models' 64 nodes a prediction reads a path
    // graph of at most 24 nodes (or simulates one path): twice the budget
    // of a 24-node graph, whatever the tree's size, not the 16 its N² would
    // give.
    let factor = treemanip::planner::LARGE_TREE_SEARCH_FACTOR;
    for n in [65, 200, 512] {
        assert_eq!(
            default_evaluations(n, true),
            factor * (48 * 30 * 29 / (24 * 23))
        );
        assert_eq!(
            default_evaluations(n, false),
            factor * (60 * 15 * 14 / (24 * 23))
        );
        assert!(default_evaluations(n, true) > default_evaluations(64, true));
    }
    let (tree, targets) = episode(20, 5);
    let mut q = query(&tree, &targets, Strategy::Physics, false);
    assert_eq!(q.evaluations(), default_evaluations(20, false));
    q.stance = Stance::Region(treemanip::eval::plan::evaluation_region());
    assert_eq!(q.evaluations(), default_evaluations(20, true));
    // Above 64 nodes both strategies get the large-tree budget (a path
    // graph's pass and one path's solve cost about the same).
    let large = treemanip::tree::generate_orchard(200, 3, &Default::default()).unwrap();
    for strategy in [Strategy::Physics, Strategy::Model] {
        let big = query(&large, large.positions(), strategy, true);
        assert_eq!(big.evaluations(), default_evaluations(200, true));
    }
    // An explicit budget bounds the search; the fallback to the policy's
    // own pushes adds at most FALLBACK_PREDICTIONS.
    let set = models();
    let (policy, forward) = policy_and_forward(&set);
    for strategy in [Strategy::Physics, Strategy::Model] {
        let mut q = query(&tree, &targets, strategy, false);
        q.max_evaluations = Some(5);
        let plan = Planner::default().plan(&q, policy, Some(forward)).unwrap();
        check_plan(&plan, &q);
        assert!(
            plan.evaluations <= 5 + treemanip::planner::FALLBACK_PREDICTIONS,
            "{strategy:?}: {} predictions",
            plan.evaluations
        );
        if plan.plan.is_some() {
            assert!(plan.predicted_error.is_some());
        }
    }
}
