//! What a sensor could not see: the shadows its returns cast.
//!
//! A sensor at a known place sees along rays. A point of space with a
//! return nearer along its ray is hidden behind that return (a leaf, a
//! branch in front); a point whose ray came back from farther away, or
//! from nothing, was seen empty. The extraction uses it to tell a gap in
//! a branch's points that something in front hid (bridged, as a gap under
//! leaves is: [`crate::scan::bridge`]) from one it looked through.
//!
//! Each viewpoint's returns go into a depth image: a pinhole camera looking
//! at the cloud's centre, square pixels [`PIXEL_AT_TREE`] across at the
//! returns' median range (the tree's scale, leaves and twigs, whatever the
//! sensor's distance), each keeping its nearest return. A point is hidden
//! when some pixel within one of its own has a return at least
//! [`IN_FRONT`] nearer: the one-pixel margin stands for the gaps between
//! returns on a surface. A sparse scan leaves pixels empty, which reads as
//! seen: it bridges less, never more.

use nalgebra::{Point3, Vector3};

use crate::scan::CloudError;

/// A depth image's pixel (m) at the returns' median range: coarser than
/// the spacing of a camera's or a terrestrial scanner's returns on a tree
/// (5 mrad at 1.5 m), finer than a leaf.
pub const PIXEL_AT_TREE: f64 = 0.0075;
/// Bounds on a pixel's angle (radians): at most about 5,000 pixels across
/// the view's cone, at least a coarse 0.05 rad.
const PIXEL_ANGLE: (f64, f64) = (0.001, 0.05);
/// A return hides what lies at least this much (m) farther along its ray:
/// more than depth noise and a twig's own thickness, so a branch does not
/// hide itself.
pub const IN_FRONT: f64 = 0.02;
/// Rays this far (radians) or more off a view's axis are not imaged.
const MAX_OFF_AXIS: f64 = 1.2;

/// One viewpoint's depth image.
struct View {
    eye: Point3<f64>,
    /// The pixel's angle (radians).
    pixel: f64,
    /// The view's axis (towards the cloud's centre) and two axes across.
    axes: [Vector3<f64>; 3],
    /// The image's first pixel and its size in pixels (the returns'
    /// extent, at most `2 · tan(MAX_OFF_AXIS) / pixel` a side).
    origin: (i64, i64),
    size: (usize, usize),
    /// Each pixel's nearest return (m), row by row; infinite where none.
    nearest: Vec<f32>,
}

impl View {
    /// Where `p` falls on the image plane (tangents of its angles off the
    /// axis) and its range, if the view's cone holds it.
    fn project(
        eye: &Point3<f64>,
        axes: &[Vector3<f64>; 3],
        p: &Point3<f64>,
    ) -> Option<((f64, f64), f64)> {
        let d = p - eye;
        let range = d.norm();
        let ahead = d.dot(&axes[0]);
        if range <= 0.0 || ahead <= range * MAX_OFF_AXIS.cos() {
            return None;
        }
        Some(((d.dot(&axes[1]) / ahead, d.dot(&axes[2]) / ahead), range))
    }

    /// The pixel `p` falls in (unbounded) and its range.
    fn pixel(&self, p: &Point3<f64>) -> Option<((i64, i64), f64)> {
        let ((u, v), range) = Self::project(&self.eye, &self.axes, p)?;
        Some((
            (
                (u / self.pixel).floor() as i64,
                (v / self.pixel).floor() as i64,
            ),
            range,
        ))
    }

    fn new(eye: Point3<f64>, axes: [Vector3<f64>; 3], returns: &[Point3<f64>]) -> Option<Self> {
        let projected: Vec<((f64, f64), f64)> = returns
            .iter()
            .filter_map(|p| Self::project(&eye, &axes, p))
            .collect();
        if projected.is_empty() {
            return None;
        }
        let mut ranges: Vec<f64> = projected.iter().map(|&(_, r)| r).collect();
        let mid = ranges.len() / 2;
        let median = *ranges.select_nth_unstable_by(mid, f64::total_cmp).1;
        let pixel = (PIXEL_AT_TREE / median).clamp(PIXEL_ANGLE.0, PIXEL_ANGLE.1);
        let seen: Vec<((i64, i64), f64)> = projected
            .iter()
            .map(|&((u, v), range)| {
                (
                    ((u / pixel).floor() as i64, (v / pixel).floor() as i64),
                    range,
                )
            })
            .collect();
        let (lo, hi) = seen.iter().fold(
            ((i64::MAX, i64::MAX), (i64::MIN, i64::MIN)),
            |(lo, hi), &((i, j), _)| ((lo.0.min(i), lo.1.min(j)), (hi.0.max(i), hi.1.max(j))),
        );
        let size = ((hi.0 - lo.0 + 1) as usize, (hi.1 - lo.1 + 1) as usize);
        let mut view = Self {
            eye,
            pixel,
            axes,
            origin: lo,
            size,
            nearest: vec![f32::INFINITY; size.0 * size.1],
        };
        for ((i, j), range) in seen {
            let k = view.index(i, j).expect("within the extent");
            view.nearest[k] = view.nearest[k].min(range as f32);
        }
        Some(view)
    }

