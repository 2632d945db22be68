//! From a connected cloud to a fine skeleton by level sets of the geodesic
//! distance from the root (Xu, Gossett & Chen 2007, as TreeQSM and
//! AdTree also start): points are binned by their shortest-path distance
//! through the neighbourhood graph, each bin's connected pieces are the
//! cross-sections of branches, and a piece's parent is the piece its
//! points' shortest paths come from. A branch point is where one piece's
//! children part.
//!
//! Two corrections make the pieces cross-sections and not fragments of
//! them: sibling pieces that overlap (a ring split by an occlusion shadow,
//! a fork whose arms have not yet parted) are merged, and each piece's
//! centre is the circle fitted across the branch, not the points' mean
//! (which a view from one side pulls toward the camera by about 0.6 r).

use nalgebra::{Point3, Vector2, Vector3};
use petgraph::unionfind::UnionFind;

use crate::scan::circle_fit::{Circle, fit_circle};
use crate::scan::neighbours::{Graph, compact_labels};

/// One cross-section of a branch: its points, the piece it grows from.
#[derive(Debug, Clone)]
pub struct Piece {
    /// Indices of the points (voxel centres).
    pub members: Vec<usize>,
    pub parent: Option<usize>,
    pub level: usize,
    /// Mean of the members, weighted by the raw points each stands for.
    pub centroid: Point3<f64>,
    /// Largest distance of a member from the centroid (m).
    pub spread: f64,
    /// Raw points in the piece.
    pub weight: usize,
}

/// The tree's points (cube means and how many raw points each stands
/// for), their graph, and the shortest paths from the trunk's base
/// ([`Graph::shortest_paths`]): what the level sets are cut from.
pub struct Geodesic<'a> {
    pub points: &'a [Point3<f64>],
    pub weights: &'a [usize],
    pub graph: &'a Graph,
    pub dist: &'a [f64],
    pub pred: &'a [Option<usize>],
}

/// Within a level set, points closer than this many bins (6.4 mm at the
/// default 16 mm) are one piece. The graph links points up to 3 cubes
/// apart (12 mm), which joins two twigs passing a centimetre apart into
/// one cross-section whose centre lies between them (sylva-rs's conifers
/// and broadleaves); a branch's own surface is sampled far more densely.
/// Chosen on sylva-rs's trees (seeds 1-3) and our train split: 0.3-0.45
/// all helped there, below 0.4 our bare scans began to lose recall;
/// sylva-rs three views 0.909 / 0.934 -> 0.930 / 0.951.
pub const PIECE_LINK: f64 = 0.4;

/// A part of a level set with fewer cubes than this is noise unless it
/// bridges two parts (below).
const MIN_PART: usize = 6;

/// Each reached point's piece label: the connected parts of its level set
/// over links at most `link` (m) long. A part reached only from another
/// part of its own level (across a longer link, with no path from the
/// level below) is that part, split by a gap in the sampling: the two
/// are one label. So every piece but the root's has a path from the level
/// below it, and parents, which are voted from there, form a tree. A
/// part of under [`MIN_PART`] cubes linked to one other part only is
/// that part too: on 3-5 mm noise a 6.4 mm link parts a branch's own
/// surface into specks (our train split's three-view 3 mm recall at
/// 0.5 r fell 0.958 -> 0.943 without this; with it 0.957).
fn level_pieces(g: &Geodesic, level: &[usize], link: f64) -> Vec<usize> {
    let Geodesic {
        points,
        weights,
        graph,
        pred,
        ..
    } = *g;
    let labels = graph.components(|a, b| {
        level[a] != usize::MAX && level[a] == level[b] && (points[a] - points[b]).norm() <= link
    });
    let count = labels.iter().max().map_or(0, |m| m + 1);
    let mut from_below = vec![0usize; count];
    let mut beside: Vec<Option<usize>> = vec![None; count];
    for (i, &l) in labels.iter().enumerate() {
        if let Some(p) = pred[i]
            && labels[p] != l
        {
            if level[p] < level[i] {
                from_below[l] += weights[i];
            } else {
                beside[l] = Some(labels[p]);
            }
        }
    }
    let mut glue = UnionFind::<usize>::new(count);
    for l in 0..count {
        if from_below[l] == 0
            && let Some(other) = beside[l]
        {
            glue.union(l, other);
        }
    }
    // The first level is the trunk's base (the sources are its bottom
    // slice): one piece, however its ring is parted. Seen from one side,
    // a thick trunk's base ring is arcs parted by the shadows of what
    // stands in front, and each arc grew a branch of its own from the
    // root, capping the trunk's radius at an arc's (sylva-rs's one-view
    // conifer: a 55 mm trunk given 5.8 mm).
    let mut base = None;
    for (i, &l) in labels.iter().enumerate() {
        if level[i] == 0 {
            glue.union(*base.get_or_insert(l), l);
        }
    }
    // A part of a few cubes is noise off its branch's surface, and joins
    // the one part it is linked to; linked to two or more, it is a bridge
    // between branches (a laser's mixed returns between two twigs), and
    // stays apart.
    let mut size = vec![0usize; count];
    for &l in &labels {
        size[l] += 1;
    }
    let mut linked: Vec<Vec<usize>> = vec![Vec::new(); count];
    for (a, &l) in labels.iter().enumerate() {
        if level[a] == usize::MAX || size[l] >= MIN_PART {
            continue;
        }
        for (b, _) in graph.neighbours(a) {
            if level[b] == level[a] && labels[b] != l && !linked[l].contains(&labels[b]) {
                linked[l].push(labels[b]);
            }
        }
    }
    for (l, others) in linked.iter().enumerate() {
        if let [other] = others[..] {
            glue.union(l, other);
        }
    }
    compact_labels(&mut glue, labels)
}

