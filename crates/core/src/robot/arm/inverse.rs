//! Inverse kinematics of the tool: every solution of the UR closed form,
//! or the numerical solver's from the reference and fixed random starts.

use nalgebra::Isometry3;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use crate::robot::arm::{Arm, IK_STARTS, SAME_SOLUTION, Solver};
use crate::robot::kinematics::numeric_ik::{IkOptions, solve};
use crate::robot::model::joint_vector::JointVector;
use crate::robot::model::urdf_chain::random_configuration;

impl Arm {
    /// The tip pose (chain base frame) that puts the tool at `tool` (world).
    pub(super) fn tip_goal(&self, tool: &Isometry3<f64>) -> Isometry3<f64> {
        self.base.inverse() * tool * self.tool_in_tip().inverse()
    }

    /// Every joint configuration found that puts the tool at `tool` (world
    /// frame), within the joint limits, nearest `reference` first (largest
    /// joint difference). The closed form gives every solution; a
    /// numerical chain the one reached from `reference` and those reached
    /// from `IK_STARTS` fixed random starts.
    pub fn inverse_kinematics(
        &self,
        tool: &Isometry3<f64>,
        reference: &JointVector,
    ) -> Vec<JointVector> {
        let mut solutions: Vec<JointVector> = self.ik_solutions(tool, reference).collect();
        solutions.sort_by(|a, b| {
            a.max_abs_diff(reference)
                .total_cmp(&b.max_abs_diff(reference))
        });
        solutions
    }

    /// The solutions of [`Self::inverse_kinematics`], distinct, unsorted
    /// and found as they are asked for: a caller that needs one usable
    /// solution (is a push reachable at all?) stops the numerical solver's
    /// starts at the first that serves.
    pub fn ik_solutions<'a>(
        &'a self,
        tool: &Isometry3<f64>,
        reference: &JointVector,
    ) -> Box<dyn Iterator<Item = JointVector> + 'a> {
        let goal = self.tip_goal(tool);
        match &self.solver {
            Solver::Ur(ur) => {
                let reference: [f64; 6] = std::array::from_fn(|i| reference[i]);
                Box::new(
                    ur.solve(&goal, &reference)
                        .into_iter()
                        .map(|q| JointVector::from_slice(&q)),
                )
            }
            Solver::Numeric if !self.within_reach(&goal) => Box::new(std::iter::empty()),
            Solver::Numeric => {
                let mut rng = ChaCha8Rng::seed_from_u64(0x1c);
                let mut found: Vec<JointVector> = Vec::new();
                let random =
                    (0..IK_STARTS).map(move |_| random_configuration(&self.chain, &mut rng));
                Box::new(
                    std::iter::once(reference.to_vec())
                        .chain(random)
                        .filter_map(move |start| self.solve_from(&goal, &start))
                        .filter(move |q| {
                            let new = found.iter().all(|f| f.max_abs_diff(q) > SAME_SOLUTION);
                            if new {
                                found.push(*q);
                            }
                            new
                        }),
                )
            }
        }
    }

    /// The configuration nearest `reference` that puts the tool at `tool`,
    /// for following a path: the nearest closed-form solution, or the
    /// numerical solver started at `reference` alone.
    pub fn inverse_kinematics_near(
        &self,
        tool: &Isometry3<f64>,
        reference: &JointVector,
    ) -> Option<JointVector> {
        match &self.solver {
            Solver::Ur(_) => self.inverse_kinematics(tool, reference).first().copied(),
            Solver::Numeric => self.solve_from(&self.tip_goal(tool), reference),
        }
    }

    pub(super) fn solve_from(&self, goal: &Isometry3<f64>, start: &[f64]) -> Option<JointVector> {
        // Tight: pushes follow a straight line at constant orientation
        // through these solutions (a few more iterations near convergence).
        let options = IkOptions {
            restarts: 1,
            position_tolerance: 1e-7,
            orientation_tolerance: 1e-6,
            ..IkOptions::default()
        };
        solve(&self.chain, goal, start, &options).map(|q| JointVector::from_slice(&q))
    }
}
