//! A tree from a point cloud: the parameters, what comes back, and the
//! steps in order.
//!
//! 1. Check the cloud, crop it, drop leaves (foliage-green points when it
//!    has colours; without, by shape when it looks leafy:
//!    [`crate::scan::foliage`]), refuse planes and lines.
//! 2. Average the points in cubes of `voxel` (the work then follows the
//!    bark's area, not the scanner's point count).
//! 3. Join each cube to its neighbours within a few cubes
//!    ([`crate::scan::neighbours`]); isolated cubes are outliers.
//! 4. Find the tree: the connected part holding `root`, or the tallest
//!    large part; bridge gaps to other parts (an occluded stretch of
//!    branch) only when the part is shaped like a branch or larger than a
//!    leaf and the gap is at most `max_gap` (at least [`LEAFY_MAX_GAP`]
//!    once leaves went by shape); what stays apart is a fragment. A second
//!    large part standing on the ground is a second tree: refused.
//! 5. Level sets of the geodesic distance from the trunk's base give the
//!    fine skeleton ([`crate::scan::levels`]), pruned of stubs shorter than
//!    three level sets; each piece's centre and radius come from a circle fitted
//!    across the branch, with the parent's radius where a branch is seen
//!    from one side only; a cloud seen from one side says so, and with
//!    `sensor` a camera its axes move back ([`crate::scan::viewpoint`]).
//! 6. [`crate::scan::simplify`] keeps a joint at every branch point and
//!    along branches at most `spacing` apart: the granularity the models
//!    and the simulator expect.

use nalgebra::{Point3, Vector3};
use petgraph::unionfind::UnionFind;

use crate::geometry::principal::principal;
use crate::scan::cloud::{CloudError, CropBox, PointCloud, check_spread};
use crate::scan::fine::{FineSkeleton, fine_skeleton};
use crate::scan::foliage::{FoliageClassifier, LEAFY_SHARE, call_foliage, is_foliage};
use crate::scan::levels::Geodesic;
use crate::scan::neighbours::{Graph, PointIndex, part_distance};
use crate::scan::simplify::simplify;
use crate::scan::skeleton::Skeleton;
use crate::scan::viewpoint::Sensor;
use crate::scan::voxel::voxelize;

/// The returned nodes' default spacing (m): the median branch length of
/// the paper's generated trees (10-30 nodes, 0.6-1.7 m tall; 420 trees of
/// the generator, quartiles 0.13 and 0.22 m).
pub const DEFAULT_SPACING: f64 = 0.18;
/// Default largest number of points in one cloud.
pub const DEFAULT_MAX_POINTS: usize = 2_000_000;
/// A cloud needs at least this many points (after cropping).
pub const MIN_POINTS: usize = 50;
/// A given root may be at most this far (m) from the nearest point.
pub const ROOT_TOLERANCE: f64 = 0.25;
/// The smallest tree (m, along `up`) the extraction looks for.
pub const MIN_TREE_HEIGHT: f64 = 0.1;

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
}

/// How the extraction finds leaves.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum FoliageFilter {
    /// By colour when the cloud has colours; without, by shape
    /// ([`crate::scan::foliage`]) when the shape classifier finds the cloud
    /// leafy (at least [`LEAFY_SHARE`] of its points).
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
        }
    }
}

impl ExtractParams {
    fn validate(&self) -> Result<Vector3<f64>, CloudError> {
        let bad = |s: &str| Err(CloudError::BadParameter(s.to_owned()));
        if !(self.spacing.is_finite() && (0.03..=1.0).contains(&self.spacing)) {
            return bad("spacing must be between 0.03 and 1 m");
        }
        if !(self.voxel.is_finite() && (0.001..=0.05).contains(&self.voxel)) {
            return bad("voxel must be between 0.001 and 0.05 m");
        }
        if !(self.max_gap.is_finite() && (0.0..=0.5).contains(&self.max_gap)) {
            return bad("max_gap must be between 0 and 0.5 m");
        }
        if let Some(root) = self.root
            && !root.iter().all(|c| c.is_finite())
        {
            return bad("root must be finite");
        }
        if let Some(crop) = self.crop
            && (!(crop.min.iter().chain(crop.max.iter())).all(|c| c.is_finite())
                || (0..3).any(|i| crop.min[i] > crop.max[i]))
        {
            return bad("crop must be finite with min <= max on every axis");
        }
        let norm = self.up.norm();
        if !(norm.is_finite() && norm > 1e-9) {
            return Err(CloudError::BadUp);
        }
        Ok(self.up / norm)
    }
}

