//! RRT*: finds a way around a wall, never returns a path whose densely
//! re-checked edges collide, and its cost never grows with iterations.

use std::f64::consts::FRAC_PI_2;

use nalgebra::Point3;
use treemanip_core::robot::arm::PAPER_BASE;
use treemanip_core::robot::collision::{Allowed, CollisionModel, TreeObstacles};
use treemanip_core::robot::motion::rrt::{
    Config, MotionValidator, RrtStarOptions, path_cost, rrt_star, shortcut,
};
use treemanip_core::robot::motion::scene::PlanningScene;
use treemanip_core::robot::motion::trajectory::time_parameterize;
use treemanip_core::robot::{Arm, ur5};

const START: Config = Config::new([0.0, -1.2, 1.4, -1.7, -FRAC_PI_2, 0.0]);
const GOAL: Config = Config::new([1.3, -1.2, 1.4, -1.7, -FRAC_PI_2, 0.0]);

/// A fence of vertical poles on the ray from the arm's base at angle
/// `bearing`, from 0.3 m to 0.9 m out, 0.5 m tall.
fn fence(bearing: f64) -> TreeObstacles {
    let base = PAPER_BASE.translation.vector;
    let (c, s) = (bearing.cos(), bearing.sin());
    let poles: Vec<_> = (0..13)
        .map(|k| {
            let r = 0.3 + 0.05 * k as f64;
            let foot = Point3::new(base.x + r * c, base.y + r * s, 0.0);
            (k, foot, foot + nalgebra::Vector3::z() * 0.5, 0.02)
        })
        .collect();
    TreeObstacles::from_capsules(&poles)
}

fn dense_path_is_free(model: &CollisionModel, obstacles: &TreeObstacles, path: &[Config]) -> bool {
    // 10× finer than planning, no margin.
    path.windows(2).all(|w| {
        let sweep: f64 = (0..6)
            .map(|i| model.lever_arms()[i] * (w[1][i] - w[0][i]).abs())
            .sum();
        let steps = (sweep / 0.001).ceil().max(1.0) as usize;
        (0..=steps).all(|k| {
            let t = k as f64 / steps as f64;
            let q: Config = Config::from_fn(6, |i| w[0][i] + (w[1][i] - w[0][i]) * t);
            model.check(&q, obstacles, &Allowed::default()).is_none()
        })
    })
}

/// Where the base's "forward" bearing lies for joint 1 angle q1 (the DH base
/// is turned by π, so q1 = 0 points the arm along world +x).
fn bearing_between() -> f64 {
    let model = Arm::default();
    let p = |q: &Config| model.tool_pose(q).translation.vector - PAPER_BASE.translation.vector;
    let (a, b) = (p(&START), p(&GOAL));
    (a.y.atan2(a.x) + b.y.atan2(b.x)) / 2.0
}

#[test]
fn finds_a_way_around_a_wall_and_the_path_is_really_free() {
    let model = CollisionModel::new(Arm::default());
    let obstacles = fence(bearing_between());
    let scene = PlanningScene::new(&model, &obstacles, Allowed::default());
    assert!(scene.config_valid(&START) && scene.config_valid(&GOAL));
    assert!(
        !scene.edge_valid(&START, &GOAL),
        "the straight line must cross the fence"
    );

    let options = RrtStarOptions {
        time_budget: None,
        seed: 3,
        ..RrtStarOptions::default()
    };
    let path = rrt_star(&START, &[GOAL], &scene, &options).expect("a path around the fence");
    assert_eq!(path.waypoints.first(), Some(&START));
    assert_eq!(path.waypoints.last(), Some(&GOAL));
    assert!(path.waypoints.len() >= 3, "it had to go around");
    assert!(dense_path_is_free(&model, &obstacles, &path.waypoints));

    let smooth = shortcut(&path.waypoints, &scene, 200, 1);
    assert!(path_cost(&smooth) <= path_cost(&path.waypoints) + 1e-12);
    assert!(dense_path_is_free(&model, &obstacles, &smooth));

    // Timed: waypoints in order, limits respected (finite differences).
    let timed = time_parameterize(&smooth, &ur5::MAX_VELOCITY, &ur5::MAX_ACCELERATION, 0.01);
    assert_eq!(timed.first().unwrap().q, START);
    assert!(
        timed
            .last()
            .unwrap()
            .q
            .iter()
            .zip(&GOAL)
            .all(|(a, b)| (a - b).abs() < 1e-12)
    );
    for w in timed.windows(2) {
        let dt = w[1].t - w[0].t;
        assert!(dt > 0.0);
        for i in 0..6 {
            assert!(((w[1].q[i] - w[0].q[i]) / dt).abs() <= ur5::MAX_VELOCITY[i] * (1.0 + 1e-9));
        }
    }
    for w in timed.windows(3) {
        let (d1, d2) = (w[1].t - w[0].t, w[2].t - w[1].t);
        for i in 0..6 {
            let v1 = (w[1].q[i] - w[0].q[i]) / d1;
            let v2 = (w[2].q[i] - w[1].q[i]) / d2;
            // Central estimate of the acceleration; sampling adds a little.
            assert!(
                ((v2 - v1) / ((d1 + d2) / 2.0)).abs() <= ur5::MAX_ACCELERATION[i] * 1.05,
                "joint {i}"
            );
        }
    }
}

