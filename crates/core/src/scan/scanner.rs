//! Synthetic scans of a tree: what a depth camera or a laser scanner
//! standing at K places around it would see, with the tree it came from as
//! ground truth.
//!
//! Each branch is a cylinder from its parent node to its node (radius from
//! the tree). Points are drawn uniformly over every surface (bark, leaves,
//! fruit) and kept when the surface faces the viewpoint and the ray from
//! the viewpoint reaches it first: occlusion is ray casting (parry) against
//! every branch, leaf and fruit. Each kept point is then moved along its ray
//! by Gaussian depth noise whose standard deviation grows with the square
//! of the range, as a structured-light or time-of-flight camera's does:
//! σ(d) = `noise` · (d / `distance`)². Leaves are discs near the twigs,
//! fruit are spheres hanging beside branches, outliers are uniform in the
//! tree's box grown by 0.2 m. Every point has the colour an RGB camera
//! would record (bark brown, leaf green, fruit red, under varied light).

use nalgebra::{Point3, Unit, UnitQuaternion, Vector3};
use parry3d_f64::query::Ray;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use rayon::prelude::*;

use crate::geometry::aabb::Aabb;
use crate::geometry::convert::vec3;
use crate::geometry::shape::Shape;
use crate::scan::cloud::PointCloud;
use crate::tree::Tree;

/// What a scan looks like. Lengths in metres.
#[derive(Debug, Clone, PartialEq)]
pub struct ScanParams {
    /// Viewpoints, evenly spaced in azimuth around the trunk (1-16).
    pub viewpoints: usize,
    /// Horizontal range from the trunk to each viewpoint (m).
    pub distance: f64,
    /// Depth noise σ at `distance` (m).
    pub noise: f64,
    /// Surface samples drawn per viewpoint before occlusion (about half
    /// face away or are hidden).
    pub samples_per_view: usize,
    /// Leaves per twig (a branch of a leaf node); 0 for a bare tree.
    pub leaves_per_twig: usize,
    /// Fruit (spheres of 3.5 cm radius) beside the branches.
    pub fruit: usize,
    /// Share of the returned points that are outliers (0-0.5).
    pub outliers: f64,
    pub seed: u64,
}

impl Default for ScanParams {
    fn default() -> Self {
        Self {
            viewpoints: 3,
            distance: 1.5,
            noise: 0.002,
            samples_per_view: 40_000,
            leaves_per_twig: 0,
            fruit: 0,
            outliers: 0.0,
            seed: 0,
        }
    }
}

/// Where a scanned point came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Origin {
    /// The branch ending at this node.
    Branch(usize),
    Leaf,
    Fruit,
    Outlier,
}

/// A synthetic scan: the cloud, each point's origin and the viewpoints.
#[derive(Debug, Clone)]
pub struct Scan {
    pub cloud: PointCloud,
    pub origins: Vec<Origin>,
    pub viewpoints: Vec<Point3<f64>>,
}

/// Leaf disc radius (m): an apple leaf is about 7 cm by 4 cm.
pub const LEAF_RADIUS: f64 = 0.025;
/// Half a leaf's thickness (m).
pub const LEAF_HALF_THICKNESS: f64 = 0.0005;
/// Fruit radius (m): a 7 cm apple.
pub const FRUIT_RADIUS: f64 = 0.035;

struct Surface {
    shape: Shape,
    origin: Origin,
    area: f64,
}

impl ScanParams {
    fn validate(&self) -> Result<(), String> {
        if !(1..=16).contains(&self.viewpoints) {
            return Err("viewpoints must be between 1 and 16".into());
        }
        if !(self.distance.is_finite() && self.distance > 0.1) {
            return Err("distance must be more than 0.1 m".into());
        }
        if !(self.noise.is_finite() && (0.0..=0.05).contains(&self.noise)) {
            return Err("noise must be between 0 and 0.05 m".into());
        }
        if !(0.0..=0.5).contains(&self.outliers) {
            return Err("outliers must be a share between 0 and 0.5".into());
        }
        if self.samples_per_view == 0 || self.samples_per_view > 5_000_000 {
            return Err("samples_per_view must be between 1 and 5,000,000".into());
        }
        if self.leaves_per_twig > 100 || self.fruit > 1000 {
            return Err("at most 100 leaves per twig and 1000 fruit".into());
        }
        Ok(())
    }
}

