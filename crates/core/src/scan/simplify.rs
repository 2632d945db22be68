//! From the fine skeleton (a node every few millimetres) to the joints the
//! simulator and the models expect: every branch point and tip stays; along
//! a branch a joint stays where the branch bends (Douglas-Peucker, with a
//! tolerance of half the radius, at least 3 mm) and where the joints would
//! otherwise be more than `spacing` apart, and never closer than
//! [`MIN_JOINT_SPACING`] to the joint before. A joint at a bend goes where
//! the straight stretches on either side meet ([`corner`]): the fine nodes
//! round a bend off inside it, and where they round it off over two
//! joints, the two become one there ([`chamfer`]). A joint also stays
//! where the branch has tapered (`taper_split`): each joint carries one
//! radius for its whole span, and the simulator's stiffness goes with its
//! fourth power. A tip's joint goes onto the line of the fine nodes before
//! it (`on_tip_line`), and seen from one side a joint along a branch
//! stands at the average of the fine nodes around it
//! (`averaged_along_chains`).

use crate::geometry::principal::principal;
use crate::scan::corner::{chamfer, corner};
use crate::scan::skeleton::{Skeleton, point_segment};

/// Joints along a branch are at least this far apart (m): the generator's
/// spacing, which the gripper needs to tell nodes apart.
pub const MIN_JOINT_SPACING: f64 = crate::tree::sca::MIN_NODE_SPACING;

/// The simplified skeleton and each joint's confidence (the mean over the
/// fine nodes it stands for). `one_sided`: the cloud was seen from one
/// side, and a joint along a branch stands at the average of the fine
/// nodes around it (`averaged_along_chains`), not at one of them.
pub fn simplify(
    fine: &Skeleton,
    confidence: &[f64],
    spacing: f64,
    one_sided: bool,
) -> (Skeleton, Vec<f64>) {
    let (chains, _) = fine.chains();
    let averaged = one_sided.then(|| averaged_along_chains(fine, &chains));
    let place = averaged.as_deref().unwrap_or(&fine.positions);
    let mut out = Skeleton {
        positions: vec![fine.positions[0]],
        parents: vec![None],
        radius: vec![fine.radius[0]],
    };
    let mut out_confidence = vec![confidence[0]];
    let mut coarse = vec![usize::MAX; fine.len()];
    coarse[0] = 0;
    let children = fine.children();
    for chain in &chains {
        let nodes = &chain.nodes;
        let keep = joints(fine, nodes, spacing);
        let mut prev = coarse[nodes[0]];
        let mut span_start = 1;
        let mut k = 0;
        while k < keep.len() {
            let x = keep[k];
            let before = k.checked_sub(1).map_or(Some(0), |b| keep.get(b).copied());
            // A joint between two kept ones (not a fork or tip) stands
            // where the branches on either side meet; two joints that
            // round one bend off between them become one there.
            let pair = match (before, keep.get(k + 1), keep.get(k + 2)) {
                (Some(b), Some(&y), Some(&after)) => {
                    chamfer(fine, nodes, [b, x, y, after]).map(|at| (at, y))
                }
                _ => None,
            };
            let (at, x) = match pair {
                Some((at, y)) => (Some(at), y),
                None => match (before, keep.get(k + 1)) {
                    (Some(b), Some(&after)) => (corner(fine, nodes, b, x, after), x),
                    _ => (None, x),
                },
            };
            k += if pair.is_some() { 2 } else { 1 };
            let span = &nodes[span_start..=x];
            let mut radii: Vec<f64> = span.iter().map(|&k| fine.radius[k]).collect();
            radii.sort_by(f64::total_cmp);
            let id = out.positions.len();
            let at = match at {
                None if x == nodes.len() - 1 && children[nodes[x]].is_empty() => {
                    on_tip_line(fine, nodes)
                }
                at => at,
            };
            out.positions.push(at.unwrap_or(place[nodes[x]]));
            out.parents.push(Some(prev));
            out.radius.push(radii[radii.len() / 2]);
            out_confidence
                .push(span.iter().map(|&k| confidence[k]).sum::<f64>() / span.len() as f64);
            coarse[nodes[x]] = id;
            prev = id;
            span_start = x + 1;
        }
    }
    (out, out_confidence)
}

