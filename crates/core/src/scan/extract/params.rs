//! How to read a cloud: the extraction's options, their defaults and
//! their checks (each bad option named by its field).

use nalgebra::{Point3, Vector3};

use crate::scan::cloud::{CloudError, CropBox};
use crate::scan::viewpoint::Sensor;

/// The returned nodes' default spacing (m): the median branch length of
/// the paper's generated trees (10-30 nodes, 0.6-1.7 m tall; 420 trees of
/// the generator, quartiles 0.13 and 0.22 m).
pub const DEFAULT_SPACING: f64 = 0.18;
/// Default largest number of points in one cloud.
pub const DEFAULT_MAX_POINTS: usize = 2_000_000;
/// The widest a laser's beam may spread past an edge (m): a footprint
/// 10 cm across is wider than the branches the extraction resolves.
pub const MAX_BEAM_RADIUS: f64 = 0.05;
/// Most viewpoints a request may give: each is a depth image of the cloud
/// (at most about 4 MB, one pass over the points).
pub const MAX_VIEWPOINTS: usize = 16;
/// How to read a cloud. Lengths in metres.
#[derive(Debug, Clone, PartialEq)]
pub struct ExtractParams {
    /// Largest distance between consecutive joints along a branch.
    pub spacing: f64,
    /// The trunk's base; by default the bottom of the tallest large
    /// connected part.
    pub root: Option<Point3<f64>>,
    /// Which way is up (any length).
    pub up: Vector3<f64>,
    pub crop: Option<CropBox>,
    pub max_points: usize,
    /// Edge of the averaging cubes.
    pub voxel: f64,
    /// Largest gap bridged between a part and the tree.
    pub max_gap: f64,
    /// How leaves are found and dropped.
    pub foliage: FoliageFilter,
    /// What the returns may be assumed to be: with
    /// [`Sensor::Camera`], a cloud seen from one side has its branch axes
    /// moved back from the near surface.
    pub sensor: Sensor,
    /// Where the sensor stood for each view (m), when known: a gap in a
    /// branch's points hidden behind what it saw is then bridged as one
    /// under leaves is ([`crate::scan::shadow`]).
    pub viewpoints: Vec<Point3<f64>>,
}

/// How the extraction finds leaves.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum FoliageFilter {
    /// By colour when the cloud has colours; without, by shape
    /// ([`crate::scan::foliage`]) when the shape classifier finds the cloud
    /// leafy (at least [`LEAFY_SHARE`](crate::scan::foliage::LEAFY_SHARE) of its points).
    #[default]
    Auto,
    /// By colour when the cloud has colours, else by shape whatever the
    /// share.
    Shape,
    /// Keep every point.
    Off,
}

impl Default for ExtractParams {
    fn default() -> Self {
        Self {
            spacing: DEFAULT_SPACING,
            root: None,
            up: Vector3::z(),
            crop: None,
            max_points: DEFAULT_MAX_POINTS,
            voxel: 0.004,
            max_gap: 0.06,
            foliage: FoliageFilter::Auto,
            sensor: Sensor::Unknown,
            viewpoints: Vec::new(),
        }
    }
}

impl ExtractParams {
    /// Checks every option; the unit up.
    pub(super) fn validate(&self) -> Result<Vector3<f64>, CloudError> {
        let bad = |field, message: &str| {
            Err(CloudError::BadParameter {
                field,
                message: message.to_owned(),
            })
        };
        if !(self.spacing.is_finite() && (0.03..=1.0).contains(&self.spacing)) {
            return bad("spacing", "spacing must be between 0.03 and 1 m");
        }
        if !(self.voxel.is_finite() && (0.001..=0.05).contains(&self.voxel)) {
            return bad("voxel", "voxel must be between 0.001 and 0.05 m");
        }
        if !(self.max_gap.is_finite() && (0.0..=0.5).contains(&self.max_gap)) {
            return bad("max_gap", "max_gap must be between 0 and 0.5 m");
        }
        if let Some(root) = self.root
            && !root.iter().all(|c| c.is_finite())
        {
            return bad("root", "root must be finite");
        }
        if self.viewpoints.len() > MAX_VIEWPOINTS {
            return bad(
                "viewpoints",
                &format!(
                    "at most {MAX_VIEWPOINTS} viewpoints, not {}",
                    self.viewpoints.len()
                ),
            );
        }
        if !self
            .viewpoints
            .iter()
            .flat_map(|v| v.iter())
            .all(|c| c.is_finite())
        {
            return bad("viewpoints", "viewpoints must be finite");
        }
        if let Sensor::Laser { beam_radius } = self.sensor
            && !(beam_radius.is_finite() && (0.0..=MAX_BEAM_RADIUS).contains(&beam_radius))
        {
            return bad(
                "beam_radius",
                &format!("beam_radius must be between 0 and {MAX_BEAM_RADIUS} m"),
            );
        }
        if let Some(crop) = self.crop
            && (!(crop.min.iter().chain(crop.max.iter())).all(|c| c.is_finite())
                || (0..3).any(|i| crop.min[i] > crop.max[i]))
        {
            return bad("crop", "crop must be finite with min <= max on every axis");
        }
        let norm = self.up.norm();
        if !(norm.is_finite() && norm > 1e-9) {
            return Err(CloudError::BadUp);
        }
        Ok(self.up / norm)
    }
}
