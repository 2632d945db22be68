//! Whether a cloud was seen from one side, and from where: what the
//! extraction says about what it could not see.
//!
//! A camera, or a scanner standing in one place, sees each branch's near
//! side only: the far side of every branch is missing, and radii come
//! from arcs. The cloud says so itself. Where a circle fits a
//! cross-section, the offset from its centre to the points' mean points at
//! the sensor, up to the tilt along the branch. When most cross-sections
//! have such an offset and they point at one place, the cloud was seen
//! from there; a cloud merged from several sides has short offsets (the
//! fits go round) that point every way.
//!
//! By default only a warning comes of it: how far behind the points the
//! axis lies depends on the sensor. A camera whose returns lie on the
//! surface facing it, with noise along its rays, leaves what the
//! extraction places from a one-sided arc (the arc's mean, or a loose
//! circle through a few noisy cubes of a 5 mm twig) between the axis and
//! the camera: on our synthetic one-view scans 87 % of the skeleton's
//! samples that missed their branch by up to 2 cm missed toward the
//! camera. A laser scanner whose beam is wider than the twigs returns
//! ranges averaged over twig and background, behind the surface: on
//! sylva-rs's beam-model scans the misses lay away from the scanner (two
//! thirds of them). [`Sensor::Camera`] says which: the axes are moved back
//! from the near surface ([`move_off_near_side`]); it costs a scanner's
//! clouds a tenth of their recall and precision (`docs/scans.md`, "Seen
//! from one side").

use nalgebra::{Matrix3, Point3, Vector3};

use crate::scan::skeleton::Skeleton;

/// What the extraction may assume of the sensor's returns.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Sensor {
    /// Nothing: the skeleton stands where the points put it, wherever the
    /// cloud was seen from.
    #[default]
    Unknown,
    /// A camera (time of flight, structured light or stereo at close
    /// range): returns on the surface facing it. A cloud seen from one
    /// side has its branch axes moved back from the near surface.
    Camera,
    /// A laser scanner whose beam spreads `beam_radius` (m) past a
    /// branch's edge: returns come from a pulse whose footprint only
    /// grazes the branch. A cloud seen from one side has its radii and
    /// axes from the silhouettes, less that spread
    /// ([`crate::scan::silhouette`]).
    Laser { beam_radius: f64 },
}

/// How far (a share of its radius) a node of a camera's one-sided cloud
/// moves away from the camera where nothing placed it on its axis: its
/// piece's mean, or a circle that fits it loosely.
pub const NEAR_SIDE_SHIFT: f64 = 0.4;
/// A circle fitted with residuals this share of its radius or more is
/// loose and its node moves by all of [`NEAR_SIDE_SHIFT`]; a tighter one
/// by a proportionally smaller share (a clean arc's centre is on the
/// axis).
///
/// Both chosen on 42 trees of generator seed 99 (one view; recall /
/// precision at 0.5 r and 1.0 r), never on the test split. Leafy at 3 mm:
/// 0.581 / 0.698 and 0.760 / 0.909 unmoved, 0.684 / 0.817 and 0.780 /
/// 0.931 moved. Bare at 1 mm, where the fits are clean, moving every node
/// by 0.4 r cost 0.5 r recall (0.927 → 0.873); scaled by the residual,
/// 0.924. Shares 0.2-0.5 of the radius and references 0.3-0.6 came within
/// 0.01 of these.
pub const LOOSE_FIT: f64 = 0.4;

/// The share of its radius a node moves off the near side, from its
/// circle's residual over its radius (infinite where none was fitted).
pub fn near_side_shift(misfit: f64) -> f64 {
    NEAR_SIDE_SHIFT * (misfit / LOOSE_FIT).min(1.0)
}

/// Moves every node but the root `shift[k]` × its radius away from
/// `view`, across its branch's axis (from its parent toward its first
/// child; `up` where those coincide).
pub fn move_off_near_side(
    skeleton: &mut Skeleton,
    view: &Point3<f64>,
    shift: &[f64],
    up: &Vector3<f64>,
) {
    let old = skeleton.positions.clone();
    let mut child = vec![None; old.len()];
    for (k, p) in skeleton.parents.iter().enumerate() {
        if let Some(p) = *p {
            child[p].get_or_insert(k);
        }
    }
    for k in 0..old.len() {
        let Some(p) = skeleton.parents[k] else {
            continue;
        };
        let ahead = child[k].map_or(old[k], |c| old[c]);
        let axis = (ahead - old[p]).try_normalize(1e-9).unwrap_or(*up);
        if let Some(toward) = across(&old[k], &axis, view) {
            skeleton.positions[k] -= toward * shift[k] * skeleton.radius[k];
        }
    }
}