/// Fine nodes before a tip that its line is fitted through
/// ([`on_tip_line`]): about 6 cm of branch. With the tip's own node among
/// five, the fit gave recall / precision at 1.0 r of 0.9521 / 0.9676 on
/// sylva-rs's three-view scans of seeds 1-3 (0.9492 / 0.9639 with the
/// joint at the tip's fine node; 0.9516 / 0.9670, 0.9524 / 0.9680 and
/// 0.9508 / 0.9661 with three, four and six) and 0.9992 recall on our
/// train split's three views at 3 mm (0.9953); without it, 0.9518 / 0.9678
/// and 1.0000, and on the train split's leafy one view 0.768 / 0.928
/// against 0.767 / 0.926.
const TIP_FIT_NODES: usize = 4;

/// Where a branch's tip joint goes: its fine node moved onto the line
/// fitted through the [`TIP_FIT_NODES`] fine nodes before it. The last
/// level set of a branch is its end cap, cut obliquely or caught with few
/// points, and its centre lies off the axis: on sylva-rs's conifers a
/// quarter of the tip joints were more than a twig's radius off it,
/// against an eighth of the joints along twigs. The cap's own centre is
/// left out of the fit, which it would tilt toward itself. `None` for a
/// chain too short to fit.
fn on_tip_line(fine: &Skeleton, nodes: &[usize]) -> Option<nalgebra::Point3<f64>> {
    if nodes.len() <= TIP_FIT_NODES + 1 {
        return None;
    }
    let before: Vec<nalgebra::Point3<f64>> = nodes
        [nodes.len() - 1 - TIP_FIT_NODES..nodes.len() - 1]
        .iter()
        .map(|&k| fine.positions[k])
        .collect();
    let line = principal(&before);
    let axis = line.axes[0];
    let tip = fine.positions[nodes[nodes.len() - 1]];
    Some(line.mean + axis * (tip - line.mean).dot(&axis))
}

/// `fine`'s positions with each node inside a chain (not a fork, tip or
/// the root) moved to the average of itself and its neighbours along the
/// chain, weighted 1 : 2 : 1. Seen from one side, a fine node's centre
/// comes from an arc fitted to the near side of its cross-section only,
/// and scatters across the branch by millimetres from node to node
/// (sylva-rs's beam-model scans: 4 mm twigs, one view); a joint placed at
/// one fine node carries its whole scatter. Averaging three leaves a straight branch where it
/// is; a sharp bend's joint is placed by [`corner`] instead. Chosen on our
/// train split and sylva-rs's trees of seeds 1-3 (recall / precision at
/// 1.0 r, one view, 3 mm, leafy: 0.753 / 0.908 at one node, 0.760 / 0.916
/// averaged once, 0.755 / 0.912 three times; sylva-rs's, one view: 0.714 /
/// 0.777, 0.794 / 0.865, 0.805 / 0.878). Seen from all sides the fine
/// nodes are the centres of full circles, and averaging them blurred our
/// trees' bends (train split, three views: 0.999 -> 0.982 recall).
fn averaged_along_chains(
    fine: &Skeleton,
    chains: &[crate::scan::skeleton::Chain],
) -> Vec<nalgebra::Point3<f64>> {
    let mut out = fine.positions.clone();
    for chain in chains {
        for w in chain.nodes.windows(3) {
            let [a, k, b] = [w[0], w[1], w[2]];
            out[k] = nalgebra::Point3::from(
                (fine.positions[a].coords
                    + fine.positions[k].coords * 2.0
                    + fine.positions[b].coords)
                    / 4.0,
            );
        }
    }
    out
}

