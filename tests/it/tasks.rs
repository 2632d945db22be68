//! Orchard objectives and load limits: residuals against closed forms,
//! loads read from positions against the simulator's, and the planner's
//! `clear` and `reach` pushes checked by simulating them.

use nalgebra::{Point3, Vector3};
use treemanip::geometry::shape::Shape;
use treemanip::planner::objective::{Limits, SATISFIED};
use treemanip::planner::predict::PhysicsPredictor;
use treemanip::planner::seeds::geometric_seeds;
use treemanip::planner::{ContactPolicy, Objective, PlanError, Planner, Query, Stance, Strategy};
use treemanip::robot::motion::push_motion::Outcome;
use treemanip::sim::loads::PushLoads;
use treemanip::sim::{ContactModel, Push, SimConfig, simulate};
use treemanip::tree::{Tree, Wood};

use crate::common::random_tree_and_pushes;

/// Root → 1 straight up 0.4 m, 1 → 2 along +x 0.3 m.
fn elbow() -> Tree {
    let wood = Wood::default();
    Tree::new(
        vec![
            Point3::origin(),
            Point3::new(0.0, 0.0, 0.4),
            Point3::new(0.3, 0.0, 0.4),
        ],
        vec![None, Some(0), Some(1)],
        vec![
            None,
            Some(wood.branch(0.01, 0.4)),
            Some(wood.branch(0.005, 0.3)),
        ],
    )
    .unwrap()
}

/// Residuals by hand: a sphere's distance to a branch capsule, a box
/// turned by its yaw, a capsule line of sight, a reach distance, and a
/// weighted shape that ignores a zero-weight node.
#[test]
fn residuals_match_closed_forms() {
    let tree = elbow();
    let p = tree.positions();
    // Branch 2 lies on z = 0.4 from x = 0 to 0.3, radius 5 mm. A 4 cm
    // fruit centred 3 cm above its middle: it overlaps the branch by
    // 0.04 + 0.005 − 0.03 = 1.5 cm, plus the margin.
    let fruit = Shape::Sphere {
        centre: Point3::new(0.15, 0.0, 0.43),
        radius: 0.04,
    };
    let clear = Objective::Clear {
        regions: vec![fruit.clone()],
        margin: 0.01,
    };
    let r = clear.residual(&tree, p);
    assert!((r - 0.025).abs() < 1e-9, "intrusion {r}");
    // Far above: clear, residual exactly 0.
    let above = Objective::Clear {
        regions: vec![Shape::Sphere {
            centre: Point3::new(0.15, 0.0, 0.6),
            radius: 0.04,
        }],
        margin: 0.01,
    };
    assert_eq!(above.residual(&tree, p), 0.0);
    // A box of half extents 10 × 2 × 2 cm centred at x = 0.35 on the
    // branch's line. Yawed 90° it spans x = 0.33…0.37 and misses branch
    // 2's end (x = 0.3) by 3 cm less the 5 mm radius: clear. Unturned it
    // spans x = 0.25…0.45 and swallows the branch's last 5 cm: the
    // shallowest way out is sideways or up, 2 cm + 5 mm.
    let boxed = |yaw: f64| Objective::Clear {
        regions: vec![Shape::turned_box(
            Point3::new(0.35, 0.0, 0.4),
            Vector3::new(0.1, 0.02, 0.02),
            yaw,
        )],
        margin: 0.0,
    };
    assert_eq!(boxed(std::f64::consts::FRAC_PI_2).residual(&tree, p), 0.0);
    let unturned = boxed(0.0).residual(&tree, p);
    assert!((unturned - 0.025).abs() < 1e-9, "{unturned}");
    // A line of sight from a camera at (0.1, −1, 0.4) to a fruit at
    // (0.1, 0.5, 0.4), 1 cm thick, crosses branch 2's axis: the capsules
    // overlap by their radii, 1 cm + 5 mm (to the precision of parry's
    // penetration query).
    let sight = Objective::Clear {
        regions: vec![Shape::Capsule {
            a: Point3::new(0.1, -1.0, 0.4),
            b: Point3::new(0.1, 0.5, 0.4),
            radius: 0.01,
        }],
        margin: 0.0,
    };
    let crossing = sight.residual(&tree, p);
    assert!((crossing - 0.015).abs() < 1e-6, "{crossing}");
    // Reach: node 2 to a 3 cm sphere 10 cm above it: 7 cm; inside: 0.
    let reach = |z: f64| Objective::Reach {
        node: 2,
        region: Shape::Sphere {
            centre: Point3::new(0.3, 0.0, z),
            radius: 0.03,
        },
    };
    assert!((reach(0.5).residual(&tree, p) - 0.07).abs() < 1e-9);
    assert_eq!(reach(0.41).residual(&tree, p), 0.0);
    // Weighted shape: node 1 off by 5 cm weighs 0, node 2 off by 2 cm
    // weighs 2 → 4 cm.
    let mut targets = p.to_vec();
    targets[1].x += 0.05;
    targets[2].y += 0.02;
    let weighted = Objective::Shape {
        targets: targets.clone(),
        weights: Some(vec![1.0, 0.0, 2.0]),
    };
    assert!((weighted.residual(&tree, p) - 0.04).abs() < 1e-12);
    assert!((Objective::shape(targets).residual(&tree, p) - 0.05).abs() < 1e-12);
}

