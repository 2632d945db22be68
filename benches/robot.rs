//! Robot throughput: `cargo bench --bench robot`.
//!
//! - collision queries/s: empty workcell, and against a 30-node tree;
//! - closed-form IK solves/s;
//! - RRT* (ours) against the `rrt` crate's RRT-Connect on the same scene
//!   (a fence between two configurations) and the same collision function.
//!   RRT-Connect only checks the configurations it adds, `extend_length`
//!   apart, so its paths are re-checked with our conservative edge test.
//!
//! Numbers only, no thresholds. Algorithm 1 over 2,100 episodes is
//! `treemanip eval plan`.

use std::cell::RefCell;
use std::f64::consts::FRAC_PI_2;
use std::hint::black_box;
use std::time::{Duration, Instant};

use nalgebra::{Isometry3, Matrix3, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use treemanip::robot::arm::PAPER_BASE;
use treemanip::robot::collision::{Allowed, CollisionModel, TreeObstacles};
use treemanip::robot::kinematics::ur_closed_form;
use treemanip::robot::motion::rrt::{Config, MotionValidator, RrtStarOptions, rrt_star};
use treemanip::robot::motion::scene::PlanningScene;
use treemanip::robot::{Arm, ur5};
use treemanip::tree::{ScaParams, generate};

fn rate(budget: Duration, mut f: impl FnMut(u64)) -> f64 {
    let start = Instant::now();
    let mut n = 0;
    while start.elapsed() < budget {
        f(n);
        n += 1;
    }
    n as f64 / start.elapsed().as_secs_f64()
}

fn percentile(v: &mut [f64], p: f64) -> f64 {
    v.sort_by(f64::total_cmp);
    v[((v.len() - 1) as f64 * p).round() as usize]
}

fn main() {
    let budget = Duration::from_secs(2);
    let model = CollisionModel::new(Arm::default());
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let configs: Vec<Config> = (0..4096)
        .map(|_| {
            Config::from_fn(6, |i| {
                rng.random_range(ur5::JOINT_LIMITS[i].0..ur5::JOINT_LIMITS[i].1)
            })
        })
        .collect();
    let empty = TreeObstacles::empty();
    let tree = generate(30, 1, &ScaParams::default()).unwrap();
    let obstacles = TreeObstacles::new(&tree);
    let none = Allowed::default();
    println!("collision queries (random configurations, one thread)");
    let r = rate(budget, |i| {
        black_box(model.check(&configs[i as usize % 4096], &empty, &none));
    });
    println!("  empty workcell      {:>10.0} /s  ({:.2} µs)", r, 1e6 / r);
    let r = rate(budget, |i| {
        black_box(model.check(&configs[i as usize % 4096], &obstacles, &none));
    });
    println!("  30-node tree        {:>10.0} /s  ({:.2} µs)", r, 1e6 / r);
    // Near the tree: configurations whose tool is within 30 cm of a node.
    let near: Vec<Config> = configs
        .iter()
        .filter(|q| {
            let p = Point3::from(model.robot.tool_pose(q).translation.vector);
            tree.positions().iter().any(|n| (n - p).norm() < 0.3)
        })
        .copied()
        .collect();
    if !near.is_empty() {
        let r = rate(budget, |i| {
            black_box(model.check(&near[i as usize % near.len()], &obstacles, &none));
        });
        println!(
            "  tool near the tree  {:>10.0} /s  ({:.2} µs, {} configurations)",
            r,
            1e6 / r,
            near.len()
        );
    }

    let targets: Vec<_> = configs
        .iter()
        .map(|q| ur_closed_form::forward(&std::array::from_fn(|i| q[i])))
        .collect();
    let r = rate(budget, |i| {
        black_box(ur_closed_form::solve(
            &targets[i as usize % 4096],
            &[0.0; 6],
        ));
    });
    println!(
        "\nclosed-form IK        {:>10.0} /s  ({:.2} µs)",
        r,
        1e6 / r
    );

    // The fence scene of tests/robot_rrt.rs.
    let start = Config::from([0.0, -1.2, 1.4, -1.7, -FRAC_PI_2, 0.0]);
    let goal = Config::from([1.3, -1.2, 1.4, -1.7, -FRAC_PI_2, 0.0]);
    let fence = fence_between(&model, &start, &goal);
    let scene = PlanningScene::new(&model, &fence, Allowed::default());
    let runs = 40;
    println!("\nfence scene, {runs} seeds each (start → goal through a 0.5 m fence)");
    let fixed = FixedStep(&scene);
    for (name, validator, lazy, refine) in [
        (
            "RRT* (ours, lazy)   ",
            &scene as &dyn MotionValidator,
            true,
            20,
        ),
        (
            "RRT* (lazy, refine 40)",
            &scene as &dyn MotionValidator,
            true,
            40,
        ),
        (
            "RRT* (ours, eager)  ",
            &scene as &dyn MotionValidator,
            false,
            20,
        ),
        (
            "RRT* (fixed-step)   ",
            &fixed as &dyn MotionValidator,
            false,
            20,
        ),
    ] {
        let mut times = Vec::new();
        let mut costs = Vec::new();
        for seed in 0..runs {
            let options = RrtStarOptions {
                seed,
                time_budget: Some(Duration::from_secs(2)),
                lazy,
                refine_iterations: refine,
                ..RrtStarOptions::default()
            };
            let t = Instant::now();
            if let Ok(p) = rrt_star(&start, &[goal], validator, &options) {
                times.push(t.elapsed().as_secs_f64() * 1e3);
                costs.push(p.cost);
            }
        }
        let solved = times.len();
        println!(
            "  {name}{solved}/{runs} solved, median {:.2} ms, p95 {:.1} ms, median cost {:.2} rad",
            percentile(&mut times, 0.5),
            percentile(&mut times, 0.95),
            percentile(&mut costs, 0.5)
        );
    }
    // Where an RRT* query's time goes: configuration checks, by caller.
    let counting = Counting {
        scene: &scene,
        configs: Default::default(),
        edges: Default::default(),
        edge_configs: Default::default(),
        edge_poses: Default::default(),
    };
    let mut iterations = 0;
    for seed in 0..runs {
        let options = RrtStarOptions {
            seed,
            time_budget: Some(Duration::from_secs(2)),
            ..RrtStarOptions::default()
        };
        if let Ok(p) = rrt_star(&start, &[goal], &counting, &options) {
            iterations += p.stats.iterations;
        }
    }
    let per = |c: &std::cell::Cell<usize>| c.get() as f64 / runs as f64;
    println!(
        "  per query (mean): {:.0} iterations, {:.0} sampled configurations checked, {:.0} edges checked at {:.0} poses (a fixed step would span {:.0})",
        iterations as f64 / runs as f64,
        per(&counting.configs),
        per(&counting.edges),
        per(&counting.edge_poses),
        per(&counting.edge_configs)
    );
    let mut times = Vec::new();
    let mut costs = Vec::new();
    let mut invalid = 0;
    for seed in 0..runs {
        let sampler = RefCell::new(ChaCha8Rng::seed_from_u64(seed));
        let t = Instant::now();
        let result = rrt::dual_rrt_connect(
            &start,
            &goal,
            |q: &[f64]| scene.config_valid(&Config::from_slice(q)),
            || {
                let mut r = sampler.borrow_mut();
                (0..6)
                    .map(|i| {
                        r.random_range(
                            ur5::JOINT_LIMITS[i].0.max(-2.5)..ur5::JOINT_LIMITS[i].1.min(2.5),
                        )
                    })
                    .collect()
            },
            0.05,
            20_000,
        );
        if let Ok(path) = result {
            times.push(t.elapsed().as_secs_f64() * 1e3);
            let path: Vec<Config> = path.iter().map(|q| Config::from_slice(q)).collect();
            costs.push(treemanip::robot::motion::rrt::path_cost(&path));
            if !path.windows(2).all(|w| scene.edge_valid(&w[0], &w[1])) {
                invalid += 1;
            }
        }
    }
    let solved = times.len();
    println!(
        "  RRT-Connect (rrt)   {solved}/{runs} solved, median {:.1} ms, p95 {:.1} ms, median cost {:.2} rad, {invalid} paths fail the conservative edge check",
        percentile(&mut times, 0.5),
        percentile(&mut times, 0.95),
        percentile(&mut costs, 0.5)
    );
    fence_per_arm(runs);
}

/// The scene, counting the checks RRT* asks for.
struct Counting<'a> {
    scene: &'a PlanningScene<'a>,
    configs: std::cell::Cell<usize>,
    edges: std::cell::Cell<usize>,
    edge_configs: std::cell::Cell<usize>,
    edge_poses: std::cell::Cell<usize>,
}

