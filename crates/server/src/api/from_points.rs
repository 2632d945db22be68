//! `POST /v1/trees/from-points`: a tree from a point cloud, sent as JSON or
//! as a PLY body. The extraction is `treemanip_core::scan::extract`; this
//! file reads the body, turns the wire types into the core's and back, and
//! names what is wrong with a cloud.

use axum::extract::{RawQuery, Request, State};
use nalgebra::Point3;
use serde_json::json;

use super::AppState;
use super::error::{ApiError, ErrorCode};
use super::json::{media_type, parse_json, read_body};
use super::validate::vector3;
use crate::api::types::error::PostErrors;
use crate::api::types::{
    CropJson, DroppedJson, FoliageJson, FromPointsQuery, FromPointsRequest, FromPointsResponse,
    SensorJson, TreeJson,
};
use treemanip_core::scan::io::FormatError;
use treemanip_core::scan::{
    CloudError, CropBox, ExtractParams, Extraction, PointCloud, Sensor, extract,
};

/// Media types read as PLY.
pub const PLY_MEDIA_TYPES: [&str; 2] = ["application/x-ply", "application/octet-stream"];

/// A tree from a point cloud.
///
/// Send the cloud as JSON (`points`, optional `normals` and `colors`, and
/// the options beside them) or as a PLY file (ASCII or binary; `Content-Type:
/// application/x-ply` or `application/octet-stream`, the options in the
/// query). The answer is a tree every other endpoint takes: a joint at each
/// branch point and along branches at most `spacing` apart, radii fitted to
/// the points (the parent's where a branch was seen from one side only), a
/// confidence per node, the points left out by reason and warnings for what
/// could not be seen. An empty cloud, NaN, points in a plane or along a line,
/// a cloud without a tree-like part, two trees side by side and a root away
/// from the cloud are 422; a cloud over the server's point limit is 413.
#[utoipa::path(post, path = "/v1/trees/from-points", tag = "trees",
    params(FromPointsQuery),
    request_body(description = "A point cloud: JSON, or a PLY file (binary or ASCII).",
        content(
            (FromPointsRequest = "application/json"),
            (Vec<u8> = "application/octet-stream"),
        )),
    responses(
    (status = 200, description = "The tree found in the cloud.", body = FromPointsResponse),
    PostErrors,
))]
pub async fn from_points(
    State(state): State<AppState>,
    RawQuery(query): RawQuery,
    request: Request,
) -> Result<axum::Json<FromPointsResponse>, ApiError> {
    let mime = media_type(&request);
    let max_points = state.limits.max_cloud_points;
    let is_json = mime == "application/json" || mime.ends_with("+json");
    if !is_json && !PLY_MEDIA_TYPES.contains(&mime.as_str()) {
        return Err(ApiError::new(
            ErrorCode::UnsupportedMediaType,
            "send the cloud as JSON (`Content-Type: application/json`) or as a PLY file (`application/x-ply` or `application/octet-stream`)",
        ));
    }
    let query = query.unwrap_or_default();
    if is_json && !query.is_empty() {
        return Err(ApiError::invalid_argument(
            "with a JSON body the options go in the body, not the query",
        ));
    }
    let bytes = read_body(request, &state).await?;
    let max_nodes = state.limits.max_nodes;
    let response = state
        .run_blocking("/v1/trees/from-points", move || {
            let (cloud, params) = if is_json {
                let request: FromPointsRequest = parse_json(&bytes)?;
                request.into_cloud()?
            } else {
                let params = FromPointsQuery::parse(&query)?.params()?;
                let cloud = treemanip_core::scan::io::ply::read(&bytes[..], max_points)
                    .map_err(format_error)?;
                (cloud, params)
            };
            let params = ExtractParams {
                max_points,
                ..params
            };
            let extraction = extract(&cloud, &params).map_err(cloud_error)?;
            Ok(FromPointsResponse::from_extraction(&extraction, max_nodes))
        })
        .await?;
    Ok(axum::Json(response))
}