/// The loads read from positions alone: fed the simulator's own final
/// positions, they give back the simulator's peak stress and contact force
/// on random trees (both contact models), exactly where nothing twists.
#[test]
fn loads_from_positions_match_the_simulator() {
    let mut errors = Vec::new();
    let mut force_errors = Vec::new();
    for (seed, contact) in [
        (11u64, ContactModel::Slot),
        (12, ContactModel::Pinned),
        (13, ContactModel::Slot),
    ] {
        let (tree, pushes) = random_tree_and_pushes(seed, 14, 8);
        let config = SimConfig {
            contact,
            ..SimConfig::default()
        };
        for push in pushes {
            let Ok(out) = simulate(&tree, &push, &config) else {
                continue;
            };
            let exact = PushLoads::of_outcome(&tree, &out);
            if exact.peak_stress < 1e5 {
                continue;
            }
            let read = PushLoads::from_positions(&tree, &push, &out.final_positions, contact);
            errors.push((read.peak_stress - exact.peak_stress).abs() / exact.peak_stress);
            force_errors
                .push((read.contact_force - exact.contact_force).abs() / exact.contact_force);
        }
    }
    assert!(errors.len() >= 10, "{} pushes", errors.len());
    errors.sort_by(f64::total_cmp);
    force_errors.sort_by(f64::total_cmp);
    let median = errors[errors.len() / 2];
    let force_median = force_errors[force_errors.len() / 2];
    // Twist leaves no trace in positions; the bending it reads is exact.
    assert!(median < 0.02, "median stress error {median}");
    assert!(force_median < 0.02, "median force error {force_median}");
}

/// On a 200-node orchard tree, whose trunk is centimetres thick, a
/// prediction's millimetres of noise on every node must not read as a
/// trunk bent to gigapascals: the stress comes from the force the whole
/// path balances, so 2 mm of noise moves it by a fraction, not a multiple.
#[test]
fn loads_from_noisy_positions_of_a_large_tree_stay_near_the_simulators() {
    use rand::{RngExt, SeedableRng};
    let tree = treemanip::tree::generate_orchard(200, 4, &Default::default()).unwrap();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    let mut ratios = Vec::new();
    for node in (20..tree.len()).step_by(9) {
        let axis = tree.branch_direction(node).unwrap();
        let push = Push {
            node,
            vector: axis.cross(&nalgebra::Vector3::z()).normalize() * 0.08,
        };
        let Ok(out) = simulate(&tree, &push, &SimConfig::default()) else {
            continue;
        };
        let exact = PushLoads::of_outcome(&tree, &out);
        if exact.peak_stress < 1e6 {
            continue;
        }
        let noisy: Vec<_> = out
            .final_positions
            .iter()
            .map(|p| p + nalgebra::Vector3::from_fn(|_, _| rng.random_range(-0.002..0.002)))
            .collect();
        let read = PushLoads::from_positions(&tree, &push, &noisy, ContactModel::Slot);
        ratios.push(read.peak_stress / exact.peak_stress);
    }
    assert!(ratios.len() >= 8, "{} pushes", ratios.len());
    ratios.sort_by(f64::total_cmp);
    let median = ratios[ratios.len() / 2];
    let worst = ratios[ratios.len() - 1];
    assert!(
        (0.7..1.4).contains(&median),
        "median ratio {median} ({ratios:?})"
    );
    assert!(worst < 3.0, "worst ratio {worst} ({ratios:?})");
}