/// What one fitted cross-section says about the sensor.
#[derive(Debug, Clone, Copy)]
pub struct Sighting {
    /// The fitted circle's centre.
    pub centre: Point3<f64>,
    /// The branch's unit axis there.
    pub axis: Vector3<f64>,
    /// From the centre to the points' mean, across the axis (m).
    pub offset: Vector3<f64>,
    /// The fitted radius (m).
    pub radius: f64,
}

/// Offsets shorter than this share of the radius say little about where
/// the sensor is (a fit that goes most of the way round).
const MIN_OFFSET: f64 = 0.15;
/// An offset agrees with a viewpoint when it points within this angle
/// (rad, 30°) of it, across the axis.
const AGREE_ANGLE: f64 = 0.52;
/// A viewpoint is believed when this share of the sightings (by weight)
/// agrees with it ...
const MIN_AGREEMENT: f64 = 0.6;
/// ... and there are at least this many ...
const MIN_SIGHTINGS: usize = 12;
/// ... and at least this share of all cross-sections is one-sided (offset
/// at least [`MIN_OFFSET`]). Measured on the test split's synthetic scans
/// (42 trees, noise 1-5 mm, with and without leaves): one view 0.55-1.00
/// a tree (0.97 on average at 2 mm), three views 0.19-0.69 (0.42-0.48
/// on average). A cloud from three sides is never called one-sided; a
/// noisy one-view cloud sometimes is not.
const MIN_ONE_SIDED: f64 = 0.75;

/// The direction from `at` toward `view` across the unit `axis`, if any.
pub fn across(at: &Point3<f64>, axis: &Vector3<f64>, view: &Point3<f64>) -> Option<Vector3<f64>> {
    let d = view - at;
    (d - axis * d.dot(axis)).try_normalize(1e-9)
}

/// A sighting reduced to what the search reads: where, the axis, the unit
/// direction of the offset, and a weight (the offset's share of the
/// radius, at most 1).
struct Ray {
    centre: Point3<f64>,
    axis: Vector3<f64>,
    toward: Vector3<f64>,
    weight: f64,
}

/// Distances (m) from the sightings' mean the search tries: a camera on
/// the gripper to a scanner across the row.
const DISTANCES: [f64; 9] = [0.4, 0.6, 0.8, 1.0, 1.5, 2.0, 3.0, 5.0, 10.0];
/// Directions tried: a grid this many steps either side of the first
/// guess, [`STEP`] apart (rad), then again at a tenth of the step.
const STEPS: i32 = 4;
const STEP: f64 = 0.17;