/// Which of a chain's nodes (indices into `nodes`, past the first) become
/// joints, in order; the last always does.
fn joints(fine: &Skeleton, nodes: &[usize], spacing: f64) -> Vec<usize> {
    let last = nodes.len() - 1;
    let mut keep = vec![false; nodes.len()];
    keep[0] = true;
    keep[last] = true;
    douglas_peucker(fine, nodes, 0, last, &mut keep);
    // Arc length along the chain.
    let mut arc = vec![0.0; nodes.len()];
    for x in 1..nodes.len() {
        arc[x] = arc[x - 1] + (fine.positions[nodes[x]] - fine.positions[nodes[x - 1]]).norm();
    }
    // Split long stretches at about equal arc lengths.
    let kept: Vec<usize> = (0..nodes.len()).filter(|&x| keep[x]).collect();
    for w in kept.windows(2) {
        let (a, b) = (w[0], w[1]);
        let len = arc[b] - arc[a];
        let parts = (len / spacing).ceil() as usize;
        for p in 1..parts {
            let target = arc[a] + len * p as f64 / parts as f64;
            keep[nearest_on_arc(arc.as_slice(), a..=b, target).unwrap_or(a)] = true;
        }
    }
    let kept: Vec<usize> = (0..nodes.len()).filter(|&x| keep[x]).collect();
    for w in kept.windows(2) {
        taper_split(fine, nodes, &arc, w[0], w[1], &mut keep);
    }
    // Never closer than the minimum spacing to the previous joint; the
    // tip stays (the previous one goes instead, unless it is the start).
    let mut out: Vec<usize> = Vec::new();
    let mut prev = 0;
    for x in 1..nodes.len() {
        if !keep[x] {
            continue;
        }
        if arc[x] - arc[prev] < MIN_JOINT_SPACING {
            if x == last {
                if let Some(&p) = out.last()
                    && p != 0
                    && arc[x] - arc[out.get(out.len().wrapping_sub(2)).copied().unwrap_or(0)]
                        <= spacing
                {
                    out.pop();
                }
                out.push(x);
            }
            continue;
        }
        out.push(x);
        prev = x;
    }
    out
}

/// A span's radius may change along it by at most this much (m) ...
const TAPER_ABS: f64 = 0.001;
/// ... or this share of its radius, whichever is larger.
const TAPER_REL: f64 = 0.05;

/// Splits the span between joints `a < b` (chain indices) at its middle,
/// again and again, while the straight line fitted to its fine radii
/// against arc length changes by more than [`TAPER_ABS`] or [`TAPER_REL`]
/// of the radius over it. A joint's radius is the median over its span,
/// so a span over a tapering stem is too thick at its thin end and too thin
/// at its thick end, and its stiffness (K_s ∝ r⁴) wrong at both: 5 % of
/// the radius is a fifth of the stiffness. Sylva-rs's model trees taper
/// like grown ones; at the default 18 cm spacing even the best single
/// radius per span was 0.9 mm off their cylinders at the median (r ≥ 5
/// mm) where the fine nodes were 0.4 mm off. The 1 mm floor keeps fit
/// noise (the fine radii scatter by about 0.5 mm) from splitting a
/// branch of even thickness: the generator's branches are even between
/// joints. Spans shorter than twice [`MIN_JOINT_SPACING`] stay whole.
fn taper_split(
    fine: &Skeleton,
    nodes: &[usize],
    arc: &[f64],
    a: usize,
    b: usize,
    keep: &mut [bool],
) {
    let len = arc[b] - arc[a];
    if len < 2.0 * MIN_JOINT_SPACING || b < a + 4 {
        return;
    }
    // Least squares r = c + slope · s over the span's own nodes (a is the
    // joint before it).
    let xs = a + 1..=b;
    let n = (b - a) as f64;
    let (ms, mr) = xs.clone().fold((0.0, 0.0), |(s, r), x| {
        (s + arc[x] / n, r + fine.radius[nodes[x]] / n)
    });
    let (sxy, sxx) = xs.fold((0.0, 0.0), |(xy, xx), x| {
        let ds = arc[x] - ms;
        (xy + ds * (fine.radius[nodes[x]] - mr), xx + ds * ds)
    });
    if sxx <= 0.0 {
        return;
    }
    let change = (sxy / sxx).abs() * len;
    if change <= TAPER_ABS.max(TAPER_REL * mr) {
        return;
    }
    let Some(m) = nearest_on_arc(arc, a + 1..b, arc[a] + 0.5 * len) else {
        return;
    };
    keep[m] = true;
    taper_split(fine, nodes, arc, a, m, keep);
    taper_split(fine, nodes, arc, m, b, keep);
}

