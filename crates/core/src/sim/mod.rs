//! Quasi-static push simulation: where a spring-jointed tree settles when a
//! gripper holds one branch and moves by T.
//!
//! The tree is rigid branches joined by spherical spring joints at their
//! parent nodes; the root is fixed; gravity is off (as in the original
//! Isaac Gym setup). A joint's deflection is its rotation from rest as a
//! rotation vector θ_k, with elastic energy ½ K_s,k |θ_k|². The steady state
//! is the minimum of that energy subject to the gripper's contact constraint
//! ([`contact`]). Damping only shapes the motion towards it, so it plays no
//! part here.
//!
//! Only joints on the root → contact path can carry load; the rest keep
//! their rest angles, and the subtree beyond the contacted node moves as a
//! rigid body. See [`path_joints`] for the kinematics and [`solver`] for the SQP.
//!
//! The documentation beside the code: `docs/simulation.md`.

pub mod contact;
pub mod guarded;
pub mod linear;
pub mod loads;
pub mod path_joints;
pub mod sampling;
pub mod solver;

use nalgebra::{DMatrix, DVector, Point3, Rotation3, Vector3};
use serde::{Deserialize, Serialize};

use contact::Contact;
pub use contact::{ContactModel, GRIP_OFFSET, Hold};
use path_joints::PathChain;
use solver::{SolveError, SolverOptions};

use crate::tree::Tree;

/// Longest push accepted (m). The paper's pushes are 5–15 cm; a push of a
/// metre would fold any tree in the data set.
pub const MAX_PUSH_LENGTH: f64 = 1.0;

/// Largest joint rotation accepted in a solution (rad, ≈ 160°). Beyond it
/// the exponential coordinates approach their singularity at π and the
/// "tree" is folded back on itself.
pub const MAX_JOINT_ANGLE: f64 = 2.8;

/// A push: the gripper holds the branch ending at `node` and moves by
/// `vector` (m).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Push {
    pub node: usize,
    pub vector: Vector3<f64>,
}

#[derive(Debug, Clone, Copy, Default)]
pub struct SimConfig {
    pub contact: ContactModel,
    pub solver: SolverOptions,
}

/// How the solve went, for anyone who wants to check it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SolverReport {
    pub iterations: usize,
    /// Largest contact-constraint violation (m).
    pub constraint_residual: f64,
    /// Largest KKT stationarity violation in stiffness-scaled coordinates,
    /// relative: |√K θ + Jᵀλ|∞ / max(1, |√K θ|∞).
    pub kkt_residual: f64,
    /// Elastic energy stored in the joints (J).
    pub energy: f64,
    /// What the gripper ended up holding: the branch in its slot
    /// (`on_axis`), or the node itself (`at_node`: the pinned model, or a
    /// slot that slid to a fork and caught there).
    pub hold: Hold,
    /// On-axis hold: distance from the contacted branch's base to where the
    /// gripper holds it (m); `None` otherwise.
    pub slide: Option<f64>,
    /// Force the gripper applies to the branch (N).
    pub contact_force: [f64; 3],
    /// Largest joint rotation (rad).
    pub max_joint_angle: f64,
}

#[derive(Debug, Clone)]
pub struct PushOutcome {
    /// Steady-state node positions (m).
    pub final_positions: Vec<Point3<f64>>,
    /// Each node's joint rotation vector (rad) — the joint at its parent; zero
    /// for the root and every joint off the loaded path.
    pub joint_rotations: Vec<Vector3<f64>>,
    pub report: SolverReport,
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SimError {
    #[error("contact node {node} does not exist (the tree has {n} nodes)")]
    NodeOutOfRange { node: usize, n: usize },
    #[error("the root (node 0) is fixed and cannot be pushed")]
    RootContact,
    #[error("the push vector must be finite")]
    NonFinitePush,
    #[error("the push is {length} m long; at most {max} m is accepted")]
    PushTooLong { length: f64, max: f64 },
    #[error(
        "the gripper lost the branch: it would hold it {slide:.4} m from its base, outside the branch (0 to {length:.4} m)"
    )]
    LostBranch { slide: f64, length: f64 },
    #[error(
        "node {node} cannot be carried {distance:.4} m from the root: the branches on its path reach from {inner:.4} to {reach:.4} m"
    )]
    OutOfReach {
        node: usize,
        distance: f64,
        reach: f64,
        /// Closest distance to the root the path can fold to (m).
        inner: f64,
    },
    #[error("the push would turn a joint by {angle:.2} rad, folding the tree")]
    OverRotated { angle: f64 },
    #[error(
        "the solver did not converge in {iterations} iterations (constraint residual {constraint_residual:.3e} m): the push is probably out of the branch's reach"
    )]
    NotConverged {
        iterations: usize,
        constraint_residual: f64,
    },
    #[error("the contact constraints are degenerate for this push")]
    Degenerate,
    #[error(
        "the simulation ran past its deadline ({iterations} solver iterations done): the path is too deep to solve in the time given"
    )]
    OutOfTime { iterations: usize },
}

