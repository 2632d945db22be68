//! Trees from scans: a point cloud in, a tree graph out, and synthetic
//! scans to test that against.
//!
//! - [`cloud`]: the point cloud and the checks every cloud passes;
//! - [`io`]: reading clouds from PLY, PCD, LAS/LAZ and XYZ files;
//! - [`voxel`], [`neighbours`]: averaging cubes, the neighbourhood graph,
//!   components and shortest paths;
//! - [`circle_fit`], [`levels`], [`fine`], [`base`], [`forks`],
//!   [`viewpoint`], [`silhouette`], [`simplify`] with [`corner`]: the steps of [`extract::extract`] (its module
//!   documentation lists them in order);
//! - [`skeleton`]: a tree as geometry (positions, parents, radii);
//! - [`scanner`]: what a camera at K viewpoints would see of a tree;
//! - [`score`](mod@score): recall, precision, radius error and topology against the
//!   true tree.
//!
//! Documentation beside the code: `docs/scans.md`.

pub mod base;
#[cfg(test)]
pub(crate) mod beam_scan;
pub mod bridge;
pub mod circle_fit;
pub mod cloud;
pub mod corner;
pub mod extract;
pub mod fine;
pub mod foliage;
pub mod forks;
pub mod io;
pub mod levels;
pub mod neighbours;
pub mod scanner;
pub mod score;
pub mod shadow;
pub mod silhouette;
pub mod simplify;
pub mod skeleton;
pub mod viewpoint;
pub mod voxel;

pub use cloud::{CloudError, CropBox, PointCloud};
pub use extract::{Dropped, ExtractParams, Extraction, FoliageFilter, extract};
pub use scanner::{Origin, Scan, ScanParams, scan};
pub use score::{ScanScore, score};
pub use skeleton::Skeleton;
pub use viewpoint::Sensor;