/// The scene with the textbook fixed-step edge check, for comparison.
struct FixedStep<'a>(&'a PlanningScene<'a>);

impl MotionValidator for FixedStep<'_> {
    fn config_valid(&self, q: &Config) -> bool {
        self.0.config_valid(q)
    }

    fn edge_valid(&self, a: &Config, b: &Config) -> bool {
        self.0.edge_valid_fixed_step(a, b)
    }

    fn joint_limits(&self) -> Vec<(f64, f64)> {
        self.0.joint_limits()
    }
}

impl MotionValidator for Counting<'_> {
    fn config_valid(&self, q: &Config) -> bool {
        self.configs.set(self.configs.get() + 1);
        self.scene.config_valid(q)
    }

    fn edge_valid(&self, a: &Config, b: &Config) -> bool {
        self.edges.set(self.edges.get() + 1);
        self.edge_configs
            .set(self.edge_configs.get() + self.scene.edge_intervals(a, b));
        let check = self.scene.edge_check(a, b);
        self.edge_poses.set(self.edge_poses.get() + check.poses);
        check.free
    }

    fn joint_limits(&self) -> Vec<(f64, f64)> {
        self.scene.joint_limits()
    }
}

/// A fence of 13 poles (2 cm radius, 0.5 m tall) on the ray from the arm's
/// base halfway between where the tool is at `start` and at `goal`, from
/// 0.3 to 0.9 m out: the way between them goes over or around it.
fn fence_between(model: &CollisionModel, start: &Config, goal: &Config) -> TreeObstacles {
    let base = model.robot.base.translation.vector;
    let tool = |q: &Config| model.robot.tool_pose(q).translation.vector - base;
    let (a, b) = (tool(start), tool(goal));
    let bearing = (a.y.atan2(a.x) + b.y.atan2(b.x)) / 2.0;
    let poles: Vec<_> = (0..13)
        .map(|k| {
            let r = 0.3 + 0.05 * k as f64;
            let foot = Point3::new(base.x + r * bearing.cos(), base.y + r * bearing.sin(), 0.0);
            (k, foot, foot + Vector3::z() * 0.5, 0.02)
        })
        .collect();
    TreeObstacles::from_capsules(&poles)
}