impl SimError {
    /// A stable snake_case name, for counting discards by reason.
    pub fn kind(&self) -> &'static str {
        match self {
            SimError::NodeOutOfRange { .. } => "node_out_of_range",
            SimError::RootContact => "root_contact",
            SimError::NonFinitePush => "non_finite_push",
            SimError::PushTooLong { .. } => "push_too_long",
            SimError::LostBranch { .. } => "lost_branch",
            SimError::OutOfReach { .. } => "out_of_reach",
            SimError::OverRotated { .. } => "over_rotated",
            SimError::NotConverged { .. } => "not_converged",
            SimError::Degenerate => "degenerate",
            SimError::OutOfTime { .. } => "out_of_time",
        }
    }
}

/// A slot that slid back past the contacted branch's base: the fork
/// there stops it, as the child branches stop it at the tip, and from then
/// on the gripper carries the fork node `base` to its point (the
/// [`ContactModel::Pinned`] push of `base`, reported as [`Hold::AtBase`]).
/// The branch is lost only at the trunk's foot, which nothing carries,
/// and where the gripper's point is farther from the fork than any push.
fn caught_at_base(
    tree: &Tree,
    base: usize,
    contact: &Contact,
    config: &SimConfig,
    warm: Option<&[Vector3<f64>]>,
    slide: f64,
    length: f64,
) -> Result<PushOutcome, SimError> {
    let caught = Push {
        node: base,
        vector: contact.target - tree.position(base),
    };
    if caught.vector.norm() > MAX_PUSH_LENGTH {
        return Err(SimError::LostBranch { slide, length });
    }
    let pinned = SimConfig {
        contact: ContactModel::Pinned,
        ..*config
    };
    let mut out = simulate_from(tree, &caught, &pinned, warm)?;
    out.report.hold = Hold::AtBase;
    Ok(out)
}

/// Solves one push.
pub fn simulate(tree: &Tree, push: &Push, config: &SimConfig) -> Result<PushOutcome, SimError> {
    simulate_from(tree, push, config, None)
}