/// Scans `tree` as `params` say; the same seed gives the same cloud.
pub fn scan(tree: &Tree, params: &ScanParams) -> Result<Scan, String> {
    params.validate()?;
    let mut rng = ChaCha8Rng::seed_from_u64(params.seed);
    let surfaces = surfaces(tree, params, &mut rng);
    let boxes: Vec<Aabb> = surfaces.iter().map(|s| s.shape.aabb()).collect();
    let parry: Vec<_> = surfaces.iter().map(|s| s.shape.parry()).collect();
    let total_area: f64 = surfaces.iter().map(|s| s.area).sum();

    let base = tree.position(0);
    let height = tree.height();
    let eye_height = base.z + 0.5 * height;
    let start = rng.random_range(0.0..std::f64::consts::TAU);
    let viewpoints: Vec<Point3<f64>> = (0..params.viewpoints)
        .map(|k| {
            let a = start + std::f64::consts::TAU * k as f64 / params.viewpoints as f64;
            Point3::new(
                base.x + params.distance * a.cos(),
                base.y + params.distance * a.sin(),
                eye_height,
            )
        })
        .collect();

    let mut points = Vec::new();
    let mut origins = Vec::new();
    for (k, eye) in viewpoints.iter().enumerate() {
        let view_seed = crate::seed::derive_seed(params.seed, &[k as u64]);
        let chunks = 64;
        let per_chunk = params.samples_per_view.div_ceil(chunks);
        let seen: Vec<(Point3<f64>, Origin)> = (0..chunks)
            .into_par_iter()
            .flat_map_iter(|c| {
                let mut rng =
                    ChaCha8Rng::seed_from_u64(crate::seed::derive_seed(view_seed, &[c as u64]));
                let mut out = Vec::new();
                for _ in 0..per_chunk {
                    let pick = rng.random_range(0.0..total_area);
                    let s = pick_surface(&surfaces, pick);
                    let (mut p, normal) = sample_on(&surfaces[s].shape, &mut rng);
                    if surfaces[s].origin == Origin::Leaf {
                        // On the face toward the eye, not inside the disc.
                        p += normal * LEAF_HALF_THICKNESS * normal.dot(&(eye - p)).signum();
                    }
                    let to_eye = eye - p;
                    let range = to_eye.norm();
                    // Both faces of a leaf are seen; bark and fruit only
                    // from outside.
                    let facing = normal.dot(&to_eye);
                    if facing <= 0.0 && surfaces[s].origin != Origin::Leaf {
                        continue;
                    }
                    let dir = -to_eye / range;
                    let ray = Ray::new(vec3(&eye.coords), vec3(&dir));
                    let blocked = (0..surfaces.len()).any(|o| {
                        ray_hits_box(eye, &dir, &boxes[o], range)
                            && parry[o]
                                .0
                                .cast_ray(&parry[o].1, &ray, range - 1e-6, true)
                                .is_some_and(|t| t < range - 1e-6)
                    });
                    if blocked {
                        continue;
                    }
                    let sigma = params.noise * (range / params.distance).powi(2);
                    let depth = if sigma > 0.0 {
                        Normal::new(0.0, sigma).map_or(0.0, |n| n.sample(&mut rng))
                    } else {
                        0.0
                    };
                    out.push((p + dir * depth, surfaces[s].origin));
                }
                out.into_iter()
            })
            .collect();
        for (p, o) in seen {
            points.push(p);
            origins.push(o);
        }
    }

    let real = points.len();
    let outliers = if params.outliers > 0.0 {
        (real as f64 * params.outliers / (1.0 - params.outliers)).round() as usize
    } else {
        0
    };
    let bounds = boxes.iter().fold(Aabb::EMPTY, |a, b| a.union(b)).grown(0.2);
    for _ in 0..outliers {
        let p = Point3::new(
            rng.random_range(bounds.min.x..bounds.max.x),
            rng.random_range(bounds.min.y..bounds.max.y),
            rng.random_range(bounds.min.z.max(base.z)..bounds.max.z),
        );
        points.push(p);
        origins.push(Origin::Outlier);
    }
    let mut paint =
        ChaCha8Rng::seed_from_u64(crate::seed::derive_seed(params.seed, &[COLOUR_STREAM]));
    let colors = origins.iter().map(|o| colour(*o, &mut paint)).collect();
    Ok(Scan {
        cloud: PointCloud {
            points,
            normals: None,
            colors: Some(colors),
        },
        origins,
        viewpoints,
    })
}

/// The seed stream of the points' colours.
const COLOUR_STREAM: u64 = 0xC010;