/// Each point's level set `bin` (m) wide; `usize::MAX` where unreached.
fn levels(dist: &[f64], bin: f64) -> Vec<usize> {
    dist.iter()
        .map(|d| {
            if d.is_finite() {
                (d / bin) as usize
            } else {
                usize::MAX
            }
        })
        .collect()
}

/// The pieces of the reached points in level sets `bin` (m) wide, parents
/// before children, piece 0 the root.
pub fn pieces(g: &Geodesic, bin: f64) -> Vec<Piece> {
    let Geodesic {
        points,
        weights,
        graph: _,
        dist,
        pred,
    } = *g;
    let level = levels(dist, bin);
    let labels = level_pieces(g, &level, PIECE_LINK * bin);
    let count = labels.iter().max().map_or(0, |m| m + 1);
    let mut members = vec![Vec::new(); count];
    for (i, &l) in labels.iter().enumerate() {
        if level[i] != usize::MAX {
            members[l].push(i);
        }
    }
    // Parent by vote of the members' shortest-path predecessors in the
    // level below (one in the same level lies across a long link).
    let mut parent = vec![None; count];
    for (l, m) in members.iter().enumerate() {
        let mut votes: Vec<(usize, usize)> = Vec::new();
        for &i in m {
            if let Some(p) = pred[i]
                && labels[p] != l
                && level[p] < level[i]
            {
                match votes.iter_mut().find(|v| v.0 == labels[p]) {
                    Some(v) => v.1 += weights[i],
                    None => votes.push((labels[p], weights[i])),
                }
            }
        }
        parent[l] = votes.iter().max_by_key(|v| v.1).map(|v| v.0);
    }
    let plevel: Vec<usize> = members
        .iter()
        .map(|m| m.first().map_or(usize::MAX, |&i| level[i]))
        .collect();
    let piece_level = |l: usize| plevel[l];
    let mut order: Vec<usize> = (0..count).filter(|&l| !members[l].is_empty()).collect();
    order.sort_by_key(|&l| (piece_level(l), std::cmp::Reverse(members[l].len())));
    let Some(&root) = order.first() else {
        return Vec::new();
    };
    // Every piece without a parent (other root-level pieces) hangs from
    // the root piece.
    for &l in &order[1..] {
        if parent[l].is_none() {
            parent[l] = Some(root);
        }
    }

    // Merge overlapping siblings, level by level (parents are settled
    // before their children are looked at).
    let mut sets = UnionFind::<usize>::new(count);
    let stats = |m: &[usize]| centroid_spread(points, weights, m);
    let mut merged: Vec<Option<(Point3<f64>, f64)>> = vec![None; count];
    let mut at = 0;
    while at < order.len() {
        let lvl = piece_level(order[at]);
        let end = order[at..]
            .iter()
            .position(|&l| piece_level(l) != lvl)
            .map_or(order.len(), |k| at + k);
        let group = &order[at..end];
        for &l in group {
            if let Some(p) = parent[l] {
                parent[l] = Some(sets.find_mut(p));
            }
            merged[l] = Some(stats(&members[l]));
        }
        for (x, &a) in group.iter().enumerate() {
            for &b in &group[x + 1..] {
                let (ra, rb) = (sets.find_mut(a), sets.find_mut(b));
                if ra == rb || parent[ra] != parent[rb] {
                    continue;
                }
                let (Some((ca, sa)), Some((cb, sb))) = (merged[ra], merged[rb]) else {
                    continue;
                };
                if (ca - cb).norm() < (sa + sb).max(MERGE_MIN) {
                    sets.union(ra, rb);
                    let keep = sets.find_mut(ra);
                    let gone = if keep == ra { rb } else { ra };
                    let moved = std::mem::take(&mut members[gone]);
                    members[keep].extend(moved);
                    parent[keep] = parent[ra];
                    merged[keep] = Some(stats(&members[keep]));
                    merged[gone] = None;
                }
            }
        }
        at = end;
    }

    // Renumber: kept pieces in level order.
    let kept: Vec<usize> = order
        .iter()
        .copied()
        .filter(|&l| sets.find_mut(l) == l && !members[l].is_empty())
        .collect();
    let mut new_id = vec![usize::MAX; count];
    for (k, &l) in kept.iter().enumerate() {
        new_id[l] = k;
    }
    kept.iter()
        .map(|&l| {
            let (centroid, spread) = merged[l].unwrap_or_else(|| stats(&members[l]));
            Piece {
                parent: parent[l].map(|p| new_id[sets.find_mut(p)]),
                level: piece_level(l),
                centroid,
                spread,
                weight: members[l].iter().map(|&i| weights[i]).sum(),
                members: std::mem::take(&mut members[l]),
            }
        })
        .collect()
}

