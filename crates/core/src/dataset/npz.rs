//! The `.npz` file of one split and size. Arrays (see `docs/dataset.md`):
//!
//! | name | dtype | shape | meaning |
//! | --- | --- | --- | --- |
//! | `format_version` | int64 | () | 1 |
//! | `initial_positions` | float64 | (E, N, 3) | p_j before the push (m) |
//! | `final_positions` | float64 | (E, N, 3) | p′_j at steady state (m) |
//! | `push` | float64 | (E, 3) | gripper displacement T (m) |
//! | `contact_node` | int64 | (E,) | contacted node j (≥ 1) |
//! | `tree_index` | int64 | (E,) | row of the tree arrays below |
//! | `hold` | uint8 | (E,) | 0: branch in the slot, 1: node held (fork catch / pinned), 2: the base fork held (slid back to it) |
//! | `tree_seed` | uint64 | (T,) | generator seed of each tree |
//! | `tree_positions` | float64 | (T, N, 3) | rest node positions (m) |
//! | `parents` | int64 | (T, N) | parent of each node, −1 for the root |
//! | `radius`, `length` | float64 | (T, N) | branch ending at each node (m); 0 for the root |
//! | `stiffness` | float64 | (T, N) | K_s (N·m/rad); 0 for the root |
//! | `damping` | float64 | (T, N) | K_d (N·m·s/rad); 0 for the root |
//!
//! Files are byte-for-byte reproducible: zip entries carry a fixed
//! timestamp.

use std::fs::File;
use std::io::{BufReader, BufWriter};
use std::path::Path;

use nalgebra::{Point3, Vector3};
use ndarray::{Array0, Array1, Array2, Array3};
use ndarray_npy::{NpzReader, NpzWriter};
use zip::CompressionMethod;
use zip::write::SimpleFileOptions;

use super::{Episode, SizeData, Split};
use crate::sim::{Hold, Push};
use crate::tree::collection::TreeOrigin;
use crate::tree::{Branch, Tree};

pub const FORMAT_VERSION: i64 = 1;

#[derive(Debug, thiserror::Error)]
pub enum NpzError {
    #[error("{path}: {message}")]
    Io { path: String, message: String },
    #[error("{path}: array `{name}`: {message}")]
    Array {
        path: String,
        name: String,
        message: String,
    },
    #[error("{path}: {message}")]
    Content { path: String, message: String },
}

pub fn write_size_file(data: &SizeData, path: &Path) -> Result<(), NpzError> {
    let io = |e: &dyn std::fmt::Display| NpzError::Io {
        path: path.display().to_string(),
        message: e.to_string(),
    };
    let file = File::create(path).map_err(|e| io(&e))?;
    let options = SimpleFileOptions::default()
        .compression_method(CompressionMethod::Deflated)
        .last_modified_time(zip::DateTime::default());
    let mut npz = NpzWriter::new_with_options(BufWriter::new(file), options);
    let n = data.n;
    let e = data.episodes.len();
    let t = data.trees.len();

    let mut initial = Array3::<f64>::zeros((e, n, 3));
    let mut final_ = Array3::<f64>::zeros((e, n, 3));
    let mut push = Array2::<f64>::zeros((e, 3));
    let mut contact = Array1::<i64>::zeros(e);
    let mut tree_index = Array1::<i64>::zeros(e);
    let mut hold = Array1::<u8>::zeros(e);
    for (k, ep) in data.episodes.iter().enumerate() {
        let tree = data.tree_of(ep);
        for j in 0..n {
            for c in 0..3 {
                initial[(k, j, c)] = tree.position(j)[c];
                final_[(k, j, c)] = ep.final_positions[j][c];
            }
        }
        for c in 0..3 {
            push[(k, c)] = ep.push.vector[c];
        }
        contact[k] = ep.push.node as i64;
        tree_index[k] = ep.tree as i64;
        hold[k] = match ep.hold {
            Hold::OnAxis => 0,
            Hold::AtNode => 1,
            Hold::AtBase => 2,
        };
    }
    let mut seeds = Array1::<u64>::zeros(t);
    let mut positions = Array3::<f64>::zeros((t, n, 3));
    let mut parents = Array2::<i64>::zeros((t, n));
    let mut per_branch = [(); 4].map(|_| Array2::<f64>::zeros((t, n)));
    for (k, (origin, tree)) in data.trees.iter().enumerate() {
        seeds[k] = origin.seed;
        for j in 0..n {
            for c in 0..3 {
                positions[(k, j, c)] = tree.position(j)[c];
            }
            parents[(k, j)] = tree.parent(j).map_or(-1, |p| p as i64);
            if let Some(b) = tree.branch(j) {
                for (array, value) in
                    per_branch
                        .iter_mut()
                        .zip([b.radius, b.length, b.stiffness, b.damping])
                {
                    array[(k, j)] = value;
                }
            }
        }
    }
    let add = |name: &str, result: Result<(), ndarray_npy::WriteNpzError>| {
        result.map_err(|e| NpzError::Array {
            path: path.display().to_string(),
            name: name.to_owned(),
            message: e.to_string(),
        })
    };
    add(
        "format_version",
        npz.add_array("format_version", &Array0::from_elem((), FORMAT_VERSION)),
    )?;
    add(
        "initial_positions",
        npz.add_array("initial_positions", &initial),
    )?;
    add("final_positions", npz.add_array("final_positions", &final_))?;
    add("push", npz.add_array("push", &push))?;
    add("contact_node", npz.add_array("contact_node", &contact))?;
    add("tree_index", npz.add_array("tree_index", &tree_index))?;
    add("hold", npz.add_array("hold", &hold))?;
    add("tree_seed", npz.add_array("tree_seed", &seeds))?;
    add(
        "tree_positions",
        npz.add_array("tree_positions", &positions),
    )?;
    add("parents", npz.add_array("parents", &parents))?;
    for (name, array) in ["radius", "length", "stiffness", "damping"]
        .iter()
        .zip(&per_branch)
    {
        add(name, npz.add_array(*name, array))?;
    }
    npz.finish().map_err(|e| io(&e))?;
    Ok(())
}

