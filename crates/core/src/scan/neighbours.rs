//! The neighbourhood graph of a point cloud: each point joined to its
//! nearest neighbours within a link radius (kiddo's k-d tree), stored as
//! compressed adjacency lists, with connected components (petgraph's
//! union-find) and shortest paths from a set of sources.

use std::cmp::Ordering;
use std::collections::BinaryHeap;
use std::num::NonZero;

use kiddo::SquaredEuclidean;
use kiddo::immutable::float::kdtree::ImmutableKdTree;
use nalgebra::Point3;
use petgraph::unionfind::UnionFind;
use rayon::prelude::*;

/// A k-d tree over points, answering by the points' indices.
pub struct PointIndex {
    tree: ImmutableKdTree<f64, u32, 3, 32>,
}

impl PointIndex {
    pub fn new(points: &[Point3<f64>]) -> Self {
        let coords: Vec<[f64; 3]> = points.iter().map(|p| [p.x, p.y, p.z]).collect();
        Self {
            tree: ImmutableKdTree::new_from_slice(&coords),
        }
    }

    /// The nearest point's index and its distance.
    pub fn nearest(&self, p: &Point3<f64>) -> (usize, f64) {
        let n = self.tree.nearest_one::<SquaredEuclidean>(&[p.x, p.y, p.z]);
        (n.item as usize, n.distance.sqrt())
    }

    /// Up to `k` nearest points within `radius`, nearest first, with their
    /// distances.
    pub fn near(&self, p: &Point3<f64>, k: usize, radius: f64) -> Vec<(usize, f64)> {
        let Some(k) = NonZero::new(k) else {
            return Vec::new();
        };
        self.tree
            .nearest_n_within::<SquaredEuclidean>(&[p.x, p.y, p.z], radius * radius, k, true)
            .into_iter()
            .map(|n| (n.item as usize, n.distance.sqrt()))
            .collect()
    }
}

/// Undirected weighted adjacency lists (weights: Euclidean lengths, m).
#[derive(Debug, Clone, Default)]
pub struct Graph {
    offsets: Vec<usize>,
    targets: Vec<u32>,
    lengths: Vec<f64>,
}

impl Graph {
    /// Joins each point to its `k` nearest within `radius` (both ways).
    pub fn knn(points: &[Point3<f64>], index: &PointIndex, k: usize, radius: f64) -> Self {
        let lists: Vec<Vec<(usize, f64)>> = points
            .par_iter()
            .enumerate()
            .map(|(i, p)| {
                index
                    .near(p, k + 1, radius)
                    .into_iter()
                    .filter(|(j, _)| *j != i)
                    .collect()
            })
            .collect();
        let mut edges = Vec::new();
        for (i, list) in lists.iter().enumerate() {
            for &(j, d) in list {
                edges.push((i, j, d));
            }
        }
        Self::from_edges(points.len(), &edges)
    }

    /// Both directions of every edge; duplicates are kept once.
    pub fn from_edges(n: usize, edges: &[(usize, usize, f64)]) -> Self {
        let mut lists: Vec<Vec<(u32, f64)>> = vec![Vec::new(); n];
        for &(a, b, d) in edges {
            lists[a].push((b as u32, d));
            lists[b].push((a as u32, d));
        }
        let mut graph = Graph {
            offsets: Vec::with_capacity(n + 1),
            ..Graph::default()
        };
        graph.offsets.push(0);
        for mut list in lists {
            list.sort_by_key(|e| e.0);
            list.dedup_by_key(|e| e.0);
            for (t, d) in list {
                graph.targets.push(t);
                graph.lengths.push(d);
            }
            graph.offsets.push(graph.targets.len());
        }
        graph
    }

    pub fn len(&self) -> usize {
        self.offsets.len().saturating_sub(1)
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The neighbours of `i` and the edge lengths.
    pub fn neighbours(&self, i: usize) -> impl Iterator<Item = (usize, f64)> + '_ {
        let range = self.offsets[i]..self.offsets[i + 1];
        self.targets[range.clone()]
            .iter()
            .zip(&self.lengths[range])
            .map(|(&t, &d)| (t as usize, d))
    }

    /// Every edge once, `(a, b, length)` with `a < b`.
    pub fn edges(&self) -> Vec<(usize, usize, f64)> {
        (0..self.len())
            .flat_map(|a| {
                self.neighbours(a)
                    .filter(move |&(b, _)| a < b)
                    .map(move |(b, d)| (a, b, d))
            })
            .collect()
    }

