//! A model's domain: the range of trees and pushes it was trained on,
//! widened by a margin, outside which its answers are extrapolation.
//!
//! Recorded in each exported model's metadata (key `domain`) and checked by
//! the server before it asks a model anything: a branch 1000× stiffer than
//! its neighbours or a 100 m branch gets a 422 that names the quantity, the
//! bound and the node, instead of a confident prediction of 1e23 m.
//!
//! Stiffness is bounded only as a ratio: κ_j = ln K_s,j − the tree's mean
//! ln K_s (the models' input, [`crate::graph::log_stiffness_ratios`]). A
//! push is displacement controlled, so a global factor on every K_s moves
//! nothing, and the models cannot see one: it is never refused.
//!
//! The margin ([`Margin::STANDARD`]): lengths (tree height, branch length,
//! radius) may be 1.5× outside the trained range either way, each branch's
//! stiffness ratio 2× beyond the most extreme ratio trained on (κ ± ln 2),
//! pushes down to half the shortest and up to twice the longest trained
//! push. Tree size is not a
//! bound: the GNN's weights do not depend on N, and the paper evaluates
//! N = 10…30 zero-shot; outside that range a warning is given instead.

use serde::{Deserialize, Serialize};

use crate::graph::log_stiffness_ratios;
use crate::graph::path::{Encoding, PATH_MAX_JOINTS, path_fits};
use crate::tree::Tree;

/// Sizes the paper evaluates on (trained on 11…19, zero-shot to 30).
pub const EVALUATED_NODES: (usize, usize) = (10, 30);

/// A closed interval [min, max] of one quantity (SI units).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Interval {
    pub min: f64,
    pub max: f64,
}

impl Interval {
    pub const EMPTY: Interval = Interval {
        min: f64::INFINITY,
        max: f64::NEG_INFINITY,
    };

    fn include(&mut self, v: f64) {
        self.min = self.min.min(v);
        self.max = self.max.max(v);
    }

    fn widened(self, factor: f64) -> Self {
        Self {
            min: self.min / factor,
            max: self.max * factor,
        }
    }

    /// Widened by `by` either way (for quantities on a log scale).
    fn widened_by(self, by: f64) -> Self {
        Self {
            min: self.min - by,
            max: self.max + by,
        }
    }

    pub fn contains(&self, v: f64) -> bool {
        v >= self.min && v <= self.max
    }
}

/// What the training split spanned, and the domain a model answers in.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Domain {
    /// Highest node above the root (m).
    pub tree_height: Interval,
    /// Branch length ℓ (m).
    pub branch_length: Interval,
    /// Branch radius r (m).
    pub branch_radius: Interval,
    /// κ = ln K_s − the tree's mean ln K_s (dimensionless): stiffness
    /// relative to the rest of the tree.
    pub stiffness_log_ratio: Interval,
    /// |T| (m); forward model only, the policy's pushes are its output.
    pub push_length: Interval,
    /// Tree sizes evaluated (outside: a warning, not a refusal).
    pub nodes: (usize, usize),
    /// A path model's domain bounds only what it reads of the tree: each
    /// branch's length (its Δp). The tree's height and size do not enter
    /// its graph, the radius only through K_s, and its κ is relative to
    /// the pushed path, not the tree.
    #[serde(default)]
    pub encoding: Encoding,
}

/// How far beyond the trained range a domain reaches.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Margin {
    pub length_factor: f64,
    /// How much stiffer or softer, relative to its tree, a branch may be
    /// than any trained on.
    pub stiffness_ratio_factor: f64,
    pub push_factor: f64,
}

impl Margin {
    pub const STANDARD: Margin = Margin {
        length_factor: 1.5,
        stiffness_ratio_factor: 2.0,
        push_factor: 2.0,
    };
}

/// The trees and pushes of a training split, as raw ranges.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Span {
    pub tree_height: Interval,
    pub branch_length: Interval,
    pub branch_radius: Interval,
    pub stiffness_log_ratio: Interval,
    pub push_length: Interval,
}

impl Default for Span {
    fn default() -> Self {
        Self {
            tree_height: Interval::EMPTY,
            branch_length: Interval::EMPTY,
            branch_radius: Interval::EMPTY,
            stiffness_log_ratio: Interval::EMPTY,
            push_length: Interval::EMPTY,
        }
    }
}

impl Span {
    pub fn add_tree(&mut self, tree: &Tree) {
        self.tree_height.include(tree_height(tree));
        let kappa = log_stiffness_ratios(tree);
        for (j, b) in tree.branches_iter() {
            self.branch_length.include(b.length);
            self.branch_radius.include(b.radius);
            self.stiffness_log_ratio.include(kappa[j]);
        }
    }

    pub fn add_push(&mut self, length: f64) {
        self.push_length.include(length);
    }

