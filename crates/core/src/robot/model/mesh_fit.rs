//! A few capsules that enclose a link's collision mesh.
//!
//! Meshes are slow to collide and a robot description should load without
//! them, so each link's mesh is replaced by one to three capsules that
//! contain every triangle (the library form of
//! `scripts/measure-ur5-meshes.py`, which sized the UR5's capsules):
//!
//! 1. the triangles are split into k slices (k = 1, 2, 3) by their
//!    centroids along each of the mesh's principal axes in turn (a link
//!    shaped like an L, as most 7-joint arms' are, splits across its
//!    main axis, not along it);
//! 2. each group gets the tightest capsule around every corner of its
//!    triangles on its own main axis: the radius is the largest distance
//!    from that axis (through the centre of the corners' bounding box
//!    across it), and the segment is as short as that radius allows;
//! 3. k-lines rounds move each triangle to the capsule whose segment is
//!    nearest its farthest corner and refit, keeping the least volume;
//! 4. the k whose capsules take the least room together wins (a larger k only when
//!    it saves at least [`SPLIT_GAIN`] of the volume).
//!
//! A capsule is convex, so holding a triangle's three corners it holds the
//! whole triangle: the capsules of a link enclose its mesh surface, which
//! is what collides. How snugly is reported as the capsules' volume over
//! the mesh's convex hull's ([`MeshFit::volume_ratio`]).

use crate::geometry::principal::principal;
use nalgebra::{Isometry3, Matrix3, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};
use parry3d_f64::math::Vec3;

/// A capsule in a link's frame: the points within `radius` of [a, b] (m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Capsule {
    pub a: Point3<f64>,
    pub b: Point3<f64>,
    pub radius: f64,
}

impl Capsule {
    /// The fitted capsule as the one shape type every collision shape is.
    pub fn shape(&self) -> crate::geometry::shape::Shape {
        crate::geometry::shape::Shape::Capsule {
            a: self.a,
            b: self.b,
            radius: self.radius,
        }
    }

    /// A capsule [`Shape`](crate::geometry::shape::Shape) as the fitter's
    /// capsule (`None` for other shapes).
    pub fn from_shape(shape: &crate::geometry::shape::Shape) -> Option<Self> {
        match shape {
            crate::geometry::shape::Shape::Capsule { a, b, radius } => Some(Self {
                a: *a,
                b: *b,
                radius: *radius,
            }),
            _ => None,
        }
    }

    /// Length of the segment (m).
    pub fn height(&self) -> f64 {
        (self.b - self.a).norm()
    }

    /// Whether `p` is inside (or on) the capsule.
    pub fn contains(&self, p: &Point3<f64>) -> bool {
        distance_to_segment(p, &self.a, &self.b) <= self.radius
    }
}

/// Fewest capsules unless more save this fraction of the volume.
pub const SPLIT_GAIN: f64 = 0.15;
/// A cylinder replaces the capsules only when it saves this fraction of
/// their volume (a tube's capsule is only about 15 % larger than its
/// cylinder, while a squat base's is 40 % or more) and is
/// [`CYLINDER_NARROWER`] than the widest of them.
pub const CYLINDER_GAIN: f64 = 0.3;
/// How much narrower than the widest capsule a cylinder must be. Capsules
/// collide in closed form, cylinders through GJK (the fence query took
/// 25 % longer with a UR's wrist flange as a cylinder as wide as its
/// capsule), and a flat disc's few thin capsules hug it closer sideways,
/// where the links above it pass.
pub const CYLINDER_NARROWER: f64 = 0.95;
/// Most capsules per link.
pub const MAX_CAPSULES: usize = 3;

/// A cylinder in a link's frame: radius `radius` about `pose`'s z axis,
/// `half_length` either side of its origin (m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cylinder {
    pub pose: Isometry3<f64>,
    pub radius: f64,
    pub half_length: f64,
}

