//! What a push would do to the tree, from the forward model or from the
//! simulator, and how far that leaves the tree from its target.

use nalgebra::Point3;

use crate::infer::InferError;
use crate::infer::models::{ServedModel, predict_displacements};
use crate::sim::{Push, SimConfig, simulate};
use crate::tree::Tree;

/// The paper's metric: the largest distance of a node from its target (m).
pub fn max_node_error(positions: &[Point3<f64>], targets: &[Point3<f64>]) -> f64 {
    positions
        .iter()
        .zip(targets)
        .map(|(p, t)| (p - t).norm())
        .fold(0.0, f64::max)
}

/// Predicts the tree's node positions after each push.
pub trait Predictor: Sync {
    /// One answer per push, in order; `None` for a push the predictor
    /// cannot answer (the simulator rejects it).
    fn final_positions(
        &self,
        tree: &Tree,
        pushes: &[Push],
    ) -> Result<Vec<Option<Vec<Point3<f64>>>>, InferError>;

    /// `model` or `physics`.
    fn name(&self) -> &'static str;
}

/// The forward GNN: one batched inference for all pushes.
pub struct ModelPredictor<'a>(pub &'a ServedModel);

impl Predictor for ModelPredictor<'_> {
    fn final_positions(
        &self,
        tree: &Tree,
        pushes: &[Push],
    ) -> Result<Vec<Option<Vec<Point3<f64>>>>, InferError> {
        let actions: Vec<_> = pushes.iter().map(|p| (p.node, p.vector)).collect();
        let displacements = predict_displacements(self.0, tree, &actions, &Default::default())?;
        Ok(displacements
            .into_iter()
            .map(|d| {
                Some(
                    tree.positions()
                        .iter()
                        .zip(d)
                        .map(|(p, dp)| p + dp)
                        .collect(),
                )
            })
            .collect())
    }

    fn name(&self) -> &'static str {
        "model"
    }
}

/// The simulator itself: exact when the tree's stiffness is known, and the
/// ceiling of what a learned forward model can do.
pub struct PhysicsPredictor;

impl Predictor for PhysicsPredictor {
    fn final_positions(
        &self,
        tree: &Tree,
        pushes: &[Push],
    ) -> Result<Vec<Option<Vec<Point3<f64>>>>, InferError> {
        use rayon::prelude::*;
        Ok(pushes
            .par_iter()
            .map(|p| {
                simulate(tree, p, &SimConfig::default())
                    .ok()
                    .map(|o| o.final_positions)
            })
            .collect())
    }

    fn name(&self) -> &'static str {
        "physics"
    }
}