/// [`simulate`], starting the solver at `warm` joint rotations (one per
/// node, as [`PushOutcome::joint_rotations`] of a nearby push of the same
/// node on the same tree) instead of at rest: a push followed in steps
/// then costs a few Newton iterations a step. Where the warm start does
/// not converge the solve starts again at rest.
pub fn simulate_from(
    tree: &Tree,
    push: &Push,
    config: &SimConfig,
    warm: Option<&[Vector3<f64>]>,
) -> Result<PushOutcome, SimError> {
    let n = tree.len();
    if push.node >= n {
        return Err(SimError::NodeOutOfRange { node: push.node, n });
    }
    if push.node == 0 {
        return Err(SimError::RootContact);
    }
    if !push.vector.iter().all(|v| v.is_finite()) {
        return Err(SimError::NonFinitePush);
    }
    let length = push.vector.norm();
    if length > MAX_PUSH_LENGTH {
        return Err(SimError::PushTooLong {
            length,
            max: MAX_PUSH_LENGTH,
        });
    }

    let chain = PathChain::new(tree, push.node);
    let contact = Contact::new(tree, push.node, &push.vector, config.contact);
    if contact.hold == Hold::AtNode {
        check_reach(tree, &chain, &contact)?;
    }
    // The warm start in the solver's coordinates x = √K θ.
    let warm_x = warm.filter(|w| w.len() == n).map(|w| {
        DVector::from_iterator(
            3 * chain.len(),
            chain
                .nodes
                .iter()
                .zip(&chain.stiffness)
                .flat_map(|(&node, k)| {
                    (w[node] * k.sqrt())
                        .into_iter()
                        .copied()
                        .collect::<Vec<_>>()
                }),
        )
    });
    let solve = |contact: &Contact| {
        warm_x
            .as_ref()
            .and_then(|x| solve_contact_from(&chain, contact, &config.solver, x.clone()))
            .map_or_else(
                || solve_contact(&chain, contact, &push.vector, &config.solver),
                Ok,
            )
    };
    let mut solved = solve(&contact)?;
    if contact.hold == Hold::OnAxis {
        let length = tree.branch(push.node).expect("non-root").length;
        let slide = contact.slide(&chain, &chain.pose(&solved.theta));
        if slide > length && !tree.is_leaf(push.node) {
            // Slid to the fork: the child branches stop the slot there.
            let caught = contact.caught_at_node();
            check_reach(tree, &chain, &caught)?;
            solved = solve(&caught)?;
        } else if slide < 0.0
            && let Some(base) = tree.parent(push.node).filter(|&p| p != 0)
        {
            return caught_at_base(tree, base, &contact, config, warm, slide, length);
        } else if !(0.0..=length).contains(&slide) {
            return Err(SimError::LostBranch { slide, length });
        }
    }
    let Solved {
        theta,
        lambda,
        contact,
        solution,
    } = solved;

    let pose = chain.pose(&theta);
    let mut joint_rotations = vec![Vector3::zeros(); n];
    for (k, &node) in chain.nodes.iter().enumerate() {
        joint_rotations[node] = Vector3::new(theta[3 * k], theta[3 * k + 1], theta[3 * k + 2]);
    }
    let max_joint_angle = joint_rotations.iter().map(|t| t.norm()).fold(0.0, f64::max);
    if max_joint_angle > MAX_JOINT_ANGLE {
        return Err(SimError::OverRotated {
            angle: max_joint_angle,
        });
    }
    let slide = (contact.hold == Hold::OnAxis).then(|| contact.slide(&chain, &pose));
    let force = contact.force(&chain, &pose, &lambda);
    Ok(PushOutcome {
        final_positions: deformed_positions(tree, &joint_rotations),
        joint_rotations,
        report: SolverReport {
            iterations: solution.iterations,
            constraint_residual: solution.constraint_residual,
            kkt_residual: solution.stationarity_residual,
            energy: 0.5 * solution.x.norm_squared(),
            hold: contact.hold,
            slide,
            contact_force: [force.x, force.y, force.z],
            max_joint_angle,
        },
    })
}

/// An at-node hold is realisable only at a distance from the root that the
/// path's rigid branches can span: at most their total length, and at
/// least the longest one minus all the others (a single branch reaches only
/// the sphere of its own length). Outside that annulus no joint angles
/// satisfy the contact, and the solver would only report that it failed.
fn check_reach(tree: &Tree, chain: &PathChain, contact: &Contact) -> Result<(), SimError> {
    let lengths = chain
        .nodes
        .iter()
        .map(|&a| tree.branch(a).expect("non-root").length);
    let (reach, longest) = lengths.fold((0.0f64, 0.0f64), |(sum, max), l| (sum + l, max.max(l)));
    let inner = (2.0 * longest - reach).max(0.0);
    let distance = (contact.target - tree.position(0)).norm();
    // Within 1e-9 m of a boundary the solve decides.
    if distance > reach + 1e-9 || distance < inner - 1e-9 {
        let node = *chain.nodes.last().expect("non-empty chain");
        return Err(SimError::OutOfReach {
            node,
            distance,
            reach,
            inner,
        });
    }
    Ok(())
}

/// One solve of `contact` from `start`, in stiffness-scaled coordinates.
fn solve_scaled(
    chain: &PathChain,
    contact: &Contact,
    options: &SolverOptions,
    start: DVector<f64>,
) -> Result<solver::Solution, SolveError> {
    let inv_sqrt_k: Vec<f64> = chain.stiffness.iter().map(|k| 1.0 / k.sqrt()).collect();
    let eval = |x: &DVector<f64>| -> (DVector<f64>, DMatrix<f64>) {
        let pose = chain.pose(&to_theta(chain, x));
        let (c, mut jac) = contact.evaluate(chain, &pose);
        for col in 0..jac.ncols() {
            jac.column_mut(col).scale_mut(inv_sqrt_k[col / 3]);
        }
        (c, jac)
    };
    solver::solve_from(start, &eval, options)
}