    pub fn degree(&self, i: usize) -> usize {
        self.offsets[i + 1] - self.offsets[i]
    }

    /// Connected components restricted to edges `keep(a, b)` accepts:
    /// each point's component label, labels 0.. by first appearance.
    pub fn components(&self, keep: impl Fn(usize, usize) -> bool) -> Vec<usize> {
        let n = self.len();
        let mut sets = UnionFind::<usize>::new(n);
        for a in 0..n {
            for (b, _) in self.neighbours(a) {
                if a < b && keep(a, b) {
                    sets.union(a, b);
                }
            }
        }
        compact_labels(&mut sets, 0..n)
    }

    /// Shortest path lengths from the nearest of `sources` (Dijkstra),
    /// and each point's predecessor on its path (`None` for a source or an
    /// unreached point; unreached points have an infinite distance).
    pub fn shortest_paths(&self, sources: &[usize]) -> (Vec<f64>, Vec<Option<usize>>) {
        let n = self.len();
        let mut dist = vec![f64::INFINITY; n];
        let mut pred = vec![None; n];
        let mut heap = BinaryHeap::new();
        for &s in sources {
            dist[s] = 0.0;
            heap.push(Visit { dist: 0.0, node: s });
        }
        while let Some(Visit { dist: d, node }) = heap.pop() {
            if d > dist[node] {
                continue;
            }
            for (next, len) in self.neighbours(node) {
                let nd = d + len;
                if nd < dist[next] {
                    dist[next] = nd;
                    pred[next] = Some(node);
                    heap.push(Visit {
                        dist: nd,
                        node: next,
                    });
                }
            }
        }
        (dist, pred)
    }
}

/// A heap entry, smallest distance first.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Visit {
    dist: f64,
    node: usize,
}

impl Eq for Visit {}

impl Ord for Visit {
    fn cmp(&self, other: &Self) -> Ordering {
        other
            .dist
            .total_cmp(&self.dist)
            .then(self.node.cmp(&other.node))
    }
}

impl PartialOrd for Visit {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

/// The set of each of `items` in `sets`, numbered 0.. by first
/// appearance.
pub fn compact_labels(
    sets: &mut UnionFind<usize>,
    items: impl IntoIterator<Item = usize>,
) -> Vec<usize> {
    let mut label: Vec<usize> = Vec::new();
    let mut next = 0;
    items
        .into_iter()
        .map(|i| {
            let root = sets.find_mut(i);
            if root >= label.len() {
                label.resize(root + 1, usize::MAX);
            }
            if label[root] == usize::MAX {
                label[root] = next;
                next += 1;
            }
            label[root]
        })
        .collect()
}

/// Closest distance between two parts' points (m).
pub fn part_distance(points: &[Point3<f64>], labels: &[usize], a: usize, b: usize) -> f64 {
    let pa: Vec<_> = (0..points.len())
        .filter(|&i| labels[i] == a)
        .map(|i| points[i])
        .collect();
    let index = PointIndex::new(&pa);
    (0..points.len())
        .filter(|&i| labels[i] == b)
        .map(|i| index.nearest(&points[i]).1)
        .fold(f64::INFINITY, f64::min)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn two_lines_are_two_components_and_paths_follow_the_line() {
        let mut points: Vec<_> = (0..10)
            .map(|i| Point3::new(i as f64 * 0.01, 0.0, 0.0))
            .collect();
        points.extend((0..10).map(|i| Point3::new(i as f64 * 0.01, 1.0, 0.0)));
        let index = PointIndex::new(&points);
        let graph = Graph::knn(&points, &index, 4, 0.015);
        let labels = graph.components(|_, _| true);
        assert!(labels[..10].iter().all(|&l| l == labels[0]));
        assert!(labels[10..].iter().all(|&l| l == labels[10]));
        assert_ne!(labels[0], labels[10]);
        let (dist, pred) = graph.shortest_paths(&[0]);
        assert!((dist[9] - 0.09).abs() < 1e-12);
        assert_eq!(pred[9], Some(8));
        assert!(dist[10].is_infinite());
        assert_eq!(index.nearest(&Point3::new(0.031, 0.0, 0.0)).0, 3);
    }
}