/// What an RGB camera would record of a point from `origin`: bark brown,
/// leaf green, fruit red, outliers anything; each under its own lighting
/// (55-125 % brightness) with a little sensor noise (±6 %, ±2).
fn colour(origin: Origin, rng: &mut ChaCha8Rng) -> [u8; 3] {
    let base = match origin {
        Origin::Branch(_) => [92.0, 68.0, 48.0],
        Origin::Leaf => [74.0, 122.0, 46.0],
        Origin::Fruit => [168.0, 42.0, 36.0],
        Origin::Outlier => [
            rng.random_range(0.0..255.0),
            rng.random_range(0.0..255.0),
            rng.random_range(0.0..255.0),
        ],
    };
    let light = rng.random_range(0.55..1.25);
    base.map(|c: f64| {
        (c * light * rng.random_range(0.94..1.06) + rng.random_range(-2.0..2.0)).clamp(0.0, 255.0)
            as u8
    })
}

fn pick_surface(surfaces: &[Surface], mut pick: f64) -> usize {
    for (i, s) in surfaces.iter().enumerate() {
        if pick < s.area {
            return i;
        }
        pick -= s.area;
    }
    surfaces.len() - 1
}

/// Slab test: does the ray from `eye` along `dir` meet `aabb` before `range`?
fn ray_hits_box(eye: &Point3<f64>, dir: &Vector3<f64>, aabb: &Aabb, range: f64) -> bool {
    let (mut t0, mut t1) = (0.0f64, range);
    for i in 0..3 {
        if dir[i].abs() < 1e-15 {
            if eye[i] < aabb.min[i] || eye[i] > aabb.max[i] {
                return false;
            }
            continue;
        }
        let inv = 1.0 / dir[i];
        let (mut a, mut b) = ((aabb.min[i] - eye[i]) * inv, (aabb.max[i] - eye[i]) * inv);
        if a > b {
            std::mem::swap(&mut a, &mut b);
        }
        t0 = t0.max(a);
        t1 = t1.min(b);
        if t0 > t1 {
            return false;
        }
    }
    true
}

/// Every surface of the scene: branches (the lateral surface of each
/// cylinder), leaves and fruit.
fn surfaces(tree: &Tree, params: &ScanParams, rng: &mut ChaCha8Rng) -> Vec<Surface> {
    let mut surfaces = Vec::new();
    for (j, branch) in tree.branches_iter() {
        let (a, b) = (tree.position(tree.parent(j).unwrap_or(0)), tree.position(j));
        surfaces.push(Surface {
            shape: Shape::Capsule {
                a,
                b,
                radius: branch.radius,
            },
            origin: Origin::Branch(j),
            area: std::f64::consts::TAU * branch.radius * branch.length,
        });
    }
    let twigs: Vec<usize> = (1..tree.len()).filter(|&j| tree.is_leaf(j)).collect();
    for &j in &twigs {
        let (a, b) = (tree.position(tree.parent(j).unwrap_or(0)), tree.position(j));
        for _ in 0..params.leaves_per_twig {
            let along = a + (b - a) * rng.random_range(0.3..1.0);
            let offset = random_unit(rng) * rng.random_range(0.01..0.04);
            let normal = Unit::new_normalize(random_unit(rng));
            let pose = nalgebra::Isometry3::from_parts(
                (along + offset).coords.into(),
                UnitQuaternion::rotation_between_axis(&Vector3::z_axis(), &normal)
                    .unwrap_or_else(UnitQuaternion::identity),
            );
            surfaces.push(Surface {
                shape: Shape::Cylinder {
                    pose,
                    radius: LEAF_RADIUS,
                    half_length: LEAF_HALF_THICKNESS,
                },
                origin: Origin::Leaf,
                area: std::f64::consts::PI * LEAF_RADIUS * LEAF_RADIUS,
            });
        }
    }
    for _ in 0..params.fruit {
        let j = rng.random_range(1..tree.len());
        let (a, b) = (tree.position(tree.parent(j).unwrap_or(0)), tree.position(j));
        let r = tree.branch(j).map_or(0.01, |b| b.radius);
        let along = a + (b - a) * rng.random_range(0.2..0.8);
        let mut side = random_unit(rng);
        side.z = -side.z.abs() - 0.5;
        let centre = along + side.normalize() * (r + FRUIT_RADIUS + 0.005);
        surfaces.push(Surface {
            shape: Shape::Sphere {
                centre,
                radius: FRUIT_RADIUS,
            },
            origin: Origin::Fruit,
            area: 4.0 * std::f64::consts::PI * FRUIT_RADIUS * FRUIT_RADIUS,
        });
    }
    surfaces
}

fn random_unit(rng: &mut ChaCha8Rng) -> Vector3<f64> {
    loop {
        let v = Vector3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        let n = v.norm();
        if n > 1e-3 && n <= 1.0 {
            return v / n;
        }
    }
}

