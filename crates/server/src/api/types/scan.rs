//! `POST /v1/trees/from-points`: a point cloud in (JSON, or a PLY body with
//! the options in the query), a tree out.

use serde::{Deserialize, Serialize};
use utoipa::{IntoParams, ToSchema};

use crate::api::types::TreeJson;
use crate::api::types::schema::{Rgb, Vec3};

/// A point cloud as JSON, with the options of the extraction. Positions in
/// metres.
#[derive(Debug, Clone, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct FromPointsRequest {
    /// The points (m).
    #[schema(value_type = Vec<Vec3>, min_items = 1)]
    pub points: Vec<Vec<f64>>,
    /// Per-point normals (optional; as many as `points`).
    #[serde(default)]
    #[schema(value_type = Option<Vec<Vec3>>)]
    pub normals: Option<Vec<Vec<f64>>>,
    /// Per-point colours, 0-255 RGB (optional; as many as `points`).
    #[serde(default)]
    #[schema(value_type = Option<Vec<Rgb>>)]
    pub colors: Option<Vec<Vec<f64>>>,
    /// The trunk's base (m); default: the bottom of the tallest large
    /// connected part of the cloud.
    #[serde(default)]
    #[schema(value_type = Option<Vec3>)]
    pub root: Option<Vec<f64>>,
    /// Which way is up (any length; default +z).
    #[serde(default)]
    #[schema(value_type = Option<Vec3>)]
    pub up: Option<Vec<f64>>,
    /// Largest distance between consecutive joints along a branch (m,
    /// 0.03-1; default 0.18, the median branch length of the paper's trees).
    #[serde(default)]
    #[schema(minimum = 0.03, maximum = 1.0)]
    pub spacing: Option<f64>,
    /// Only points inside this box are used (m).
    #[serde(default)]
    pub crop: Option<CropJson>,
    /// How leaves are found and dropped (default `auto`).
    #[serde(default)]
    pub foliage: Option<FoliageJson>,
    /// What made the cloud (default `unknown`).
    #[serde(default)]
    pub sensor: Option<SensorJson>,
    /// How far past a branch's edge a `laser`'s pulse still returns (m,
    /// 0-0.05; default 0): about half the beam's footprint at the tree
    /// (exit diameter plus range × divergence), less where the receiver
    /// needs a larger share of the pulse's energy. Only with `sensor:
    /// laser`.
    #[serde(default)]
    #[schema(minimum = 0.0, maximum = 0.05)]
    pub beam_radius: Option<f64>,
    /// Where the sensor stood for each view (m; at most 16), when known:
    /// a camera's own cloud, in its frame, was seen from the origin. A gap
    /// in a branch's points that lies behind something the sensor saw is
    /// then bridged as one under leaves is; one it looked through is not.
    #[serde(default)]
    #[schema(value_type = Option<Vec<Vec3>>, max_items = 16)]
    pub viewpoints: Option<Vec<Vec<f64>>>,
}

/// What made the cloud. `unknown`: the skeleton stands where the points
/// put it. `camera` (time of flight, structured light or stereo at close
/// range; returns on the surface facing the camera): when the cloud was
/// seen from one side, the branch axes are moved back from the near
/// surface, by up to 0.4 of the radius where no tight circle fits. Not for
/// a laser scanner whose beam is wider than the twigs: its returns lie
/// behind the surface, and moving the axes back lost a tenth of recall
/// and precision on such scans. `laser` (a terrestrial or mobile laser
/// scanner, with its `beam_radius`): when the cloud was seen from one side,
/// each branch's radius and axis come from its silhouette less the beam's
/// spread, where a pulse that only grazed the branch still returned.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize, Serialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum SensorJson {
    #[default]
    Unknown,
    Camera,
    Laser,
}

/// How leaves are found: `auto`, by colour when `colors` are sent, else by
/// shape when the shape classifier finds the cloud leafy (a fifth of its
/// points or more look like leaves); `shape`, by shape without colours
/// whatever the share; `off`, every point is kept.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize, Serialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum FoliageJson {
    #[default]
    Auto,
    Shape,
    Off,
}