/// Siblings closer than this (m) are one piece whatever their spread.
pub const MERGE_MIN: f64 = 0.01;

fn centroid_spread(points: &[Point3<f64>], weights: &[usize], m: &[usize]) -> (Point3<f64>, f64) {
    let total: usize = m.iter().map(|&i| weights[i]).sum();
    let c = m.iter().fold(Vector3::zeros(), |s, &i| {
        s + points[i].coords * weights[i] as f64
    }) / total.max(1) as f64;
    let c = Point3::from(c);
    let spread = m
        .iter()
        .map(|&i| (points[i] - c).norm())
        .fold(0.0, f64::max);
    (c, spread)
}

/// The cross-section fitted to a piece: the centre (m) on the branch's
/// axis and the circle, `None` where the points do not support a circle.
pub fn cross_section(
    points: &[Point3<f64>],
    members: &[usize],
    centroid: &Point3<f64>,
    axis: &Vector3<f64>,
) -> Option<(Point3<f64>, Circle)> {
    let axis = axis.try_normalize(1e-12)?;
    let helper = if axis.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let u = axis.cross(&helper).normalize();
    let v = axis.cross(&u);
    let flat: Vec<Vector2<f64>> = members
        .iter()
        .map(|&i| {
            let d = points[i] - centroid;
            Vector2::new(d.dot(&u), d.dot(&v))
        })
        .collect();
    let circle = fit_circle(&flat)?;
    let centre = centroid + u * circle.centre.x + v * circle.centre.y;
    Some((centre, circle))
}

/// How hard a fitted centre is pulled toward its points' centroid, per
/// unit of the circle's residual over its radius ([`pulled_to_centroid`]).
/// 1, 2, 3 and 5 gave recall / precision at 1.0 r of 0.946 / 0.961, 0.949 /
/// 0.965, 0.947 / 0.963 and 0.949 / 0.965 on sylva-rs's three-view scans of
/// seeds 1-3 (0.943 / 0.958 without; at 0.5 r 0.887, 0.885, 0.848 and
/// 0.837 against 0.870), and 0.9941, 0.9953, 0.9949, 0.9950 recall on our
/// train split's three views at 3 mm (0.9932 without).
const CENTROID_PULL: f64 = 2.0;

