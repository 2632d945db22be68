//! Random pushes as in the paper's data collection:
//! - contact node uniform over the non-root nodes;
//! - direction: a random vector projected onto the plane perpendicular to
//!   the contacted branch, then tilted out of that plane (towards or away
//!   from the branch direction) by an angle uniform in ±`max_tilt_deg`;
//! - length uniform in `length_range`.

use nalgebra::Vector3;
use rand::{Rng, RngExt};
use serde::{Deserialize, Serialize};

use super::Push;
use crate::seed::standard_normal;
use crate::tree::Tree;

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PushDistribution {
    /// |T| range (m). Default 0.05–0.15.
    pub length_range: (f64, f64),
    /// Largest tilt out of the plane perpendicular to the branch (degrees).
    /// Default 45.
    pub max_tilt_deg: f64,
}

impl Default for PushDistribution {
    fn default() -> Self {
        Self {
            length_range: (0.05, 0.15),
            max_tilt_deg: 45.0,
        }
    }
}

impl PushDistribution {
    pub fn sample<R: Rng + ?Sized>(&self, tree: &Tree, rng: &mut R) -> Push {
        let node = rng.random_range(1..tree.len());
        let axis = tree.branch_direction(node).expect("non-root");
        let across = loop {
            let v = Vector3::new(
                standard_normal(rng),
                standard_normal(rng),
                standard_normal(rng),
            );
            let perpendicular = v - axis * v.dot(&axis);
            if perpendicular.norm() > 1e-6 {
                break perpendicular.normalize();
            }
        };
        let tilt = rng
            .random_range(-self.max_tilt_deg..=self.max_tilt_deg)
            .to_radians();
        let direction = (across * tilt.cos() + axis * tilt.sin()).normalize();
        let length = rng.random_range(self.length_range.0..=self.length_range.1);
        Push {
            node,
            vector: direction * length,
        }
    }
}
