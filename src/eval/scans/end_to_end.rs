//! End to end: `clear` tasks planned on the tree extracted from a scan
//! (the arm-free search with the simulator and load limits, the clearance
//! margin grown by [`EXTRACTED_MARGIN`], [`EXTRACTED_STRESS_RESERVE`] of the
//! stress limit kept in reserve) and carried out on the true tree
//! where a gripper closing at the planned contact would hold it
//! ([`held_at`]) as a guarded move that stops at the plan's guard force
//! ([`Limits::guard_force`], [`guarded_push`]), against the same planning on the true tree; each
//! task the extracted tree misses is counted with why ([`Missed`]).

use nalgebra::Point3;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::Serialize;

use crate::eval::tasks::{best_push, clear_task, execute};
use crate::planner::objective::{Limits, SATISFIED};
use crate::scan::Extraction;
use crate::scan::skeleton::point_segment;
use crate::seed::derive_seed;
use crate::sim::guarded::guarded_push;
use crate::sim::loads::PushLoads;
use crate::sim::{Push, SimConfig};
use crate::tree::{Branch, MAX_NODES, Tree, Wood};

/// End to end over one condition's extractions.
#[derive(Debug, Clone, Default, Serialize)]
pub struct EndToEnd {
    pub tasks: usize,
    /// Tasks whose push planned on the true tree succeeds on it.
    pub true_solved: usize,
    /// Of those, how many the push planned on the extracted tree solves on
    /// the true tree.
    pub extracted_solved: usize,
    /// Tasks the extracted tree's push solves (whether or not the true
    /// tree's does).
    pub extracted_solved_any: usize,
    /// Extracted-tree pushes over the load limits on the true tree, carried
    /// out as guarded moves that stop at the plan's guard force
    /// ([`Limits::guard_force`], [`guarded_push`]): what an arm with a wrist force sensor does.
    pub over_limit: usize,
    /// The same pushes carried out to their end whatever the force.
    pub over_limit_unguarded: usize,
    /// Pushes the guard stopped short.
    pub guard_stopped: usize,
    /// Tasks without an extracted tree the simulator takes (refused cloud,
    /// too many nodes).
    pub no_tree: usize,
    /// Why the tasks the true tree's push solves and the extracted tree's
    /// does not are missed.
    pub missed: Missed,
}

/// Why a task solved on the true tree is missed from the extracted one.
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct Missed {
    /// The search found no push on the extracted tree.
    pub no_push: usize,
    /// No true branch within [`CONTACT_MATCH`] of the planned contact.
    pub no_branch: usize,
    /// Carried out on the true tree, the push leaves the region unclear.
    pub not_cleared: usize,
    /// Carried out on the true tree, the push loads it over a limit.
    pub over_limit: usize,
}

impl Missed {
    fn add(self, o: Missed) -> Missed {
        Missed {
            no_push: self.no_push + o.no_push,
            no_branch: self.no_branch + o.no_branch,
            not_cleared: self.not_cleared + o.not_cleared,
            over_limit: self.over_limit + o.over_limit,
        }
    }
}

/// How far (m) the extracted push's contact may be from the true branch it
/// is carried out on.
pub const CONTACT_MATCH: f64 = 0.05;

/// Planning on an extracted tree adds this (m) to a `clear` task's margin:
/// the tree's geometry is known to a few millimetres, not exactly.
pub const EXTRACTED_MARGIN: f64 = 0.01;

/// Planning on an extracted tree keeps this share of the stress limit in
/// reserve: σ = 4M/(πr³) goes with the cube of the radius, which the
/// extraction knows to about 0.16 mm (median, 3 views, 2 mm noise) on
/// twigs of 5 mm, so 3 Δr/r ≈ 10 %. The guard is read under the same
/// reserved limits: the stress per newton it converts the stress limit
/// into a force with is the extracted tree's, off by as much.
pub const EXTRACTED_STRESS_RESERVE: f64 = 0.1;

