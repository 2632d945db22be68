//! Where a joint at a bend goes: the fine skeleton rounds a bend off
//! inside it (a bend's cross-sections are cut obliquely), so a joint there
//! moves to where the straight stretches on either side meet ([`corner`]),
//! and two joints that round one bend off between them become one there
//! ([`chamfer`]). Used by [`crate::scan::simplify`].

use crate::geometry::principal::principal;
use crate::scan::skeleton::Skeleton;

/// Smallest turn (rad) between the straight stretches on either side of a
/// joint for it to be moved to where they meet.
const CORNER_MIN_TURN: f64 = 0.2;
/// Farthest (m) a joint is moved to where its stretches meet.
const CORNER_MAX_SHIFT: f64 = 0.03;
/// Two joints round one bend off ([`chamfer`]) only between stretches at
/// least this many times longer than the span between them.
const CHAMFER_SIDES: f64 = 2.0;

/// Where the stretches of fine nodes before and after joint `x` (chain
/// indices `before < x < after`, the joints on either side) meet: the
/// midpoint of the shortest segment between the lines fitted to each,
/// leaving out the nodes within two radii of the joint. A bend's cross
/// sections are cut obliquely, so the fine nodes round the corner off
/// inside it (on the generator's trees by 1-2 cm on 5 mm twigs); `None`
/// where a stretch is too short to fit, the turn is slight or the meeting
/// point is more than `CORNER_MAX_SHIFT` away.
pub fn corner(
    fine: &Skeleton,
    nodes: &[usize],
    before: usize,
    x: usize,
    after: usize,
) -> Option<nalgebra::Point3<f64>> {
    corner_lines(fine, nodes, [before, x, x, after]).map(|(meet, _)| meet)
}

/// Two joints `x < y` that round one bend off between them (the
/// Douglas-Peucker joints where a rounded corner starts and ends: on the
/// generator's 5 mm twigs 2.5-3 cm apart, the true corner 1-2 cm outside
/// them), where the straight stretches before `x` and after `y` meet;
/// `None` unless they meet near one of them and both stretches are at
/// least `CHAMFER_SIDES` times as long as the span between the joints.
/// A branch curving evenly has its Douglas-Peucker joints about evenly
/// spaced, and keeps them: merging two of them would put the joint where
/// the chords' lines meet, outside the curve. `joints` are chain indices
/// `[before, x, y, after]`.
pub fn chamfer(
    fine: &Skeleton,
    nodes: &[usize],
    joints: [usize; 4],
) -> Option<nalgebra::Point3<f64>> {
    let (meet, long_sides) = corner_lines(fine, nodes, joints)?;
    long_sides.then_some(meet)
}

/// Where the stretches before joint `x` and after joint `y` (`joints` =
/// `[before, x, y, after]`, chain indices, `before < x ≤ y < after`) meet, as [`corner`] finds it for one joint, each
/// stretch's nodes within two radii of its joint left out; `None` also
/// where the meeting point is more than `CORNER_MAX_SHIFT` from the
/// nearer joint or the joints lie more than twice that apart. With it,
/// whether both stretches are at least `CHAMFER_SIDES` times as long as
/// the span between the joints.
fn corner_lines(
    fine: &Skeleton,
    nodes: &[usize],
    [before, x, y, after]: [usize; 4],
) -> Option<(nalgebra::Point3<f64>, bool)> {
    let (px, py) = (fine.positions[nodes[x]], fine.positions[nodes[y]]);
    let guard = |j: usize| (2.0 * fine.radius[nodes[j]]).max(0.01);
    let fit = |range: std::ops::RangeInclusive<usize>, at: nalgebra::Point3<f64>, guard: f64| {
        let pts: Vec<nalgebra::Point3<f64>> = range
            .map(|i| fine.positions[nodes[i]])
            .filter(|p| (p - at).norm() > guard)
            .collect();
        if pts.len() < 3 {
            return None;
        }
        let p = principal(&pts);
        Some((p.mean, p.axes[0]))
    };
    let (c1, d1) = fit(before..=x, px, guard(x))?;
    let (c2, d2) = fit(y..=after, py, guard(y))?;
    let cos = d1.dot(&d2).abs();
    if cos > CORNER_MIN_TURN.cos() {
        return None;
    }
    // Closest points of the two lines c1 + s d1 and c2 + t d2.
    let w = c1 - c2;
    let (b, d, e) = (d1.dot(&d2), d1.dot(&w), d2.dot(&w));
    let denom = 1.0 - b * b;
    let s = (b * e - d) / denom;
    let t = (e - b * d) / denom;
    let meet = nalgebra::center(&(c1 + d1 * s), &(c2 + d2 * t));
    // Two joints are one bend when they lie within twice the largest
    // shift of each other along the branch and the corner is near one.
    let arc = |a: usize, b: usize| -> f64 {
        (a..b)
            .map(|i| (fine.positions[nodes[i + 1]] - fine.positions[nodes[i]]).norm())
            .sum()
    };
    let between = arc(x, y);
    let near = (meet - px).norm().min((meet - py).norm());
    let long_sides = arc(before, x).min(arc(y, after)) >= CHAMFER_SIDES * between;
    (near <= CORNER_MAX_SHIFT && between <= 2.0 * CORNER_MAX_SHIFT).then_some((meet, long_sides))
}
