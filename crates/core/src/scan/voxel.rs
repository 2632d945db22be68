//! Points averaged in cubes: a cloud of any density becomes one point per
//! occupied cube of edge `voxel`, weighted by how many points it stands for.

use std::collections::HashMap;

use nalgebra::{Point3, Vector3};

/// The occupied cubes' mean points and counts, in first-seen order.
#[derive(Debug, Clone, Default)]
pub struct Voxels {
    pub centres: Vec<Point3<f64>>,
    pub counts: Vec<usize>,
    /// Each input point's cube (an index into `centres`).
    pub of_point: Vec<usize>,
}

impl Voxels {
    /// Each cube's input points, grouped by cube.
    pub fn members(&self) -> CubeMembers {
        let mut start = vec![0usize; self.centres.len() + 1];
        for &c in &self.of_point {
            start[c + 1] += 1;
        }
        for c in 0..self.centres.len() {
            start[c + 1] += start[c];
        }
        let mut next = start.clone();
        let mut order = vec![0usize; self.of_point.len()];
        for (i, &c) in self.of_point.iter().enumerate() {
            order[next[c]] = i;
            next[c] += 1;
        }
        CubeMembers { start, order }
    }
}

/// The input points of every cube ([`Voxels::members`]).
#[derive(Debug, Clone, Default)]
pub struct CubeMembers {
    start: Vec<usize>,
    order: Vec<usize>,
}

impl CubeMembers {
    /// The input points (indices) cube `c` averages.
    pub fn of(&self, c: usize) -> &[usize] {
        &self.order[self.start[c]..self.start[c + 1]]
    }
}

pub fn voxelize(points: &[Point3<f64>], voxel: f64) -> Voxels {
    let mut slot: HashMap<[i64; 3], usize> = HashMap::with_capacity(points.len() / 4);
    let mut sums: Vec<Vector3<f64>> = Vec::new();
    let mut counts = Vec::new();
    let mut of_point = Vec::with_capacity(points.len());
    for p in points {
        let key = [
            (p.x / voxel).floor() as i64,
            (p.y / voxel).floor() as i64,
            (p.z / voxel).floor() as i64,
        ];
        let k = *slot.entry(key).or_insert_with(|| {
            sums.push(Vector3::zeros());
            counts.push(0);
            counts.len() - 1
        });
        sums[k] += p.coords;
        counts[k] += 1;
        of_point.push(k);
    }
    Voxels {
        centres: sums
            .iter()
            .zip(&counts)
            .map(|(s, &c)| Point3::from(s / c as f64))
            .collect(),
        counts,
        of_point,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn points_in_one_cube_become_their_mean() {
        let points = [
            Point3::new(0.001, 0.001, 0.001),
            Point3::new(0.003, 0.001, 0.001),
            Point3::new(0.011, 0.0, 0.0),
        ];
        let v = voxelize(&points, 0.004);
        assert_eq!(v.counts, vec![2, 1]);
        assert_eq!(v.of_point, vec![0, 0, 1]);
        assert!((v.centres[0] - Point3::new(0.002, 0.001, 0.001)).norm() < 1e-12);
        let members = v.members();
        assert_eq!(members.of(0), &[0, 1]);
        assert_eq!(members.of(1), &[2]);
    }
}