    /// The domain this span gives with `margin`; `nodes` is the range of
    /// sizes the model is evaluated on.
    pub fn domain(&self, margin: Margin, nodes: (usize, usize)) -> Domain {
        Domain {
            tree_height: self.tree_height.widened(margin.length_factor),
            branch_length: self.branch_length.widened(margin.length_factor),
            branch_radius: self.branch_radius.widened(margin.length_factor),
            stiffness_log_ratio: self
                .stiffness_log_ratio
                .widened_by(margin.stiffness_ratio_factor.ln()),
            push_length: self.push_length.widened(margin.push_factor),
            nodes,
            encoding: Encoding::Full,
        }
    }
}

/// Highest node above the root (m).
pub fn tree_height(tree: &Tree) -> f64 {
    let root = tree.position(0).z;
    tree.positions()
        .iter()
        .map(|p| p.z - root)
        .fold(0.0, f64::max)
}

/// One quantity outside the domain.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Violation {
    /// `tree_height`, `branch_length`, `branch_radius`,
    /// `stiffness_log_ratio`, `push_length`, `nodes` or `path_joints`.
    pub quantity: &'static str,
    pub value: f64,
    pub min: f64,
    pub max: f64,
    /// The node whose branch (or push) it is; `None` for whole-tree
    /// quantities.
    pub node: Option<usize>,
    /// False for what only earns a warning (tree size).
    pub refused: bool,
}

impl std::fmt::Display for Violation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let at = self
            .node
            .map(|n| format!(" at node {n}"))
            .unwrap_or_default();
        write!(
            f,
            "{}{at} is {:.4e}, outside the model's domain [{:.4e}, {:.4e}]",
            self.quantity, self.value, self.min, self.max
        )
    }
}

impl Domain {
    /// Everything about `tree` outside the domain, tree-wide quantities
    /// first, then per branch in node order.
    pub fn check_tree(&self, tree: &Tree) -> Vec<Violation> {
        let mut out = Vec::new();
        let mut check = |quantity, interval: Interval, value: f64, node| {
            if !interval.contains(value) {
                out.push(Violation {
                    quantity,
                    value,
                    min: interval.min,
                    max: interval.max,
                    node,
                    refused: true,
                });
            }
        };
        let path = self.encoding.is_path();
        if !path {
            check("tree_height", self.tree_height, tree_height(tree), None);
        }
        let kappa = log_stiffness_ratios(tree);
        for (j, b) in tree.branches_iter() {
            check("branch_length", self.branch_length, b.length, Some(j));
            if path {
                continue;
            }
            check("branch_radius", self.branch_radius, b.radius, Some(j));
            check(
                "stiffness_log_ratio",
                self.stiffness_log_ratio,
                kappa[j],
                Some(j),
            );
        }
        let n = tree.len();
        if !path && (n < self.nodes.0 || n > self.nodes.1) {
            out.push(Violation {
                quantity: "nodes",
                value: n as f64,
                min: self.nodes.0 as f64,
                max: self.nodes.1 as f64,
                node: None,
                refused: false,
            });
        }
        out
    }

    /// A path model's check of the branches a push at `node` moves: the
    /// path's depth against what one path graph holds ([`path_fits`]), and each branch's κ relative to the
    /// path's mean (what the model reads) against the trained range. Empty
    /// for the paper's encoding.
    pub fn check_path(&self, tree: &Tree, node: usize) -> Vec<Violation> {
        if !self.encoding.is_path() || node == 0 || node >= tree.len() {
            return Vec::new();
        }
        if !path_fits(tree, node) {
            return vec![Violation {
                quantity: "path_joints",
                value: tree.depth(node) as f64,
                min: 1.0,
                max: PATH_MAX_JOINTS as f64,
                node: Some(node),
                refused: true,
            }];
        }
        let mut path = tree.path_to_root(node);
        path.pop();
        let logs: Vec<f64> = path
            .iter()
            .map(|&j| tree.branch(j).map_or(0.0, |b| b.stiffness.ln()))
            .collect();
        let mean = logs.iter().sum::<f64>() / logs.len().max(1) as f64;
        path.iter()
            .zip(&logs)
            .filter(|(_, l)| !self.stiffness_log_ratio.contains(*l - mean))
            .map(|(&j, l)| Violation {
                quantity: "stiffness_log_ratio",
                value: l - mean,
                min: self.stiffness_log_ratio.min,
                max: self.stiffness_log_ratio.max,
                node: Some(j),
                refused: true,
            })
            .collect()
    }

    /// A push of `length` (m) at `node`, if outside the domain.
    pub fn check_push(&self, node: usize, length: f64) -> Option<Violation> {
        (!self.push_length.contains(length)).then_some(Violation {
            quantity: "push_length",
            value: length,
            min: self.push_length.min,
            max: self.push_length.max,
            node: Some(node),
            refused: true,
        })
    }
}
