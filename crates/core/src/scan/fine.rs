//! The fine skeleton: one node per cross-section piece, pruned of stubs,
//! placed on the fitted branch axis, with radii smoothed along each branch
//! and borrowed from the parent where a branch was seen from one side.

use nalgebra::{Point3, Vector3};

use crate::scan::base::base_arcs;
use crate::scan::forks::relocate_forks;
use crate::scan::levels::{Geodesic, Piece, cross_section, pieces, pulled_to_centroid};
use crate::scan::silhouette::from_silhouette;
use crate::scan::skeleton::Skeleton;
use crate::scan::viewpoint::{
    Sensor, Sighting, move_off_near_side, near_side_shift, one_sided_viewpoint,
};
use crate::scan::voxel::Voxels;

/// The input points and the cubes that average them.
#[derive(Clone, Copy)]
pub struct RawPoints<'a> {
    pub points: &'a [Point3<f64>],
    pub voxels: &'a Voxels,
}

/// The fine skeleton and what was learnt making it.
pub struct FineSkeleton {
    pub skeleton: Skeleton,
    pub confidence: Vec<f64>,
    /// Raw points in the kept pieces.
    pub points_used: usize,
    /// Warnings for the caller.
    pub notes: Vec<String>,
    /// Where the sensor stood, when the cloud was seen from one side.
    pub seen_from: Option<Point3<f64>>,
}

/// A fitted cross-section counts when its points span at least this angle
/// (rad): about a quarter turn.
const MIN_COVERAGE: f64 = 1.6;
/// Full confidence from this coverage (rad, two thirds of a turn).
const FULL_COVERAGE: f64 = 4.2;
/// Raw points a piece needs for full confidence.
const FULL_SUPPORT: f64 = 30.0;

/// A stub (a tip run from its fork) shorter than this many level sets is
/// a leaf, a fruit or noise beside a branch, and goes. Measured from where
/// the level sets part it from its parent, which for a twig leaving at a
/// sharp angle is centimetres past its fork: on sylva-rs's conifers 13-15 %
/// of the twigs are under 6.3 cm from their fork, and the 0.35 × spacing
/// this once also took pruned them (three-view recall 0.893 -> 0.911 on
/// its trees, seeds 1-3, with the parent's axis run through forks; our
/// train split's clouds unchanged or slightly better).
const STUB_LEVELS: f64 = 3.0;