/// Joint rotations θ = x / √K from the solver's coordinates.
fn to_theta(chain: &PathChain, x: &DVector<f64>) -> Vec<f64> {
    x.iter()
        .enumerate()
        .map(|(i, v)| v / chain.stiffness[i / 3].sqrt())
        .collect()
}

/// [`solve_scaled`] from a warm start, or `None` when it does not converge.
fn solve_contact_from(
    chain: &PathChain,
    contact: &Contact,
    options: &SolverOptions,
    start: DVector<f64>,
) -> Option<Solved> {
    let solution = solve_scaled(chain, contact, options, start).ok()?;
    Some(Solved {
        theta: to_theta(chain, &solution.x),
        lambda: solution.lambda.clone(),
        contact: contact.clone(),
        solution,
    })
}

struct Solved {
    theta: Vec<f64>,
    lambda: DVector<f64>,
    contact: Contact,
    solution: solver::Solution,
}

/// Minimises the elastic energy under `contact`, in stiffness-scaled
/// coordinates x = √K θ so that the energy is ½|x|².
///
/// The solve starts at rest. Where that fails (a straight trunk pushed
/// along itself starts on a singular Jacobian, λ ≈ 1e5, and Newton wanders
/// instead of buckling it), it follows the push path instead, as the
/// gripper does: the hold is moved in steps along `push`, each solve
/// warm-started from the previous state (4 steps, then 16).
fn solve_contact(
    chain: &PathChain,
    contact: &Contact,
    push: &Vector3<f64>,
    options: &SolverOptions,
) -> Result<Solved, SimError> {
    let solve_for =
        |contact: &Contact, start: DVector<f64>| solve_scaled(chain, contact, options, start);
    let n = 3 * chain.len();
    let mut result = solve_for(contact, DVector::zeros(n));
    for steps in [4usize, 16] {
        if !matches!(result, Err(SolveError::NotConverged { .. })) {
            break;
        }
        let mut x = DVector::zeros(n);
        result = (1..=steps)
            .try_fold(None, |_, k| {
                let partway = contact.partway(push, k as f64 / steps as f64);
                let step = solve_for(&partway, x.clone())?;
                x = step.x.clone();
                Ok(Some(step))
            })
            .map(|s| s.expect("at least one step"));
    }
    let solution = result.map_err(|e| match e {
        SolveError::NotConverged {
            iterations,
            constraint_residual,
            ..
        } => SimError::NotConverged {
            iterations,
            constraint_residual,
        },
        SolveError::Degenerate => SimError::Degenerate,
        SolveError::OutOfTime { iterations } => SimError::OutOfTime { iterations },
    })?;
    Ok(Solved {
        theta: to_theta(chain, &solution.x),
        lambda: solution.lambda.clone(),
        contact: contact.clone(),
        solution,
    })
}

/// Forward kinematics of the whole tree for given joint rotations: each
/// branch's world orientation is its parent branch's times exp(θ).
pub fn deformed_positions(tree: &Tree, joint_rotations: &[Vector3<f64>]) -> Vec<Point3<f64>> {
    let n = tree.len();
    let mut orientation = vec![Rotation3::identity(); n];
    let mut positions = tree.positions().to_vec();
    let mut stack = vec![0usize];
    while let Some(i) = stack.pop() {
        for &j in tree.children(i) {
            orientation[j] = orientation[i] * Rotation3::new(joint_rotations[j]);
            positions[j] = positions[i] + orientation[j] * (tree.position(j) - tree.position(i));
            stack.push(j);
        }
    }
    positions
}

/// Elastic energy ½ Σ K_s |θ|² of given joint rotations (J).
pub fn elastic_energy(tree: &Tree, joint_rotations: &[Vector3<f64>]) -> f64 {
    tree.branches_iter()
        .map(|(j, b)| 0.5 * b.stiffness * joint_rotations[j].norm_squared())
        .sum()
}