/// `tasks_per_tree` `clear` tasks per tree: planned on the extracted tree
/// and on the true one (arm ignored, simulator as the predictor, under
/// `limits`), each push carried out on the true tree at the true node
/// nearest to the planned contact.
pub fn end_to_end(
    trees: &[Tree],
    extractions: &[Option<Extraction>],
    tasks_per_tree: usize,
    limits: &Limits,
    seed: u64,
) -> EndToEnd {
    let reserved = Limits {
        max_stress: limits.max_stress * (1.0 - EXTRACTED_STRESS_RESERVE),
        ..*limits
    };
    let results: Vec<EndToEnd> = trees
        .par_iter()
        .zip(extractions)
        .enumerate()
        .map(|(i, (tree, extraction))| {
            let mut out = EndToEnd::default();
            let mut rng = ChaCha8Rng::seed_from_u64(derive_seed(seed, &[i as u64, 77]));
            let found = extraction
                .as_ref()
                .and_then(|e| e.skeleton.to_tree(&Wood::default()).ok());
            for t in 0..tasks_per_tree {
                let Some(objective) = clear_task(tree, &mut rng) else {
                    continue;
                };
                out.tasks += 1;
                let task_seed = derive_seed(seed, &[i as u64, t as u64]);
                // (satisfied within the limits, over the limits) on `held`.
                let solves = |held: &Tree, push: &Push| {
                    execute(held, &objective, push).map(|(residual, _, loads)| {
                        (
                            residual <= SATISFIED && limits.allow(&loads),
                            !limits.allow(&loads),
                        )
                    })
                };
                let true_ok = best_push(tree, &objective, Some(limits), task_seed)
                    .and_then(|s| solves(tree, &s.push))
                    .is_some_and(|(ok, _)| ok);
                let Some(found) = &found else {
                    out.no_tree += 1;
                    out.true_solved += usize::from(true_ok);
                    continue;
                };
                let cautious = match &objective {
                    crate::planner::objective::Objective::Clear { regions, margin } => {
                        crate::planner::objective::Objective::Clear {
                            regions: regions.clone(),
                            margin: margin + EXTRACTED_MARGIN,
                        }
                    }
                    o => o.clone(),
                };
                let planned = best_push(found, &cautious, Some(&reserved), task_seed);
                let held = planned
                    .as_ref()
                    .and_then(|s| held_at(tree, &found.position(s.push.node)));
                let branch_there = held.is_some();
                let carried = planned.as_ref().zip(held).and_then(|(s, (held, node))| {
                    // The guard of the limits the push was planned
                    // under: the reserve covers the stress per newton
                    // the extracted radii get wrong, as it covers the
                    // plan's stress.
                    let guard = reserved.guard_force(found, &s.push)?;
                    let push = Push {
                        node,
                        vector: s.push.vector,
                    };
                    Some((
                        guarded(&held, &push, &objective, limits, guard),
                        solves(&held, &push),
                    ))
                });
                let (guarded_ok, unguarded) = carried.unzip();
                let (ok, over, stopped) = guarded_ok.flatten().unwrap_or((false, false, false));
                out.over_limit_unguarded +=
                    usize::from(unguarded.flatten().is_some_and(|(_, o)| o));
                out.guard_stopped += usize::from(stopped);
                if true_ok && !ok {
                    let m = &mut out.missed;
                    // A push the simulator rejects on the true tree
                    // clears nothing.
                    match (planned.is_some(), branch_there, over) {
                        (false, _, _) => m.no_push += 1,
                        (true, false, _) => m.no_branch += 1,
                        (true, true, true) => m.over_limit += 1,
                        (true, true, false) => m.not_cleared += 1,
                    }
                }
                out.true_solved += usize::from(true_ok);
                out.extracted_solved += usize::from(true_ok && ok);
                out.extracted_solved_any += usize::from(ok);
                out.over_limit += usize::from(over);
            }
            out
        })
        .collect();
    results
        .into_iter()
        .fold(EndToEnd::default(), |a, b| EndToEnd {
            tasks: a.tasks + b.tasks,
            true_solved: a.true_solved + b.true_solved,
            extracted_solved: a.extracted_solved + b.extracted_solved,
            extracted_solved_any: a.extracted_solved_any + b.extracted_solved_any,
            over_limit: a.over_limit + b.over_limit,
            over_limit_unguarded: a.over_limit_unguarded + b.over_limit_unguarded,
            guard_stopped: a.guard_stopped + b.guard_stopped,
            no_tree: a.no_tree + b.no_tree,
            missed: a.missed.add(b.missed),
        })
}

/// `push` carried out on `tree` as a move that stops where the wrist's
/// force reaches `stop_at` (N): (satisfied within the limits, over a limit, stopped short);
/// `None` when the simulator rejects it.
fn guarded(
    tree: &Tree,
    push: &Push,
    objective: &crate::planner::objective::Objective,
    limits: &Limits,
    stop_at: f64,
) -> Option<(bool, bool, bool)> {
    let g = guarded_push(tree, push, &SimConfig::default(), stop_at).ok()?;
    let residual = objective
        .scorer()
        .residual(tree, &g.outcome.final_positions);
    let loads = PushLoads::of_outcome(tree, &g.outcome);
    Some((
        residual <= SATISFIED && limits.allow(&loads),
        !limits.allow(&loads),
        g.stopped,
    ))
}