/// Of the chain indices `range`, the one whose arc length is nearest
/// `target`; `None` for an empty range.
fn nearest_on_arc(arc: &[f64], range: impl Iterator<Item = usize>, target: f64) -> Option<usize> {
    range.min_by(|&x, &y| (arc[x] - target).abs().total_cmp(&(arc[y] - target).abs()))
}

/// How far (m) a fine node may lie off a straight stretch through it for
/// the stretch to stay one span: half the radius, at least 3 mm.
fn dp_tolerance(radius: f64) -> f64 {
    (0.5 * radius).max(0.003)
}

fn douglas_peucker(fine: &Skeleton, nodes: &[usize], a: usize, b: usize, keep: &mut [bool]) {
    if b <= a + 1 {
        return;
    }
    let (pa, pb) = (fine.positions[nodes[a]], fine.positions[nodes[b]]);
    let (far, dev) = (a + 1..b)
        .map(|x| (x, point_segment(&fine.positions[nodes[x]], &pa, &pb).0))
        .max_by(|p, q| p.1.total_cmp(&q.1))
        .unwrap_or((a, 0.0));
    if dev > dp_tolerance(fine.radius[nodes[far]]) {
        keep[far] = true;
        douglas_peucker(fine, nodes, a, far, keep);
        douglas_peucker(fine, nodes, far, b, keep);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Point3;

    /// One unbranched fine skeleton through `positions`, every node `radius`
    /// thick.
    fn chain(positions: Vec<Point3<f64>>, radius: f64) -> Skeleton {
        let n = positions.len();
        Skeleton {
            positions,
            parents: (0..n).map(|i| i.checked_sub(1)).collect(),
            radius: vec![radius; n],
        }
    }

    #[test]
    fn a_bent_branch_keeps_its_bend_and_long_stretches_are_split() {
        // Up 0.3 m in 1 cm steps, then sideways 0.05 m.
        let mut positions: Vec<_> = (0..=30)
            .map(|i| Point3::new(0.0, 0.0, i as f64 * 0.01))
            .collect();
        positions.extend((1..=5).map(|i| Point3::new(i as f64 * 0.01, 0.0, 0.3)));
        let n = positions.len();
        let fine = chain(positions, 0.01);
        let (out, confidence) = simplify(&fine, &vec![1.0; n], 0.12, false);
        assert_eq!(confidence.len(), out.len());
        // The bend at 0.3 m, the tip and the 0.3 m stretch in three.
        assert!(
            out.positions
                .iter()
                .any(|p| (p - Point3::new(0.0, 0.0, 0.3)).norm() < 1e-9)
        );
        assert!((out.positions[out.len() - 1] - Point3::new(0.05, 0.0, 0.3)).norm() < 1e-9);
        assert_eq!(out.len(), 5, "{:?}", out.positions);
        for (j, p) in out.parents.iter().enumerate().skip(1) {
            let d = (out.positions[j] - out.positions[p.unwrap()]).norm();
            assert!((MIN_JOINT_SPACING - 1e-9..=0.12 + 1e-9).contains(&d), "{d}");
        }
    }

    /// Cross sections cut a bend obliquely, so the fine nodes round the
    /// corner off inside it: the joint goes where the straight stretches
    /// on either side meet, not on the rounded nodes.
    #[test]
    fn a_rounded_bend_gets_its_joint_at_the_corner() {
        // Up 0.3 m, then along +x 0.2 m, on a 12 mm branch; the node at
        // the corner lies 7 mm inside it.
        let corner = Point3::new(0.0, 0.0, 0.3);
        let mut positions: Vec<Point3<f64>> = (0..=29)
            .map(|i| Point3::new(0.0, 0.0, i as f64 * 0.01))
            .collect();
        positions.push(Point3::new(0.005, 0.0, 0.295));
        positions.extend((1..=20).map(|i| Point3::new(i as f64 * 0.01, 0.0, 0.3)));
        let n = positions.len();
        let fine = chain(positions, 0.012);
        let nearest = |out: &Skeleton| {
            out.positions
                .iter()
                .map(|p| (p - corner).norm())
                .fold(f64::INFINITY, f64::min)
        };
        let rounded = nearest(&fine);
        assert!(rounded > 0.007, "{rounded}");
        let (out, _) = simplify(&fine, &vec![1.0; n], 0.4, false);
        assert!(
            nearest(&out) < 1e-9,
            "{} {:?}",
            nearest(&out),
            out.positions
        );
        // A slight turn is left where the nodes put it.
        let (gentle, _) = simplify(
            &Skeleton {
                positions: fine
                    .positions
                    .iter()
                    .map(|p| Point3::new(p.x * 0.1, 0.0, p.z))
                    .collect(),
                ..fine.clone()
            },
            &vec![1.0; n],
            0.4,
            false,
        );
        assert!(gentle.positions.iter().all(|p| {
            fine.positions
                .iter()
                .any(|q| (Point3::new(q.x * 0.1, 0.0, q.z) - p).norm() < 1e-9)
        }));
    }

    /// A stem tapering from 25 to 10 mm over 36 cm gets a joint wherever
    /// one radius would no longer stand for its span (each span's radius
    /// within 1.25 mm of the true one along it); a branch of even
    /// thickness whose fitted radii scatter by ±0.4 mm keeps the spacing's
    /// joints only.
    #[test]
    fn a_tapering_stem_gets_joints_where_its_radius_changes() {
        let positions: Vec<_> = (0..=36)
            .map(|i| Point3::new(0.0, 0.0, i as f64 * 0.01))
            .collect();
        let n = positions.len();
        let true_radius = |z: f64| 0.025 - 0.015 * z / 0.36;
        let mut tapering = chain(positions.clone(), 0.0);
        tapering.radius = positions.iter().map(|p| true_radius(p.z)).collect();
        let (out, _) = simplify(&tapering, &vec![1.0; n], 0.18, false);
        assert!(out.len() > 3, "{:?}", out.positions);
        for (j, p) in out.parents.iter().enumerate().skip(1) {
            let (lo, hi) = (out.positions[p.unwrap()].z, out.positions[j].z);
            for z in [lo, hi] {
                let off = (out.radius[j] - true_radius(z)).abs();
                assert!(
                    off <= 0.00125 + 1e-9,
                    "span {lo}-{hi}: {} against {}",
                    out.radius[j],
                    true_radius(z)
                );
            }
        }
        let mut even = chain(positions, 0.01);
        for (k, r) in even.radius.iter_mut().enumerate() {
            *r += if k % 2 == 0 { 0.0004 } else { -0.0004 };
        }
        let (out, _) = simplify(&even, &vec![1.0; n], 0.18, false);
        assert_eq!(out.len(), 3, "{:?}", out.positions);
    }

    /// A 5 mm twig's bend rounded off into a quarter circle of 3 cm (the
    /// corner 1.2 cm outside it) keeps two Douglas-Peucker joints on the
    /// rounding, and the straight stretches on either side meet at the
    /// corner: one joint goes there, none stays on the rounding. A twig
    /// curving evenly (a 15 cm radius over 120°) keeps joints on its
    /// curve: merging two would put one where the chords' lines meet,
    /// outside it.
    #[test]
    fn a_bend_rounded_off_by_two_joints_gets_one_at_the_corner() {
        let corner = Point3::new(0.0, 0.0, 0.3);
        let mut positions: Vec<Point3<f64>> = (0..=50)
            .map(|i| Point3::new(0.0, 0.0, i as f64 * 0.0054))
            .collect();
        positions.extend((1..=9).map(|i| {
            let phi = std::f64::consts::FRAC_PI_2 * i as f64 / 9.0;
            Point3::new(0.03 - 0.03 * phi.cos(), 0.0, 0.27 + 0.03 * phi.sin())
        }));
        positions.extend((1..=50).map(|i| Point3::new(0.03 + i as f64 * 0.005, 0.0, 0.3)));
        let n = positions.len();
        let fine = chain(positions, 0.005);
        let (out, _) = simplify(&fine, &vec![1.0; n], 0.4, false);
        let near: Vec<f64> = out
            .positions
            .iter()
            .map(|p| (p - corner).norm())
            .filter(|&d| d < 0.04)
            .collect();
        assert_eq!(near.len(), 1, "{:?}", out.positions);
        assert!(near[0] < 0.002, "{:?}", out.positions);

        let radius = 0.15;
        let arc: Vec<Point3<f64>> = (0..=314)
            .map(|i| {
                let phi = 2.0 * std::f64::consts::FRAC_PI_3 * i as f64 / 314.0;
                Point3::new(radius * (1.0 - phi.cos()), 0.0, radius * phi.sin())
            })
            .collect();
        let n = arc.len();
        let (out, _) = simplify(&chain(arc, 0.005), &vec![1.0; n], 0.4, false);
        assert!(out.len() > 4, "{:?}", out.positions);
        for p in &out.positions {
            let off = ((p - Point3::new(radius, 0.0, 0.0)).norm() - radius).abs();
            assert!(off < 0.004, "{off}: {:?}", out.positions);
        }
    }

    /// Seen from one side, a joint along a straight branch stands at the
    /// average of the fine nodes around it: fine nodes scattered 2 mm to
    /// either side of the axis, alternately, leave the joints on it; seen
    /// from all sides, each joint stays at its fine node, 2 mm off.
    #[test]
    fn seen_from_one_side_a_joint_stands_at_the_average_of_its_fine_nodes() {
        let positions: Vec<_> = (0..=60)
            .map(|i| {
                let side = if i == 0 || i == 60 {
                    0.0
                } else if i % 2 == 0 {
                    0.002
                } else {
                    -0.002
                };
                Point3::new(side, 0.0, i as f64 * 0.01)
            })
            .collect();
        let n = positions.len();
        let fine = chain(positions, 0.01);
        let off_axis = |s: &Skeleton| {
            s.positions[1..s.len() - 1]
                .iter()
                .map(|p| p.x.abs())
                .fold(0.0, f64::max)
        };
        let (one_sided, _) = simplify(&fine, &vec![1.0; n], 0.12, true);
        let (all_sides, _) = simplify(&fine, &vec![1.0; n], 0.12, false);
        assert!(one_sided.len() > 3 && one_sided.len() == all_sides.len());
        assert!(off_axis(&one_sided) < 1e-9, "{:?}", one_sided.positions);
        assert!((off_axis(&all_sides) - 0.002).abs() < 1e-9);
        // The tip stays within the scatter of the nodes before it.
        let tip = one_sided.positions[one_sided.len() - 1];
        assert!((tip - Point3::new(0.0, 0.0, 0.6)).norm() < 0.003, "{tip:?}");
    }

    /// A tip whose fine node is 5 mm off its twig's axis (an end cap cut
    /// obliquely) gets its joint on the line through the fine nodes before
    /// it, on the axis; a straight tip stays where it is.
    #[test]
    fn a_tips_joint_goes_onto_the_line_of_its_last_fine_nodes() {
        let mut positions: Vec<_> = (0..=40)
            .map(|i| Point3::new(0.0, 0.0, i as f64 * 0.01))
            .collect();
        let n = positions.len();
        let straight = chain(positions.clone(), 0.004);
        let (out, _) = simplify(&straight, &vec![1.0; n], 0.12, false);
        assert!((out.positions[out.len() - 1] - Point3::new(0.0, 0.0, 0.4)).norm() < 1e-9);
        positions[n - 1].x = 0.005;
        let capped = chain(positions, 0.004);
        let (out, _) = simplify(&capped, &vec![1.0; n], 0.12, false);
        let tip = out.positions[out.len() - 1];
        assert!(
            tip.x.abs() < 0.0015 && (tip.z - 0.4).abs() < 0.002,
            "{tip:?}"
        );
    }
}