impl FromPointsRequest {
    /// The cloud and the extraction's options.
    pub fn into_cloud(self) -> Result<(PointCloud, ExtractParams), ApiError> {
        let points = self
            .points
            .iter()
            .enumerate()
            .map(|(i, p)| {
                <[f64; 3]>::try_from(p.as_slice())
                    .map(Point3::from)
                    .map_err(|_| {
                        ApiError::invalid_argument(format!(
                            "point {i} must have 3 numbers, it has {}",
                            p.len()
                        ))
                        .with_details(json!({ "field": "points", "index": i }))
                    })
            })
            .collect::<Result<Vec<_>, _>>()?;
        let normals = self
            .normals
            .map(|n| {
                n.iter()
                    .map(|v| vector3(v, "normals"))
                    .collect::<Result<Vec<_>, _>>()
            })
            .transpose()?;
        let colors = self
            .colors
            .map(|c| {
                c.iter()
                    .map(|v| {
                        let ok = v.len() == 3
                            && v.iter()
                                .all(|c| (0.0..=255.0).contains(c) && c.fract() == 0.0);
                        if ok {
                            Ok([v[0] as u8, v[1] as u8, v[2] as u8])
                        } else {
                            Err(ApiError::invalid_argument(
                                "each colour must be 3 integers from 0 to 255",
                            )
                            .with_details(json!({ "field": "colors" })))
                        }
                    })
                    .collect::<Result<Vec<_>, _>>()
            })
            .transpose()?;
        let params = params(
            self.root.as_deref(),
            self.up.as_deref(),
            self.spacing,
            self.crop,
            self.foliage,
            sensor(self.sensor, self.beam_radius)?,
            self.viewpoints.as_deref(),
        )?;
        Ok((
            PointCloud {
                points,
                normals,
                colors,
            },
            params,
        ))
    }
}

/// What made the cloud, from `sensor` and the laser's `beam_radius` (its
/// range is the extraction's own check).
fn sensor(sensor: Option<SensorJson>, beam_radius: Option<f64>) -> Result<Sensor, ApiError> {
    match (sensor.unwrap_or_default(), beam_radius) {
        (SensorJson::Laser, beam_radius) => Ok(Sensor::Laser {
            beam_radius: beam_radius.unwrap_or(0.0),
        }),
        (_, Some(_)) => Err(ApiError::invalid_field(
            "beam_radius",
            "beam_radius is a laser's: send it with \"sensor\": \"laser\"",
        )),
        (SensorJson::Unknown, None) => Ok(Sensor::Unknown),
        (SensorJson::Camera, None) => Ok(Sensor::Camera),
    }
}

/// The extraction's options from the wire's (JSON body or query).
fn params(
    root: Option<&[f64]>,
    up: Option<&[f64]>,
    spacing: Option<f64>,
    crop: Option<CropJson>,
    foliage: Option<FoliageJson>,
    sensor: Sensor,
    viewpoints: Option<&[Vec<f64>]>,
) -> Result<ExtractParams, ApiError> {
    let defaults = ExtractParams::default();
    Ok(ExtractParams {
        spacing: spacing.unwrap_or(defaults.spacing),
        root: root
            .map(|v| vector3(v, "root").map(Point3::from))
            .transpose()?,
        up: up
            .map(|v| vector3(v, "up"))
            .transpose()?
            .unwrap_or(defaults.up),
        crop: crop.map(|c| CropBox {
            min: Point3::from(c.min),
            max: Point3::from(c.max),
        }),
        foliage: foliage.unwrap_or_default().into(),
        sensor,
        viewpoints: viewpoints
            .unwrap_or_default()
            .iter()
            .map(|v| vector3(v, "viewpoints").map(Point3::from))
            .collect::<Result<_, _>>()?,
        ..defaults
    })
}

impl FromPointsQuery {
    pub fn parse(query: &str) -> Result<Self, ApiError> {
        serde_urlencoded::from_str(query).map_err(|e| {
            ApiError::invalid_argument(format!("bad query: {e}"))
                .with_details(json!({ "field": "query" }))
        })
    }

