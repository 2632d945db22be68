//! A laser's cross-section seen from one side: radius and axis from the
//! branch's silhouette, less the beam's spread.
//!
//! A laser scanner's beam has a footprint (its exit diameter plus range ×
//! divergence: about 7.5 mm across at 1.5 m for a RIEGL VZ-400i). A pulse
//! whose footprint grazes a branch returns an echo at the range of what it
//! grazed, placed on the pulse's central axis: the branch is seen wider
//! than it is by up to the footprint's radius on either side, and those
//! edge returns lie near the silhouette's depth, flat where the surface
//! would curve away. A circle fitted to such an arc is too large and its
//! centre too far back: on sylva-rs's beam-model scans, seen from one side,
//! twigs of 4-5 mm came out 2.6 mm too thick and branches of 10-20 mm
//! 2.0 mm (signed medians, seeds 1-3).
//!
//! Across the line of sight the beam's spread is all there is: range noise
//! lies along the pulse, which at the silhouette is across it. So the
//! branch's half-width there, less the spread, is its radius, and the
//! middle of the silhouette is its axis across the view. Along the view,
//! the axis lies a radius behind the surface facing the sensor.

use nalgebra::{Point3, Vector3};

use crate::scan::viewpoint::across;

/// Mean depth of a circle's near surface over the middle half of its
/// width, as a share of its radius: ∫ √(1 − t²) dt over |t| ≤ ½, by its
/// length.
const FRONT_DEPTH: f64 = 0.956;
/// The least radius (m) a silhouette gives.
const MIN_RADIUS: f64 = 0.0005;

/// A cross-section's axis point and radius from its silhouette, seen from
/// `view` by a beam spreading `beam_radius` (m) past an edge; `points` are
/// the cross-section's, `centre` and the unit `axis` a first estimate.
/// `None` for fewer than four points or no direction across the view.
pub fn from_silhouette(
    points: &[Point3<f64>],
    centre: &Point3<f64>,
    axis: &Vector3<f64>,
    view: &Point3<f64>,
    beam_radius: f64,
) -> Option<(Point3<f64>, f64)> {
    if points.len() < 4 {
        return None;
    }
    let toward = across(centre, axis, view)?;
    let side = axis.cross(&toward);
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for p in points {
        let x = (p - centre).dot(&side);
        lo = lo.min(x);
        hi = hi.max(x);
    }
    let half = 0.5 * (hi - lo);
    let radius = (half - beam_radius).max(MIN_RADIUS);
    let mid = 0.5 * (hi + lo);
    // The near surface: the points across the middle half of the
    // silhouette (of the branch, or of the whole where the beam is most
    // of it).
    let band = 0.5 * radius.max(0.5 * half);
    let (mut sum, mut count) = (0.0, 0usize);
    for p in points {
        let d = p - centre;
        if (d.dot(&side) - mid).abs() <= band {
            sum += d.dot(&toward);
            count += 1;
        }
    }
    if count == 0 {
        return None;
    }
    let depth = sum / count as f64 - FRONT_DEPTH * radius;
    Some((centre + side * mid + toward * depth, radius))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scan::beam_scan::{BeamScan, scanned_stem};
    use crate::scan::circle_fit::fit_circle;
    use nalgebra::Vector2;

    /// One side of a vertical branch of radius `r` on the z axis, scanned
    /// from +y by pulses 0.2 mm apart whose footprint has radius `w`.
    fn beam_scan(r: f64, w: f64) -> Vec<Point3<f64>> {
        let scan = BeamScan {
            beam: w,
            step: 0.0002,
            rows: 5,
            noise: 0.0,
        };
        scanned_stem(r, &scan)
    }

    #[test]
    fn a_laser_silhouette_less_the_beam_gives_the_branch() {
        let view = Point3::new(0.0, 1.5, 0.004);
        for (r, w) in [(0.004, 0.003), (0.006, 0.003), (0.02, 0.0035), (0.01, 0.0)] {
            let points = beam_scan(r, w);
            // A first guess off the axis, as a circle through the arc gives.
            let guess = Point3::new(0.001, -0.004, 0.004);
            let (centre, radius) =
                from_silhouette(&points, &guess, &Vector3::z(), &view, w).unwrap();
            assert!(
                (radius - r).abs() < 0.0003,
                "r {r}, beam {w}: radius {radius}"
            );
            let miss = Vector2::new(centre.x, centre.y).norm();
            assert!(miss < 0.15 * r + 0.0003, "r {r}, beam {w}: axis {miss} off");
            // What a circle through the same arc makes of it: too large
            // wherever the beam is.
            let flat: Vec<Vector2<f64>> = points.iter().map(|p| Vector2::new(p.x, p.y)).collect();
            let circle = fit_circle(&flat).unwrap();
            if w > 0.0 {
                assert!(circle.radius > r + 0.001, "r {r}: circle {}", circle.radius);
            } else {
                assert!((circle.radius - r).abs() < 1e-4);
            }
        }
    }

    #[test]
    fn too_few_points_or_a_view_along_the_axis_give_nothing() {
        let p = [Point3::origin(); 3];
        let up = Vector3::z();
        assert!(
            from_silhouette(&p, &Point3::origin(), &up, &Point3::new(1.0, 0.0, 0.0), 0.0).is_none()
        );
        let p = beam_scan(0.01, 0.0);
        assert!(
            from_silhouette(&p, &Point3::origin(), &up, &Point3::new(0.0, 0.0, 2.0), 0.0).is_none()
        );
    }
}