/// A uniform point on the surface and its outward normal: a capsule's
/// lateral (cylindrical) surface, a thin cylinder's face (a leaf), a
/// sphere.
fn sample_on(shape: &Shape, rng: &mut ChaCha8Rng) -> (Point3<f64>, Vector3<f64>) {
    match shape {
        Shape::Capsule { a, b, radius } => {
            let axis = b - a;
            let u = crate::geometry::segment::any_perpendicular(vec3(&axis));
            let u = Vector3::new(u.x, u.y, u.z);
            let v = axis.normalize().cross(&u);
            let phi = rng.random_range(0.0..std::f64::consts::TAU);
            let normal = u * phi.cos() + v * phi.sin();
            (
                a + axis * rng.random_range(0.0..1.0) + normal * *radius,
                normal,
            )
        }
        Shape::Cylinder { pose, radius, .. } => {
            let r = radius * rng.random_range(0.0f64..1.0).sqrt();
            let phi = rng.random_range(0.0..std::f64::consts::TAU);
            let local = Point3::new(r * phi.cos(), r * phi.sin(), 0.0);
            (pose * local, pose.rotation * Vector3::z())
        }
        Shape::Sphere { centre, radius } => {
            let n = random_unit(rng);
            (centre + n * *radius, n)
        }
        Shape::Box { pose, .. } => (pose * Point3::origin(), Vector3::z()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tree::{ScaParams, generate};

    #[test]
    fn points_lie_on_the_bark_within_the_noise_and_hidden_sides_are_missing() {
        let tree = generate(20, 3, &ScaParams::default()).unwrap();
        let params = ScanParams {
            viewpoints: 1,
            noise: 0.0,
            samples_per_view: 20_000,
            ..ScanParams::default()
        };
        let scan = scan(&tree, &params).unwrap();
        assert!(scan.cloud.len() > 4_000 && scan.cloud.len() < 15_000);
        let eye = scan.viewpoints[0];
        for (p, o) in scan.cloud.points.iter().zip(&scan.origins) {
            let Origin::Branch(j) = *o else {
                panic!("a bare scan has only bark")
            };
            let a = tree.position(tree.parent(j).unwrap());
            let b = tree.position(j);
            let (d, t) = crate::scan::skeleton::point_segment(p, &a, &b);
            let r = tree.branch(j).unwrap().radius;
            assert!((d - r).abs() < 1e-9, "off the bark by {}", d - r);
            // Seen from the front: the bark's outward normal faces the eye.
            let on_axis = a + (b - a) * t;
            assert!((p - on_axis).dot(&(eye - p)) > 0.0, "a back face was seen");
        }
        let same = scan_again(&tree, &params);
        assert_eq!(same, scan.cloud.points);
    }

    fn scan_again(tree: &Tree, params: &ScanParams) -> Vec<Point3<f64>> {
        scan(tree, params).unwrap().cloud.points
    }

    #[test]
    fn noise_grows_with_the_given_sigma() {
        let tree = generate(12, 5, &ScaParams::default()).unwrap();
        let params = ScanParams {
            viewpoints: 2,
            noise: 0.003,
            samples_per_view: 10_000,
            ..ScanParams::default()
        };
        let scan = scan(&tree, &params).unwrap();
        let mut sq = 0.0;
        for (p, o) in scan.cloud.points.iter().zip(&scan.origins) {
            let Origin::Branch(j) = *o else { continue };
            let a = tree.position(tree.parent(j).unwrap());
            let (d, _) = crate::scan::skeleton::point_segment(p, &a, &tree.position(j));
            sq += (d - tree.branch(j).unwrap().radius).powi(2);
        }
        let rms = (sq / scan.cloud.len() as f64).sqrt();
        // Depth noise, mostly across the bark: between the lateral share
        // and the full sigma (ranges are near `distance`).
        assert!(rms > 0.0015 && rms < 0.0045, "rms {rms}");
    }

    #[test]
    fn leaves_fruit_and_outliers_are_labelled() {
        let tree = generate(15, 9, &ScaParams::default()).unwrap();
        let params = ScanParams {
            leaves_per_twig: 6,
            fruit: 3,
            outliers: 0.05,
            samples_per_view: 20_000,
            ..ScanParams::default()
        };
        let scan = scan(&tree, &params).unwrap();
        let count = |f: fn(&Origin) -> bool| scan.origins.iter().filter(|o| f(o)).count();
        assert!(count(|o| *o == Origin::Leaf) > 100);
        assert!(count(|o| *o == Origin::Fruit) > 50);
        let outliers = count(|o| *o == Origin::Outlier) as f64 / scan.cloud.len() as f64;
        assert!((outliers - 0.05).abs() < 0.005);
    }
}
