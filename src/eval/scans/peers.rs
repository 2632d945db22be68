//! Peers side by side: other skeletonisers' answers on the same clouds
//! (`scripts/scan-peers` runs them and writes `STEM.KEY.json` beside each
//! cloud), turned into skeletons and scored by the same code as ours.

use nalgebra::Point3;

use super::rows::{Condition, ConditionRow, TreeRow, cloud_stem, summarise};
use crate::scan::Skeleton;
use crate::tree::Tree;

/// A peer skeletoniser: the key its answer files carry, its name, and
/// whether it fits radii (pc-skeletor gives a graph of positions only).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Peer {
    pub key: &'static str,
    pub name: &'static str,
    pub fits_radius: bool,
}

/// The peers `scripts/scan-peers` runs (each in its own virtual
/// environment, never linked: two are GPL-3.0).
pub const PEERS: [Peer; 3] = [
    Peer {
        key: "pytlidar",
        name: "PyTLidar 1.1.2",
        fits_radius: true,
    },
    Peer {
        key: "sylva",
        name: "sylva-rs 0.3.0",
        fits_radius: true,
    },
    Peer {
        key: "pcskeletor",
        name: "pc-skeletor 1.0.0",
        fits_radius: false,
    },
];

/// A peer's rows summarised under `condition`, labelled with its name
/// and `what`; no radius error for a peer that fits none.
fn peer_summary(peer: Peer, condition: &Condition, rows: &[TreeRow], what: &str) -> ConditionRow {
    let mut row = summarise(condition, rows);
    row.label = format!("{}: {what}{}", peer.name, row.label);
    if !peer.fits_radius {
        row.radius_error_mm = [f64::NAN; 3];
    }
    row
}

/// A peer's answer for one cloud (`STEM.KEY.json`).
#[derive(Debug, serde::Deserialize)]
struct PeerAnswer {
    points: usize,
    seconds: Option<f64>,
    cylinders: Option<Cylinders>,
    error: Option<String>,
}

/// Cylinders as PyTLidar and sylva-rs give them (and as
/// `scripts/scan-independent` writes the truth): starts, unit axes,
/// lengths, radii (m) and parent rows (-1, or out of range, for none).
#[derive(Debug, serde::Deserialize)]
pub(super) struct Cylinders {
    start: Vec<[f64; 3]>,
    axis: Vec<[f64; 3]>,
    length: Vec<f64>,
    radius: Vec<f64>,
    parent: Vec<i64>,
}

/// Cylinders with parents as a skeleton: a node at each cylinder's end,
/// hanging from its parent cylinder where it starts (a branch may leave
/// its parent part way along, as sylva-rs's model trees do: the parent is
/// split there, at the foot of the child's start on its axis), through a
/// node at its own start when that is more than 1 mm from the parent's
/// axis; root cylinders hang from the nearest node before them, the first
/// from a node at its start.
pub(super) fn cylinders_skeleton(c: &Cylinders) -> Option<Skeleton> {
    let n = c.start.len();
    if n == 0 || [c.axis.len(), c.length.len(), c.radius.len(), c.parent.len()] != [n; 4] {
        return None;
    }
    let finite = |v: &[f64]| v.iter().all(|x| x.is_finite());
    if !(c.start.iter().all(|p| finite(p))
        && c.axis.iter().all(|a| finite(a))
        && c.length.iter().all(|&l| l.is_finite() && l >= 0.0)
        && finite(&c.radius))
    {
        return None;
    }
    let start = |k: usize| Point3::from(c.start[k]);
    let axis = |k: usize| nalgebra::Vector3::from(c.axis[k]);
    let end = |k: usize| start(k) + axis(k) * c.length[k];
    let mut s = Skeleton {
        positions: vec![start(0)],
        parents: vec![None],
        radius: vec![c.radius[0]],
    };
    // Each placed cylinder's nodes along its axis: (distance from its
    // start, node), sorted.
    let mut along: Vec<Vec<(f64, usize)>> = vec![Vec::new(); n];
    for k in 0..n {
        let from = match usize::try_from(c.parent[k]).ok().filter(|&p| p < n) {
            Some(p) if !along[p].is_empty() => {
                let t = (start(k) - start(p)).dot(&axis(p)).clamp(0.0, c.length[p]);
                split_at(
                    &mut s,
                    &mut along[p],
                    t,
                    start(p) + axis(p) * t,
                    c.radius[p],
                )
            }
            _ => (0..s.len())
                .min_by(|&a, &b| {
                    (s.positions[a] - start(k))
                        .norm()
                        .total_cmp(&(s.positions[b] - start(k)).norm())
                })
                .unwrap_or(0),
        };
        let mut at = from;
        if (s.positions[from] - start(k)).norm() > 0.001 {
            s.positions.push(start(k));
            s.parents.push(Some(from));
            s.radius.push(c.radius[k]);
            at = s.len() - 1;
        }
        s.positions.push(end(k));
        s.parents.push(Some(at));
        s.radius.push(c.radius[k]);
        along[k] = vec![(0.0, at), (c.length[k], s.len() - 1)];
    }
    Some(s)
}