    pub fn params(self) -> Result<ExtractParams, ApiError> {
        let numbers = |field: &'static str, s: &str, n: usize| -> Result<Vec<f64>, ApiError> {
            let v: Vec<f64> = s
                .split(',')
                .map(|t| t.trim().parse::<f64>())
                .collect::<Result<_, _>>()
                .ok()
                .filter(|v: &Vec<f64>| v.len() == n && v.iter().all(|c| c.is_finite()))
                .ok_or_else(|| {
                    ApiError::invalid_argument(format!(
                        "`{field}` must be {n} comma-separated finite numbers"
                    ))
                    .with_details(json!({ "field": field }))
                })?;
            Ok(v)
        };
        let root = self
            .root
            .as_deref()
            .map(|s| numbers("root", s, 3))
            .transpose()?;
        let up = self
            .up
            .as_deref()
            .map(|s| numbers("up", s, 3))
            .transpose()?;
        let crop = self
            .crop
            .as_deref()
            .map(|s| {
                numbers("crop", s, 6).map(|v| CropJson {
                    min: [v[0], v[1], v[2]],
                    max: [v[3], v[4], v[5]],
                })
            })
            .transpose()?;
        let viewpoints = self
            .viewpoints
            .as_deref()
            .map(|s| {
                // Triples here; how many, and their values, the
                // extraction's own checks judge.
                let n = s.split(',').count();
                if n % 3 != 0 {
                    return Err(ApiError::invalid_argument(
                        "`viewpoints` must be x,y,z for each view, comma-separated",
                    )
                    .with_details(json!({ "field": "viewpoints" })));
                }
                Ok(numbers("viewpoints", s, n)?
                    .chunks(3)
                    .map(<[f64]>::to_vec)
                    .collect::<Vec<_>>())
            })
            .transpose()?;
        params(
            root.as_deref(),
            up.as_deref(),
            self.spacing,
            crop,
            self.foliage,
            sensor(self.sensor, self.beam_radius)?,
            viewpoints.as_deref(),
        )
    }
}

impl FromPointsResponse {
    /// The answer for an extraction; warns when the tree is larger than
    /// `max_nodes` (the other endpoints' limit).
    pub fn from_extraction(e: &Extraction, max_nodes: usize) -> Self {
        let s = &e.skeleton;
        let mut warnings = e.warnings.clone();
        if s.len() > max_nodes {
            warnings.push(format!(
                "the tree has {} nodes, more than the {max_nodes} this server's other endpoints take: send a larger `spacing` or crop the cloud",
                s.len()
            ));
        }
        FromPointsResponse {
            tree: TreeJson {
                positions: s.positions.iter().map(|p| vec![p.x, p.y, p.z]).collect(),
                parents: s.parents.clone(),
                radius: s
                    .parents
                    .iter()
                    .zip(&s.radius)
                    .map(|(p, r)| p.map(|_| *r))
                    .collect(),
                stiffness: None,
            },
            confidence: e.confidence.clone(),
            points_used: e.points_used,
            points_dropped: DroppedJson {
                outliers: e.dropped.outliers,
                fragments: e.dropped.fragments,
                outside_crop: e.dropped.outside_crop,
                foliage: e.dropped.foliage,
            },
            seen_from: e.seen_from.map(|p| vec![p.x, p.y, p.z]),
            warnings,
        }
    }
}

/// 413 for a cloud over the limit; 422 for every other bad cloud.
pub fn cloud_error(e: CloudError) -> ApiError {
    let field = match &e {
        CloudError::TooMany { .. } => return ApiError::too_large(e.to_string()),
        CloudError::RootOutside { .. } => "root",
        CloudError::BadUp => "up",
        CloudError::ViewpointAmongPoints { .. } => "viewpoints",
        CloudError::TooFewInCrop { .. } => "crop",
        CloudError::LengthMismatch { field, .. } => field,
        CloudError::BadParameter { field, .. } => field,
        _ => "points",
    };
    ApiError::invalid_argument(e.to_string()).with_details(json!({ "field": field }))
}

fn format_error(e: FormatError) -> ApiError {
    match e {
        FormatError::TooMany { .. } => ApiError::too_large(e.to_string()),
        e => ApiError::invalid_argument(e.to_string()).with_details(json!({ "field": "body" })),
    }
}
