//! Forks where the branches meet. Level sets part a fork's arms only once
//! the arms are apart, so the last pieces below a fork hold both arms and
//! their centre lies between them, a few centimetres past the true fork.
//! Here each fork moves to the point nearest the axes of its parent branch
//! and of its arms (least squares over the lines fitted to the pieces
//! clear of the fork), and the merged pieces beyond that point go.

use nalgebra::{Matrix3, Point3, Vector3};

use crate::geometry::principal::principal;
use crate::scan::skeleton::Skeleton;

/// Arm pieces used for an arm's axis: this far from the fork (m).
const ARM_RANGE: (f64, f64) = (0.015, 0.08);
/// Two arm pieces this far apart (m) give an arm's axis.
const ARM_PAIR: f64 = 0.01;
/// Parent pieces used for the parent's axis: this far below the fork (m).
const PARENT_RANGE: (f64, f64) = (0.03, 0.12);
/// A parent axis fitted through an earlier fork must pass this close (m)
/// to every piece it is fitted to.
const STRAIGHT: f64 = 0.003;
/// Pieces closer than this (m) below a moved fork go too.
const MIN_SEGMENT: f64 = 0.005;
/// A fork moves at most this far (m).
const MAX_MOVE: f64 = 0.08;
/// Two forks this close (m) along the skeleton are one: where three arms,
/// or two forks a few centimetres apart, leave a branch, the level sets
/// part the arms one at a time, and neither find has arms and a parent
/// long enough to fit on its own.
const CLUSTER: f64 = 0.04;

/// Moves the forks of `skeleton` and returns which nodes stay (the merged
/// pieces between a moved fork and its old place do not).
pub fn relocate_forks(skeleton: &mut Skeleton) -> Vec<bool> {
    let n = skeleton.len();
    let children = skeleton.children();
    let mut keep = vec![true; n];
    for f in 0..n {
        if children[f].len() < 2 || skeleton.parents[f].is_none() || !keep[f] {
            continue;
        }
        let pos = &skeleton.positions;
        // Each arm's axis; a fork within `CLUSTER` up an arm is the same
        // fork found twice, and its arms are this fork's.
        let mut lines: Vec<(Point3<f64>, Vector3<f64>)> = Vec::new();
        let mut absorbed: Vec<usize> = Vec::new();
        // (where an arm starts, its first piece, whether it is an absorbed
        // fork's arm)
        let mut arms: Vec<(usize, usize, bool)> =
            children[f].iter().map(|&c| (f, c, false)).collect();
        let mut next = 0;
        while next < arms.len() {
            let (from, c, nested) = arms[next];
            next += 1;
            let mut run = Vec::new();
            let mut path = Vec::new();
            let (mut at, mut arc, mut prev) = (c, 0.0, from);
            loop {
                arc += (pos[at] - pos[prev]).norm();
                if arc > ARM_RANGE.1 {
                    break;
                }
                path.push(at);
                if children[at].len() > 1 && !nested && arc <= CLUSTER {
                    if path.iter().all(|&k| keep[k]) {
                        absorbed.extend(&path);
                        arms.extend(children[at].iter().map(|&g| (at, g, true)));
                        run.clear();
                    }
                    break;
                }
                if arc >= ARM_RANGE.0 {
                    run.push(pos[at]);
                }
                if children[at].len() != 1 {
                    break;
                }
                prev = at;
                at = children[at][0];
            }
            if let Some(line) = arm_axis(&run) {
                lines.push(line);
            }
        }
        if lines.len() < 2 {
            continue;
        }
        // The parent's axis, and the pieces a moved fork may pass (up to
        // the first fork below). The axis is fitted up to that fork, or,
        // where that leaves too few pieces (a whorl's or a twig's forks lie
        // a few centimetres apart), on through it while the pieces stay on
        // one straight line.
        let mut below = Vec::new();
        let mut run = Vec::new();
        let mut local = None;
        let (mut at, mut arc) = (f, 0.0);
        while let Some(p) = skeleton.parents[at] {
            arc += (pos[at] - pos[p]).norm();
            if arc > PARENT_RANGE.1.max(MAX_MOVE) {
                break;
            }
            if (PARENT_RANGE.0..=PARENT_RANGE.1).contains(&arc) {
                run.push(pos[p]);
            }
            if arc <= MAX_MOVE && local.is_none() {
                below.push(p);
            }
            if skeleton.parents[p].is_none() {
                break;
            }
            if children[p].len() != 1 && local.is_none() {
                local = Some(run.len());
            }
            at = p;
        }
        let local_axis = axis(&run[..local.unwrap_or(run.len())]);
        let Some(parent_line) = local_axis.or_else(|| straight_axis(&run)) else {
            continue;
        };
        // Orient the parent axis toward the fork.
        let toward = if (pos[f] - parent_line.0).dot(&parent_line.1) >= 0.0 {
            parent_line.1
        } else {
            -parent_line.1
        };
        lines.push((parent_line.0, toward));
        let Some(x) = nearest_to_lines(&lines) else {
            continue;
        };
        if (x - pos[f]).norm() > MAX_MOVE {
            continue;
        }
        // Pieces past the new fork along the parent's axis go; the fork
        // hangs from the first one below it.
        let mut new_parent = skeleton.parents[f];
        for &b in &below {
            if children[b].len() != 1 || !keep[b] {
                break;
            }
            if (pos[b] - x).dot(&toward) > -MIN_SEGMENT {
                keep[b] = false;
                new_parent = skeleton.parents[b];
            } else {
                break;
            }
        }
        skeleton.parents[f] = new_parent;
        skeleton.positions[f] = x;
        // The second find of this fork goes: its arms hang from this one.
        for &a in &absorbed {
            keep[a] = false;
            for &c in &children[a] {
                if !absorbed.contains(&c) {
                    skeleton.parents[c] = Some(f);
                }
            }
        }
    }
    keep
}

