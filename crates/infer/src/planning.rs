//! The served models as the planner's predictors
//! ([`treemanip_core::planner::ContactPolicy`] and
//! [`treemanip_core::planner::Predictor`]).

use nalgebra::Point3;
use treemanip_core::graph::path::path_fits;
use treemanip_core::planner::{Candidate, ContactPolicy, PredictError, Predictor};
use treemanip_core::sim::Push;
use treemanip_core::tree::Tree;

use crate::InferError;
use crate::models::{ServedModel, predict_displacements, rank_candidates};

impl From<InferError> for PredictError {
    fn from(e: InferError) -> Self {
        PredictError(Box::new(e))
    }
}

impl ContactPolicy for ServedModel {
    fn rank(&self, tree: &Tree, targets: &[Point3<f64>]) -> Result<Vec<Candidate>, PredictError> {
        Ok(rank_candidates(self, tree, targets, &Default::default())?)
    }
}

/// A forward model: one batched inference for all the pushes it can read
/// (a path model reads the pushes whose path fits one path graph,
/// [`path_fits`]; deeper pushes get no prediction).
impl Predictor for ServedModel {
    fn final_positions(
        &self,
        tree: &Tree,
        pushes: &[Push],
    ) -> Result<Vec<Option<Vec<Point3<f64>>>>, PredictError> {
        let readable = |p: &Push| !self.card.encoding.is_path() || path_fits(tree, p.node);
        let actions: Vec<_> = pushes
            .iter()
            .filter(|p| readable(p))
            .map(|p| (p.node, p.vector))
            .collect();
        let mut displacements =
            predict_displacements(self, tree, &actions, &Default::default())?.into_iter();
        Ok(pushes
            .iter()
            .map(|p| {
                if !readable(p) {
                    return None;
                }
                let d = displacements.next()?;
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
