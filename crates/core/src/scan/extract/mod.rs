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
//!    once leaves went by shape), or the dropped leaves cover the gap, or
//!    it lies behind what the sensor saw from the `viewpoints` given
//!    ([`crate::scan::bridge`], [`crate::scan::shadow`]); what stays apart is a fragment. A second
//!    large part standing on the ground is a second tree: refused.
//! 5. Level sets of the geodesic distance from the trunk's base give the
//!    fine skeleton ([`crate::scan::levels`]), pruned of stubs shorter than
//!    three level sets; each piece's centre and radius come from a circle fitted
//!    across the branch, with the parent's radius where a branch is seen
//!    from one side only; a cloud seen from one side says so, and with
//!    `sensor` a camera its axes move back ([`crate::scan::viewpoint`]), a
//!    laser's radii and axes come from the silhouettes less the beam's
//!    spread ([`crate::scan::silhouette`]).
//! 6. [`crate::scan::simplify`] keeps a joint at every branch point and
//!    along branches at most `spacing` apart: the granularity the models
//!    and the simulator expect.

use nalgebra::Point3;
use petgraph::unionfind::UnionFind;

use crate::scan::bridge::{COVERED_MAX_GAP, Cover, Covered, MIN_PART_VOXELS, bridges};
use crate::scan::cloud::{CloudError, PointCloud, check_spread};
use crate::scan::fine::{FineSkeleton, RawPoints, fine_skeleton};
use crate::scan::foliage::{FoliageClassifier, LEAFY_SHARE, call_foliage, is_foliage};
use crate::scan::levels::Geodesic;
use crate::scan::neighbours::{Graph, PointIndex, part_distance};
use crate::scan::shadow::{Shadows, check_viewpoints};
use crate::scan::simplify::simplify;
use crate::scan::skeleton::Skeleton;
use crate::scan::voxel::voxelize;

mod params;
pub use params::{
    DEFAULT_MAX_POINTS, DEFAULT_SPACING, ExtractParams, FoliageFilter, MAX_BEAM_RADIUS,
    MAX_VIEWPOINTS,
};

/// A cloud needs at least this many points (after cropping).
pub const MIN_POINTS: usize = 50;
/// A given root may be at most this far (m) from the nearest point.
pub const ROOT_TOLERANCE: f64 = 0.25;
/// The smallest tree (m, along `up`) the extraction looks for.
pub const MIN_TREE_HEIGHT: f64 = 0.1;

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
    check_viewpoints(&cloud.points, &params.viewpoints)?;
    let mut dropped = Dropped::default();
    let inside: Vec<usize> = (0..cloud.len())
        .filter(|&i| params.crop.is_none_or(|c| c.contains(&cloud.points[i])))
        .collect();
    dropped.outside_crop = cloud.len() - inside.len();
    // With colours, foliage goes first: green points are leaves.
    let colour = params.foliage != FoliageFilter::Off && cloud.colors.is_some();
    // The points dropped as leaves are kept aside: where they cover a gap,
    // the gap is a stretch of branch they hid ([`crate::scan::bridge`]).
    let (mut leaves, mut kept) = (Vec::new(), Vec::with_capacity(inside.len()));
    for &i in &inside {
        let leaf = colour && cloud.colors.as_ref().is_some_and(|c| is_foliage(c[i]));
        if leaf { &mut leaves } else { &mut kept }.push(cloud.points[i]);
    }
    dropped.foliage = leaves.len();
    let mut warnings = Vec::new();
    // Without, by shape.
    let mut max_gap = params.max_gap;
    let mut leaves_by_shape = false;
    // Each kept point's chance of being leaf, where leaves went by shape.
    let mut leaf_chance: Option<Vec<f64>> = None;
    if params.foliage != FoliageFilter::Off && cloud.colors.is_none() && kept.len() >= MIN_POINTS {
        let min_share = (params.foliage == FoliageFilter::Auto).then_some(LEAFY_SHARE);
        if let Some(call) = call_foliage(&kept, &up, FoliageClassifier::shipped(), min_share) {
            let before = leaves.len();
            let (mut bark, mut chances) = (Vec::with_capacity(kept.len()), Vec::new());
            for ((p, &f), &c) in kept.iter().zip(&call.foliage).zip(&call.chance) {
                if f {
                    leaves.push(*p);
                } else {
                    bark.push(*p);
                    chances.push(c);
                }
            }
            dropped.foliage += leaves.len() - before;
            kept = bark;
            leaf_chance = Some(chances);
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
    let cover = Cover::new(
        &leaves,
        Shadows::new(&cloud.points, &params.viewpoints),
        leaf_chance.map(|c| cube_means(&c, &voxels.of_point, points.len())),
    );
    let bridges = bridges(points, &labels, &part_voxels, main, max_gap, cover.as_ref());
    let mut sets = UnionFind::<usize>::new(parts);
    let mut edges = Vec::new();
    for b in &bridges {
        if sets.union(labels[b.from], labels[b.to]) {
            edges.push(*b);
        }
    }
    // Which parts the bridges joined to the tree's, decided once.
    let in_tree: Vec<bool> = (0..parts).map(|l| sets.equiv(l, main)).collect();
    edges.retain(|b| in_tree[labels[b.from]]);
    if !edges.is_empty() {
        let largest = edges.iter().map(|b| b.gap).fold(0.0, f64::max);
        let by = |c| edges.iter().filter(|b| b.covered == Some(c)).count();
        let (leaves, shadow) = (by(Covered::Leaves), by(Covered::Shadow));
        let mut covered = Vec::new();
        if leaves > 0 {
            covered.push(format!("{leaves} under leaves"));
        }
        if shadow > 0 {
            covered.push(format!("{shadow} behind what the sensor saw"));
        }
        warnings.push(format!(
            "{} gaps in the points were bridged (the largest {:.1} cm): occluded or unsampled stretches of branch{}",
            edges.len(),
            largest * 100.0,
            if covered.is_empty() {
                String::new()
            } else {
                format!(
                    "; {} (up to {:.0} cm), where only a few centimetres of a twig showed: their branches are guessed straight across",
                    covered.join(", "),
                    COVERED_MAX_GAP * 100.0
                )
            }
        ));
    }
    let tree_edges: Vec<(usize, usize, f64)> =
        edges.iter().map(|b| (b.from, b.to, b.gap)).collect();
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
        RawPoints {
            points: &kept,
            voxels: &voxels,
        },
    );
    warnings.extend(notes);
    if seen_from.is_some() && params.viewpoints.is_empty() {
        warnings.push(
            "send where the sensor stood (`viewpoints`; [0, 0, 0] for a cloud in the camera's own frame): gaps hidden behind leaves and branches in front are then bridged".to_owned(),
        );
    }
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

/// Each cube's mean of a per-point value.
fn cube_means(values: &[f64], of_point: &[usize], cubes: usize) -> Vec<f64> {
    let mut sum = vec![0.0; cubes];
    let mut count = vec![0usize; cubes];
    for (&v, &c) in values.iter().zip(of_point) {
        sum[c] += v;
        count[c] += 1;
    }
    sum.iter()
        .zip(&count)
        .map(|(s, &n)| s / n.max(1) as f64)
        .collect()
}

#[cfg(test)]
mod tests;