/// A gripper closing at `at` holds the true tree's branch nearest to it:
/// the true tree with a node there (the branch split in two, the outer
/// part joined rigidly, 1000 times stiffer, so the tree bends as before)
/// and that node; a node of the tree when `at` is within 1 cm of it (the
/// branch's end, or its base: a contact at a fork is held at the fork,
/// whichever of the branches meeting there comes out nearest). `None` when
/// no branch passes within [`CONTACT_MATCH`], or the nearest point is the
/// fixed root.
pub fn held_at(tree: &Tree, at: &Point3<f64>) -> Option<(Tree, usize)> {
    let (j, d, t) = (1..tree.len())
        .filter_map(|j| {
            let p = tree.parent(j)?;
            let (d, t) = point_segment(at, &tree.position(p), &tree.position(j));
            Some((j, d, t))
        })
        .min_by(|a, b| a.1.total_cmp(&b.1))?;
    if d > CONTACT_MATCH {
        return None;
    }
    let p = tree.parent(j)?;
    let (a, b) = (tree.position(p), tree.position(j));
    let length = (b - a).norm();
    if t * length <= 0.01 {
        // At the branch's base: the fork (or the trunk's foot, which no
        // gripper can move).
        return (p != 0).then(|| (tree.clone(), p));
    }
    if (1.0 - t) * length <= 0.01 || tree.len() >= MAX_NODES {
        return Some((tree.clone(), j));
    }
    let branch = *tree.branch(j)?;
    let q = a + (b - a) * t;
    let mut positions = tree.positions().to_vec();
    let mut parents = tree.parents().to_vec();
    let mut branches = tree.branches().to_vec();
    let new = positions.len();
    positions.push(q);
    parents.push(Some(p));
    branches.push(Some(Branch {
        length: t * length,
        ..branch
    }));
    parents[j] = Some(new);
    branches[j] = Some(Branch {
        length: (1.0 - t) * length,
        stiffness: branch.stiffness * 1000.0,
        damping: branch.damping * 1000.0,
        ..branch
    });
    let split = Tree::new(positions, parents, branches).ok()?;
    Some((split, new))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dataset::Split;
    use crate::eval::scans::{Condition, evaluate_condition, split_trees};
    use crate::planner::objective::{DEFAULT_MAX_CONTACT_FORCE, DEFAULT_MAX_STRESS};
    use crate::scan::Sensor;

    /// A trunk forking into two arms at node 2.
    fn fork() -> Tree {
        crate::scan::Skeleton {
            positions: vec![
                Point3::origin(),
                Point3::new(0.0, 0.0, 0.4),
                Point3::new(0.0, 0.0, 0.8),
                Point3::new(0.3, 0.0, 1.1),
                Point3::new(-0.3, 0.0, 1.1),
            ],
            parents: vec![None, Some(0), Some(1), Some(2), Some(2)],
            radius: vec![0.0, 0.01, 0.01, 0.005, 0.005],
        }
        .to_tree(&Wood::default())
        .unwrap()
    }

    /// A gripper closing at a fork holds the fork, never the tip of one of
    /// the arms that start there (the old mapping sent a push planned at a
    /// fork to an arm's tip 42 cm away).
    #[test]
    fn a_contact_at_a_fork_is_held_at_the_fork() {
        let tree = fork();
        for offset in [0.0, 0.004, -0.004] {
            let at = Point3::new(offset, 0.0, 0.8 + offset);
            let (held, node) = held_at(&tree, &at).unwrap();
            assert_eq!((held.len(), node), (5, 2), "contact {at:?}");
        }
        // Near an arm's tip: the tip; along an arm: a new node there.
        let (_, tip) = held_at(&tree, &Point3::new(0.297, 0.0, 1.097)).unwrap();
        assert_eq!(tip, 3);
        let (split, node) = held_at(&tree, &Point3::new(-0.15, 0.01, 0.95)).unwrap();
        assert_eq!((split.len(), node), (6, 5));
        assert_eq!(split.parent(4), Some(5));
        assert!((split.position(5) - Point3::new(-0.15, 0.0, 0.95)).norm() < 1e-9);
        // At the trunk's foot nothing can be pushed; far from every branch
        // nothing is held.
        assert!(held_at(&tree, &Point3::new(0.0, 0.0, 0.003)).is_none());
        assert!(held_at(&tree, &Point3::new(0.5, 0.5, 0.5)).is_none());
    }

    /// Every task the true tree's push solves and the extracted tree's
    /// does not is counted once, with its reason, on clouds good enough
    /// that every tree is extracted.
    #[test]
    fn every_task_the_extracted_tree_misses_is_counted_with_why() {
        let trees = split_trees(Split::Test, &[12, 16], 2).unwrap();
        let condition = Condition {
            views: 3,
            noise: 0.002,
            leaves: 0,
            colour: false,
            sensor: Sensor::Unknown,
            placed: true,
        };
        let (_, extractions) = evaluate_condition(&trees, &condition, 7);
        let limits = Limits {
            max_stress: DEFAULT_MAX_STRESS,
            max_contact_force: DEFAULT_MAX_CONTACT_FORCE,
        };
        let e = end_to_end(&trees, &extractions, 3, &limits, 7);
        assert_eq!(e.no_tree, 0);
        assert!(e.tasks >= 10 && e.true_solved > 0 && e.extracted_solved > 0);
        let m = e.missed;
        assert_eq!(
            e.true_solved - e.extracted_solved,
            m.no_push + m.no_branch + m.not_cleared + m.over_limit
        );
        // Over the limits on the true tree: only the missed ones counted
        // there, or tasks the true tree's own push does not solve either.
        assert!(m.over_limit <= e.over_limit);
    }
}