/// Points left out of the tree, by reason.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Dropped {
    /// Points with no neighbour within the link distance.
    pub outliers: usize,
    /// Points of connected parts not joined to the tree (too small to be
    /// a branch, or too far from it).
    pub fragments: usize,
    pub outside_crop: usize,
    /// Points dropped as leaves: by colour when colours are given, else by
    /// shape when the cloud is leafy.
    pub foliage: usize,
}

/// A tree found in a cloud.
#[derive(Debug, Clone)]
pub struct Extraction {
    pub skeleton: Skeleton,
    /// Per node, 0-1: how well the points around it supported its
    /// position and radius (1: a full cross-section seen; low: one side
    /// only, radius borrowed from the parent, few points).
    pub confidence: Vec<f64>,
    /// Points in the tree.
    pub points_used: usize,
    pub dropped: Dropped,
    /// What the extraction could not see or had to guess.
    pub warnings: Vec<String>,
    /// The fine skeleton before simplification (one node per piece).
    pub fine: Skeleton,
    /// Where the sensor stood (m), when the cloud was seen from one side
    /// ([`crate::scan::viewpoint`]); said in a warning too.
    pub seen_from: Option<Point3<f64>>,
}

/// Largest gap bridged once leaves were dropped by shape: the classifier
/// takes some twig cubes with the leaves around them. Chosen on 42
/// train-split trees (leafy, one view, 3 mm; recall / precision at 1.0 r
/// and `clear` tasks solved of 75): 6 cm 0.674 / 0.896, 42; 10 cm 0.701 /
/// 0.870, 43; 15 cm 0.718 / 0.852, 48.
pub const LEAFY_MAX_GAP: f64 = 0.15;

/// Cubes joined to neighbours within this many cube edges.
const LINK_VOXELS: f64 = 3.0;
/// Neighbours per cube in the graph.
const NEIGHBOURS: usize = 12;
/// A part needs this many cubes to be bridged to the tree.
const MIN_PART_VOXELS: usize = 8;
/// A part is bridged when its length is this many times its width.
const ELONGATION: f64 = 2.5;
/// ... or when it spreads this much (m, standard deviation along its
/// longest axis: a straight 14 cm stretch, a 16 cm disc): more than a leaf
/// (2.5 cm radius, 1.25 cm), a cluster of a twig's leaves or a fruit.
/// Without it a fork seen apart from the tree was dropped as a fragment:
/// leafy one-view scans lost 8 points of recall at t = 1.0 that way
/// (0.697 with every leaf point removed; 0.778 bridged).
const SUBTREE_SPREAD: f64 = 0.04;
/// Cubes double until the largest connected part holds this share of the
/// points ...
const CONNECTED_SHARE: f64 = 0.3;
/// ... or reach this edge (m).
const MAX_VOXEL: f64 = 0.064;

/// Width of a level set, in cube edges.
const BIN_VOXELS: f64 = 4.0;

/// Extracts the tree in `cloud`.
///
/// Where leaves went by shape (no colours, [`FoliageFilter::Auto`]) and
/// what was left stands on the ground as two trees, the shape call took
/// wood that joined them (one of sylva-rs's bare eucalypts, three views,
/// was refused so): the cloud is read again keeping every point, and a
/// warning says so. A cloud that is two trees is refused either way.
pub fn extract(cloud: &PointCloud, params: &ExtractParams) -> Result<Extraction, CloudError> {
    match extract_once(cloud, params) {
        Ok(found) => Ok(found),
        Err(Refused {
            error: CloudError::SeveralTrees { .. },
            leaves_by_shape: true,
        }) if params.foliage == FoliageFilter::Auto => {
            let every_point = ExtractParams {
                foliage: FoliageFilter::Off,
                ..params.clone()
            };
            let mut found = extract_once(cloud, &every_point).map_err(|r| r.error)?;
            found.warnings.push(
                "without the points that look like leaves the cloud stood as two trees; it was read keeping every point (send `foliage: shape` to drop them anyway)".to_owned(),
            );
            Ok(found)
        }
        Err(refused) => Err(refused.error),
    }
}

/// Why [`extract_once`] refused a cloud, and whether it had dropped
/// leaves by shape first (then a second tree may be the drop's doing).
struct Refused {
    error: CloudError,
    leaves_by_shape: bool,
}