/// A cross-section's centre seen from all sides: the fitted circle's
/// centre moved toward the centroid of its points by `CENTROID_PULL` ×
/// its residual over its radius (`misfit`), all the way from half of it.
/// Points all round a branch put their centroid near its axis, a second
/// estimate of the centre that noise moves little. The circle's centre
/// is the better one on a branch much wider than the noise; on a twig
/// barely wider than it (sylva-rs's conifers: 4 mm twigs, a beam that
/// widens them) it wanders by millimetres, and the residual says so.
/// Where there is no circle (`misfit` infinite) the centroid is already
/// the centre. Not for a cloud seen from one side, whose centroid lies on
/// the near surface.
pub fn pulled_to_centroid(
    centre: &Point3<f64>,
    centroid: &Point3<f64>,
    misfit: f64,
) -> Point3<f64> {
    if !misfit.is_finite() {
        return *centroid;
    }
    let pull = (CENTROID_PULL * misfit).min(1.0);
    centre + (centroid - centre) * pull
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scan::neighbours::PointIndex;

    /// Surface points of a 4 mm twig: rings of 12 every 2 mm along the
    /// axis from `a` to `b`.
    fn twig(a: Point3<f64>, b: Point3<f64>) -> Vec<Point3<f64>> {
        let axis = (b - a).normalize();
        let u = axis.cross(&Vector3::y()).normalize();
        let v = axis.cross(&u);
        let rings = ((b - a).norm() / 0.002) as usize;
        (0..=rings)
            .flat_map(|k| {
                let c = a + (b - a) * (k as f64 / rings as f64);
                (0..12).map(move |j| {
                    let t = j as f64 * std::f64::consts::TAU / 12.0;
                    c + (u * t.cos() + v * t.sin()) * 0.004
                })
            })
            .collect()
    }

    /// The level sets of `points` (1 each) through a graph linking every
    /// point to every other within 12 mm (cross-twig links included),
    /// from point 0.
    fn levels_of(points: &[Point3<f64>], bin: f64) -> (Vec<usize>, Vec<usize>) {
        levels_from(points, bin, &[0])
    }

    /// The piece labels found in level set `l`, each once.
    fn labels_at(level: &[usize], labels: &[usize], l: usize) -> Vec<usize> {
        let mut here: Vec<usize> = (0..level.len())
            .filter(|&i| level[i] == l)
            .map(|i| labels[i])
            .collect();
        here.sort_unstable();
        here.dedup();
        here
    }

    /// As [`levels_of`], from every point of `sources`.
    fn levels_from(
        points: &[Point3<f64>],
        bin: f64,
        sources: &[usize],
    ) -> (Vec<usize>, Vec<usize>) {
        let index = PointIndex::new(points);
        let graph = Graph::knn(points, &index, 400, 0.012);
        let (dist, pred) = graph.shortest_paths(sources);
        let weights = vec![1; points.len()];
        let g = Geodesic {
            points,
            weights: &weights,
            graph: &graph,
            dist: &dist,
            pred: &pred,
        };
        let level = levels(&dist, bin);
        let labels = level_pieces(&g, &level, PIECE_LINK * bin);
        (level, labels)
    }

    /// Two twigs from one base, parallel 16 mm apart above 4 cm (their
    /// surfaces 8 mm apart, linked in the graph): every level set above is
    /// two pieces, one per twig, not one piece between them.
    #[test]
    fn twigs_a_centimetre_apart_are_pieces_of_their_own() {
        let mut points = twig(Point3::origin(), Point3::new(0.0, 0.0, 0.3));
        points.extend(twig(
            Point3::new(0.0, 0.0, 0.01),
            Point3::new(0.016, 0.0, 0.04),
        ));
        points.extend(twig(
            Point3::new(0.016, 0.0, 0.04),
            Point3::new(0.016, 0.0, 0.3),
        ));
        let (level, labels) = levels_of(&points, 0.016);
        for l in 6..=15 {
            let side = |far: bool| {
                let mut ls: Vec<usize> = (0..points.len())
                    .filter(|&i| level[i] == l && (points[i].x > 0.008) == far)
                    .map(|i| labels[i])
                    .collect();
                ls.sort_unstable();
                ls.dedup();
                ls
            };
            let (a, b) = (side(false), side(true));
            assert_eq!((a.len(), b.len()), (1, 1), "level {l}: {a:?} {b:?}");
            assert_ne!(a, b, "level {l}: one piece per twig");
        }
    }

    /// A twig with a gap in its sampling inside one level set (points 1 cm
    /// apart across it, farther than a piece links): the
    /// points past the gap are reached across it from that level, not from
    /// below, and stay in the level's one piece.
    #[test]
    fn a_ring_parted_by_a_gap_is_one_piece() {
        // A horizontal twig along x; level 6 spans x = 96-112 mm.
        let points: Vec<Point3<f64>> = twig(Point3::origin(), Point3::new(0.2, 0.0, 0.0))
            .into_iter()
            .filter(|p| !(0.1..0.107).contains(&p.x))
            .collect();
        let (level, labels) = levels_of(&points, 0.016);
        assert!(level.iter().all(|&l| l < 20), "every point reached");
        for l in 0..=12 {
            let here = labels_at(&level, &labels, l);
            assert_eq!(here.len(), 1, "level {l}: {here:?}");
        }
    }

    /// A 50 mm trunk seen from one side, its bottom ring parted into three
    /// arcs by shadows 2 cm wide: the first level (the trunk's base, from
    /// its bottom slice) is one piece, not one per arc.
    #[test]
    fn a_trunk_base_parted_into_arcs_is_one_piece() {
        let mut points = Vec::new();
        for k in 0..=20 {
            let z = k as f64 * 0.002;
            for j in 0..60 {
                let a = j as f64 * std::f64::consts::PI / 60.0;
                let shadow = [0.9, 2.0].iter().any(|&s| (a - s).abs() < 0.2);
                if !shadow {
                    points.push(Point3::new(0.05 * a.cos(), 0.05 * a.sin(), z));
                }
            }
        }
        let sources: Vec<usize> = (0..points.len()).filter(|&i| points[i].z < 1e-9).collect();
        let (level, labels) = levels_from(&points, 0.016, &sources);
        let base = labels_at(&level, &labels, 0);
        assert_eq!(base.len(), 1, "{base:?}");
        // Above it each arc is still a piece of its own (the siblings'
        // overlap merges them later, where it can).
        let above = labels_at(&level, &labels, 1);
        assert_eq!(above.len(), 3, "{above:?}");
    }

    /// Cross-sections of a branch seen from three sides 120° apart (each
    /// the half facing it, 2 mm depth noise): on a 4 mm twig the fitted
    /// circles' centres wander and pulling them toward the centroid brings
    /// them nearer the axis; on a 40 mm branch the circle fits well and
    /// the centre stays within a few hundredths of a millimetre of it.
    #[test]
    fn a_noisy_twigs_centres_are_pulled_toward_their_centroids() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let noise = Normal::new(0.0, 0.002).unwrap();
        let axis = Vector3::z();
        // Mean distance from the axis of the circles' centres and of the
        // pulled ones, and the largest shift the pull makes.
        let mut errors = |radius: f64| {
            let (mut circle, mut pulled, mut shift) = (0.0, 0.0, 0.0f64);
            let slices = 200;
            for _ in 0..slices {
                let mut points = Vec::new();
                for view in 0..3 {
                    let towards = 2.0 * std::f64::consts::PI * view as f64 / 3.0;
                    let toward = Vector3::new(towards.cos(), towards.sin(), 0.0);
                    for i in 0..10 {
                        let phi = towards + (i as f64 / 9.0 - 0.5) * 0.9 * std::f64::consts::PI;
                        let on = Vector3::new(phi.cos(), phi.sin(), 0.0) * radius;
                        let z = 0.002 * i as f64;
                        points.push(Point3::from(
                            on + toward * noise.sample(&mut rng) + axis * z,
                        ));
                    }
                }
                let members: Vec<usize> = (0..points.len()).collect();
                let centroid = Point3::from(
                    points.iter().map(|p| p.coords).sum::<Vector3<f64>>() / points.len() as f64,
                );
                let (centre, c) = cross_section(&points, &members, &centroid, &axis).unwrap();
                let moved = pulled_to_centroid(&centre, &centroid, c.rms / c.radius);
                let off = |p: &Point3<f64>| p.x.hypot(p.y);
                circle += off(&centre) / slices as f64;
                pulled += off(&moved) / slices as f64;
                shift = shift.max((moved - centre).norm());
            }
            (circle, pulled, shift)
        };
        let (circle, pulled, _) = errors(0.004);
        assert!(pulled < 0.8 * circle, "twig: {pulled} against {circle}");
        let (circle, pulled, shift) = errors(0.04);
        assert!(
            pulled <= circle + 5e-5 && shift < 1e-4,
            "branch: {pulled} {circle} {shift}"
        );
    }
}