/// A line through points (their mean and principal direction), from three.
fn axis(points: &[Point3<f64>]) -> Option<(Point3<f64>, Vector3<f64>)> {
    if points.len() < 3 {
        return None;
    }
    let p = principal(points);
    (p.spread[0] > 1e-4).then_some((p.mean, p.axes[0]))
}

/// An arm's axis: [`axis`], or through two pieces at least [`ARM_PAIR`]
/// apart. A twig that forks again a few centimetres out (a conifer's
/// whorls, most twigs of sylva-rs's trees) has only two pieces clear of
/// its fork, and with three required such a fork never moved back: on
/// sylva-rs's three-view scans 0.930 / 0.951 -> 0.941 / 0.957 (held out,
/// seeds 4-6: 0.947 / 0.965 -> 0.965 / 0.974); leafy one-view scans of our
/// train split 0.752 / 0.907 -> 0.750 / 0.905, of the test split 0.744 /
/// 0.893 -> 0.749 / 0.898.
fn arm_axis(points: &[Point3<f64>]) -> Option<(Point3<f64>, Vector3<f64>)> {
    match points {
        [a, b] => {
            let d = b - a;
            (d.norm() >= ARM_PAIR).then(|| (*a, d.normalize()))
        }
        _ => axis(points),
    }
}

/// [`axis`], when every point lies within [`STRAIGHT`] of the line.
fn straight_axis(points: &[Point3<f64>]) -> Option<(Point3<f64>, Vector3<f64>)> {
    let (c, d) = axis(points)?;
    points
        .iter()
        .all(|p| {
            let v = p - c;
            (v - d * v.dot(&d)).norm() <= STRAIGHT
        })
        .then_some((c, d))
}