impl From<CloudError> for Refused {
    fn from(error: CloudError) -> Self {
        Self {
            error,
            leaves_by_shape: false,
        }
    }
}

fn extract_once(cloud: &PointCloud, params: &ExtractParams) -> Result<Extraction, Refused> {
    let up = params.validate()?;
    cloud.check(params.max_points)?;
    let mut dropped = Dropped::default();
    let inside: Vec<usize> = (0..cloud.len())
        .filter(|&i| params.crop.is_none_or(|c| c.contains(&cloud.points[i])))
        .collect();
    dropped.outside_crop = cloud.len() - inside.len();
    // With colours, foliage goes first: green points are leaves.
    let colour = params.foliage != FoliageFilter::Off && cloud.colors.is_some();
    let mut kept: Vec<Point3<f64>> = inside
        .iter()
        .filter(|&&i| {
            let leaf = colour && cloud.colors.as_ref().is_some_and(|c| is_foliage(c[i]));
            dropped.foliage += usize::from(leaf);
            !leaf
        })
        .map(|&i| cloud.points[i])
        .collect();
    let mut warnings = Vec::new();
    // Without, by shape.
    let mut max_gap = params.max_gap;
    let mut leaves_by_shape = false;
    if params.foliage != FoliageFilter::Off && cloud.colors.is_none() && kept.len() >= MIN_POINTS {
        let min_share = (params.foliage == FoliageFilter::Auto).then_some(LEAFY_SHARE);
        if let Some(call) = call_foliage(&kept, &up, FoliageClassifier::shipped(), min_share) {
            let before = kept.len();
            kept = kept
                .iter()
                .zip(&call.foliage)
                .filter(|(_, f)| !**f)
                .map(|(p, _)| *p)
                .collect();
            dropped.foliage += before - kept.len();
            leaves_by_shape = true;
            max_gap = max_gap.max(LEAFY_MAX_GAP);
            warnings.push(format!(
                "{:.0} % of the points look like leaves by their shape and were dropped (the cloud has no colours; with an RGB camera's colours leaves are told more surely); gaps up to {:.0} cm are bridged",
                100.0 * call.share,
                max_gap * 100.0
            ));
        }
    }
    if kept.len() < MIN_POINTS {
        return Err(CloudError::TooFewInCrop {
            kept: kept.len(),
            min: MIN_POINTS,
        }
        .into());
    }
    check_spread(&kept)?;

    // A sparse cloud (a mobile mapping scan, a distant tree) does not
    // connect in small cubes: the cubes double until the largest connected
    // part holds a good share of the points.
    let mut voxel = params.voxel;
    let (voxels, index, mut graph, labels) = loop {
        let voxels = voxelize(&kept, voxel);
        let index = PointIndex::new(&voxels.centres);
        let graph = Graph::knn(&voxels.centres, &index, NEIGHBOURS, LINK_VOXELS * voxel);
        let labels = graph.components(|_, _| true);
        let mut size = vec![0usize; labels.iter().max().map_or(0, |m| m + 1)];
        for (i, &l) in labels.iter().enumerate() {
            size[l] += voxels.counts[i];
        }
        let largest = size.iter().copied().max().unwrap_or(0);
        if largest as f64 >= CONNECTED_SHARE * kept.len() as f64 || 2.0 * voxel > MAX_VOXEL {
            break (voxels, index, graph, labels);
        }
        voxel *= 2.0;
    };
    if voxel > params.voxel {
        warnings.push(format!(
            "the points are sparse: averaged in cubes of {:.1} cm instead of {:.1}, so branches thinner than about {:.1} cm are not resolved",
            voxel * 100.0,
            params.voxel * 100.0,
            voxel * 100.0
        ));
    }
    let (points, weights) = (&voxels.centres, &voxels.counts);
    let height = |p: &Point3<f64>| p.coords.dot(&up);

    let parts = labels.iter().max().map_or(0, |m| m + 1);
    let mut part_voxels = vec![0usize; parts];
    let mut part_points = vec![0usize; parts];
    let mut part_low = vec![f64::INFINITY; parts];
    let mut part_high = vec![f64::NEG_INFINITY; parts];
    for (i, &l) in labels.iter().enumerate() {
        part_voxels[l] += 1;
        part_points[l] += weights[i];
        part_low[l] = part_low[l].min(height(&points[i]));
        part_high[l] = part_high[l].max(height(&points[i]));
    }
    for (i, w) in weights.iter().enumerate() {
        if graph.degree(i) == 0 {
            dropped.outliers += w;
        }
    }
    if graph.len() - (0..points.len()).filter(|&i| graph.degree(i) == 0).count() < MIN_POINTS / 5 {
        return Err(CloudError::TooFew {
            got: kept.len() - dropped.outliers,
            min: MIN_POINTS,
        }
        .into());
    }

    // The tree's part.
    let largest = part_voxels.iter().copied().max().unwrap_or(0);
    let main = match params.root {
        Some(root) => {
            let (i, d) = index.nearest(&root);
            if d > ROOT_TOLERANCE {
                return Err(CloudError::RootOutside {
                    x: root.x,
                    y: root.y,
                    z: root.z,
                    distance: d,
                    max: ROOT_TOLERANCE,
                }
                .into());
            }
            // The largest part near the root (a stray point may be nearest).
            index
                .near(&root, 256, ROOT_TOLERANCE)
                .iter()
                .map(|&(j, _)| labels[j])
                .max_by_key(|&l| part_points[l])
                .unwrap_or(labels[i])
        }
        // The tallest of the large parts (a quarter of the largest or
        // more): a tree stands up from the ground; a clump of undergrowth
        // or a stray patch does not.
        None => (0..parts)
            .filter(|&l| part_voxels[l] >= MIN_PART_VOXELS.max(largest / 4))
            .max_by(|&a, &b| (part_high[a] - part_low[a]).total_cmp(&(part_high[b] - part_low[b])))
            .unwrap_or(0),
    };

    // Bridge parts to the tree (Kruskal over the parts' closest pairs).
    let bridges = bridges(points, &labels, &part_voxels, main, max_gap);
    let mut sets = UnionFind::<usize>::new(parts);
    let mut edges: Vec<(usize, usize, f64)> = Vec::new();
    let mut largest_bridge: f64 = 0.0;
    for &(d, a, b) in &bridges {
        if sets.union(labels[a], labels[b]) {
            edges.push((a, b, d));
            largest_bridge = largest_bridge.max(d);
        }
    }
    // Which parts the bridges joined to the tree's, decided once.
    let in_tree: Vec<bool> = (0..parts).map(|l| sets.equiv(l, main)).collect();
    let tree_edges: Vec<_> = edges.into_iter().filter(|e| in_tree[labels[e.0]]).collect();
    if !tree_edges.is_empty() {
        warnings.push(format!(
            "{} gaps in the points were bridged (the largest {:.1} cm): occluded or unsampled stretches of branch",
            tree_edges.len(),
            largest_bridge * 100.0
        ));
    }
    let main_low = (0..parts)
        .filter(|&l| in_tree[l])
        .map(|l| part_low[l])
        .fold(f64::INFINITY, f64::min);
    let main_points: usize = (0..parts)
        .filter(|&l| in_tree[l])
        .map(|l| part_points[l])
        .sum();
    // A second tree: a large part apart from this one, standing as low.
    for l in 0..parts {
        if in_tree[l] || part_points[l] * 5 < main_points || part_voxels[l] < MIN_PART_VOXELS {
            continue;
        }
        if params.root.is_none() && part_low[l] < main_low + 0.15 {
            let distance = part_distance(points, &labels, main, l);
            return Err(Refused {
                error: CloudError::SeveralTrees {
                    points: part_points[l],
                    distance,
                },
                leaves_by_shape,
            });
        }
    }
    for l in 0..parts {
        if !in_tree[l] && part_voxels[l] > 1 {
            dropped.fragments += part_points[l];
        }
    }
    let mut all_edges = graph.edges();
    all_edges.extend(tree_edges);
    graph = Graph::from_edges(points.len(), &all_edges);

    let members: Vec<usize> = (0..points.len()).filter(|&i| in_tree[labels[i]]).collect();
    let (lo, hi) = members
        .iter()
        .map(|&i| height(&points[i]))
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), h| {
            (a.min(h), b.max(h))
        });
    if hi - lo < MIN_TREE_HEIGHT || members.len() < MIN_PART_VOXELS {
        return Err(CloudError::NoTree {
            largest: main_points,
            extent: (hi - lo).max(0.0),
            min_extent: MIN_TREE_HEIGHT,
        }
        .into());
    }

    // The trunk's base: the bottom slice of the tree (near the root when
    // one is given).
    let bin = BIN_VOXELS * voxel;
    let sources: Vec<usize> = match params.root {
        Some(root) => members
            .iter()
            .copied()
            .filter(|&i| {
                let d = points[i] - root;
                let along = d.dot(&up);
                (along.abs() <= bin) && (d - up * along).norm() < 0.15
            })
            .collect(),
        None => members
            .iter()
            .copied()
            .filter(|&i| height(&points[i]) <= lo + bin)
            .collect(),
    };
    let sources = if sources.is_empty() {
        vec![index.nearest(&params.root.unwrap_or(Point3::origin())).0]
    } else {
        sources
    };
    let (dist, pred) = graph.shortest_paths(&sources);

    let FineSkeleton {
        skeleton: fine,
        confidence: fine_confidence,
        points_used,
        notes,
        seen_from,
    } = fine_skeleton(
        &Geodesic {
            points,
            weights,
            graph: &graph,
            dist: &dist,
            pred: &pred,
        },
        bin,
        &up,
        params.sensor,
    );
    warnings.extend(notes);
    let (skeleton, confidence) =
        simplify(&fine, &fine_confidence, params.spacing, seen_from.is_some());
    Ok(Extraction {
        skeleton,
        confidence,
        points_used,
        dropped,
        warnings,
        fine,
        seen_from,
    })
}