/// The fine skeleton of the level sets `bin` (m) wide; `up` is the unit
/// up, `sensor` what the returns may be assumed to be ([`Sensor`]).
/// `raw` are the points the cubes average, what a laser's silhouettes are
/// measured on (a cube's mean lies inside the edge it straddles).
pub fn fine_skeleton(
    g: &Geodesic,
    bin: f64,
    up: &Vector3<f64>,
    sensor: Sensor,
    raw: RawPoints,
) -> FineSkeleton {
    let points = g.points;
    let all = pieces(g, bin);
    let prune_length = STUB_LEVELS * bin;
    let mut notes = Vec::new();
    let (pieces, pruned) = prune(all, prune_length);
    if pruned > 0 {
        notes.push(format!(
            "{pruned} stubs shorter than {:.1} cm were pruned (leaves, fruit or noise beside a branch)",
            prune_length * 100.0
        ));
    }
    let n = pieces.len();
    let mut children = vec![Vec::new(); n];
    for (k, p) in pieces.iter().enumerate() {
        if let Some(q) = p.parent {
            children[q].push(k);
        }
    }
    // Axis of each piece: from its parent toward its children.
    let axes: Vec<Vector3<f64>> = (0..n)
        .map(|k| {
            let from = pieces[k]
                .parent
                .map_or(pieces[k].centroid, |q| pieces[q].centroid);
            let to = if children[k].is_empty() {
                pieces[k].centroid
            } else {
                Point3::from(
                    children[k]
                        .iter()
                        .map(|&c| pieces[c].centroid.coords)
                        .sum::<Vector3<f64>>()
                        / children[k].len() as f64,
                )
            };
            let a = to - from;
            if a.norm() > 1e-9 { a.normalize() } else { *up }
        })
        .collect();
    let mut positions = Vec::with_capacity(n);
    let mut fitted: Vec<Option<f64>> = Vec::with_capacity(n);
    let mut confidence = Vec::with_capacity(n);
    let mut sightings = Vec::new();
    // Each piece's circle's residual over its radius (infinite: no circle).
    let mut misfit = Vec::with_capacity(n);
    for (k, piece) in pieces.iter().enumerate() {
        let support = (piece.weight as f64 / FULL_SUPPORT).min(1.0);
        let fit = cross_section(points, &piece.members, &piece.centroid, &axes[k]).filter(
            |(centre, c)| {
                piece.members.len() >= 6
                    && c.coverage >= MIN_COVERAGE
                    && c.radius >= 0.0005
                    && c.radius <= piece.spread + 0.002
                    && c.rms <= (0.5 * c.radius).max(0.003)
                    && (centre - piece.centroid).norm() <= c.radius + 0.003
            },
        );
        let fit = fit.map(|(mut centre, c)| {
            if k == 0 {
                // The root sits on the ground: at the bottom of its piece.
                let low = piece
                    .members
                    .iter()
                    .map(|&i| points[i].coords.dot(up))
                    .fold(f64::INFINITY, f64::min);
                centre += up * (low - centre.coords.dot(up));
            }
            (centre, c)
        });
        match fit {
            Some((centre, c)) => {
                positions.push(centre);
                fitted.push(Some(c.debiased_radius()));
                misfit.push(c.rms / c.radius.max(1e-4));
                if k != 0 {
                    let off = piece.centroid - centre;
                    sightings.push(Sighting {
                        centre,
                        axis: axes[k],
                        offset: off - axes[k] * off.dot(&axes[k]),
                        radius: c.radius,
                    });
                }
                confidence.push(support * (c.coverage / FULL_COVERAGE).min(1.0));
            }
            None => {
                positions.push(piece.centroid);
                fitted.push(None);
                misfit.push(f64::INFINITY);
                confidence.push(0.3 * support);
            }
        }
    }
    let seen_from = one_sided_viewpoint(&sightings);
    if let (Sensor::Laser { beam_radius }, Some(view)) = (sensor, seen_from) {
        // Where a circle was fitted: its centre lies behind the axis and
        // its radius is too large by the beam's spread. Elsewhere the
        // points did not show a branch's cross-section clearly enough to
        // trust its silhouette (on sylva-rs's scans, seeds 1-3, taking
        // those too gained 0.006 recall and lost 0.013 precision).
        let cubes = raw.voxels.members();
        for k in 1..n {
            let Some(circle_radius) = fitted[k] else {
                continue;
            };
            let members: Vec<Point3<f64>> = pieces[k]
                .members
                .iter()
                .flat_map(|&c| cubes.of(c))
                .map(|&i| raw.points[i])
                .collect();
            if let Some((centre, radius)) =
                from_silhouette(&members, &positions[k], &axes[k], &view, beam_radius)
            {
                positions[k] = centre;
                // Never wider than the circle (a fork's two branches in
                // one piece have one wide silhouette).
                fitted[k] = Some(radius.min(circle_radius));
            }
        }
    }
    if seen_from.is_none() {
        // Seen from all sides (the root keeps its place on the ground).
        for k in 1..n {
            positions[k] = pulled_to_centroid(&positions[k], &pieces[k].centroid, misfit[k]);
        }
    }
    let parents: Vec<Option<usize>> = pieces.iter().map(|p| p.parent).collect();
    let mut skeleton = Skeleton {
        positions,
        parents,
        radius: vec![0.0; n],
    };
    let mut keep = relocate_forks(&mut skeleton);
    if let Some(root_radius) = fitted[0] {
        base_arcs(&skeleton, root_radius, up, &mut keep);
    }
    let (skeleton_kept, kept) = compact(&skeleton, &keep);
    skeleton = skeleton_kept;
    let fitted: Vec<Option<f64>> = kept.iter().map(|&k| fitted[k]).collect();
    let confidence: Vec<f64> = kept.iter().map(|&k| confidence[k]).collect();
    let borrowed = smooth_radii(&mut skeleton, &fitted);
    if borrowed > 0 {
        notes.push(format!(
            "{borrowed} of {n} cross-sections were seen from too narrow an angle to fit a radius; their radius comes from the branch around them or its parent"
        ));
    }
    if let Some(view) = seen_from {
        notes.push(format!(
            "the cloud was seen from one side, from the direction of ({:.2}, {:.2}, {:.2}) m (the distance is rough): the far side of every branch is unseen, and radii and axes come from the arcs facing the sensor{}",
            view.x, view.y, view.z,
            match sensor {
                Sensor::Camera =>
                    "; as `sensor` is `camera`, the axes were moved back from the near surface",
                Sensor::Laser { .. } =>
                    "; as `sensor` is `laser`, radii and axes come from the branches' silhouettes less the beam's spread",
                Sensor::Unknown => "",
            }
        ));
        if sensor == Sensor::Camera {
            let shift: Vec<f64> = kept.iter().map(|&k| near_side_shift(misfit[k])).collect();
            move_off_near_side(&mut skeleton, &view, &shift, up);
        }
    }
    FineSkeleton {
        points_used: kept.iter().map(|&k| pieces[k].weight).sum(),
        skeleton,
        confidence,
        notes,
        seen_from,
    }
}

