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
pub(super) fn peer_summary(
    peer: Peer,
    condition: &Condition,
    rows: &[TreeRow],
    what: &str,
) -> ConditionRow {
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
/// hanging from its parent cylinder's end (through a node at its own
/// start when that is more than 1 mm away); root cylinders hang from the
/// nearest node before them, the first from a node at its start.
pub(super) fn cylinders_skeleton(c: &Cylinders) -> Option<Skeleton> {
    let n = c.start.len();
    if n == 0 || [c.axis.len(), c.length.len(), c.radius.len(), c.parent.len()] != [n; 4] {
        return None;
    }
    let start = |k: usize| Point3::from(c.start[k]);
    let end = |k: usize| start(k) + nalgebra::Vector3::from(c.axis[k]) * c.length[k];
    let mut s = Skeleton {
        positions: vec![start(0)],
        parents: vec![None],
        radius: vec![c.radius[0]],
    };
    let mut end_node = vec![usize::MAX; n];
    for k in 0..n {
        let from = match usize::try_from(c.parent[k]).ok().filter(|&p| p < n) {
            Some(p) if end_node[p] != usize::MAX => end_node[p],
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
        end_node[k] = s.len() - 1;
    }
    Some(s)
}

/// A peer's answer as a skeleton: the cloud's size, the peer's time (s)
/// and its skeleton or why there is none.
pub(super) struct Answer {
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
pub(super) fn read_answer(path: &std::path::Path) -> anyhow::Result<Option<Answer>> {
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
    let mut rows = Vec::new();
    for (i, tree) in trees.iter().enumerate() {
        let path = dir.join(format!("{}.{}.json", cloud_stem(condition, i), peer.key));
        if let Some(answer) = read_answer(&path)? {
            rows.push(answer.row(&Skeleton::of_tree(tree)));
        }
    }
    Ok((!rows.is_empty()).then(|| peer_summary(peer, condition, &rows, "")))
}