/// Reads and validates a file written by [`write_size_file`]; every tree is
/// rebuilt through [`Tree::new`], so a damaged file is an error, not a
/// silently wrong tree.
pub fn read_size_file(path: &Path, split: Split) -> Result<SizeData, NpzError> {
    let where_ = path.display().to_string();
    let file = File::open(path).map_err(|e| NpzError::Io {
        path: where_.clone(),
        message: e.to_string(),
    })?;
    read_size(BufReader::new(file), &where_, split)
}

/// [`read_size_file`] from any seekable reader; `where_` names it in errors.
pub fn read_size<R: std::io::Read + std::io::Seek>(
    reader: R,
    where_: &str,
    split: Split,
) -> Result<SizeData, NpzError> {
    let where_ = where_.to_owned();
    let mut npz = NpzReader::new(reader).map_err(|e| NpzError::Io {
        path: where_.clone(),
        message: format!("not an npz archive: {e}"),
    })?;
    macro_rules! array {
        ($name:literal) => {
            npz.by_name($name).map_err(|e| NpzError::Array {
                path: where_.clone(),
                name: $name.to_owned(),
                message: e.to_string(),
            })?
        };
    }
    let content = |message: String| NpzError::Content {
        path: where_.clone(),
        message,
    };
    let version: Array0<i64> = array!("format_version");
    if version[()] != FORMAT_VERSION {
        return Err(content(format!(
            "format version {} (this build reads {FORMAT_VERSION})",
            version[()]
        )));
    }
    let final_: Array3<f64> = array!("final_positions");
    let push: Array2<f64> = array!("push");
    let contact: Array1<i64> = array!("contact_node");
    let tree_index: Array1<i64> = array!("tree_index");
    let hold: Array1<u8> = array!("hold");
    let seeds: Array1<u64> = array!("tree_seed");
    let positions: Array3<f64> = array!("tree_positions");
    let parents: Array2<i64> = array!("parents");
    let radius: Array2<f64> = array!("radius");
    let length: Array2<f64> = array!("length");
    let stiffness: Array2<f64> = array!("stiffness");
    let damping: Array2<f64> = array!("damping");

    let (t, n, _) = positions.dim();
    let e = final_.dim().0;
    let shapes_ok = positions.dim().2 == 3
        && final_.dim() == (e, n, 3)
        && push.dim() == (e, 3)
        && contact.len() == e
        && tree_index.len() == e
        && hold.len() == e
        && seeds.len() == t
        && [
            &parents.dim(),
            &radius.dim(),
            &length.dim(),
            &stiffness.dim(),
            &damping.dim(),
        ]
        .iter()
        .all(|d| **d == (t, n));
    if !shapes_ok {
        return Err(content(format!(
            "array shapes disagree (expected E = {e} episodes, T = {t} trees, N = {n} nodes)"
        )));
    }
    let mut trees = Vec::with_capacity(t);
    for k in 0..t {
        let tree_positions = (0..n)
            .map(|j| {
                Point3::new(
                    positions[(k, j, 0)],
                    positions[(k, j, 1)],
                    positions[(k, j, 2)],
                )
            })
            .collect();
        let tree_parents = (0..n)
            .map(|j| usize::try_from(parents[(k, j)]).ok())
            .collect();
        let branches = (0..n)
            .map(|j| {
                (parents[(k, j)] >= 0).then(|| Branch {
                    radius: radius[(k, j)],
                    length: length[(k, j)],
                    stiffness: stiffness[(k, j)],
                    damping: damping[(k, j)],
                })
            })
            .collect();
        let tree = Tree::new(tree_positions, tree_parents, branches)
            .map_err(|err| content(format!("tree {k}: {err}")))?;
        let origin = TreeOrigin {
            n,
            index: k,
            seed: seeds[k],
            candidate: 0,
        };
        trees.push((origin, tree));
    }
    let mut episodes = Vec::with_capacity(e);
    for k in 0..e {
        let tree = usize::try_from(tree_index[k])
            .ok()
            .filter(|&i| i < t)
            .ok_or_else(|| {
                content(format!(
                    "episode {k}: tree index {} out of range",
                    tree_index[k]
                ))
            })?;
        let node = usize::try_from(contact[k])
            .ok()
            .filter(|&j| (1..n).contains(&j))
            .ok_or_else(|| {
                content(format!(
                    "episode {k}: contact node {} out of range",
                    contact[k]
                ))
            })?;
        let hold = match hold[k] {
            0 => Hold::OnAxis,
            1 => Hold::AtNode,
            2 => Hold::AtBase,
            other => return Err(content(format!("episode {k}: unknown hold {other}"))),
        };
        let final_positions: Vec<Point3<f64>> = (0..n)
            .map(|j| Point3::new(final_[(k, j, 0)], final_[(k, j, 1)], final_[(k, j, 2)]))
            .collect();
        if final_positions
            .iter()
            .any(|p| !p.iter().all(|c| c.is_finite()))
        {
            return Err(content(format!("episode {k}: non-finite final position")));
        }
        episodes.push(Episode {
            tree,
            push: Push {
                node,
                vector: Vector3::new(push[(k, 0)], push[(k, 1)], push[(k, 2)]),
            },
            final_positions,
            hold,
        });
    }
    Ok(SizeData {
        split,
        n,
        trees,
        episodes,
    })
}