#[test]
fn cost_never_increases_with_more_iterations() {
    let model = CollisionModel::new(Arm::default());
    let obstacles = fence(bearing_between());
    let scene = PlanningScene::new(&model, &obstacles, Allowed::default());
    let run = |iterations: usize| {
        let options = RrtStarOptions {
            max_iterations: iterations,
            refine_iterations: usize::MAX / 2,
            time_budget: None,
            seed: 11,
            ..RrtStarOptions::default()
        };
        rrt_star(&START, &[GOAL], &scene, &options).unwrap()
    };
    let short = run(600);
    let long = run(1800);
    assert!(long.cost <= short.cost, "{} > {}", long.cost, short.cost);
    for w in long.stats.cost_history.windows(2) {
        assert!(w[1].1 <= w[0].1, "{:?}", long.stats.cost_history);
    }
    // Same seed: the longer run's history starts with the shorter's.
    assert_eq!(
        &long.stats.cost_history[..short.stats.cost_history.len()],
        &short.stats.cost_history[..]
    );
}

#[test]
fn unreachable_goals_and_bad_starts_are_reported() {
    let model = CollisionModel::new(Arm::default());
    let obstacles = fence(bearing_between());
    let scene = PlanningScene::new(&model, &obstacles, Allowed::default());
    let into_ground = Config::new([0.0, 1.2, 0.0, 0.0, 0.0, 0.0]);
    let options = RrtStarOptions {
        max_iterations: 50,
        ..RrtStarOptions::default()
    };
    assert_eq!(
        rrt_star(&into_ground, &[GOAL], &scene, &options).unwrap_err(),
        treemanip_core::robot::motion::rrt::RrtError::StartInvalid
    );
    assert_eq!(
        rrt_star(&START, &[into_ground], &scene, &options).unwrap_err(),
        treemanip_core::robot::motion::rrt::RrtError::NoValidGoal
    );
}

/// The edge check's spacing is a true bound: along random edges, no point
/// of the arm's shapes (capsule ends, sampled finely) moves farther from
/// its place at the edge's start than intervals × resolution, the sweep
/// the configuration-dependent reach promises.
#[test]
fn edge_spacing_bounds_every_shape_points_motion() {
    use rand::{RngExt, SeedableRng};
    let model = CollisionModel::new(Arm::default());
    let empty = TreeObstacles::empty();
    let scene = PlanningScene::new(&model, &empty, Allowed::default());
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
    let limits = treemanip_core::robot::kinematics::dh::JOINT_LIMITS;
    let mut tight = 0.0f64;
    for _ in 0..300 {
        let a: Config = Config::from_fn(6, |i| rng.random_range(limits[i].0..limits[i].1) * 0.5);
        let b: Config = Config::from_fn(6, |i| a[i] + rng.random_range(-0.6..0.6));
        let bound = scene.edge_intervals(&a, &b) as f64 * scene.resolution;
        let start = model.capsules_at(&a);
        let mut moved = 0.0f64;
        for k in 1..=200 {
            let t = k as f64 / 200.0;
            let q: Config = Config::from_fn(6, |i| a[i] + (b[i] - a[i]) * t);
            for (c0, c) in start.iter().zip(model.capsules_at(&q)) {
                moved = moved.max((c.1 - c0.1).norm()).max((c.2 - c0.2).norm());
            }
        }
        assert!(
            moved <= bound + 1e-9,
            "moved {moved} m, bound {bound} m: {a:?} → {b:?}"
        );
        tight = tight.max(moved / bound);
    }
    // The bound is not vacuous either.
    assert!(tight > 0.3, "largest motion / bound {tight}");
}