/// The closest pair of points of every two parts (of at least
/// [`MIN_PART_VOXELS`] cubes) at most `max_gap` apart, shortest first.
fn bridges(
    points: &[Point3<f64>],
    labels: &[usize],
    part_voxels: &[usize],
    main: usize,
    max_gap: f64,
) -> Vec<(f64, usize, usize)> {
    let parts = part_voxels.len();
    let mut of_part: Vec<Vec<usize>> = vec![Vec::new(); parts];
    for (i, &l) in labels.iter().enumerate() {
        if part_voxels[l] >= MIN_PART_VOXELS {
            of_part[l].push(i);
        }
    }
    // A part is bridged only when it is shaped like a stretch of branch
    // (at least ELONGATION times longer than wide) or larger than any leaf
    // or fruit (a fork or a whole subtree seen apart from the tree behind
    // leaves is not elongated): a leaf or a fruit seen apart from its twig
    // is neither.
    let branch_like = |l: usize| {
        let pts: Vec<Point3<f64>> = of_part[l].iter().map(|&i| points[i]).collect();
        let spread = principal(&pts).spread;
        spread[0] >= ELONGATION * spread[1] || spread[0] >= SUBTREE_SPREAD
    };
    let big: Vec<usize> = (0..parts)
        .filter(|&l| !of_part[l].is_empty() && (l == main || branch_like(l)))
        .collect();
    if big.len() < 2 || max_gap <= 0.0 {
        return Vec::new();
    }
    let boxes: Vec<(Vector3<f64>, Vector3<f64>)> = big
        .iter()
        .map(|&l| {
            of_part[l].iter().fold(
                (
                    Vector3::repeat(f64::INFINITY),
                    Vector3::repeat(f64::NEG_INFINITY),
                ),
                |(lo, hi), &i| (lo.inf(&points[i].coords), hi.sup(&points[i].coords)),
            )
        })
        .collect();
    let trees: Vec<PointIndex> = big
        .iter()
        .map(|&l| {
            let pts: Vec<_> = of_part[l].iter().map(|&i| points[i]).collect();
            PointIndex::new(&pts)
        })
        .collect();
    let mut out = Vec::new();
    for x in 0..big.len() {
        for y in x + 1..big.len() {
            let (a, b) = (&boxes[x], &boxes[y]);
            let apart = (0..3).any(|k| a.0[k] > b.1[k] + max_gap || b.0[k] > a.1[k] + max_gap);
            if apart {
                continue;
            }
            // Query the smaller part's points in the larger part's tree.
            let (s, t) = if of_part[big[x]].len() <= of_part[big[y]].len() {
                (x, y)
            } else {
                (y, x)
            };
            let best = of_part[big[s]]
                .iter()
                .map(|&i| {
                    let (j, d) = trees[t].nearest(&points[i]);
                    (d, i, of_part[big[t]][j])
                })
                .min_by(|p, q| p.0.total_cmp(&q.0));
            if let Some(best) = best
                && best.0 <= max_gap
            {
                out.push(best);
            }
        }
    }
    out.sort_by(|p, q| p.0.total_cmp(&q.0));
    out
}

#[cfg(test)]
mod tests;