/// A single branch pushed sideways at its tip (pinned): the loads read
/// from positions are the closed form M = K φ, F⊥ = M / ℓ.
#[test]
fn loads_from_positions_of_a_cantilever() {
    let (length, radius, phi) = (0.4, 0.006, 0.25_f64);
    let wood = Wood::default();
    let tree = Tree::new(
        vec![Point3::origin(), Point3::new(0.0, 0.0, length)],
        vec![None, Some(0)],
        vec![None, Some(wood.branch(radius, length))],
    )
    .unwrap();
    let tip = Point3::new(length * phi.sin(), 0.0, length * phi.cos());
    let push = Push {
        node: 1,
        vector: tip - tree.position(1),
    };
    let loads =
        PushLoads::from_positions(&tree, &push, &[Point3::origin(), tip], ContactModel::Pinned);
    let k = tree.branch(1).unwrap().stiffness;
    let stress = 4.0 * k * phi / (std::f64::consts::PI * radius.powi(3));
    assert!((loads.peak_stress - stress).abs() < 1e-9 * stress);
    assert_eq!(loads.peak_node, Some(1));
    assert!((loads.contact_force - k * phi / length).abs() < 1e-9 * k * phi / length);
}

/// A policy that must not be asked: `clear` and `reach` are seeded by
/// geometry.
struct NoPolicy;

impl ContactPolicy for NoPolicy {
    fn rank(
        &self,
        _: &Tree,
        _: &[Point3<f64>],
    ) -> Result<Vec<treemanip::planner::Candidate>, treemanip::planner::PredictError> {
        panic!("the contact policy is for full target shapes only")
    }
}

/// A random 12-node tree with a 3 cm fruit across the middle of its last
/// branch, to be cleared by 1 cm.
fn fruit_task(seed: u64) -> (Tree, Objective) {
    let (tree, _) = random_tree_and_pushes(300 + seed, 12, 1);
    let j = tree.len() - 1;
    let parent = tree.parent(j).unwrap();
    let centre = nalgebra::center(&tree.position(parent), &tree.position(j));
    let objective = Objective::Clear {
        regions: vec![Shape::Sphere {
            centre,
            radius: 0.03,
        }],
        margin: 0.01,
    };
    (tree, objective)
}

/// `clear` with the simulator as predictor and a base region, on random
/// trees with a fruit across a branch: every plan, simulated, clears the
/// fruit by the margin and stays within the limits; pushes over a limit
/// are reported as such; `paper` refuses a non-shape objective.
#[test]
fn physics_clears_a_fruit_within_the_limits() {
    let limits = Limits {
        max_stress: 40e6,
        max_contact_force: 50.0,
    };
    let (mut planned, mut tasks) = (0, 0);
    for seed in 0..6u64 {
        let (tree, objective) = fruit_task(seed);
        assert!(objective.residual(&tree, tree.positions()) > 0.0);
        assert!(!geometric_seeds(&tree, &objective, 6).is_empty());
        let mut query = Query::with_objective(tree.clone(), objective.clone());
        query.strategy = Strategy::Physics;
        query.limits = Some(limits);
        query.stance = Stance::Region(treemanip::eval::plan::evaluation_region());
        let plan = Planner::default().plan(&query, &NoPolicy, None).unwrap();
        tasks += 1;
        assert_eq!(plan.objective, "clear");
        for a in &plan.attempts {
            if a.outcome == Outcome::OverLimit {
                let l = a.simulated_loads.or(a.predicted_loads).unwrap();
                assert!(!limits.allow(&l), "{a:?}");
            }
        }
        if let Some(p) = &plan.plan {
            planned += 1;
            let push = Push {
                node: p.node,
                vector: p.push,
            };
            let out = simulate(&tree, &push, &SimConfig::default()).unwrap();
            let residual = objective.residual(&tree, &out.final_positions);
            assert!(residual <= SATISFIED, "seed {seed}: residual {residual}");
            let loads = PushLoads::of_outcome(&tree, &out);
            assert!(limits.allow(&loads), "{loads:?}");
            assert_eq!(plan.simulated_loads, Some(loads));
            // The clearance reached: at least the margin, and the physics
            // prediction is the simulation.
            let clearance = plan.clearance.unwrap();
            assert!(clearance.simulated.unwrap() >= 0.01 - 1e-6, "{clearance:?}");
            assert!((clearance.predicted.unwrap() - clearance.simulated.unwrap()).abs() < 1e-6);
        }
        query.strategy = Strategy::Paper;
        assert!(matches!(
            Planner::default().plan(&query, &NoPolicy, None),
            Err(PlanError::PaperNeedsShape("clear"))
        ));
    }
    assert!(planned * 2 >= tasks, "{planned} of {tasks} planned");
}

