//! Trees: the validated model, the Space Colonization generator, the URDF
//! format and an SVG drawing. Everything else in treemanip depends on this
//! module and it depends on nothing else in the crate.
//!
//! The documentation beside the code: `docs/trees.md`.

pub mod collection;
pub mod crop;
pub mod model;
pub mod orchard;
pub mod render;
pub mod sca;
pub mod stiffness;
pub mod urdf;
pub mod wood;

pub use model::{Branch, FULL_GRAPH_MAX_NODES, MAX_NODES, MIN_NODES, Tree, TreeError};
pub use orchard::{OrchardParams, generate_orchard};
pub use sca::{ScaError, ScaParams, generate, tree_seed};
pub use stiffness::StiffnessVariation;
pub use wood::Wood;