/// The sensor's position, when the sightings agree on one.
///
/// Why a search and not least squares on the planes through each axis and
/// its offset: the planes of branches that radiate from the trunk all hold
/// the trunk's axis, so the trunk fits them about as well as the sensor
/// does. The search scores a candidate by how closely each offset points
/// at it (a lobe, cos⁸ of the angle), which the trunk does not do, and the
/// answer stands when `MIN_AGREEMENT` of the weight points within
/// `AGREE_ANGLE` of it. The direction comes out within a few degrees on
/// the scans measured; the distance is rough (the offsets' directions
/// change little across a tree seen from 1.5 m).
pub fn one_sided_viewpoint(sightings: &[Sighting]) -> Option<Point3<f64>> {
    let rays: Vec<Ray> = sightings
        .iter()
        .filter_map(|s| {
            let share = s.offset.norm() / s.radius.max(1e-4);
            if !(share.is_finite() && share >= MIN_OFFSET) {
                return None;
            }
            Some(Ray {
                centre: s.centre,
                axis: s.axis.try_normalize(1e-9)?,
                toward: s.offset.try_normalize(1e-9)?,
                weight: share.min(1.0),
            })
        })
        .collect();
    if rays.len() < MIN_SIGHTINGS || (rays.len() as f64) < MIN_ONE_SIDED * sightings.len() as f64 {
        return None;
    }
    let total: f64 = rays.iter().map(|r| r.weight).sum();
    let mean = Point3::from(
        rays.iter()
            .map(|r| r.centre.coords * r.weight)
            .sum::<Vector3<f64>>()
            / total,
    );
    // First guess, as if the sensor were far: the direction nearest every
    // plane through an axis and its offset, on the side the offsets face.
    let mut planes = Matrix3::zeros();
    for r in &rays {
        if let Some(n) = r.axis.cross(&r.toward).try_normalize(1e-9) {
            planes += n * n.transpose() * r.weight;
        }
    }
    let eigen = planes.symmetric_eigen();
    let smallest = eigen.eigenvalues.imin();
    let mut guess: Vector3<f64> = eigen.eigenvectors.column(smallest).into_owned();
    if rays
        .iter()
        .map(|r| r.weight * r.toward.dot(&guess))
        .sum::<f64>()
        < 0.0
    {
        guess = -guess;
    }
    // How well a candidate fits: each offset's weight times a lobe around
    // its direction (cos⁸: half at 33°), smooth so that the distance
    // matters too.
    let fit = |view: &Point3<f64>| -> f64 {
        rays.iter()
            .filter_map(|r| {
                across(&r.centre, &r.axis, view)
                    .map(|e| r.weight * e.dot(&r.toward).max(0.0).powi(8))
            })
            .sum()
    };
    let agreement = |view: &Point3<f64>| -> f64 {
        rays.iter()
            .filter(|r| {
                across(&r.centre, &r.axis, view)
                    .is_some_and(|e| e.dot(&r.toward) >= AGREE_ANGLE.cos())
            })
            .map(|r| r.weight)
            .sum()
    };
    let mut best = (f64::NEG_INFINITY, mean + guess);
    for step in [STEP, STEP / 10.0] {
        let centre = (best.1 - mean).try_normalize(1e-9).unwrap_or(guess);
        let u = centre
            .cross(&Vector3::z())
            .try_normalize(1e-6)
            .unwrap_or_else(Vector3::x);
        let v = centre.cross(&u);
        for i in -STEPS..=STEPS {
            for j in -STEPS..=STEPS {
                let dir = (centre + u * (i as f64 * step).tan() + v * (j as f64 * step).tan())
                    .normalize();
                for d in DISTANCES {
                    let view = mean + dir * d;
                    let a = fit(&view);
                    if a > best.0 {
                        best = (a, view);
                    }
                }
            }
        }
    }
    (agreement(&best.1) >= MIN_AGREEMENT * total).then_some(best.1)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Sightings of branches in many directions, each offset pointing at
    /// `view` (or, with `scatter`, every other one pointing away).
    fn sightings(view: &Point3<f64>, scatter: bool) -> Vec<Sighting> {
        (0..40)
            .map(|i| {
                let t = i as f64 * 0.37;
                let centre = Point3::new(0.3 * t.sin(), 0.2 * t.cos(), 0.1 + 0.02 * i as f64);
                let axis = Vector3::new(t.cos(), (2.0 * t).sin(), 1.0).normalize();
                let mut toward = across(&centre, &axis, view).unwrap();
                if scatter && i % 2 == 1 {
                    toward = -toward;
                }
                Sighting {
                    centre,
                    axis,
                    offset: toward * 0.004,
                    radius: 0.006,
                }
            })
            .collect()
    }

    #[test]
    fn offsets_that_point_at_one_place_find_it() {
        let view = Point3::new(1.5, -0.4, 0.7);
        let found = one_sided_viewpoint(&sightings(&view, false)).expect("a viewpoint");
        // Every offset points within a few degrees of the one found.
        for s in sightings(&view, false) {
            let e = across(&s.centre, &s.axis, &found).unwrap();
            assert!(e.dot(&s.offset.normalize()) > 0.1f64.cos(), "{found}");
        }
    }

    /// A straight branch beside a camera: each node moves straight away
    /// from it, by its share of its radius; the root stays.
    #[test]
    fn nodes_move_away_from_the_camera_across_their_branch() {
        let mut skeleton = Skeleton {
            positions: (0..4)
                .map(|k| Point3::new(0.0, 0.0, 0.1 * k as f64))
                .collect(),
            parents: vec![None, Some(0), Some(1), Some(2)],
            radius: vec![0.01; 4],
        };
        let view = Point3::new(1.5, 0.0, 2.0);
        move_off_near_side(&mut skeleton, &view, &[0.4, 0.4, 0.2, 0.0], &Vector3::z());
        assert_eq!(skeleton.positions[0], Point3::origin());
        for (k, dx) in [(1, -0.004), (2, -0.002), (3, 0.0)] {
            let p = skeleton.positions[k];
            assert!((p.x - dx).abs() < 1e-12 && p.y.abs() < 1e-12, "{k}: {p}");
            assert!((p.z - 0.1 * k as f64).abs() < 1e-12);
        }
        assert!((near_side_shift(f64::INFINITY) - NEAR_SIDE_SHIFT).abs() < 1e-12);
        assert!((near_side_shift(0.5 * LOOSE_FIT) - 0.5 * NEAR_SIDE_SHIFT).abs() < 1e-12);
    }

    #[test]
    fn offsets_that_point_every_way_find_none() {
        let view = Point3::new(1.5, -0.4, 0.7);
        assert!(one_sided_viewpoint(&sightings(&view, true)).is_none());
        assert!(one_sided_viewpoint(&sightings(&view, false)[..5]).is_none());
    }
}