    fn index(&self, i: i64, j: i64) -> Option<usize> {
        let (x, y) = (i - self.origin.0, j - self.origin.1);
        (x >= 0 && y >= 0 && (x as usize) < self.size.0 && (y as usize) < self.size.1)
            .then(|| y as usize * self.size.0 + x as usize)
    }

    fn hides(&self, p: &Point3<f64>) -> bool {
        let Some(((i, j), range)) = self.pixel(p) else {
            return false;
        };
        (-1..=1).any(|di| {
            (-1..=1).any(|dj| {
                self.index(i + di, j + dj)
                    .is_some_and(|k| f64::from(self.nearest[k]) <= range - IN_FRONT)
            })
        })
    }
}

/// The nearest (m) a sensor's returns may be to it: a close-range depth
/// camera's least range is 7 cm.
pub const MIN_SENSOR_RANGE: f64 = 0.05;

/// A sensor stands apart from what it sees: a viewpoint among the points
/// was given in another frame (a world frame's origin at the trunk's foot
/// sent as a camera's `[0, 0, 0]`), and its shadows would be nonsense.
pub fn check_viewpoints(
    returns: &[Point3<f64>],
    viewpoints: &[Point3<f64>],
) -> Result<(), CloudError> {
    for (index, eye) in viewpoints.iter().enumerate() {
        let distance = returns
            .iter()
            .map(|p| (p - eye).norm_squared())
            .fold(f64::INFINITY, f64::min)
            .sqrt();
        if distance < MIN_SENSOR_RANGE {
            return Err(CloudError::ViewpointAmongPoints {
                index,
                distance,
                min: MIN_SENSOR_RANGE,
            });
        }
    }
    Ok(())
}

/// The shadows of a cloud's returns from the viewpoints it was seen from.
pub struct Shadows {
    views: Vec<View>,
}

impl Shadows {
    /// The depth images of `returns` (every point the sensor gave back,
    /// leaves and outliers too) seen from `viewpoints`. `None` without
    /// viewpoints or returns.
    pub fn new(returns: &[Point3<f64>], viewpoints: &[Point3<f64>]) -> Option<Self> {
        if returns.is_empty() || viewpoints.is_empty() {
            return None;
        }
        let centre = Point3::from(
            returns.iter().map(|p| p.coords).sum::<Vector3<f64>>() / returns.len() as f64,
        );
        let views = viewpoints
            .iter()
            .filter_map(|&eye| {
                let axis = (centre - eye).try_normalize(1e-9)?;
                let helper = if axis.z.abs() < 0.9 {
                    Vector3::z()
                } else {
                    Vector3::x()
                };
                let across = axis.cross(&helper).normalize();
                View::new(eye, [axis, across, axis.cross(&across)], returns)
            })
            .collect::<Vec<_>>();
        (!views.is_empty()).then_some(Self { views })
    }

    /// Whether `p` was hidden from every viewpoint: behind a return in
    /// each of them.
    pub fn hidden(&self, p: &Point3<f64>) -> bool {
        self.views.iter().all(|v| v.hides(p))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A leaf-sized patch of returns 30 cm in front of a point hides it
    /// from a sensor behind the patch, not from one to the side, and not
    /// a point beside the patch's shadow, from 1.2 m or 12 m; a point in
    /// front of every return is not hidden; two views hide only what both
    /// miss.
    #[test]
    fn a_patch_hides_what_lies_behind_it_and_nothing_else() {
        // A 5 cm square of returns 5 mm apart in the plane x = 1.2.
        let patch: Vec<Point3<f64>> = (0..=10)
            .flat_map(|i| {
                (0..=10).map(move |j| {
                    Point3::new(
                        1.2,
                        -0.025 + 0.005 * i as f64,
                        1.0 - 0.025 + 0.005 * j as f64,
                    )
                })
            })
            .collect();
        let front = Point3::new(0.0, 0.0, 1.0);
        let shadows = Shadows::new(&patch, &[front]).unwrap();
        assert!(
            shadows.hidden(&Point3::new(1.5, 0.0, 1.0)),
            "straight behind"
        );
        assert!(
            shadows.hidden(&Point3::new(1.5, 0.02, 1.01)),
            "behind, off centre"
        );
        assert!(
            !shadows.hidden(&Point3::new(1.5, 0.1, 1.0)),
            "beside the shadow: seen"
        );
        assert!(
            !shadows.hidden(&Point3::new(1.0, 0.0, 1.0)),
            "in front of the patch: seen"
        );
        assert!(
            !shadows.hidden(&Point3::new(1.21, 0.0, 1.0)),
            "on the patch itself: within noise of its returns"
        );
        // From 12 m, pixels keep the tree's scale: the shadow is still the
        // patch's, not 10 cm wider.
        let far = Shadows::new(&patch, &[Point3::new(-10.8, 0.0, 1.0)]).unwrap();
        assert!(far.hidden(&Point3::new(1.5, 0.0, 1.0)));
        assert!(!far.hidden(&Point3::new(1.5, 0.1, 1.0)));
        // A second sensor to the side sees behind the patch.
        let side = Point3::new(1.5, -1.5, 1.0);
        let both = Shadows::new(&patch, &[front, side]).unwrap();
        assert!(!both.hidden(&Point3::new(1.5, 0.0, 1.0)));
        assert!(Shadows::new(&patch, &[]).is_none());
        assert!(Shadows::new(&[], &[front]).is_none());
    }
}
