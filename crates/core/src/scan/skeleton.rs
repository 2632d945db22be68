//! A tree's skeleton as geometry only: node positions, parents and the
//! radius of the branch ending at each node. It is what an extraction
//! returns and what the scan metrics compare; [`Skeleton::to_tree`] gives
//! it stiffness from [`Wood`] for the simulator and the planner.

use nalgebra::Point3;

use crate::tree::render::{Dots, Figure, Layer};
use crate::tree::{Tree, TreeError, Wood};

/// Node 0 is the root; `parents[j] < j` is not required, but the parent
/// chain of every node ends at node 0. `radius[j]` (m) belongs to the
/// branch from `parents[j]` to j (the root's entry is its trunk radius).
#[derive(Debug, Clone, PartialEq)]
pub struct Skeleton {
    pub positions: Vec<Point3<f64>>,
    pub parents: Vec<Option<usize>>,
    pub radius: Vec<f64>,
}

/// One branch in the botanical sense: the nodes from a branch point (or
/// the root) to the next branch point or tip, `nodes[0]` being the node it
/// grows from.
#[derive(Debug, Clone, PartialEq)]
pub struct Chain {
    pub nodes: Vec<usize>,
    /// The chain that `nodes[0]` ends, if any.
    pub parent: Option<usize>,
}

impl Skeleton {
    /// The geometry of a tree.
    pub fn of_tree(tree: &Tree) -> Self {
        let radius = (0..tree.len())
            .map(|j| match tree.branch(j) {
                Some(b) => b.radius,
                None => tree
                    .children(j)
                    .iter()
                    .filter_map(|&c| tree.branch(c))
                    .map(|b| b.radius)
                    .fold(0.0, f64::max),
            })
            .collect();
        Self {
            positions: tree.positions().to_vec(),
            parents: tree.parents().to_vec(),
            radius,
        }
    }

    pub fn len(&self) -> usize {
        self.positions.len()
    }

    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    pub fn children(&self) -> Vec<Vec<usize>> {
        let mut children = vec![Vec::new(); self.len()];
        for (j, p) in self.parents.iter().enumerate() {
            if let Some(p) = p {
                children[*p].push(j);
            }
        }
        children
    }

    /// The segments parent → node with the node's branch radius.
    pub fn segments(&self) -> impl Iterator<Item = (Point3<f64>, Point3<f64>, f64)> + '_ {
        self.parents
            .iter()
            .enumerate()
            .filter_map(|(j, p)| p.map(|p| (self.positions[p], self.positions[j], self.radius[j])))
    }

    /// The branches between branch points, root chains first; and for each
    /// node (not the root) the chain its incoming segment belongs to.
    pub fn chains(&self) -> (Vec<Chain>, Vec<Option<usize>>) {
        let children = self.children();
        let mut chains = Vec::new();
        let mut chain_of = vec![None; self.len()];
        // (start node, parent chain)
        let mut stack: Vec<(usize, Option<usize>)> = vec![(0, None)];
        // Each node is walked once; a parent cycle (which no stage should
        // make) ends the walk instead of growing a chain without end.
        let mut walked = vec![false; self.len()];
        while let Some((start, parent)) = stack.pop() {
            for &first in children[start].iter().rev() {
                if std::mem::replace(&mut walked[first], true) {
                    continue;
                }
                let id = chains.len();
                let mut nodes = vec![start, first];
                let mut at = first;
                chain_of[first] = Some(id);
                while children[at].len() == 1
                    && !std::mem::replace(&mut walked[children[at][0]], true)
                {
                    at = children[at][0];
                    chain_of[at] = Some(id);
                    nodes.push(at);
                }
                chains.push(Chain { nodes, parent });
                if !children[at].is_empty() {
                    stack.push((at, Some(id)));
                }
            }
        }
        (chains, chain_of)
    }

    /// Nodes with two or more children: where branches fork.
    pub fn branch_points(&self) -> Vec<usize> {
        self.children()
            .iter()
            .enumerate()
            .filter(|(_, c)| c.len() >= 2)
            .map(|(j, _)| j)
            .collect()
    }

    /// A tree for the simulator: stiffness from `wood` and each branch's
    /// radius and length; fails where the tree model does (too many nodes,
    /// two nodes at one place).
    pub fn to_tree(&self, wood: &Wood) -> Result<Tree, TreeError> {
        let branches = self
            .parents
            .iter()
            .enumerate()
            .map(|(j, p)| {
                p.map(|p| {
                    let length = (self.positions[j] - self.positions[p]).norm();
                    wood.branch(self.radius[j], length)
                })
            })
            .collect();
        Tree::new(self.positions.clone(), self.parents.clone(), branches)
    }
}

