//! Orchard-shaped trees of any size up to [`MAX_NODES`]: a central leader
//! with scaffolds and laterals, at the paper's node spacing.
//!
//! Space Colonization ([`super::sca`]) grows the paper's trees; it fills a
//! crown by making segments *shorter* as N grows (D ∝ 1/√N), so a 500-node
//! SCA tree is a 1.7 m bush with 2 cm branches. A grower's tree is the
//! other way round: its joints stay roughly a hand apart and it grows by
//! adding wood. This generator keeps the segment length at the paper's
//! spacing (drawn from [`OrchardParams::segment_range`], 8-13 cm: the SCA
//! trees' median branch length at N = 10-30) and adds structure in the
//! order a trained tree has it:
//!
//! 1. the **leader**, a near-vertical trunk of `leader_height` m;
//! 2. **scaffolds**: 2-6 primary limbs from the lower leader, spread round
//!    it by the golden angle (137.5°), leaving it 40-70° from vertical and
//!    curving upwards, 0.6-1.8 m long;
//! 3. **laterals** on the leader and the scaffolds, alternating sides, 45-80°
//!    from their parent limb, 0.2-0.7 m; when every slot is taken,
//!    **spurs** (1-3 segments) on the laterals.
//!
//! Branches are added until the tree has exactly N nodes (the last one cut
//! short). The leader and scaffold lengths grow with N up to their maxima,
//! so a 40-node tree is a small leader with two or three short scaffolds
//! and a 500-node tree a 3 m leader with six scaffolds and dozens of
//! laterals. Radii follow the pipe model as in [`super::sca`]: every tip
//! has `tip_radius`, and a parent's r² is the sum of its children's.

use nalgebra::{Point3, Rotation3, Unit, Vector3};
use rand::{Rng, RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use super::model::{MAX_NODES, Tree};
use super::sca::{MIN_NODE_SPACING, ScaError, check_node_count};
use super::wood::Wood;

/// Generator parameters (SI).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OrchardParams {
    /// Segment length (m), drawn once per tree, each segment within ±15 %.
    pub segment_range: (f64, f64),
    /// Leader height (m) at N = 500 and beyond; smaller trees get a
    /// shorter leader, in proportion to √N, never below 0.6 m.
    pub leader_height_range: (f64, f64),
    /// Scaffold length (m) of a full-sized tree, scaled like the leader.
    pub scaffold_length_range: (f64, f64),
    /// Lateral length (m).
    pub lateral_length_range: (f64, f64),
    /// Radius of every tip (m).
    pub tip_radius: f64,
    pub wood: Wood,
}

impl Default for OrchardParams {
    fn default() -> Self {
        Self {
            segment_range: (0.08, 0.13),
            leader_height_range: (2.4, 3.4),
            scaffold_length_range: (1.0, 1.8),
            lateral_length_range: (0.2, 0.7),
            tip_radius: 0.005,
            wood: Wood::default(),
        }
    }
}

/// Where a branch starts and how it grows.
struct Limb {
    parent: usize,
    direction: Vector3<f64>,
    segments: usize,
    /// Pull towards vertical per segment (0: straight).
    upturn: f64,
}

struct Growth {
    positions: Vec<Point3<f64>>,
    parents: Vec<Option<usize>>,
    /// Direction of the branch ending at each node.
    directions: Vec<Vector3<f64>>,
    /// 0 leader, 1 scaffold, 2 lateral, 3 spur.
    order: Vec<u8>,
    children: Vec<usize>,
    segment: f64,
    n: usize,
}

impl Growth {
    fn full(&self) -> bool {
        self.positions.len() >= self.n
    }

