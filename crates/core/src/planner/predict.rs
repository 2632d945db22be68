//! What the planner asks of a model, as two small traits: which pushes the
//! contact policy proposes ([`ContactPolicy`]) and what a push would do to
//! the tree ([`Predictor`]: the forward model, or the simulator itself).
//! `treemanip-infer` implements them for its served ONNX models; the
//! planner never sees an inference engine.

use nalgebra::Point3;

use serde::Serialize;

use crate::sim::loads::PushLoads;
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

/// A model that could not answer, with the inference layer's error as its
/// source (the server maps it to a status by downcasting).
#[derive(Debug, thiserror::Error)]
#[error(transparent)]
pub struct PredictError(pub Box<dyn std::error::Error + Send + Sync>);

impl PredictError {
    /// The inference layer's error, when it is an `E`.
    pub fn source_as<E: std::error::Error + 'static>(&self) -> Option<&E> {
        self.0.downcast_ref::<E>()
    }
}

/// One node to push and how, from the contact policy.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Candidate {
    pub node: usize,
    /// Share of the affordance over the tree's pushable (non-root) nodes.
    pub affordance: f64,
    /// Gripper displacement T (m).
    pub push: [f64; 3],
    /// 1 = most promising.
    pub rank: usize,
}

/// The contact policy: every non-root node ranked by affordance, each with
/// the push it proposes toward `targets`.
pub trait ContactPolicy: Sync {
    fn rank(&self, tree: &Tree, targets: &[Point3<f64>]) -> Result<Vec<Candidate>, PredictError>;
}

/// Predicts the tree's node positions after each push.
pub trait Predictor: Sync {
    /// One answer per push, in order; `None` for a push the predictor
    /// cannot answer (the simulator rejects it).
    fn final_positions(
        &self,
        tree: &Tree,
        pushes: &[Push],
    ) -> Result<Vec<Option<Vec<Point3<f64>>>>, PredictError>;

    /// `model` or `physics`.
    fn name(&self) -> &'static str;

    /// The held state after each push: positions and loads. By default the
    /// loads are read from the predicted positions
    /// ([`PushLoads::from_positions`]); the simulator gives its own.
    fn predict(
        &self,
        tree: &Tree,
        pushes: &[Push],
    ) -> Result<Vec<Option<Predicted>>, PredictError> {
        let contact = SimConfig::default().contact;
        Ok(self
            .final_positions(tree, pushes)?
            .into_iter()
            .zip(pushes)
            .map(|(positions, push)| {
                positions.map(|positions| Predicted {
                    loads: PushLoads::from_positions(tree, push, &positions, contact),
                    positions,
                })
            })
            .collect())
    }
}

/// What a push is predicted to leave: the held tree and its loads.
#[derive(Debug, Clone, PartialEq)]
pub struct Predicted {
    pub positions: Vec<Point3<f64>>,
    pub loads: PushLoads,
}

/// The simulator itself: exact when the tree's stiffness is known, and the
/// ceiling of what a learned forward model can do.
pub struct PhysicsPredictor;

impl Predictor for PhysicsPredictor {
    fn final_positions(
        &self,
        tree: &Tree,
        pushes: &[Push],
    ) -> Result<Vec<Option<Vec<Point3<f64>>>>, PredictError> {
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

    fn predict(
        &self,
        tree: &Tree,
        pushes: &[Push],
    ) -> Result<Vec<Option<Predicted>>, PredictError> {
        use rayon::prelude::*;
        Ok(pushes
            .par_iter()
            .map(|p| {
                simulate(tree, p, &SimConfig::default())
                    .ok()
                    .map(|o| Predicted {
                        loads: PushLoads::of_outcome(tree, &o),
                        positions: o.final_positions,
                    })
            })
            .collect())
    }
}