fn median(values: &mut [f64]) -> Option<f64> {
    values.sort_by(f64::total_cmp);
    values.get(values.len() / 2).copied()
}

/// A side branch shorter than this (m) that is wider than its parent is a
/// leaf (an apple leaf is 5-10 cm long).
const LEAF_LENGTH: f64 = 0.12;
/// "Wider": this many times the parent's piece spread ...
const LEAF_WIDTH_RATIO: f64 = 1.5;
/// ... plus this (m), for noise.
const LEAF_WIDTH_SLACK: f64 = 0.003;

/// The nodes `keep` marks, renumbered, and the old index of each.
fn compact(skeleton: &Skeleton, keep: &[bool]) -> (Skeleton, Vec<usize>) {
    let kept: Vec<usize> = (0..skeleton.len()).filter(|&k| keep[k]).collect();
    let mut new_id = vec![usize::MAX; skeleton.len()];
    for (i, &k) in kept.iter().enumerate() {
        new_id[k] = i;
    }
    let out = Skeleton {
        positions: kept.iter().map(|&k| skeleton.positions[k]).collect(),
        parents: kept
            .iter()
            .map(|&k| skeleton.parents[k].map(|p| new_id[p]))
            .collect(),
        radius: kept.iter().map(|&k| skeleton.radius[k]).collect(),
    };
    (out, kept)
}

/// A run from a fork to a tip: its length (m) and its pieces.
type Run = (f64, Vec<usize>);

/// Removes side branches shorter than `length` that end in a tip (when a
/// fork's every arm is that short, the longest stays), until none is
/// left. Returns the kept pieces (renumbered, parents first) and how many
/// stubs went.
fn prune(mut pieces: Vec<Piece>, length: f64) -> (Vec<Piece>, usize) {
    let mut removed_stubs = 0;
    loop {
        let n = pieces.len();
        let mut children = vec![Vec::new(); n];
        for (k, p) in pieces.iter().enumerate() {
            if let Some(q) = p.parent {
                children[q].push(k);
            }
        }
        // Length of the single-child run from each fork child to its tip
        // (None when it forks again).
        let run = |start: usize| -> Option<Run> {
            let mut nodes = vec![start];
            let mut at = start;
            let mut len = (pieces[start].centroid
                - pieces[pieces[start].parent.unwrap_or(start)].centroid)
                .norm();
            while children[at].len() == 1 {
                let next = children[at][0];
                len += (pieces[next].centroid - pieces[at].centroid).norm();
                nodes.push(next);
                at = next;
            }
            children[at].is_empty().then_some((len, nodes))
        };
        let mut remove = vec![false; n];
        let mut any = false;
        for (fork, arms) in children.iter().enumerate() {
            if arms.len() < 2 {
                continue;
            }
            let runs: Vec<(usize, Option<Run>)> = arms.iter().map(|&c| (c, run(c))).collect();
            let longest_arm = runs
                .iter()
                .map(|(_, r)| r.as_ref().map_or(f64::INFINITY, |r| r.0))
                .fold(0.0, f64::max);
            let mut kept_one = longest_arm >= length;
            // How wide the branch is below the fork.
            let mut below = Vec::new();
            let mut at = fork;
            while let Some(p) = pieces[at].parent {
                below.push(pieces[p].spread);
                if below.len() == 3 {
                    break;
                }
                at = p;
            }
            let parent_width = median(&mut below).unwrap_or(f64::INFINITY);
            // A stub is too short to be a twig, or short and wider than
            // the branch it would grow from (a leaf: a twig is never wider
            // than its parent).
            let leafy = |r: &Run| {
                let mut widths: Vec<f64> = r.1.iter().map(|&k| pieces[k].spread).collect();
                r.0 < LEAF_LENGTH
                    && median(&mut widths)
                        .is_some_and(|w| w > LEAF_WIDTH_RATIO * parent_width + LEAF_WIDTH_SLACK)
            };
            // Shortest stubs go first; the longest of an all-stub fork stays.
            let mut stubs: Vec<&Run> = runs
                .iter()
                .filter_map(|(_, r)| r.as_ref())
                .filter(|r| r.0 < length || leafy(r))
                .collect();
            stubs.sort_by(|a, b| b.0.total_cmp(&a.0));
            for stub in stubs {
                if !kept_one {
                    kept_one = true;
                    continue;
                }
                for &k in &stub.1 {
                    remove[k] = true;
                }
                removed_stubs += 1;
                any = true;
            }
        }
        if !any {
            return (pieces, removed_stubs);
        }
        let mut new_id = vec![usize::MAX; n];
        let mut next = 0;
        for k in 0..n {
            if !remove[k] {
                new_id[k] = next;
                next += 1;
            }
        }
        pieces = pieces
            .into_iter()
            .enumerate()
            .filter(|(k, _)| !remove[*k])
            .map(|(_, mut p)| {
                p.parent = p.parent.map(|q| new_id[q]);
                p
            })
            .collect();
    }
}

