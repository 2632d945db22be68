//! Push, look, push again: `/v1/plan` with the first push's observation.
//!
//! Per test tree: the truth's stiffness is hidden and perturbed; the target
//! is where a random paper-style push that the arm can make from the base
//! region moves the true tree. The first plan
//! is made on the radius formula's stiffness (physics strategy, the arm in
//! the evaluation's base region) and executed on the truth; the positions
//! held at its end (3 mm noise) become an observation. The second plan is
//! made from rest with that observation ([`Query::observations`]: identify,
//! then plan on the estimate, searching the first push again) and executed
//! on the truth again (the tree springs back in
//! between). An oracle that plans on the true stiffness is the ceiling.

use std::time::Duration;

use nalgebra::Point3;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

use crate::identify::{Noise, Probe, observe};
use crate::infer::models::ServedModel;
use crate::planner::predict::max_node_error;
use crate::planner::{Planner, Predictor, Query, Stance, Strategy};
use crate::seed::{derive_seed, standard_normal};
use crate::sim::sampling::PushDistribution;
use crate::sim::{ContactModel, Push, SimConfig, simulate};
use crate::tree::Tree;

/// One tree's errors (m); `None` where a plan found no push.
#[derive(Debug, Clone, Serialize)]
pub struct LoopOutcome {
    pub n: usize,
    pub no_action: f64,
    pub first: f64,
    pub second: f64,
    pub oracle: f64,
}

/// Plans on `model_tree` (with `observations`, as `/v1/plan` does: on the
/// stiffness identified from them) and executes on `truth`: the push and the held
/// positions, or `None` when nothing is planned or the push fails.
fn plan_and_execute(
    (planner, policy, forward): (&Planner, &ServedModel, &ServedModel),
    model_tree: &Tree,
    observations: Vec<Probe>,
    truth: &Tree,
    targets: &[Point3<f64>],
    seed: u64,
) -> Option<(Push, Vec<Point3<f64>>)> {
    let mut query = Query::new(model_tree.clone(), targets.to_vec());
    query.observations = observations;
    // As the shape benchmark: no load limits.
    query.limits = None;
    query.strategy = Strategy::Physics;
    query.budget = Duration::from_secs(2);
    query.stance = Stance::Region(crate::eval::plan::evaluation_region());
    query.seed = seed;
    let plan = planner
        .plan(&query, policy, Some(forward as &dyn Predictor))
        .ok()?
        .plan?;
    let push = Push {
        node: plan.node,
        vector: plan.push,
    };
    let held = simulate(truth, &push, &SimConfig::default()).ok()?;
    Some((push, held.final_positions))
}

/// One tree of the closed-loop study.
pub fn run_tree(
    planner: &Planner,
    policy: &ServedModel,
    forward: &ServedModel,
    nominal: &Tree,
    sigma: f64,
    seed: u64,
) -> Option<LoopOutcome> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let k: Vec<f64> = nominal
        .branches()
        .iter()
        .map(|b| {
            b.map_or(0.0, |b| {
                b.stiffness * (sigma * standard_normal(&mut rng)).exp()
            })
        })
        .collect();
    let truth = crate::identify::with_stiffness(nominal, &k);
    // A target the arm could have made: the first sampled push it can
    // reach from the region (an unreachable one measures the arm, which
    // no stiffness estimate changes).
    let stance = Stance::Region(crate::eval::plan::evaluation_region());
    let reachable = planner.reach_test(nominal, &[], &stance, None);
    let targets = (0..50).find_map(|_| {
        let push = PushDistribution::default().sample(nominal, &mut rng);
        if !reachable(&push) {
            return None;
        }
        simulate(&truth, &push, &SimConfig::default())
            .ok()
            .map(|o| o.final_positions)
    })?;
    let no_action = max_node_error(nominal.positions(), &targets);
    let error = |held: Option<&(Push, Vec<Point3<f64>>)>| {
        held.map_or(no_action, |(_, p)| max_node_error(p, &targets))
    };
    let plan = |model: &Tree, observations: Vec<Probe>| {
        plan_and_execute(
            (planner, policy, forward),
            model,
            observations,
            &truth,
            &targets,
            seed,
        )
    };
    let first = plan(nominal, Vec::new());
    let oracle = plan(&truth, Vec::new());
    let second = first.as_ref().and_then(|(push, _)| {
        let probe = observe(
            &truth,
            *push,
            ContactModel::Slot,
            &Noise::default(),
            false,
            &mut rng,
        )?;
        plan(nominal, vec![probe])
    });
    Some(LoopOutcome {
        n: nominal.len(),
        no_action,
        first: error(first.as_ref()),
        second: error(second.as_ref().or(first.as_ref())),
        oracle: error(oracle.as_ref()),
    })
}

