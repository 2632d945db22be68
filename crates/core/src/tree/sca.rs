//! Space Colonization Algorithm (Runions, Lane & Prusinkiewicz 2007) that
//! grows trees of an exact node count.
//!
//! Growth happens in a unit-height space: attraction points fill an
//! ellipsoidal crown; each iteration every point pulls its nearest node
//! within the influence radius, each pulled node grows one segment of length
//! D towards the mean of the unit vectors to its points, and points within
//! the kill distance of a node die. While no point is in reach the trunk
//! grows straight (slightly tilted) up. Growth stops the moment the tree has
//! N nodes: when an iteration would overshoot, the nodes pulled by the most
//! points grow first. The finished skeleton is scaled so the tree's height
//! is a uniformly drawn target height, radii follow the pipe model from a
//! fixed tip radius, and stiffness and damping follow [`Wood`].
//!
//! Everything is drawn from one ChaCha8 stream seeded by the caller, so a
//! seed always gives the same tree, bit for bit, on every platform.

use nalgebra::{Point3, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use super::model::{Tree, TreeError};
use super::wood::Wood;

/// No two nodes of a generated tree are closer than this (m). The physics and
/// the gripper (a slot about 2 cm wide) need nodes that can be told apart.
pub const MIN_NODE_SPACING: f64 = 0.03;

/// Largest node count Space Colonization grows. Its segments shrink as
/// 1/√N to fill the same crown, so past this a tree is a bush of
/// 2-4 cm branches with nothing of an orchard tree's structure (and the
/// growth gives up more often); [`super::orchard`] grows larger trees.
pub const MAX_SCA_NODES: usize = 64;

/// Smallest node count the generator accepts: a root, a trunk node and two
/// children are needed for a tree that branches.
pub const MIN_GENERATED_NODES: usize = 4;

/// Generator parameters. Lengths marked "unit" are fractions of the tree's
/// height before it is scaled to its drawn height; the rest are SI.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ScaParams {
    /// Final tree height is drawn uniformly from this range (m).
    /// Default 0.6–1.7 m, the paper's range.
    pub height_range: (f64, f64),
    /// Height of the crown's lower edge (unit), drawn uniformly. Default 0.15–0.5.
    pub crown_base_range: (f64, f64),
    /// Horizontal semi-axis of the crown ellipsoid (unit), drawn uniformly.
    /// Default 0.3–0.5.
    pub crown_radius_range: (f64, f64),
    /// Largest horizontal offset of the crown centre from the trunk axis
    /// (unit). Default 0.1.
    pub crown_offset: f64,
    /// Number of attraction points scattered in the crown, drawn uniformly.
    /// Sparse crowns grow irregular trees, dense ones regular trees; the
    /// spread is what gives 100 distinct topologies per size. Default 15–300.
    pub attraction_points_range: (usize, usize),
    /// Segment length D = `segment_scale` / √N (unit), with `segment_scale`
    /// drawn uniformly: bigger trees get finer segments so that every size
    /// fills its crown. Default 0.45–0.75 (D ≈ 0.14–0.24 at N = 10).
    pub segment_scale_range: (f64, f64),
    /// Influence radius d_i as a multiple of D, drawn uniformly. Default 1.5–4.
    pub influence_radius_range: (f64, f64),
    /// Kill distance d_k as a multiple of D. Default 1.2.
    pub kill_distance: f64,
    /// A new node closer than this multiple of D to an existing node is not
    /// grown (unit-space spacing; the metric [`MIN_NODE_SPACING`] is checked
    /// after scaling). Default 0.6.
    pub min_spacing: f64,
    /// Probability that a pulled node grows in a given iteration (the most
    /// pulled one always grows when nothing else does). Below 1 the order in
    /// which branches grow varies, and with it the topology at the moment
    /// the tree reaches N nodes. Default 0.6.
    pub growth_probability: f64,
    /// Largest tilt of the trunk from vertical (degrees). Default 8.
    pub trunk_tilt_deg: f64,
    /// Radius of every leaf branch (m); the pipe model r_parent² = Σ r_child²
    /// gives the rest. Default 0.005 m, so a 15-leaf tree has a 1.9 cm trunk.
    pub tip_radius: f64,
    /// Material constants (E, K_d / K_s, density).
    pub wood: Wood,
    /// Growth attempts per seed before giving up. Default 200.
    pub max_attempts: usize,
}