/// The point with the least sum of squared distances to the lines.
fn nearest_to_lines(lines: &[(Point3<f64>, Vector3<f64>)]) -> Option<Point3<f64>> {
    let mut a = Matrix3::zeros();
    let mut b = Vector3::zeros();
    for (c, d) in lines {
        let d = d.normalize();
        let m = Matrix3::identity() - d * d.transpose();
        a += m;
        b += m * c.coords;
    }
    // Parallel lines leave the system singular: no fork point.
    let eig = a.symmetric_eigenvalues();
    if eig.min() < 0.05 * eig.max() {
        return None;
    }
    a.lu().solve(&b).map(Point3::from)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Pieces every 2 cm up the z axis to 0.3 m (nodes 0-15).
    fn trunk() -> (Vec<Point3<f64>>, Vec<Option<usize>>) {
        (0..=15usize)
            .map(|i| (Point3::new(0.0, 0.0, i as f64 * 0.02), i.checked_sub(1)))
            .unzip()
    }

    /// Adds a piece at `p` hanging from `parent`; its index.
    fn grow(
        positions: &mut Vec<Point3<f64>>,
        parents: &mut Vec<Option<usize>>,
        p: Point3<f64>,
        parent: usize,
    ) -> usize {
        positions.push(p);
        parents.push(Some(parent));
        positions.len() - 1
    }

    /// Node `k` of `skeleton` lies at `at`.
    fn assert_at(skeleton: &Skeleton, k: usize, at: Point3<f64>) {
        let p = skeleton.positions[k];
        assert!((p - at).norm() < 1e-6, "node {k} at {p:?}, not {at:?}");
    }

    /// The skeleton through `positions` (every piece 1 cm thick) with its
    /// forks relocated, and which nodes stay.
    fn relocated(
        positions: Vec<Point3<f64>>,
        parents: Vec<Option<usize>>,
    ) -> (Skeleton, Vec<bool>) {
        let n = positions.len();
        let mut skeleton = Skeleton {
            positions,
            parents,
            radius: vec![0.01; n],
        };
        let keep = relocate_forks(&mut skeleton);
        (skeleton, keep)
    }

    #[test]
    fn a_fork_found_late_moves_back_to_where_the_axes_meet() {
        // A trunk up the z axis to 0.3 m, two arms at ±45° from there; the
        // level sets found the fork at 0.33 m with two merged pieces.
        let (mut positions, mut parents) = trunk();
        positions.push(Point3::new(0.0, 0.0, 0.315));
        parents.push(Some(15));
        positions.push(Point3::new(0.0, 0.0, 0.33));
        parents.push(Some(16));
        let fork = positions.len() - 1;
        for side in [-1.0, 1.0] {
            let mut prev = fork;
            for k in 3..10 {
                let s = k as f64 * 0.01;
                positions.push(Point3::new(side * s, 0.0, 0.3 + s));
                parents.push(Some(prev));
                prev = positions.len() - 1;
            }
        }
        let (skeleton, keep) = relocated(positions, parents);
        assert!((skeleton.positions[fork] - Point3::new(0.0, 0.0, 0.3)).norm() < 1e-6);
        assert!(!keep[16] && !keep[15] && keep[14]);
        assert_eq!(skeleton.parents[fork], Some(14));
    }

    /// As above, with a twig leaving the trunk 2 cm below the true fork
    /// (a whorl): the trunk's axis is fitted on through that fork, so the
    /// late find still moves back, and the twig's fork stays.
    #[test]
    fn a_fork_just_above_another_still_moves_back() {
        let (mut positions, mut parents) = trunk();
        let mut add = |p, parent| grow(&mut positions, &mut parents, p, parent);
        let mut prev = 14;
        for k in 1..7 {
            prev = add(Point3::new(0.0, k as f64 * 0.02, 0.28), prev);
        }
        let merged = add(Point3::new(0.0, 0.0, 0.315), 15);
        let fork = add(Point3::new(0.0, 0.0, 0.33), merged);
        for side in [-1.0, 1.0] {
            let mut prev = fork;
            for k in 3..10 {
                let s = k as f64 * 0.01;
                prev = add(Point3::new(side * s, 0.0, 0.3 + s), prev);
            }
        }
        let (skeleton, keep) = relocated(positions, parents);
        assert_at(&skeleton, fork, Point3::new(0.0, 0.0, 0.3));
        assert!(!keep[merged] && !keep[15] && keep[14]);
        assert_eq!(skeleton.parents[fork], Some(14));
        assert!((skeleton.positions[14] - Point3::new(0.0, 0.0, 0.28)).norm() < 1e-6);
    }

    /// As the first, each arm forking again 5 cm out: only two pieces of
    /// each arm lie clear of the fork, and the line through them is enough.
    #[test]
    fn a_fork_whose_arms_fork_again_soon_moves_back() {
        let (mut positions, mut parents) = trunk();
        let mut add = |p, parent| grow(&mut positions, &mut parents, p, parent);
        let merged = add(Point3::new(0.0, 0.0, 0.315), 15);
        let fork = add(Point3::new(0.0, 0.0, 0.33), merged);
        for side in [-1.0, 1.0] {
            let near = add(Point3::new(side * 0.03, 0.0, 0.33), fork);
            let again = add(Point3::new(side * 0.05, 0.0, 0.35), near);
            for turn in [-1.0, 1.0] {
                let mut prev = again;
                for k in 1..4 {
                    let s = k as f64 * 0.02;
                    prev = add(Point3::new(side * 0.05, turn * s, 0.35 + s), prev);
                }
            }
        }
        let (skeleton, keep) = relocated(positions, parents);
        assert_at(&skeleton, fork, Point3::new(0.0, 0.0, 0.3));
        assert!(!keep[merged] && !keep[15] && keep[14]);
    }

    /// Three arms leave a trunk at 0.3 m; the level sets parted one arm at
    /// 0.32 m and the other two at 0.345 m. The two finds are one fork, at
    /// the trunk's top, with all three arms.
    #[test]
    fn two_finds_of_one_fork_become_one_fork_where_the_axes_meet() {
        let (mut positions, mut parents) = trunk();
        let mut add = |p, parent| grow(&mut positions, &mut parents, p, parent);
        let first = add(Point3::new(0.0, 0.0, 0.32), 15);
        let second = add(Point3::new(0.0, 0.0, 0.345), first);
        let arm = |azimuth: f64, k: usize| {
            let s = k as f64 * 0.01;
            Point3::new(s * azimuth.cos(), s * azimuth.sin(), 0.3 + s)
        };
        let mut arm_nodes = Vec::new();
        for (azimuth, from, start) in [(0.0, first, 3), (2.1, second, 5), (4.2, second, 5)] {
            let mut prev = from;
            for k in start..12 {
                prev = add(arm(azimuth, k), prev);
                if k == start {
                    arm_nodes.push(prev);
                }
            }
        }
        let (skeleton, keep) = relocated(positions, parents);
        assert_at(&skeleton, first, Point3::new(0.0, 0.0, 0.3));
        assert!(!keep[second] && !keep[15] && keep[first] && keep[14]);
        assert_eq!(skeleton.parents[first], Some(14));
        for a in arm_nodes {
            assert_eq!(
                skeleton.parents[a],
                Some(first),
                "every arm hangs from the one fork"
            );
        }
    }
}
