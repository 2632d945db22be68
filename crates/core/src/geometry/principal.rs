//! The principal directions of a point set: the eigenvectors of the
//! points' covariance, largest spread first.
//!
//! One computation behind every place that asks which way points run: a
//! scanned branch's axis and whether a cloud is flat (`scan`), and a link
//! mesh's long axis when it is fitted with a capsule or a box
//! (`robot::model::mesh_fit`).

use nalgebra::{Matrix3, Point3, SymmetricEigen, Vector3};

/// How points spread about their mean.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Principal {
    /// The points' mean (m).
    pub mean: Point3<f64>,
    /// The standard deviation along each of [`Principal::axes`] (m),
    /// largest first.
    pub spread: [f64; 3],
    /// The principal directions (unit), in the order of `spread`; any
    /// orthonormal three when the points are all one point.
    pub axes: [Vector3<f64>; 3],
}

/// The principal directions of `points` (an empty slice reads as one point
/// at the origin).
pub fn principal(points: &[Point3<f64>]) -> Principal {
    let n = points.len().max(1) as f64;
    let mean = points.iter().fold(Vector3::zeros(), |s, p| s + p.coords) / n;
    let mut cov = Matrix3::zeros();
    for p in points {
        let d = p.coords - mean;
        cov += d * d.transpose();
    }
    cov /= n;
    let eig = SymmetricEigen::new(cov);
    let mut order = [0usize, 1, 2];
    order.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
    Principal {
        mean: Point3::from(mean),
        spread: order.map(|i| eig.eigenvalues[i].max(0.0).sqrt()),
        axes: order.map(|i| eig.eigenvectors.column(i).into_owned()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Points on a slanted rectangle 0.4 × 0.1 m: the long side first, the
    /// short side second, the normal last with no spread.
    #[test]
    fn a_rectangles_long_side_comes_first_and_its_normal_last() {
        let long = Vector3::new(1.0, 1.0, 0.0).normalize();
        let short = Vector3::new(0.0, 0.0, 1.0);
        let corner = Point3::new(0.3, -0.2, 1.0);
        let points: Vec<Point3<f64>> = (0..=20)
            .flat_map(|i| {
                (0..=5).map(move |j| corner + long * (0.02 * i as f64) + short * (0.02 * j as f64))
            })
            .collect();
        let p = principal(&points);
        assert!(p.spread[0] > p.spread[1] && p.spread[1] > 1e-3);
        assert!(p.spread[2] < 1e-7, "{:?}", p.spread);
        assert!(p.axes[0].dot(&long).abs() > 1.0 - 1e-9);
        assert!(p.axes[1].dot(&short).abs() > 1.0 - 1e-9);
        let centre = corner + long * 0.2 + short * 0.05;
        assert!((p.mean - centre).norm() < 1e-12);
        // A uniform grid of 21 points over 0.4 m: σ² = 0.02² (21² − 1) / 12.
        let sigma = 0.02 * ((21.0f64 * 21.0 - 1.0) / 12.0).sqrt();
        assert!((p.spread[0] - sigma).abs() < 1e-12, "{}", p.spread[0]);
    }
}