/// Radius (m) of a node nothing gives one: no fit on its branch and no
/// parent branch to borrow from.
const UNSEEN_RADIUS: f64 = 0.005;

/// A branch caps its children's radii only when at least this many of its
/// cross-sections were fitted.
const CAP_FITS: usize = 3;

/// Each branch's radii: the median of the fitted radii within two pieces
/// either side; where none was fitted, the branch's median, else the
/// parent branch's radius where it starts. A branch is never thicker than
/// the one it grows from, except the branches from the root: the root is
/// where the trunk meets the ground, and its piece is often one arc of the
/// trunk's bottom ring (an occluded or uneven base parts the ring into
/// arcs), whose small radius would cap the whole tree. Returns how many
/// radii were not fitted.
fn smooth_radii(skeleton: &mut Skeleton, fitted: &[Option<f64>]) -> usize {
    let (chains, _) = skeleton.chains();
    let n = skeleton.len();
    let mut radius = vec![f64::NAN; n];
    // The root's radius: its own fit or its first chain's.
    let mut borrowed = 0;
    // Each chain's fitted cross-sections.
    let fits: Vec<usize> = chains
        .iter()
        .map(|c| {
            c.nodes[1..]
                .iter()
                .filter(|&&k| fitted[k].is_some())
                .count()
        })
        .collect();
    // The cap each chain was given, for its children to inherit.
    let mut cap_of: Vec<Option<f64>> = vec![None; chains.len()];
    for (c, chain) in chains.iter().enumerate() {
        let nodes = &chain.nodes[1..];
        // The parent branch's radius where the chain starts: none for a
        // branch from the root (see above) or a parent not yet given one.
        // A parent of fewer than CAP_FITS fitted cross-sections does not
        // cap a child better seen than itself (the child inherits the
        // parent's own cap): a few arcs of a thick trunk's base, parted by
        // shadows, capped the whole trunk at an arc's radius (sylva-rs's
        // one-view conifer, 55 mm -> 6 mm).
        let start_radius = match chain.parent {
            Some(pc) if fits[pc] < CAP_FITS && fits[c] > fits[pc] => cap_of[pc],
            _ => Some(chain.nodes[0])
                .filter(|&s| s != 0)
                .map(|s| radius[s])
                .filter(|r| !r.is_nan()),
        };
        cap_of[c] = start_radius;
        let values: Vec<Option<f64>> = nodes.iter().map(|&k| fitted[k]).collect();
        let mut known: Vec<f64> = values.iter().flatten().copied().collect();
        known.sort_by(f64::total_cmp);
        let chain_median = known.get(known.len() / 2).copied();
        for (x, &k) in nodes.iter().enumerate() {
            let lo = x.saturating_sub(2);
            let hi = (x + 3).min(nodes.len());
            let mut window: Vec<f64> = values[lo..hi].iter().flatten().copied().collect();
            window.sort_by(f64::total_cmp);
            let r = match window.get(window.len() / 2) {
                Some(&r) => r,
                None => {
                    borrowed += 1;
                    chain_median.or(start_radius).unwrap_or(UNSEEN_RADIUS)
                }
            };
            radius[k] = start_radius.map_or(r, |s| r.min(s));
        }
        if chain.nodes[0] == 0 && radius[0].is_nan() {
            radius[0] = fitted[0].unwrap_or(radius[nodes[0]]);
        }
    }
    if radius[0].is_nan() {
        radius[0] = fitted[0].unwrap_or(UNSEEN_RADIUS);
    }
    for r in &mut radius {
        if r.is_nan() {
            *r = UNSEEN_RADIUS;
        }
    }
    skeleton.radius = radius;
    borrowed
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A root with a short stub (an arc of the trunk's bottom ring, radius
    /// 8 mm) and the trunk (50 mm), the stub listed `stub_first` or last,
    /// and a twig forking from the trunk whose fit (60 mm) is thicker than
    /// the trunk.
    fn rooted(stub_first: bool) -> (Skeleton, Vec<Option<f64>>, [usize; 2]) {
        let z = |h: f64| Point3::new(0.0, 0.0, h);
        let (stub, trunk) = if stub_first { (1, 3) } else { (5, 1) };
        let mut positions = vec![Point3::origin(); 8];
        let mut parents = vec![None; 8];
        let mut fitted = vec![Some(0.008); 8];
        for (k, j) in (stub..stub + 2).enumerate() {
            positions[j] = Point3::new(0.05, 0.0, 0.01 * (k + 1) as f64);
            parents[j] = Some(if k == 0 { 0 } else { j - 1 });
        }
        for (k, j) in (trunk..trunk + 4).enumerate() {
            positions[j] = z(0.02 * (k + 1) as f64);
            parents[j] = Some(if k == 0 { 0 } else { j - 1 });
            fitted[j] = Some(0.05);
        }
        positions[7] = Point3::new(0.1, 0.0, 0.1);
        parents[7] = Some(trunk + 1);
        fitted[7] = Some(0.06);
        let skeleton = Skeleton {
            positions,
            parents,
            radius: vec![0.0; 8],
        };
        (skeleton, fitted, [stub, trunk])
    }

    /// The conifers of sylva-rs's scans came out with a 10 mm trunk where
    /// it is 56 mm: the root's piece was one arc of the bottom ring, and
    /// its radius capped every branch. Branches from the root are not
    /// capped; elsewhere a branch is still never thicker than its parent.
    #[test]
    fn a_small_arc_at_the_root_does_not_cap_the_trunk() {
        for stub_first in [true, false] {
            let (mut skeleton, fitted, [stub, trunk]) = rooted(stub_first);
            assert_eq!(smooth_radii(&mut skeleton, &fitted), 0);
            for j in trunk..trunk + 4 {
                assert!(
                    (skeleton.radius[j] - 0.05).abs() < 1e-12,
                    "trunk {j}: {:?}",
                    skeleton.radius
                );
            }
            for j in stub..stub + 2 {
                assert!((skeleton.radius[j] - 0.008).abs() < 1e-12);
            }
            assert!(
                (skeleton.radius[7] - 0.05).abs() < 1e-12,
                "the twig is capped by the trunk"
            );
        }
    }

    /// Root → two arcs of the trunk's base (6 mm fits) → a fork: the trunk
    /// on above it (six 50 mm fits) and a twig (one 10 mm fit). A branch
    /// of two fits does not cap the better-seen trunk (sylva-rs's one-view
    /// conifer had its 55 mm trunk capped at 6 mm so), but still caps the
    /// twig, seen less than itself; a twig off the trunk fitted thicker
    /// than it is capped by it.
    #[test]
    fn a_branch_of_few_fits_caps_only_branches_seen_less() {
        let z = |h: f64| Point3::new(0.0, 0.0, h);
        let mut positions = vec![z(0.0), z(0.01), z(0.02)];
        let mut parents = vec![None, Some(0), Some(1)];
        let mut fitted = vec![Some(0.05), Some(0.006), Some(0.006)];
        for k in 0..6 {
            positions.push(z(0.04 + 0.02 * k as f64));
            parents.push(Some(if k == 0 { 2 } else { 2 + k }));
            fitted.push(Some(0.05));
        }
        let twig = positions.len();
        positions.push(Point3::new(0.05, 0.0, 0.03));
        parents.push(Some(2));
        fitted.push(Some(0.01));
        let off_trunk = positions.len();
        positions.push(Point3::new(0.05, 0.0, 0.1));
        parents.push(Some(5));
        fitted.push(Some(0.06));
        let n = positions.len();
        let mut skeleton = Skeleton {
            positions,
            parents,
            radius: vec![0.0; n],
        };
        assert_eq!(smooth_radii(&mut skeleton, &fitted), 0);
        for j in 3..9 {
            assert!(
                (skeleton.radius[j] - 0.05).abs() < 1e-12,
                "trunk {j}: {:?}",
                skeleton.radius
            );
        }
        assert!(
            (skeleton.radius[twig] - 0.006).abs() < 1e-12,
            "{:?}",
            skeleton.radius
        );
        assert!(
            (skeleton.radius[off_trunk] - 0.05).abs() < 1e-12,
            "{:?}",
            skeleton.radius
        );
    }
}