impl Cylinder {
    /// Whether `p` is inside (or on) the cylinder.
    pub fn contains(&self, p: &Point3<f64>) -> bool {
        let local = self.pose.inverse_transform_point(p);
        local.z.abs() <= self.half_length && local.coords.xy().norm() <= self.radius
    }

    fn volume(&self) -> f64 {
        std::f64::consts::PI * self.radius * self.radius * 2.0 * self.half_length
    }
}

/// The shapes fitted to one mesh: capsules, or for a squat mesh (a base
/// puck, whose enclosing capsule would bulge a dome over its flat top) one
/// cylinder when it takes [`CYLINDER_GAIN`] less room than the capsules
/// and is narrower.
#[derive(Debug, Clone, PartialEq)]
pub struct MeshFit {
    pub capsules: Vec<Capsule>,
    /// Replaces `capsules` (then empty) when it is the snugger fit.
    pub cylinder: Option<Cylinder>,
    /// The capsules' total volume over the mesh's convex hull's (≥ 1 for
    /// one capsule; how much room the approximation adds). `None` when the
    /// hull is flat.
    pub volume_ratio: Option<f64>,
    /// Triangles enclosed.
    pub triangles: usize,
}

fn capsule_volume(c: &Capsule) -> f64 {
    let r = c.radius;
    std::f64::consts::PI * r * r * (c.height() + 4.0 / 3.0 * r)
}

/// Grid cells per side over which [`union_volume`] counts.
const UNION_GRID: usize = 32;

/// The volume of the capsules' union (m³): exact for one capsule, else
/// counted on a [`UNION_GRID`]³ grid of cell centres over their bounding
/// box (a few per cent; what splitting a link saves is the room the
/// capsules take together, not the sum of their volumes, which counts
/// overlaps twice).
fn union_volume(capsules: &[Capsule]) -> f64 {
    if let [one] = capsules {
        return capsule_volume(one);
    }
    let (mut lo, mut hi) = (
        Vector3::repeat(f64::INFINITY),
        Vector3::repeat(f64::NEG_INFINITY),
    );
    for c in capsules {
        let r = Vector3::repeat(c.radius);
        lo = lo.inf(&(c.a.coords.inf(&c.b.coords) - r));
        hi = hi.sup(&(c.a.coords.sup(&c.b.coords) + r));
    }
    if capsules.is_empty() {
        return 0.0;
    }
    let cell = (hi - lo) / UNION_GRID as f64;
    let mut inside = 0usize;
    for i in 0..UNION_GRID {
        for j in 0..UNION_GRID {
            for k in 0..UNION_GRID {
                let p = Point3::from(
                    lo + cell.component_mul(&Vector3::new(
                        i as f64 + 0.5,
                        j as f64 + 0.5,
                        k as f64 + 0.5,
                    )),
                );
                if capsules.iter().any(|c| c.contains(&p)) {
                    inside += 1;
                }
            }
        }
    }
    inside as f64 * cell.x * cell.y * cell.z
}

/// The principal axes of `points`, largest spread first (unit; z, x, y
/// when they are all one point).
fn principal_axes(points: &[Point3<f64>]) -> [Vector3<f64>; 3] {
    let p = principal(points);
    if p.spread[0] <= 1e-9 {
        return [Vector3::z(), Vector3::x(), Vector3::y()];
    }
    p.axes.map(|axis| {
        if axis.norm() > 1e-12 {
            axis.normalize()
        } else {
            Vector3::z()
        }
    })
}

/// The main axis of `points` (unit; z when they are all one point).
fn main_axis(points: &[Point3<f64>]) -> Vector3<f64> {
    principal_axes(points)[0]
}

/// Two unit axes `v`, `w` across `u` (right-handed u, v, w) and the
/// extent of `points` along u, v and w.
struct Extent {
    v: Vector3<f64>,
    w: Vector3<f64>,
    lo: [f64; 3],
    hi: [f64; 3],
}