/// A child starting within this (m) of a node along its parent hangs from
/// that node: a skeletoniser's next cylinder starts near, not exactly at,
/// its parent's end, and splitting there would leave millimetre stubs
/// that count as branches.
const REUSE: f64 = 0.01;

/// The node `t` along a placed cylinder whose nodes are `along`: an
/// existing one within `REUSE` along it, else a new node at `at` spliced
/// into the cylinder's chain (the part past it now hangs from it).
fn split_at(
    s: &mut Skeleton,
    along: &mut Vec<(f64, usize)>,
    t: f64,
    at: Point3<f64>,
    radius: f64,
) -> usize {
    if let Some(&(_, node)) = along
        .iter()
        .filter(|(u, _)| (u - t).abs() <= REUSE)
        .min_by(|a, b| (a.0 - t).abs().total_cmp(&(b.0 - t).abs()))
    {
        return node;
    }
    let i = along
        .iter()
        .position(|&(u, _)| u > t)
        .unwrap_or(along.len() - 1);
    let node = s.len();
    s.positions.push(at);
    s.parents.push(Some(along[i - 1].1));
    s.radius.push(radius);
    s.parents[along[i].1] = Some(node);
    along.insert(i, (t, node));
    node
}

/// A peer's answer as a skeleton: the cloud's size, the peer's time (s)
/// and its skeleton or why there is none.
struct Answer {
    pub points: usize,
    pub seconds: f64,
    pub found: Result<Skeleton, String>,
}

impl Answer {
    /// `found` scored against `truth`.
    pub fn row(&self, truth: &Skeleton) -> TreeRow {
        TreeRow::new(
            truth,
            self.points,
            self.seconds,
            self.found.as_ref().map_err(Clone::clone),
        )
    }
}

/// A peer's answer file read and turned into a skeleton; `None` when
/// there is no such file.
fn read_answer(path: &std::path::Path) -> anyhow::Result<Option<Answer>> {
    let Ok(text) = std::fs::read_to_string(path) else {
        return Ok(None);
    };
    let answer: PeerAnswer =
        serde_json::from_str(&text).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    let found = answer.cylinders.as_ref().and_then(cylinders_skeleton);
    let failure = answer.error.unwrap_or_else(|| "no cylinders".into());
    Ok(Some(Answer {
        points: answer.points,
        seconds: answer.seconds.unwrap_or(f64::NAN),
        found: found.ok_or(failure),
    }))
}

/// `peer`'s answers in `dir` for `condition`, scored like ours; `None`
/// when the directory holds none for it.
pub fn peer_row(
    trees: &[Tree],
    condition: &Condition,
    dir: &std::path::Path,
    peer: Peer,
) -> anyhow::Result<Option<ConditionRow>> {
    let cases: Vec<(String, Skeleton)> = trees
        .iter()
        .enumerate()
        .map(|(i, tree)| (cloud_stem(condition, i), Skeleton::of_tree(tree)))
        .collect();
    peer_cases_row(
        cases.iter().map(|(stem, truth)| (stem.as_str(), truth)),
        condition,
        dir,
        peer,
        "",
    )
}