/// `reach` by the simulator's search, arm ignored: a node whose episode
/// push carried it somewhere is brought into a 3 cm sphere there.
#[test]
fn the_search_brings_a_node_into_reach() {
    use treemanip::planner::search::{SearchOptions, search_pushes};
    let mut met = 0;
    let mut cases = 0;
    for seed in 0..4u64 {
        let (tree, pushes) = random_tree_and_pushes(500 + seed, 10, 4);
        for push in pushes {
            let Ok(out) = simulate(&tree, &push, &SimConfig::default()) else {
                continue;
            };
            let node = push.node;
            if (out.final_positions[node] - tree.position(node)).norm() < 0.05 {
                continue;
            }
            let objective = Objective::Reach {
                node,
                region: Shape::Sphere {
                    centre: out.final_positions[node],
                    radius: 0.03,
                },
            };
            let seeds = geometric_seeds(&tree, &objective, 6);
            assert_eq!(seeds[0].node, node, "the node itself first");
            let all = |_: &Push| true;
            let options = SearchOptions {
                max_evaluations: 64,
                ..SearchOptions::default()
            };
            let (scored, _) = search_pushes(
                &tree,
                &objective,
                None,
                &seeds,
                &PhysicsPredictor,
                &all,
                &options,
            )
            .unwrap();
            cases += 1;
            if scored[0].predicted_error <= SATISFIED {
                met += 1;
                // Ties at zero go to the least stressed push.
                let best = scored[0].loads.peak_stress;
                assert!(
                    scored
                        .iter()
                        .take_while(|s| s.predicted_error <= SATISFIED)
                        .all(|s| s.loads.peak_stress >= best)
                );
            }
            break;
        }
    }
    assert!(cases >= 3 && met * 4 >= cases * 3, "{met} of {cases}");
}

/// The simulator's positions with every displacement halved: loads read
/// from them run about half the simulator's, as a forward model's may, so
/// its best pushes overload the tree in their simulation.
struct Timid;

impl treemanip::planner::Predictor for Timid {
    fn final_positions(
        &self,
        tree: &Tree,
        pushes: &[Push],
    ) -> Result<Vec<Option<Vec<Point3<f64>>>>, treemanip::planner::PredictError> {
        let full = PhysicsPredictor.final_positions(tree, pushes)?;
        Ok(full
            .into_iter()
            .map(|o| {
                o.map(|after| {
                    after
                        .iter()
                        .zip(tree.positions())
                        .map(|(p, rest)| rest + (p - rest) * 0.5)
                        .collect()
                })
            })
            .collect())
    }

    fn name(&self) -> &'static str {
        "model"
    }
}

/// `model` with a predictor that reads loads too low: the pushes whose
/// simulation is over a limit are tried again eased back to it
/// (`planner::eased`), and what is carried out is within the limits.
#[test]
fn overloaded_pushes_are_eased_back_to_the_limits() {
    let limits = Limits {
        max_stress: 40e6,
        max_contact_force: 50.0,
    };
    let mut eased = 0;
    for seed in 0..16u64 {
        let (tree, objective) = fruit_task(seed);
        let mut query = Query::with_objective(tree.clone(), objective);
        query.strategy = Strategy::Model;
        query.limits = Some(limits);
        query.stance = Stance::Region(treemanip::eval::plan::evaluation_region());
        let plan = Planner::default()
            .plan(&query, &NoPolicy, Some(&Timid))
            .unwrap();
        let Some(p) = &plan.plan else { continue };
        let out = simulate(
            &tree,
            &Push {
                node: p.node,
                vector: p.push,
            },
            &SimConfig::default(),
        )
        .unwrap();
        assert!(limits.allow(&PushLoads::of_outcome(&tree, &out)));
        // An eased push: the same node and direction as a push refused
        // over a limit, at most 0.95 of its length.
        let from_overload = plan.attempts.iter().any(|a| {
            let v = Vector3::from(a.push);
            a.outcome == Outcome::OverLimit
                && a.node == p.node
                && p.push.norm() <= 0.95 * v.norm() + 1e-9
                && p.push.normalize().dot(&v.normalize()) > 1.0 - 1e-9
        });
        eased += usize::from(from_overload);
    }
    assert!(eased >= 2, "{eased} of 16 plans were eased pushes");
}