/// Two unit axes across unit `u`, with it a right-handed frame (u, v, w).
fn across(u: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
    let helper = if u.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let v = u.cross(&helper).normalize();
    (v, u.cross(&v))
}

fn extent(points: &[Point3<f64>], u: &Vector3<f64>) -> Extent {
    let (v, w) = across(u);
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for p in points {
        for (k, e) in [*u, v, w].iter().enumerate() {
            let s = p.coords.dot(e);
            lo[k] = lo[k].min(s);
            hi[k] = hi[k].max(s);
        }
    }
    Extent { v, w, lo, hi }
}

/// The tightest capsule along `points`' main axis that holds them all.
pub fn enclosing_capsule(points: &[Point3<f64>]) -> Capsule {
    let u = main_axis(points);
    // The axis line passes through the middle of the corners' extent
    // across it.
    let Extent { v, w, lo, hi } = extent(points, &u);
    let centre = v * 0.5 * (lo[1] + hi[1]) + w * 0.5 * (lo[2] + hi[2]);
    let across = |p: &Point3<f64>| {
        let d = p.coords - centre;
        (d - u * d.dot(&u)).norm()
    };
    let radius = points.iter().map(across).fold(0.0, f64::max);
    // The shortest segment [t_lo, t_hi] keeping each point within
    // `radius`: a point at t with offset d needs t_lo ≤ t + √(r² − d²)
    // and t_hi ≥ t − √(r² − d²).
    let (mut t_lo, mut t_hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for p in points {
        let t = p.coords.dot(&u);
        let reach = (radius * radius - across(p).powi(2)).max(0.0).sqrt();
        t_lo = t_lo.min(t + reach);
        t_hi = t_hi.max(t - reach);
    }
    if t_lo > t_hi {
        let mid = 0.5 * (t_lo + t_hi);
        (t_lo, t_hi) = (mid, mid);
    }
    let a = Point3::from(centre + u * t_lo);
    let b = Point3::from(centre + u * t_hi);
    // Exact up to rounding: the radius is re-measured from the segment.
    let radius = points
        .iter()
        .map(|p| distance_to_segment(p, &a, &b))
        .fold(radius, f64::max);
    Capsule {
        a,
        b,
        radius: radius * (1.0 + 1e-9) + 1e-12,
    }
}

/// Distance from `p` to the segment [a, b].
pub fn distance_to_segment(p: &Point3<f64>, a: &Point3<f64>, b: &Point3<f64>) -> f64 {
    let ab = b - a;
    let t = if ab.norm_squared() > 0.0 {
        ((p - a).dot(&ab) / ab.norm_squared()).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (p - (a + ab * t)).norm()
}

/// Lloyd rounds that move triangles to the capsule whose axis holds them
/// closest and refit (k-lines clustering).
const REFINE_ROUNDS: usize = 12;

/// Fits one to [`MAX_CAPSULES`] capsules around `triangles` (see the
/// module's documentation). `None` for an empty mesh.
pub fn fit_capsules(triangles: &[[Point3<f64>; 3]]) -> Option<MeshFit> {
    if triangles.is_empty() {
        return None;
    }
    let corners: Vec<Point3<f64>> = triangles.iter().flatten().copied().collect();
    let axes = principal_axes(&corners);
    let mut best: Option<(Vec<Capsule>, f64)> = None;
    for k in 1..=MAX_CAPSULES {
        // The best split into k capsules over the three starting axes.
        let mut best_k: Option<(Vec<Capsule>, f64)> = None;
        let starts = if k == 1 { &axes[..1] } else { &axes[..] };
        for u in starts {
            let groups = slices(triangles, u, k);
            let (capsules, volume) = refine(triangles, groups);
            if best_k.as_ref().is_none_or(|(_, v)| volume < *v) {
                best_k = Some((capsules, volume));
            }
        }
        let Some((capsules, volume)) = best_k else {
            continue;
        };
        if best
            .as_ref()
            .is_none_or(|(_, v)| volume < v * (1.0 - SPLIT_GAIN))
        {
            best = Some((capsules, volume));
        }
    }
    let (capsules, volume) = best?;
    // About the principal axes, and the link frame's own (meshes are
    // mostly drawn along them, and a puck's principal axes are arbitrary).
    let cylinder = axes
        .iter()
        .chain(&[Vector3::x(), Vector3::y(), Vector3::z()])
        .map(|u| enclosing_cylinder(&corners, u))
        .min_by(|a, b| a.volume().total_cmp(&b.volume()))
        .filter(|c| {
            c.volume() < volume * (1.0 - CYLINDER_GAIN)
                && c.radius
                    <= CYLINDER_NARROWER * capsules.iter().map(|k| k.radius).fold(0.0, f64::max)
        });
    let (capsules, volume) = match &cylinder {
        Some(c) => (Vec::new(), c.volume()),
        None => (capsules, volume),
    };
    let hull = convex_hull_volume(&corners);
    Some(MeshFit {
        capsules,
        cylinder,
        volume_ratio: hull.filter(|h| *h > 1e-12).map(|h| volume / h),
        triangles: triangles.len(),
    })
}

/// The cylinder about an axis along `u` that holds `points`: the axis
/// through the middle of their extent across it, the radius their largest
/// distance from it, the length their extent along it.
fn enclosing_cylinder(points: &[Point3<f64>], u: &Vector3<f64>) -> Cylinder {
    let Extent { v, w, lo, hi } = extent(points, u);
    let centre = (*u * (lo[0] + hi[0]) + v * (lo[1] + hi[1]) + w * (lo[2] + hi[2])) * 0.5;
    let radius = points
        .iter()
        .map(|p| {
            let d = p.coords - centre;
            (d - *u * d.dot(u)).norm()
        })
        .fold(0.0, f64::max);
    let rotation = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(
        Matrix3::from_columns(&[v, w, *u]),
    ));
    Cylinder {
        pose: Isometry3::from_parts(Translation3::from(centre), rotation),
        radius: radius * (1.0 + 1e-9) + 1e-12,
        half_length: 0.5 * (hi[0] - lo[0]) * (1.0 + 1e-9) + 1e-12,
    }
}

/// The triangles' indices in k slices of equal width by their centroids
/// along `u`.
fn slices(triangles: &[[Point3<f64>; 3]], u: &Vector3<f64>, k: usize) -> Vec<Vec<usize>> {
    let centroid = |t: &[Point3<f64>; 3]| (t[0].coords + t[1].coords + t[2].coords).dot(u) / 3.0;
    let (lo, hi) = triangles
        .iter()
        .map(centroid)
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), c| {
            (a.min(c), b.max(c))
        });
    let width = (hi - lo) / k as f64;
    let mut groups = vec![Vec::new(); k];
    for (i, t) in triangles.iter().enumerate() {
        let s = if width > 0.0 {
            (((centroid(t) - lo) / width) as usize).min(k - 1)
        } else {
            0
        };
        groups[s].push(i);
    }
    groups
}