/// Conservative advancement is sound: on random edges near a tree and a
/// post, every edge it accepts is free at 1 mm spacing with no margin, and
/// an edge the dense check finds blocked is always rejected. It also agrees
/// with the fixed-step check on most edges and needs fewer poses.
#[test]
fn conservative_advancement_accepts_only_free_edges() {
    use rand::{RngExt, SeedableRng};
    use treemanip_core::geometry::shape::Shape;
    use treemanip_core::tree::{ScaParams, generate};

    let model = CollisionModel::new(Arm::default());
    let tree = generate(20, 4, &ScaParams::default()).unwrap();
    let post = Shape::turned_box(
        Point3::new(-0.2, 0.35, 0.4),
        nalgebra::Vector3::new(0.04, 0.04, 0.4),
        0.3,
    );
    let obstacles = TreeObstacles::new(&tree).with_obstacles(&[post]);
    let scene = PlanningScene::new(&model, &obstacles, Allowed::default());
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
    let (mut accepted, mut rejected, mut agree, mut total) = (0, 0, 0, 0);
    let (mut ca_poses, mut fixed_poses) = (0usize, 0usize);
    while total < 400 {
        // Edges around the arm's working poses toward the tree.
        let a: Config = Config::from_fn(6, |i| START[i] + rng.random_range(-1.2..1.2));
        if !scene.config_valid(&a) {
            continue;
        }
        let b: Config = Config::from_fn(6, |i| a[i] + rng.random_range(-0.6..0.6));
        total += 1;
        let check = scene.edge_check(&a, &b);
        let dense = dense_path_is_free(&model, &obstacles, &[a, b]);
        if check.free {
            accepted += 1;
            assert!(dense, "accepted edge {a:?} → {b:?} collides");
        } else {
            rejected += 1;
        }
        if check.free == scene.edge_valid_fixed_step(&a, &b) {
            agree += 1;
        }
        if check.free {
            ca_poses += check.poses;
            fixed_poses += scene.edge_intervals(&a, &b) + 1;
        }
    }
    assert!(
        accepted > 80 && rejected > 80,
        "{accepted} accepted, {rejected} rejected"
    );
    assert!(
        agree * 100 >= total * 95,
        "agrees with the fixed step on {agree}/{total}"
    );
    assert!(
        ca_poses * 2 < fixed_poses,
        "free edges: {ca_poses} poses against {fixed_poses} for the fixed step"
    );
}

/// Lazy edge evaluation returns only densely free paths, as the textbook
/// algorithm does, while checking fewer edges, at no worse a median cost.
#[test]
fn lazy_rrt_star_returns_free_paths_with_fewer_edge_checks() {
    use std::cell::Cell;
    struct Counting<'a>(&'a PlanningScene<'a>, Cell<usize>);
    impl MotionValidator for Counting<'_> {
        fn config_valid(&self, q: &Config) -> bool {
            self.0.config_valid(q)
        }
        fn edge_valid(&self, a: &Config, b: &Config) -> bool {
            self.1.set(self.1.get() + 1);
            self.0.edge_valid(a, b)
        }
        fn joint_limits(&self) -> Vec<(f64, f64)> {
            self.0.joint_limits()
        }
    }
    let model = CollisionModel::new(Arm::default());
    let obstacles = fence(bearing_between());
    let scene = PlanningScene::new(&model, &obstacles, Allowed::default());
    let mut edges = [0usize; 2];
    let mut costs = [Vec::new(), Vec::new()];
    for seed in 0..12 {
        for (k, lazy) in [true, false].into_iter().enumerate() {
            let counting = Counting(&scene, Cell::new(0));
            let options = RrtStarOptions {
                seed,
                lazy,
                time_budget: None,
                ..RrtStarOptions::default()
            };
            let path = rrt_star(&START, &[GOAL], &counting, &options).expect("a path");
            assert_eq!(path.waypoints.first(), Some(&START));
            assert_eq!(path.waypoints.last(), Some(&GOAL));
            assert!((path_cost(&path.waypoints) - path.cost).abs() < 1e-9);
            assert!(
                dense_path_is_free(&model, &obstacles, &path.waypoints),
                "seed {seed}, lazy {lazy}: the path collides"
            );
            edges[k] += counting.1.get();
            costs[k].push(path.cost);
        }
    }
    assert!(
        edges[0] < edges[1],
        "lazy {} edges, eager {}",
        edges[0],
        edges[1]
    );
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let (lazy, eager) = (median(&mut costs[0]), median(&mut costs[1]));
    assert!(
        lazy <= eager * 1.1,
        "median cost lazy {lazy}, eager {eager}"
    );
}

