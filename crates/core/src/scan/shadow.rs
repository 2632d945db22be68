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
//! at the cloud's centre, square pixels [`PIXEL`] radians across, each
//! keeping its nearest return. A point is hidden when some pixel within one
//! of its own has a return at least [`IN_FRONT`] nearer: the one-pixel
//! margin stands for the gaps between returns on a surface.

use std::collections::HashMap;

use nalgebra::{Point3, Vector3};

/// A depth image's pixel (radians): 7.5 mm at 1.5 m, coarser than the
/// spacing of a camera's or a terrestrial scanner's returns at that range.
pub const PIXEL: f64 = 0.005;
/// A return hides what lies at least this much (m) farther along its ray:
/// more than depth noise and a twig's own thickness, so a branch does not
/// hide itself.
pub const IN_FRONT: f64 = 0.02;
/// Rays this far (radians) or more off a view's axis are not imaged.
const MAX_OFF_AXIS: f64 = 1.2;

/// One viewpoint's depth image.
struct View {
    eye: Point3<f64>,
    /// The view's axis (towards the cloud's centre) and two axes across.
    axes: [Vector3<f64>; 3],
    nearest: HashMap<(i32, i32), f64>,
}

impl View {
    /// The pixel `p` falls in and its range, if the view images it.
    fn pixel(&self, p: &Point3<f64>) -> Option<((i32, i32), f64)> {
        let d = p - self.eye;
        let range = d.norm();
        let ahead = d.dot(&self.axes[0]);
        if range <= 0.0 || ahead <= range * MAX_OFF_AXIS.cos() {
            return None;
        }
        let (u, v) = (d.dot(&self.axes[1]) / ahead, d.dot(&self.axes[2]) / ahead);
        Some((
            ((u / PIXEL).floor() as i32, (v / PIXEL).floor() as i32),
            range,
        ))
    }

    fn hides(&self, p: &Point3<f64>) -> bool {
        let Some(((i, j), range)) = self.pixel(p) else {
            return false;
        };
        (-1..=1).any(|di| {
            (-1..=1).any(|dj| {
                self.nearest
                    .get(&(i + di, j + dj))
                    .is_some_and(|&r| r <= range - IN_FRONT)
            })
        })
    }
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
                let mut view = View {
                    eye,
                    axes: [axis, across, axis.cross(&across)],
                    nearest: HashMap::new(),
                };
                for p in returns {
                    if let Some((px, range)) = view.pixel(p) {
                        let slot = view.nearest.entry(px).or_insert(range);
                        *slot = slot.min(range);
                    }
                }
                Some(view)
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
    /// a point beside the patch's shadow; a point in front of every return
    /// is not hidden; two views hide only what both miss.
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
        // A second sensor to the side sees behind the patch.
        let side = Point3::new(1.5, -1.5, 1.0);
        let both = Shadows::new(&patch, &[front, side]).unwrap();
        assert!(!both.hidden(&Point3::new(1.5, 0.0, 1.0)));
        assert!(Shadows::new(&patch, &[]).is_none());
        assert!(Shadows::new(&[], &[front]).is_none());
    }
}