/// A start and a goal on either side of where [`fence_between`] puts the
/// fence: the tool 0.2 m above the base, pointing outward (or down), at half the
/// arm's reach (or a little nearer or farther), 0.65 rad (or 0.9) either
/// side of the base's x axis; the IK solutions nearest each other in
/// joint space that are free of the fence and whose straight line is not.
fn across_fence(model: &CollisionModel) -> Option<(Config, Config, TreeObstacles)> {
    let base = model.robot.base;
    let heading = base.rotation * Vector3::x();
    let ahead = heading.y.atan2(heading.x);
    let reach = model.robot.reach();
    let home = model.robot.home();
    let tool_at = |bearing: f64, r: f64, down: bool| {
        let out = Vector3::new(bearing.cos(), bearing.sin(), 0.0);
        let up = Vector3::z();
        let (x, z) = if down { (out, -up) } else { (up, out) };
        let rotation = Rotation3::from_matrix(&Matrix3::from_columns(&[x, z.cross(&x), z]));
        let p = base.translation.vector + out * r + up * 0.2;
        Isometry3::from_parts(
            Translation3::from(p),
            UnitQuaternion::from_rotation_matrix(&rotation),
        )
    };
    let tries = [
        (0.5, 0.65),
        (0.4, 0.65),
        (0.6, 0.65),
        (0.5, 0.9),
        (0.6, 0.9),
    ];
    for (down, (r, angle)) in [false, true]
        .into_iter()
        .flat_map(|d| tries.into_iter().map(move |t| (d, t)))
    {
        // Solved from home turned toward the tool (a 7-joint arm's
        // nearest solution to home itself can keep its elbow over the
        // fence and cross it with the forearm).
        let solutions = |bearing: f64| {
            let mut reference = home;
            reference[0] += bearing - ahead;
            model
                .robot
                .inverse_kinematics(&tool_at(bearing, r * reach, down), &reference)
        };
        let (starts, goals) = (solutions(ahead + angle), solutions(ahead - angle));
        // The nearest pair in joint space that the fence leaves free and
        // stands between (the straight joint-space line collides).
        let mut pairs: Vec<(f64, Config, Config)> = starts
            .iter()
            .flat_map(|a| goals.iter().map(move |b| (a.max_abs_diff(b), *a, *b)))
            .collect();
        pairs.sort_by(|x, y| x.0.total_cmp(&y.0));
        for (_, start, goal) in pairs {
            let fence = fence_between(model, &start, &goal);
            let scene = PlanningScene::new(model, &fence, Allowed::default());
            if scene.config_valid(&start)
                && scene.config_valid(&goal)
                && !scene.edge_valid(&start, &goal)
            {
                return Some((start, goal, fence));
            }
        }
    }
    None
}