/// Every tree, in order (the planner parallelises inside).
pub fn run_study(
    planner: &Planner,
    policy: &ServedModel,
    forward: &ServedModel,
    trees: &[Tree],
    sigma: f64,
    seed: u64,
    mut progress: impl FnMut(),
) -> Vec<LoopOutcome> {
    trees
        .iter()
        .enumerate()
        .filter_map(|(i, t)| {
            let out = run_tree(
                planner,
                policy,
                forward,
                t,
                sigma,
                derive_seed(seed, &[i as u64, 0x100]),
            );
            progress();
            out
        })
        .collect()
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}

/// Targets the arm reproduces: the planner on the true stiffness leaves
/// at most this much (m). The rest are targets the reach test let through
/// but no path or straight push reaches; no stiffness estimate changes
/// them, and their errors (10-50 cm) would swamp the mean.
pub const REPRODUCED: f64 = 0.02;

/// Means and medians over trees (cm), and the excess over the oracle: the
/// part of the error that the stiffness, not the search or the arm, makes;
/// one row for every tree and one for the targets the arm reproduces.
pub fn to_markdown(sigma: f64, outcomes: &[LoopOutcome]) -> String {
    let reproduced: Vec<LoopOutcome> = outcomes
        .iter()
        .filter(|o| o.oracle <= REPRODUCED)
        .cloned()
        .collect();
    format!(
        "{}{}",
        row(sigma, "all", outcomes),
        row(sigma, "reproduced by the arm (oracle ≤ 2 cm)", &reproduced)
    )
}

/// The table's header (see [`to_markdown`]).
pub const HEADER: &str = "| σ | targets | trees | No Action | first plan (radius-formula K) | second plan (identified from the first push) | reduction | oracle (true K) | excess over oracle: first → second |\n| --- | --- | --- | --- | --- | --- | --- | --- | --- |\n";

fn row(sigma: f64, label: &str, outcomes: &[LoopOutcome]) -> String {
    let mean = |f: &dyn Fn(&LoopOutcome) -> f64| {
        outcomes.iter().map(f).sum::<f64>() / outcomes.len().max(1) as f64
    };
    let med = |f: &dyn Fn(&LoopOutcome) -> f64| median(outcomes.iter().map(f).collect());
    let (first, second) = (mean(&|o| o.first), mean(&|o| o.second));
    let (excess_first, excess_second) = (
        mean(&|o| (o.first - o.oracle).max(0.0)),
        mean(&|o| (o.second - o.oracle).max(0.0)),
    );
    format!(
        "| {sigma} | {label} | {} | {:.2} cm | mean {:.2} cm, median {:.2} cm | mean {:.2} cm, median {:.2} cm | mean {:.0} %, median {:.0} % | mean {:.2} cm, median {:.2} cm | {:.2} → {:.2} mm |\n",
        outcomes.len(),
        mean(&|o| o.no_action) * 100.0,
        first * 100.0,
        med(&|o| o.first) * 100.0,
        second * 100.0,
        med(&|o| o.second) * 100.0,
        (1.0 - second / first) * 100.0,
        (1.0 - med(&|o| o.second) / med(&|o| o.first)) * 100.0,
        mean(&|o| o.oracle) * 100.0,
        med(&|o| o.oracle) * 100.0,
        excess_first * 1e3,
        excess_second * 1e3,
    )
}