/// Capsules around each group, then up to [`REFINE_ROUNDS`] rounds moving
/// each triangle to the capsule whose segment is nearest its farthest
/// corner; the round with the least total volume wins. Every round's
/// capsules enclose every triangle, so any round is a valid fit.
fn refine(triangles: &[[Point3<f64>; 3]], mut groups: Vec<Vec<usize>>) -> (Vec<Capsule>, f64) {
    let fit = |groups: &[Vec<usize>]| -> Vec<Capsule> {
        groups
            .iter()
            .filter(|g| !g.is_empty())
            .map(|g| {
                let points: Vec<Point3<f64>> = g.iter().flat_map(|&i| triangles[i]).collect();
                enclosing_capsule(&points)
            })
            .collect()
    };
    let mut capsules = fit(&groups);
    let mut best_volume = union_volume(&capsules);
    let mut best = capsules.clone();
    for _ in 0..REFINE_ROUNDS {
        let mut next = vec![Vec::new(); capsules.len()];
        for (i, t) in triangles.iter().enumerate() {
            let reach = |c: &Capsule| {
                t.iter()
                    .map(|p| distance_to_segment(p, &c.a, &c.b))
                    .fold(0.0, f64::max)
            };
            let nearest = (0..capsules.len())
                .min_by(|&a, &b| reach(&capsules[a]).total_cmp(&reach(&capsules[b])))
                .unwrap_or(0);
            next[nearest].push(i);
        }
        if next == groups {
            break;
        }
        groups = next;
        capsules = fit(&groups);
        let volume = union_volume(&capsules);
        if volume < best_volume {
            best_volume = volume;
            best = capsules.clone();
        }
    }
    (best, best_volume)
}

