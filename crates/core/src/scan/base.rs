//! The trunk's base: where a thick trunk meets the ground, the cloud's
//! lowest points are few and scattered round its ring (the base is seen at
//! a grazing angle, or partly hidden), and distances along the cloud from
//! them reach one side of the trunk before the other. The first level
//! sets then split into arcs round the trunk, and each arc grows into a
//! stub from the root that [`crate::scan::fine`]'s pruning keeps when it is
//! longer than a few level sets: on sylva-rs's conifers (5.5 cm stems)
//! seven such stubs of 5 cm each, 2 % of the skeleton and all of it more
//! than 2 cm from any true branch. [`base_arcs`] finds them.

use nalgebra::Vector3;

use crate::scan::skeleton::Skeleton;

/// An arc stays within this many root radii of the root's axis ...
const ARC_REACH: f64 = 1.5;
/// ... and this many root radii above the root.
const ARC_HEIGHT: f64 = 2.0;

/// Marks in `keep` (false) the root's children whose whole branch is an
/// unforked run of nodes within `ARC_REACH` root radii of the root's
/// axis (along `up`) and `ARC_HEIGHT` root radii above it: arcs of the
/// trunk's bottom ring, not branches. A branch leaving the root goes
/// outside that in a few centimetres, and the trunk rises above it; the
/// root keeps at least one child. Nodes already marked are left out.
pub fn base_arcs(skeleton: &Skeleton, root_radius: f64, up: &Vector3<f64>, keep: &mut [bool]) {
    let n = skeleton.len();
    if n < 2 || root_radius.is_nan() || root_radius <= 0.0 {
        return;
    }
    let mut children = vec![Vec::new(); n];
    for (k, p) in skeleton.parents.iter().enumerate() {
        if let Some(p) = *p
            && keep[k]
        {
            children[p].push(k);
        }
    }
    let root = skeleton.positions[0];
    let inside = |k: usize| {
        let d = skeleton.positions[k] - root;
        let along = d.dot(up);
        along <= ARC_HEIGHT * root_radius && (d - up * along).norm() <= ARC_REACH * root_radius
    };
    // Each root child's run, when it is an arc.
    let mut arcs = Vec::new();
    for &c in &children[0] {
        let mut run = vec![c];
        let mut at = c;
        let arc = loop {
            if !inside(at) {
                break false;
            }
            match children[at].as_slice() {
                [] => break true,
                [next] => {
                    at = *next;
                    run.push(at);
                }
                _ => break false,
            }
        };
        if arc {
            arcs.push(run);
        }
    }
    if arcs.len() == children[0].len() {
        // Only arcs: the longest is the tree.
        let longest = (0..arcs.len()).max_by_key(|&i| arcs[i].len());
        if let Some(i) = longest {
            arcs.swap_remove(i);
        }
    }
    for run in arcs {
        for k in run {
            keep[k] = false;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Point3;

    /// A trunk of radius 5 cm rising from the root, with three arcs of its
    /// bottom ring (5 cm out, 1-6 cm up) and a low branch that leaves the
    /// trunk's cylinder: the arcs go, the trunk and the branch stay.
    #[test]
    fn arcs_of_a_thick_trunks_base_are_dropped_and_branches_kept() {
        let mut positions = vec![Point3::origin()];
        let mut parents = vec![None];
        let mut add = |p: Point3<f64>, parent: usize| {
            positions.push(p);
            parents.push(Some(parent));
            positions.len() - 1
        };
        // The trunk: off-axis at first, as the real ones are, then up.
        let mut at = add(Point3::new(0.05, 0.0, 0.03), 0);
        for i in 1..=10 {
            at = add(Point3::new(0.0, 0.0, 0.03 + 0.05 * i as f64), at);
        }
        let trunk_top = at;
        // Three arcs round the ring.
        let mut arcs = Vec::new();
        for a in [2.0f64, 3.5, 5.0] {
            let first = add(Point3::new(0.05 * a.cos(), 0.05 * a.sin(), 0.01), 0);
            let second = add(
                Point3::new(0.05 * (a + 0.4).cos(), 0.05 * (a + 0.4).sin(), 0.04),
                first,
            );
            arcs.push([first, second]);
        }
        // A low branch: out of the cylinder 10 cm from the root.
        let b1 = add(Point3::new(0.04, 0.04, 0.02), 0);
        let b2 = add(Point3::new(0.1, 0.1, 0.03), b1);
        let n = positions.len();
        let skeleton = Skeleton {
            positions,
            parents,
            radius: vec![0.05; n],
        };
        let mut keep = vec![true; n];
        base_arcs(&skeleton, 0.05, &Vector3::z(), &mut keep);
        for [a, b] in arcs {
            assert!(!keep[a] && !keep[b]);
        }
        assert!(keep[trunk_top] && keep[b1] && keep[b2] && keep[1]);
        assert_eq!(keep.iter().filter(|&&k| !k).count(), 6);
        // A root with only arcs keeps the longest.
        let arcs_only = Skeleton {
            positions: vec![
                Point3::origin(),
                Point3::new(0.05, 0.0, 0.01),
                Point3::new(-0.05, 0.0, 0.01),
                Point3::new(-0.05, 0.01, 0.03),
            ],
            parents: vec![None, Some(0), Some(0), Some(2)],
            radius: vec![0.05; 4],
        };
        let mut keep = vec![true; 4];
        base_arcs(&arcs_only, 0.05, &Vector3::z(), &mut keep);
        assert_eq!(keep, vec![true, false, true, true]);
    }
}