impl Default for ScaParams {
    fn default() -> Self {
        Self {
            height_range: (0.6, 1.7),
            crown_base_range: (0.15, 0.5),
            crown_radius_range: (0.3, 0.5),
            crown_offset: 0.1,
            attraction_points_range: (15, 300),
            segment_scale_range: (0.45, 0.75),
            influence_radius_range: (1.5, 4.0),
            kill_distance: 1.2,
            min_spacing: 0.6,
            growth_probability: 0.6,
            trunk_tilt_deg: 8.0,
            tip_radius: 0.005,
            wood: Wood::default(),
            max_attempts: 200,
        }
    }
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ScaError {
    #[error("can only generate trees of {min} to {max} nodes, asked for {got}")]
    NodeCount { got: usize, min: usize, max: usize },
    #[error("invalid generator parameter: {0}")]
    Params(String),
    #[error("no valid {n}-node tree for seed {seed} after {attempts} attempts")]
    GaveUp {
        n: usize,
        seed: u64,
        attempts: usize,
    },
    #[error("generated tree is invalid: {0}")]
    Tree(#[from] TreeError),
}

impl ScaParams {
    fn validate(&self) -> Result<(), ScaError> {
        let bad = |what: &str| Err(ScaError::Params(what.to_owned()));
        let range_ok =
            |(lo, hi): (f64, f64)| lo.is_finite() && hi.is_finite() && 0.0 < lo && lo <= hi;
        if !range_ok(self.height_range) {
            return bad("height_range must be 0 < min <= max");
        }
        if !range_ok(self.crown_base_range) || self.crown_base_range.1 >= 1.0 {
            return bad("crown_base_range must be 0 < min <= max < 1");
        }
        if !range_ok(self.segment_scale_range) {
            return bad("segment_scale_range must be 0 < min <= max");
        }
        if !range_ok(self.crown_radius_range) {
            return bad("crown_radius_range must be 0 < min <= max");
        }
        let positive = [
            self.kill_distance,
            self.min_spacing,
            self.tip_radius,
            self.wood.young_modulus,
            self.wood.density,
        ];
        if positive.iter().any(|v| !(v.is_finite() && *v > 0.0)) {
            return bad("lengths, radii and material constants must be positive and finite");
        }
        let non_negative = |v: f64| v.is_finite() && v >= 0.0;
        if !non_negative(self.crown_offset) || !non_negative(self.wood.damping_ratio) {
            return bad("crown_offset and damping_ratio must be >= 0");
        }
        if !(0.0..90.0).contains(&self.trunk_tilt_deg) {
            return bad("trunk_tilt_deg must be in [0, 90)");
        }
        if !range_ok(self.influence_radius_range) {
            return bad("influence_radius_range must be 0 < min <= max");
        }
        if !(self.growth_probability > 0.0 && self.growth_probability <= 1.0) {
            return bad("growth_probability must be in (0, 1]");
        }
        if self.kill_distance >= self.influence_radius_range.0 {
            return bad("kill_distance must be smaller than the smallest influence radius");
        }
        let (lo, hi) = self.attraction_points_range;
        if lo == 0 || lo > hi || self.max_attempts == 0 {
            return bad("attraction_points_range must be 1 <= min <= max; max_attempts >= 1");
        }
        Ok(())
    }
}

/// The seed of tree `index` of size `n` in a collection generated from
/// `base_seed` (SplitMix64 over the three numbers), so any single tree can be
/// regenerated without the others.
pub fn tree_seed(base_seed: u64, n: usize, index: u64) -> u64 {
    crate::seed::derive_seed(base_seed, &[n as u64, index])
}

/// Every generator's size check: from [`MIN_GENERATED_NODES`] to its own
/// largest size.
pub(super) fn check_node_count(n: usize, max: usize) -> Result<(), ScaError> {
    if (MIN_GENERATED_NODES..=max).contains(&n) {
        Ok(())
    } else {
        Err(ScaError::NodeCount {
            got: n,
            min: MIN_GENERATED_NODES,
            max,
        })
    }
}

/// Grows a tree of exactly `n` nodes from `seed`.
pub fn generate(n: usize, seed: u64, params: &ScaParams) -> Result<Tree, ScaError> {
    check_node_count(n, MAX_SCA_NODES)?;
    params.validate()?;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    for _ in 0..params.max_attempts {
        if let Some(skeleton) = grow_skeleton(n, params, &mut rng)
            && let Some(tree) = finish(skeleton, params, &mut rng)?
        {
            return Ok(tree);
        }
    }
    Err(ScaError::GaveUp {
        n,
        seed,
        attempts: params.max_attempts,
    })
}

/// Node positions (unit space) and parents; parents always precede children.
struct Skeleton {
    positions: Vec<Point3<f64>>,
    parents: Vec<Option<usize>>,
}

fn grow_skeleton(n: usize, p: &ScaParams, rng: &mut ChaCha8Rng) -> Option<Skeleton> {
    let segment_scale = rng.random_range(p.segment_scale_range.0..=p.segment_scale_range.1);
    let seg = segment_scale / (n as f64).sqrt();
    let influence = rng.random_range(p.influence_radius_range.0..=p.influence_radius_range.1);
    let influence2 = (influence * seg).powi(2);
    let kill2 = (p.kill_distance * seg).powi(2);
    let spacing2 = (p.min_spacing * seg).powi(2);

    let crown_base = rng.random_range(p.crown_base_range.0..=p.crown_base_range.1);
    let crown_radius = rng.random_range(p.crown_radius_range.0..=p.crown_radius_range.1);
    let half_height = (1.0 - crown_base) / 2.0;
    let offset_angle = rng.random_range(0.0..std::f64::consts::TAU);
    let offset = p.crown_offset * rng.random::<f64>().sqrt();
    let centre = Point3::new(
        offset * offset_angle.cos(),
        offset * offset_angle.sin(),
        crown_base + half_height,
    );
    let point_count = rng.random_range(p.attraction_points_range.0..=p.attraction_points_range.1);
    let mut points: Vec<Point3<f64>> = (0..point_count)
        .map(|_| sample_ellipsoid(rng, centre, crown_radius, half_height))
        .collect();

    let tilt = rng.random_range(0.0..=p.trunk_tilt_deg).to_radians();
    let azimuth = rng.random_range(0.0..std::f64::consts::TAU);
    let trunk_dir = Vector3::new(
        tilt.sin() * azimuth.cos(),
        tilt.sin() * azimuth.sin(),
        tilt.cos(),
    );

    let mut positions = vec![Point3::origin()];
    let mut parents = vec![None];
    // Bounded: every productive iteration adds a node; a barren one ends growth.
    while positions.len() < n {
        let (sums, counts) = attract(&points, &positions, influence2);
        if counts.iter().all(|&c| c == 0) {
            // Trunk phase: nothing in reach yet, keep growing the newest node up.
            let last = positions.len() - 1;
            if positions[last].z > 1.5 {
                return None; // the crown is unreachable: give up this attempt
            }
            positions.push(positions[last] + trunk_dir * seg);
            parents.push(Some(last));
        } else {
            let mut candidates: Vec<(usize, usize, Point3<f64>)> = Vec::new();
            for (node, (&sum, &count)) in sums.iter().zip(&counts).enumerate() {
                if count == 0 || sum.norm() < 1e-9 {
                    continue;
                }
                candidates.push((count, node, positions[node] + sum.normalize() * seg));
            }
            // Most-pulled first; ties by node index, so the order is total.
            let mut deferred = None;
            candidates.sort_by(|a, b| b.0.cmp(&a.0).then(a.1.cmp(&b.1)));
            let before = positions.len();
            let mut grown_any = false;
            for (_, node, candidate) in candidates {
                if positions.len() == n {
                    break;
                }
                if positions
                    .iter()
                    .any(|q| (q - candidate).norm_squared() < spacing2)
                {
                    continue;
                }
                // Each pulled node grows with probability q; the most-pulled
                // valid one always does, so every iteration makes progress.
                let grows = rng.random::<f64>() < p.growth_probability;
                if grows {
                    positions.push(candidate);
                    parents.push(Some(node));
                    grown_any = true;
                } else if !grown_any {
                    deferred.get_or_insert((node, candidate));
                }
            }
            if !grown_any && let Some((node, candidate)) = deferred.take() {
                positions.push(candidate);
                parents.push(Some(node));
            }
            if positions.len() == before {
                return None; // stalled: every pull lands on an existing node
            }
        }
        points.retain(|a| positions.iter().all(|q| (a - q).norm_squared() >= kill2));
        if points.is_empty() && positions.len() < n {
            return None;
        }
    }
    Some(Skeleton { positions, parents })
}

/// For every node: the sum of unit vectors towards the points whose nearest
/// node (within the influence radius) it is, and how many such points.
fn attract(
    points: &[Point3<f64>],
    nodes: &[Point3<f64>],
    influence2: f64,
) -> (Vec<Vector3<f64>>, Vec<usize>) {
    let mut sums = vec![Vector3::zeros(); nodes.len()];
    let mut counts = vec![0usize; nodes.len()];
    for a in points {
        let mut best = None;
        let mut best_d2 = influence2;
        for (j, q) in nodes.iter().enumerate() {
            let d2 = (a - q).norm_squared();
            if d2 < best_d2 {
                best_d2 = d2;
                best = Some(j);
            }
        }
        if let Some(j) = best {
            sums[j] += (a - nodes[j]) / best_d2.sqrt();
            counts[j] += 1;
        }
    }
    (sums, counts)
}

fn sample_ellipsoid(
    rng: &mut ChaCha8Rng,
    centre: Point3<f64>,
    radius: f64,
    half_height: f64,
) -> Point3<f64> {
    loop {
        let v = Vector3::new(
            rng.random_range(-1.0..=1.0),
            rng.random_range(-1.0..=1.0),
            rng.random_range(-1.0..=1.0),
        );
        if v.norm_squared() <= 1.0 {
            return centre + Vector3::new(v.x * radius, v.y * radius, v.z * half_height);
        }
    }
}

/// Scales the skeleton to its drawn height, adds pipe-model radii and
/// material parameters, and checks the result. `None` when this skeleton
/// does not make an acceptable tree (no branching, nodes too close).
fn finish(
    skeleton: Skeleton,
    p: &ScaParams,
    rng: &mut ChaCha8Rng,
) -> Result<Option<Tree>, ScaError> {
    let Skeleton { positions, parents } = skeleton;
    let n = positions.len();
    let mut child_count = vec![0usize; n];
    for parent in parents.iter().flatten() {
        child_count[*parent] += 1;
    }
    if !child_count.iter().any(|&c| c >= 2) {
        return Ok(None);
    }
    let unit_height = positions.iter().map(|q| q.z).fold(0.0, f64::max);
    let height = rng.random_range(p.height_range.0..=p.height_range.1);
    if unit_height <= 0.0 {
        return Ok(None);
    }
    let scale = height / unit_height;
    let positions: Vec<Point3<f64>> = positions.iter().map(|q| q * scale).collect();

    // Pipe model, leaves to root: parents precede children, so a reverse
    // index sweep sees every child before its parent.
    let mut radius2 = vec![0.0; n];
    for j in (1..n).rev() {
        if child_count[j] == 0 {
            radius2[j] = p.tip_radius * p.tip_radius;
        }
        if let Some(parent) = parents[j] {
            radius2[parent] += radius2[j];
        }
    }
    let branches = (0..n)
        .map(|j| {
            parents[j].map(|parent| {
                let length = (positions[j] - positions[parent]).norm();
                p.wood.branch(radius2[j].sqrt(), length)
            })
        })
        .collect();
    let tree = Tree::new(positions, parents, branches)?;
    if tree.min_node_spacing() < MIN_NODE_SPACING {
        return Ok(None);
    }
    Ok(Some(tree))
}