    /// Grows one limb; returns the nodes added (it may stop early when the
    /// tree is full or a node would come too close to another).
    fn grow(&mut self, limb: &Limb, order: u8, rng: &mut ChaCha8Rng) -> Vec<usize> {
        let mut added = Vec::new();
        let mut at = limb.parent;
        let mut direction = limb.direction.normalize();
        for _ in 0..limb.segments {
            if self.full() {
                break;
            }
            let wobble = Vector3::new(
                rng.random_range(-1.0..=1.0),
                rng.random_range(-1.0..=1.0),
                rng.random_range(-1.0..=1.0),
            ) * 0.12;
            direction = (direction + Vector3::z() * limb.upturn + wobble).normalize();
            let length = self.segment * rng.random_range(0.85..=1.15);
            let p = self.positions[at] + direction * length;
            let crowded = self
                .positions
                .iter()
                .any(|q| (q - p).norm() < 0.6 * self.segment);
            if crowded || p.z < 0.1 {
                break;
            }
            self.positions.push(p);
            self.parents.push(Some(at));
            self.directions.push(direction);
            self.order.push(order);
            self.children.push(0);
            self.children[at] += 1;
            at = self.positions.len() - 1;
            added.push(at);
        }
        added
    }
}

/// A direction `angle` (rad) away from `axis`, turned `azimuth` (rad) about it.
fn off_axis(axis: &Vector3<f64>, angle: f64, azimuth: f64) -> Vector3<f64> {
    let axis = axis.normalize();
    let helper = if axis.z.abs() < 0.9 {
        Vector3::z()
    } else {
        Vector3::x()
    };
    let side = Unit::new_normalize(axis.cross(&helper));
    let tilted = Rotation3::from_axis_angle(&side, angle) * axis;
    Rotation3::from_axis_angle(&Unit::new_normalize(axis), azimuth) * tilted
}

/// Grows an orchard tree of exactly `n` nodes from `seed`.
pub fn generate_orchard(n: usize, seed: u64, p: &OrchardParams) -> Result<Tree, ScaError> {
    check_node_count(n, MAX_NODES)?;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    for _ in 0..50 {
        if let Some(tree) = attempt(n, p, &mut rng) {
            return Ok(tree);
        }
    }
    Err(ScaError::GaveUp {
        n,
        seed,
        attempts: 50,
    })
}

fn attempt(n: usize, p: &OrchardParams, rng: &mut ChaCha8Rng) -> Option<Tree> {
    let segment = rng.random_range(p.segment_range.0..=p.segment_range.1);
    // Sizes grow like √N up to a full tree at N = 500.
    let size = ((n as f64) / 500.0).sqrt().min(1.0);
    let leader_height =
        (rng.random_range(p.leader_height_range.0..=p.leader_height_range.1) * size).max(0.6);
    let mut g = Growth {
        positions: vec![Point3::origin()],
        parents: vec![None],
        directions: vec![Vector3::z()],
        order: vec![0],
        children: vec![0],
        segment,
        n,
    };
    let tilt = rng.random_range(0.0..0.08f64);
    let leader = g.grow(
        &Limb {
            parent: 0,
            direction: off_axis(
                &Vector3::z(),
                tilt,
                rng.random_range(0.0..std::f64::consts::TAU),
            ),
            segments: ((leader_height / segment).round() as usize).max(3),
            upturn: 0.05,
        },
        0,
        rng,
    );
    if leader.len() < 3 {
        return None;
    }
    // Scaffolds from the lower part of the leader, round it by the golden angle.
    let scaffolds = (2 + n / 90).min(6);
    let low = ((0.3 / segment).round() as usize).clamp(1, leader.len() - 1);
    let high = (leader.len() * 2 / 5).max(low + 1).min(leader.len() - 1);
    let mut azimuth = rng.random_range(0.0..std::f64::consts::TAU);
    let mut limbs: Vec<Vec<usize>> = vec![leader.clone()];
    for s in 0..scaffolds {
        if g.full() {
            break;
        }
        let at = leader[low + (s * (high - low)) / scaffolds.max(1)];
        let angle = rng.random_range(40f64..70.0).to_radians();
        let length = (rng.random_range(p.scaffold_length_range.0..=p.scaffold_length_range.1)
            * size)
            .max(2.0 * segment);
        let added = g.grow(
            &Limb {
                parent: at,
                direction: off_axis(&Vector3::z(), angle, azimuth),
                segments: (length / segment).round().max(1.0) as usize,
                upturn: 0.06,
            },
            1,
            rng,
        );
        azimuth += 137.5f64.to_radians();
        if !added.is_empty() {
            limbs.push(added);
        }
    }
    // Laterals on the leader and the scaffolds, then spurs on the laterals.
    grow_side_branches(&mut g, &limbs, 2, p.lateral_length_range, rng);
    let laterals: Vec<Vec<usize>> = (0..g.positions.len())
        .filter(|&j| g.order[j] == 2)
        .map(|j| vec![j])
        .collect();
    grow_side_branches(&mut g, &laterals, 3, (segment, 3.0 * segment), rng);
    if !g.full() {
        return None;
    }
    finish(g, p)
}