/// `peer`'s answers in `dir` for the clouds `cases` names (file stem and
/// truth), scored and summarised under `condition` with `what` in the
/// label; `None` when it answered none of them.
pub(super) fn peer_cases_row<'a>(
    cases: impl Iterator<Item = (&'a str, &'a Skeleton)>,
    condition: &Condition,
    dir: &std::path::Path,
    peer: Peer,
    what: &str,
) -> anyhow::Result<Option<ConditionRow>> {
    let mut rows = Vec::new();
    for (stem, truth) in cases {
        if let Some(answer) = read_answer(&dir.join(format!("{stem}.{}.json", peer.key)))? {
            rows.push(answer.row(truth));
        }
    }
    Ok((!rows.is_empty()).then(|| peer_summary(peer, condition, &rows, what)))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 1 m stem and a branch leaving it half way up, from its surface:
    /// the branch hangs from a node on the stem's axis at 0.5 m, not from
    /// the stem's top, and the stem is whole.
    #[test]
    fn a_branch_leaving_its_parent_part_way_hangs_from_there() {
        let c = Cylinders {
            start: vec![[0.0, 0.0, 0.0], [0.01, 0.0, 0.5], [0.0, 0.0, 1.0]],
            axis: vec![[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]],
            length: vec![1.0, 0.3, 0.2],
            radius: vec![0.02, 0.005, 0.015],
            parent: vec![-1, 0, 0],
        };
        let s = cylinders_skeleton(&c).unwrap();
        let segments: Vec<(Point3<f64>, Point3<f64>)> =
            s.segments().map(|(a, b, _)| (a, b)).collect();
        let has = |a: [f64; 3], b: [f64; 3]| {
            segments.iter().any(|(p, q)| {
                (p - Point3::from(a)).norm() < 1e-9 && (q - Point3::from(b)).norm() < 1e-9
            })
        };
        assert!(has([0.0, 0.0, 0.0], [0.0, 0.0, 0.5]) && has([0.0, 0.0, 0.5], [0.0, 0.0, 1.0]));
        assert!(has([0.0, 0.0, 0.5], [0.01, 0.0, 0.5]) && has([0.01, 0.0, 0.5], [0.31, 0.0, 0.5]));
        assert!(has([0.0, 0.0, 1.0], [0.0, 0.0, 1.2]));
        let total: f64 = segments.iter().map(|(p, q)| (q - p).norm()).sum();
        assert!(
            (total - (1.0 + 0.01 + 0.3 + 0.2)).abs() < 1e-9,
            "no wood added: {total}"
        );
    }

    /// A chain of 5 mm cylinders, each starting at its parent's end: a
    /// chain of nodes, each cylinder hanging from its parent's end (the
    /// nearest of its nodes, though both ends are within `REUSE`).
    #[test]
    fn short_cylinders_hang_from_their_parents_end() {
        let c = Cylinders {
            start: (0..4).map(|k| [0.0, 0.0, 0.005 * k as f64]).collect(),
            axis: vec![[0.0, 0.0, 1.0]; 4],
            length: vec![0.005; 4],
            radius: vec![0.004; 4],
            parent: vec![-1, 0, 1, 2],
        };
        let s = cylinders_skeleton(&c).unwrap();
        assert_eq!(s.len(), 5);
        assert_eq!(s.parents, vec![None, Some(0), Some(1), Some(2), Some(3)]);
    }

    #[test]
    fn cylinders_that_are_not_numbers_are_refused() {
        let c = Cylinders {
            start: vec![[0.0, 0.0, f64::NAN]],
            axis: vec![[0.0, 0.0, 1.0]],
            length: vec![1.0],
            radius: vec![0.02],
            parent: vec![-1],
        };
        assert!(cylinders_skeleton(&c).is_none());
    }
}