/// A picture of a cloud (grey dots) and the skeleton found in it (bark
/// brown, nodes numbered), with the true tree in green beneath when known.
pub fn cloud_svg(
    points: &[Point3<f64>],
    skeleton: &Skeleton,
    truth: Option<&Skeleton>,
    title: &str,
) -> String {
    let layer = |s: &Skeleton| Layer {
        parents: s.parents.clone(),
        radius: s.radius.clone(),
        positions: s.positions.clone(),
        colour: "#6b4423".to_owned(),
        opacity: 0.9,
        label_nodes: s.len() <= 200,
    };
    let mut layers = Vec::new();
    if let Some(t) = truth {
        layers.push(Layer {
            colour: "#2ca02c".to_owned(),
            opacity: 0.5,
            label_nodes: false,
            ..layer(t)
        });
    }
    layers.push(layer(skeleton));
    Figure {
        title: title.to_owned(),
        dots: vec![Dots {
            points: points.to_vec(),
            colour: "#9a9a9a".to_owned(),
        }],
        layers,
        arrows: Vec::new(),
    }
    .to_svg()
}

/// Distance from `p` to the segment a–b, and where along it (0 at a, 1 at b).
pub fn point_segment(p: &Point3<f64>, a: &Point3<f64>, b: &Point3<f64>) -> (f64, f64) {
    let ab = b - a;
    let len2 = ab.norm_squared();
    let t = if len2 > 0.0 {
        ((p - a).dot(&ab) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    ((a + ab * t - p).norm(), t)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chains_run_between_branch_points() {
        // 0 - 1 - 2 < (3 - 4), (5)
        let positions = (0..6).map(|i| Point3::new(0.0, i as f64, 0.0)).collect();
        let skeleton = Skeleton {
            positions,
            parents: vec![None, Some(0), Some(1), Some(2), Some(3), Some(2)],
            radius: vec![0.01; 6],
        };
        let (chains, chain_of) = skeleton.chains();
        assert_eq!(chains.len(), 3);
        assert_eq!(chains[0].nodes, vec![0, 1, 2]);
        assert_eq!(chains[0].parent, None);
        let mut rest: Vec<_> = chains[1..].iter().map(|c| c.nodes.clone()).collect();
        rest.sort();
        assert_eq!(rest, vec![vec![2, 3, 4], vec![2, 5]]);
        assert!(chains[1..].iter().all(|c| c.parent == Some(0)));
        assert_eq!(chain_of[0], None);
        assert_eq!(chain_of[2], Some(0));
        assert_eq!(skeleton.branch_points(), vec![2]);
    }

    /// A parent cycle through the root (a bug upstream once made one, and
    /// the walk then grew a chain until memory ran out) ends the walk.
    #[test]
    fn a_parent_cycle_does_not_walk_forever() {
        let positions = (0..4).map(|i| Point3::new(0.0, i as f64, 0.0)).collect();
        let skeleton = Skeleton {
            positions,
            parents: vec![Some(2), Some(0), Some(1), Some(1)],
            radius: vec![0.01; 4],
        };
        let (chains, _) = skeleton.chains();
        let walked: usize = chains.iter().map(|c| c.nodes.len() - 1).sum();
        assert!(walked <= 4, "{chains:?}");
    }

    #[test]
    fn point_to_segment_distance_is_the_closed_form() {
        let (a, b) = (Point3::new(0.0, 0.0, 0.0), Point3::new(0.0, 0.0, 2.0));
        let (d, t) = point_segment(&Point3::new(3.0, 4.0, 1.0), &a, &b);
        assert!((d - 5.0).abs() < 1e-12 && (t - 0.5).abs() < 1e-12);
        let (d, t) = point_segment(&Point3::new(0.0, 0.0, 5.0), &a, &b);
        assert!((d - 3.0).abs() < 1e-12 && t == 1.0);
    }
}