/// Volume of the convex hull of `points` (`None` when it is flat).
fn convex_hull_volume(points: &[Point3<f64>]) -> Option<f64> {
    let glam: Vec<Vec3> = points.iter().map(|p| Vec3::new(p.x, p.y, p.z)).collect();
    let (vertices, faces) = parry3d_f64::transformation::try_convex_hull(&glam).ok()?;
    // Divergence theorem over the hull's faces, from its first vertex.
    let origin = *vertices.first()?;
    let volume: f64 = faces
        .iter()
        .filter_map(|f| {
            let corner = |k: usize| vertices.get(f[k] as usize).map(|v| *v - origin);
            Some(corner(0)?.dot(corner(1)?.cross(corner(2)?)) / 6.0)
        })
        .sum();
    Some(volume.abs())
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn inside(c: &Capsule, p: &Point3<f64>) -> bool {
        c.contains(p)
    }

    /// A cylinder's side mesh (radius 4 cm, 30 cm long, along a tilted
    /// axis): one capsule of about its radius holds every corner.
    #[test]
    fn a_cylinder_gets_one_snug_capsule_that_holds_it() {
        let axis = Vector3::new(0.3, -0.2, 1.0).normalize();
        let v = axis.cross(&Vector3::x()).normalize();
        let w = axis.cross(&v);
        let ring = |z: f64, k: usize| {
            let a = k as f64 * std::f64::consts::TAU / 24.0;
            Point3::from(axis * z + (v * a.cos() + w * a.sin()) * 0.04)
        };
        let mut triangles = Vec::new();
        for k in 0..24 {
            for z in [0.0, 0.1, 0.2] {
                triangles.push([ring(z, k), ring(z, k + 1), ring(z + 0.1, k)]);
                triangles.push([ring(z, k + 1), ring(z + 0.1, k + 1), ring(z + 0.1, k)]);
            }
        }
        let fit = fit_capsules(&triangles).unwrap();
        assert_eq!(fit.capsules.len(), 1);
        let c = &fit.capsules[0];
        assert!((c.radius - 0.04).abs() < 1e-3, "radius {}", c.radius);
        assert!(c.height() < 0.3, "segment {}", c.height());
        for t in &triangles {
            assert!(t.iter().all(|p| inside(c, p)));
        }
        let ratio = fit.volume_ratio.unwrap();
        assert!((1.0..1.6).contains(&ratio), "volume ratio {ratio}");
    }

    /// An L-shaped link (two bars at right angles) is worth two or three
    /// capsules, and every corner of every triangle is inside one of them.
    #[test]
    fn an_elbow_is_split_and_stays_enclosed() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let mut jitter = |p: Vector3<f64>| {
            Point3::from(
                p + Vector3::new(
                    rng.random_range(-0.02..0.02),
                    rng.random_range(-0.02..0.02),
                    rng.random_range(-0.02..0.02),
                ),
            )
        };
        let mut triangles = Vec::new();
        for k in 0..40 {
            let s = k as f64 / 40.0 * 0.4;
            let a = Vector3::new(s, 0.0, 0.0);
            let b = Vector3::new(0.4, 0.0, s);
            triangles.push([jitter(a), jitter(a), jitter(a)]);
            triangles.push([jitter(b), jitter(b), jitter(b)]);
        }
        let fit = fit_capsules(&triangles).unwrap();
        assert!(fit.capsules.len() >= 2, "{} capsules", fit.capsules.len());
        for t in &triangles {
            for p in t {
                assert!(fit.capsules.iter().any(|c| inside(c, p)), "{p} outside");
            }
        }
        let one: f64 = capsule_volume(&enclosing_capsule(
            &triangles.iter().flatten().copied().collect::<Vec<_>>(),
        ));
        let split: f64 = fit.capsules.iter().map(capsule_volume).sum();
        assert!(split < one * (1.0 - SPLIT_GAIN));
    }

    /// The side mesh of a cylinder of `radius` from `a` to `b`.
    fn cylinder(a: Vector3<f64>, b: Vector3<f64>, radius: f64) -> Vec<[Point3<f64>; 3]> {
        let (v, w) = across(&(b - a).normalize());
        let ring = |end: &Vector3<f64>, k: usize| {
            let t = k as f64 * std::f64::consts::TAU / 16.0;
            Point3::from(end + (v * t.cos() + w * t.sin()) * radius)
        };
        (0..16)
            .flat_map(|k| {
                [
                    [ring(&a, k), ring(&a, k + 1), ring(&b, k)],
                    [ring(&a, k + 1), ring(&b, k + 1), ring(&b, k)],
                ]
            })
            .collect()
    }

    /// A link shaped like a 7-joint arm's (a 6 cm tube along z with the
    /// next joint's housing across it at the top, a T): one capsule needs
    /// about 9 cm of radius, while a split across the main axis keeps every
    /// capsule within a few millimetres of the tubes' own radius.
    #[test]
    fn a_t_shaped_link_splits_into_its_tubes() {
        let mut triangles = cylinder(Vector3::zeros(), Vector3::new(0.0, 0.0, 0.2), 0.06);
        triangles.extend(cylinder(
            Vector3::new(0.0, -0.1, 0.25),
            Vector3::new(0.0, 0.1, 0.25),
            0.06,
        ));
        let one = enclosing_capsule(&triangles.iter().flatten().copied().collect::<Vec<_>>());
        assert!(one.radius > 0.085, "one capsule r {}", one.radius);
        let fit = fit_capsules(&triangles).unwrap();
        assert!(fit.capsules.len() >= 2);
        let widest = fit.capsules.iter().map(|c| c.radius).fold(0.0, f64::max);
        assert!(widest < 0.07, "widest of the split r {widest}");
        for p in triangles.iter().flatten() {
            assert!(fit.capsules.iter().any(|c| inside(c, p)), "{p} outside");
        }
    }

    /// A squat puck (a base: 12 cm radius, 16 cm tall) gets one cylinder,
    /// which holds every corner and is far snugger than a capsule's domes.
    #[test]
    fn a_puck_gets_a_cylinder() {
        let triangles = cylinder(Vector3::zeros(), Vector3::new(0.0, 0.0, 0.16), 0.12);
        let fit = fit_capsules(&triangles).unwrap();
        let c = fit.cylinder.expect("a cylinder");
        assert!(fit.capsules.is_empty());
        assert!((c.radius - 0.12).abs() < 1e-3, "radius {}", c.radius);
        assert!(
            (c.half_length - 0.08).abs() < 1e-3,
            "half length {}",
            c.half_length
        );
        for p in triangles.iter().flatten() {
            assert!(c.contains(p), "{p} outside");
        }
        // A long tube keeps its capsule.
        let tube = cylinder(Vector3::zeros(), Vector3::new(0.0, 0.0, 0.4), 0.05);
        assert!(fit_capsules(&tube).unwrap().cylinder.is_none());
    }

    #[test]
    fn an_empty_mesh_has_no_fit() {
        assert!(fit_capsules(&[]).is_none());
    }
}
