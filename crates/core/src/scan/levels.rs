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
use crate::scan::neighbours::Graph;

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

/// The pieces of the reached points in level sets `bin` (m) wide, parents
/// before children, piece 0 the root.
pub fn pieces(g: &Geodesic, bin: f64) -> Vec<Piece> {
    let Geodesic {
        points,
        weights,
        graph,
        dist,
        pred,
    } = *g;
    let level: Vec<usize> = dist
        .iter()
        .map(|d| {
            if d.is_finite() {
                (d / bin) as usize
            } else {
                usize::MAX
            }
        })
        .collect();
    let labels = graph.components(|a, b| level[a] != usize::MAX && level[a] == level[b]);
    let count = labels.iter().max().map_or(0, |m| m + 1);
    let mut members = vec![Vec::new(); count];
    for (i, &l) in labels.iter().enumerate() {
        if level[i] != usize::MAX {
            members[l].push(i);
        }
    }
    // Parent by vote of the members' shortest-path predecessors.
    let mut parent = vec![None; count];
    for (l, m) in members.iter().enumerate() {
        let mut votes: Vec<(usize, usize)> = Vec::new();
        for &i in m {
            if let Some(p) = pred[i]
                && labels[p] != l
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