/// Adds branches of `order` at free nodes of `limbs` (every other node,
/// alternating sides) until the tree is full or no slot is left.
fn grow_side_branches(
    g: &mut Growth,
    limbs: &[Vec<usize>],
    order: u8,
    length: (f64, f64),
    rng: &mut ChaCha8Rng,
) {
    let mut slots: Vec<usize> = limbs
        .iter()
        .flat_map(|limb| limb.iter().copied())
        .filter(|&j| g.children[j] <= 1 && j != 0)
        .collect();
    shuffle(&mut slots, rng);
    for at in slots {
        if g.full() {
            return;
        }
        if g.children[at] > 1 || g.parents[at].is_some_and(|q| g.children[q] > 1 && q != 0) {
            continue;
        }
        let axis = g.directions[at];
        let angle = rng.random_range(45f64..80.0).to_radians();
        let direction = off_axis(&axis, angle, rng.random_range(0.0..std::f64::consts::TAU));
        let l = rng.random_range(length.0..=length.1);
        g.grow(
            &Limb {
                parent: at,
                direction,
                segments: (l / g.segment).round().max(1.0) as usize,
                upturn: 0.03,
            },
            order,
            rng,
        );
    }
}

fn shuffle<T, R: Rng + ?Sized>(v: &mut [T], rng: &mut R) {
    for i in (1..v.len()).rev() {
        let j = rng.random_range(0..=i);
        v.swap(i, j);
    }
}

/// Pipe-model radii and the validated tree.
fn finish(g: Growth, p: &OrchardParams) -> Option<Tree> {
    let n = g.positions.len();
    let mut radius2 = vec![0.0; n];
    for j in (1..n).rev() {
        if g.children[j] == 0 {
            radius2[j] = p.tip_radius * p.tip_radius;
        }
        if let Some(parent) = g.parents[j] {
            radius2[parent] += radius2[j];
        }
    }
    let branches = (0..n)
        .map(|j| {
            g.parents[j].map(|parent| {
                let length = (g.positions[j] - g.positions[parent]).norm();
                p.wood.branch(radius2[j].sqrt(), length)
            })
        })
        .collect();
    let tree = Tree::new(g.positions, g.parents, branches).ok()?;
    (tree.min_node_spacing() >= MIN_NODE_SPACING).then_some(tree)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_are_exact_and_spacing_is_the_papers() {
        for n in [10, 40, 200, 500] {
            let tree = generate_orchard(n, 7, &OrchardParams::default()).unwrap();
            assert_eq!(tree.len(), n);
            let mut lengths: Vec<f64> = tree.branches_iter().map(|(_, b)| b.length).collect();
            lengths.sort_by(f64::total_cmp);
            let median = lengths[lengths.len() / 2];
            assert!((0.065..=0.15).contains(&median), "N = {n}: median {median}");
        }
    }

    #[test]
    fn large_trees_have_scaffolds_and_laterals() {
        let tree = generate_orchard(500, 3, &OrchardParams::default()).unwrap();
        let forks = (0..tree.len())
            .filter(|&j| tree.children(j).len() >= 2)
            .count();
        let tips = (0..tree.len()).filter(|&j| tree.is_leaf(j)).count();
        assert!(forks >= 40, "{forks} forks");
        assert!(tips >= 40, "{tips} tips");
        assert!(tree.height() > 1.8, "height {}", tree.height());
        let depth = (0..tree.len()).map(|j| tree.depth(j)).max().unwrap();
        assert!((15..=60).contains(&depth), "depth {depth}");
    }

    #[test]
    fn seeds_reproduce() {
        let p = OrchardParams::default();
        assert_eq!(
            generate_orchard(120, 11, &p).unwrap(),
            generate_orchard(120, 11, &p).unwrap()
        );
        assert_ne!(
            generate_orchard(120, 11, &p).unwrap(),
            generate_orchard(120, 12, &p).unwrap()
        );
    }
}