impl From<FoliageJson> for treemanip_core::scan::FoliageFilter {
    fn from(f: FoliageJson) -> Self {
        match f {
            FoliageJson::Auto => Self::Auto,
            FoliageJson::Shape => Self::Shape,
            FoliageJson::Off => Self::Off,
        }
    }
}

/// The options of a PLY body, as query parameters: vectors as
/// comma-separated numbers (`root=0.1,0,0`), the crop box as six
/// (`crop=min_x,min_y,min_z,max_x,max_y,max_z`).
#[derive(Debug, Clone, Default, Deserialize, IntoParams)]
#[into_params(parameter_in = Query)]
#[serde(deny_unknown_fields)]
pub struct FromPointsQuery {
    /// The trunk's base (m), `x,y,z`.
    pub root: Option<String>,
    /// Which way is up, `x,y,z`.
    pub up: Option<String>,
    /// Largest distance between joints along a branch (m, 0.03-1).
    #[param(minimum = 0.03, maximum = 1.0)]
    pub spacing: Option<f64>,
    /// Only points in this box (m): `min_x,min_y,min_z,max_x,max_y,max_z`.
    pub crop: Option<String>,
    /// How leaves are found: `auto` (default), `shape` or `off`.
    pub foliage: Option<FoliageJson>,
    /// What made the cloud: `unknown` (default), `camera` or `laser`.
    pub sensor: Option<SensorJson>,
    /// How far past a branch's edge a `laser`'s pulse still returns (m,
    /// 0-0.05; default 0): about half the beam's footprint at the tree
    /// (exit diameter plus range × divergence), less where the receiver
    /// needs a larger share of the pulse's energy. Only with `sensor:
    /// laser`.
    #[param(minimum = 0.0, maximum = 0.05)]
    pub beam_radius: Option<f64>,
    /// Where the sensor stood for each view (m): `x,y,z` for each, all
    /// comma-separated (`viewpoints=0,0,0,1.5,0,0.8`).
    pub viewpoints: Option<String>,
}

/// An axis-aligned box (m).
#[derive(Debug, Clone, Copy, Deserialize, Serialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct CropJson {
    #[schema(value_type = Vec3)]
    pub min: [f64; 3],
    #[schema(value_type = Vec3)]
    pub max: [f64; 3],
}

/// Points left out of the tree, by reason.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct DroppedJson {
    /// Points with no neighbour near them.
    pub outliers: usize,
    /// Points of connected parts that are not joined to the tree (too
    /// small or not shaped like a branch, or too far from it).
    pub fragments: usize,
    /// Points outside the crop box.
    pub outside_crop: usize,
    /// Points dropped as leaves: by colour (foliage green, excess green
    /// over 0.15) when `colors` are sent, else by shape when the cloud is
    /// leafy (see `foliage` in the request).
    pub foliage: usize,
}

/// The tree found in the cloud, ready for every other endpoint.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct FromPointsResponse {
    /// Node 0 is the trunk's base; a joint at every branch point and along
    /// branches at most `spacing` apart; radii fitted to the points.
    pub tree: TreeJson,
    /// Per node, 0-1: how well the points supported its position and
    /// radius (low: seen from one side, radius taken from the parent, few
    /// points).
    pub confidence: Vec<f64>,
    /// Points that make up the tree.
    pub points_used: usize,
    pub points_dropped: DroppedJson,
    /// Where the sensor stood (m), when the cloud was seen from one side
    /// (the direction is sure to a few degrees, the distance rough); null
    /// for a cloud seen from several sides.
    #[schema(value_type = Option<Vec3>)]
    pub seen_from: Option<Vec<f64>>,
    /// What could not be seen or had to be guessed, and whether the tree is
    /// larger than this server's other endpoints take.
    pub warnings: Vec<String>,
}