/// The fence query for every shipped arm: the tool from one side of the
/// fence to the other ([`across_fence`]; lazy RRT*, the planner's
/// settings).
fn fence_per_arm(runs: u64) {
    println!(
        "\nfence query per shipped arm (tool 0.65-0.9 rad either side of a 0.5 m fence), {runs} seeds each"
    );
    for name in ["ur5", "ur10", "panda", "iiwa"] {
        let spec = treemanip::robot::catalog::RobotSpec::at(
            name.to_owned(),
            format!("robots/{name}.toml").into(),
        );
        let arm = treemanip::robot::catalog::load(&spec, &[]).expect("a shipped arm loads");
        let model = CollisionModel::new(arm.with_base(PAPER_BASE));
        let Some((start, goal, fence)) = across_fence(&model) else {
            println!("  {name:<6} no free start and goal either side of the fence: no query");
            continue;
        };
        let scene = PlanningScene::new(&model, &fence, Allowed::default());
        // The fence is in the way: the straight joint-space line collides.
        let direct = scene.edge_valid(&start, &goal);
        let (mut times, mut costs) = (Vec::new(), Vec::new());
        let mut failure = None;
        for seed in 0..runs {
            let options = RrtStarOptions {
                seed,
                time_budget: Some(Duration::from_secs(2)),
                ..RrtStarOptions::default()
            };
            let t = Instant::now();
            match rrt_star(&start, &[goal], &scene, &options) {
                Ok(p) => {
                    times.push(t.elapsed().as_secs_f64() * 1e3);
                    costs.push(p.cost);
                }
                Err(e) => failure = Some(e),
            }
        }
        if times.is_empty() {
            println!("  {name:<6} 0/{runs} solved: {failure:?}");
            continue;
        }
        println!(
            "  {name:<6} ({} joints{}) {}/{runs} solved, median {:.2} ms, p95 {:.1} ms, median cost {:.2} rad",
            model.robot.dof(),
            if direct {
                ", direct edge free"
            } else {
                ", fence in the way"
            },
            times.len(),
            percentile(&mut times, 0.5),
            percentile(&mut times, 0.95),
            percentile(&mut costs, 0.5)
        );
    }
}
