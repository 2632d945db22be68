//! A point cloud as a scanner delivers it, and the checks every cloud
//! passes before a tree is looked for in it: finite coordinates, a size
//! the caller allows, and a spread in three dimensions (a plane or a line
//! of points is no tree).

use nalgebra::{Point3, Vector3};

use crate::geometry::principal::principal;

/// Points (m) with optional per-point normals and colours (0-255 RGB).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PointCloud {
    pub points: Vec<Point3<f64>>,
    pub normals: Option<Vec<Vector3<f64>>>,
    pub colors: Option<Vec<[u8; 3]>>,
}

/// An axis-aligned box (m): points outside it are dropped before anything
/// else is done.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CropBox {
    pub min: Point3<f64>,
    pub max: Point3<f64>,
}

impl CropBox {
    pub fn contains(&self, p: &Point3<f64>) -> bool {
        (0..3).all(|i| self.min[i] <= p[i] && p[i] <= self.max[i])
    }
}

/// Why a cloud holds no tree that can be extracted. Each says what the
/// caller can change.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CloudError {
    #[error("the point cloud is empty")]
    Empty,
    #[error("the point cloud has {got} points, more than the limit of {max}")]
    TooMany { got: usize, max: usize },
    #[error("point {index} has a coordinate that is not a finite number")]
    NonFinite { index: usize },
    #[error("`{field}` has {got} entries but `points` has {expected}")]
    LengthMismatch {
        field: &'static str,
        expected: usize,
        got: usize,
    },
    #[error(
        "{kept} points remain inside the crop box (foliage-green ones dropped); at least {min} are needed"
    )]
    TooFewInCrop { kept: usize, min: usize },
    #[error("only {got} points remain after outliers are removed; at least {min} are needed")]
    TooFew { got: usize, min: usize },
    #[error(
        "the points lie {what} (spread {spread_mm:.2} mm across it): a tree needs points spread in three dimensions"
    )]
    Degenerate { what: &'static str, spread_mm: f64 },
    #[error(
        "the root given, ({x:.3}, {y:.3}, {z:.3}), is {distance:.3} m from the nearest point; it must be within {max:.3} m of the cloud"
    )]
    RootOutside {
        x: f64,
        y: f64,
        z: f64,
        distance: f64,
        max: f64,
    },
    #[error("`up` must be a finite, non-zero vector")]
    BadUp,
    #[error(
        "viewpoint {index} lies among the points ({distance:.3} m from the nearest; a sensor sees them from at least {min:.3} m): send where the sensor stood in the cloud's own frame"
    )]
    ViewpointAmongPoints {
        index: usize,
        distance: f64,
        min: f64,
    },
    /// An option out of its range; `field` names it as the request does.
    #[error("{message}")]
    BadParameter {
        field: &'static str,
        message: String,
    },
    #[error(
        "no tree-like component: the largest connected part has {largest} points spanning {extent:.3} m; a tree needs a connected part at least {min_extent:.3} m tall"
    )]
    NoTree {
        largest: usize,
        extent: f64,
        min_extent: f64,
    },
    #[error(
        "the cloud holds several trees: a second connected part of {points} points rises from the ground {distance:.2} m from the first; crop the cloud to one tree (`crop`) or give its `root`"
    )]
    SeveralTrees { points: usize, distance: f64 },
}

/// Below this spread (m, the standard deviation across the cloud's
/// thinnest direction) points are a plane; a tree's thinnest twig is 5
/// mm thick and a crown spreads much further.
pub const FLAT_SPREAD: f64 = 1e-3;

impl PointCloud {
    pub fn new(points: Vec<Point3<f64>>) -> Self {
        Self {
            points,
            ..Self::default()
        }
    }

    pub fn len(&self) -> usize {
        self.points.len()
    }

    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Checks what every cloud must satisfy: not empty, at most `max_points`,
    /// finite coordinates, optional arrays as long as `points`.
    pub fn check(&self, max_points: usize) -> Result<(), CloudError> {
        if self.points.is_empty() {
            return Err(CloudError::Empty);
        }
        if self.points.len() > max_points {
            return Err(CloudError::TooMany {
                got: self.points.len(),
                max: max_points,
            });
        }
        if let Some(index) = self
            .points
            .iter()
            .position(|p| !p.iter().all(|c| c.is_finite()))
        {
            return Err(CloudError::NonFinite { index });
        }
        let n = self.points.len();
        if let Some(normals) = &self.normals
            && normals.len() != n
        {
            return Err(CloudError::LengthMismatch {
                field: "normals",
                expected: n,
                got: normals.len(),
            });
        }
        if let Some(colors) = &self.colors
            && colors.len() != n
        {
            return Err(CloudError::LengthMismatch {
                field: "colors",
                expected: n,
                got: colors.len(),
            });
        }
        Ok(())
    }
}

/// Refuses points that lie in a plane or along a line: a scan of a wall,
/// the ground or a single wire is not a tree.
pub fn check_spread(points: &[Point3<f64>]) -> Result<(), CloudError> {
    let spread = principal(points).spread;
    if spread[1] < FLAT_SPREAD {
        return Err(CloudError::Degenerate {
            what: if spread[0] < FLAT_SPREAD {
                "at one point"
            } else {
                "along a line"
            },
            spread_mm: spread[1] * 1e3,
        });
    }
    if spread[2] < FLAT_SPREAD {
        return Err(CloudError::Degenerate {
            what: "in a plane",
            spread_mm: spread[2] * 1e3,
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn planes_and_lines_are_refused_and_a_crown_is_not() {
        let plane: Vec<_> = (0..400)
            .map(|i| Point3::new((i % 20) as f64 * 0.01, (i / 20) as f64 * 0.01, 0.3))
            .collect();
        assert!(matches!(
            check_spread(&plane),
            Err(CloudError::Degenerate {
                what: "in a plane",
                ..
            })
        ));
        let line: Vec<_> = (0..100)
            .map(|i| Point3::new(0.0, 0.0, i as f64 * 0.01))
            .collect();
        assert!(matches!(
            check_spread(&line),
            Err(CloudError::Degenerate {
                what: "along a line",
                ..
            })
        ));
        let ball: Vec<_> = (0..1000)
            .map(|i| {
                let (a, b) = (i as f64 * 0.37, i as f64 * 0.11);
                Point3::new(a.cos() * b.sin(), a.sin() * b.sin(), b.cos())
            })
            .collect();
        assert!(check_spread(&ball).is_ok());
    }

    #[test]
    fn non_finite_points_and_mismatched_normals_are_named() {
        let mut cloud = PointCloud::new(vec![Point3::origin(), Point3::new(f64::NAN, 0.0, 0.0)]);
        assert_eq!(cloud.check(10), Err(CloudError::NonFinite { index: 1 }));
        cloud.points[1].x = 1.0;
        cloud.normals = Some(vec![Vector3::z()]);
        assert!(matches!(
            cloud.check(10),
            Err(CloudError::LengthMismatch {
                field: "normals",
                ..
            })
        ));
        assert_eq!(cloud.check(1), Err(CloudError::TooMany { got: 2, max: 1 }));
        assert_eq!(PointCloud::default().check(1), Err(CloudError::Empty));
    }
}