/// Counts the edge checks a search asks for; blocks every edge when
/// `block_all` (a config is always valid).
struct EdgeCounter {
    block_all: bool,
    scene: Option<PlanningScene<'static>>,
    edges: std::cell::Cell<usize>,
}

impl MotionValidator for EdgeCounter {
    fn config_valid(&self, q: &Config) -> bool {
        self.scene.as_ref().is_none_or(|s| s.config_valid(q))
    }
    fn edge_valid(&self, a: &Config, b: &Config) -> bool {
        self.edges.set(self.edges.get() + 1);
        !self.block_all && self.scene.as_ref().is_none_or(|s| s.edge_valid(a, b))
    }
    fn joint_limits(&self) -> Vec<(f64, f64)> {
        treemanip_core::robot::ur5::JOINT_LIMITS.to_vec()
    }
}

#[test]
fn a_free_direct_edge_to_the_nearest_goal_ends_the_search_at_once() {
    let model: &'static CollisionModel = Box::leak(Box::new(CollisionModel::new(Arm::default())));
    // The fence stands behind the arm: nothing between START and GOAL.
    let obstacles: &'static TreeObstacles =
        Box::leak(Box::new(fence(bearing_between() + std::f64::consts::PI)));
    let counter = EdgeCounter {
        block_all: false,
        scene: Some(PlanningScene::new(model, obstacles, Allowed::default())),
        edges: std::cell::Cell::new(0),
    };
    let farther: Config = Config::new([1.6, -1.2, 1.4, -1.7, -FRAC_PI_2, 0.4]);
    for lazy in [true, false] {
        counter.edges.set(0);
        let options = RrtStarOptions {
            lazy,
            time_budget: None,
            ..RrtStarOptions::default()
        };
        let path = rrt_star(&START, &[farther, GOAL], &counter, &options).expect("a path");
        assert_eq!(path.waypoints, vec![START, GOAL], "lazy {lazy}");
        assert_eq!(path.goal, 1);
        assert!(
            (path.cost - treemanip_core::robot::motion::rrt::distance(&START, &GOAL)).abs() < 1e-12
        );
        assert_eq!(path.stats.iterations, 0, "lazy {lazy}: no sampling needed");
        assert_eq!(
            counter.edges.get(),
            1,
            "lazy {lazy}: only the nearest goal's direct edge is checked"
        );
    }
}

#[test]
fn shortcut_never_checks_a_blocked_pair_twice() {
    let blocked = EdgeCounter {
        block_all: true,
        scene: None,
        edges: std::cell::Cell::new(0),
    };
    let path: Vec<Config> = (0..5)
        .map(|k| Config::new([0.1 * k as f64, 0.05 * (k % 2) as f64, 0.0, 0.0, 0.0, 0.0]))
        .collect();
    // Three waypoints have one pair to try; five have six.
    for (len, pairs) in [(3, 1), (5, 6)] {
        blocked.edges.set(0);
        let out = shortcut(&path[..len], &blocked, 100, 7);
        assert_eq!(out, path[..len].to_vec());
        assert_eq!(blocked.edges.get(), pairs, "{len} waypoints");
    }
    // With every edge free, the path becomes its two ends.
    let free = EdgeCounter {
        block_all: false,
        scene: None,
        edges: std::cell::Cell::new(0),
    };
    let out = shortcut(&path, &free, 100, 7);
    assert_eq!(out, vec![path[0], path[4]]);
    assert!(path_cost(&out) <= path_cost(&path));
}
