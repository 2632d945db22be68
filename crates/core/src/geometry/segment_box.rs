//! Distance between a segment and a box in closed form: most checks that
//! involve the gripper's boxes pair one with a capsule (a branch, a post or
//! an arm link), and parry's general dispatcher would run GJK on them, a
//! fifth of an RRT* query's time on the robot bench's fence.
//!
//! In the box's frame the box is |x_k| ≤ h_k and the segment is
//! p(t) = a + t (b − a), t ∈ [0, 1]. The squared distance from p(t) to the
//! box is g(t) = Σ_k max(0, |p_k(t)| − h_k)², a convex piecewise quadratic
//! whose pieces change only where p_k(t) = ±h_k. Between consecutive such
//! breakpoints every axis's term is either zero or one fixed quadratic, so
//! the minimum of g on each piece is the clamped vertex of a parabola; the
//! smallest over the (at most seven) pieces is the exact distance.

use parry3d_f64::math::{Pose, Vec3};
use parry3d_f64::shape::Cuboid;

/// Squared distance between the segment `a`–`b` (world frame) and `cuboid`
/// at `pose`; 0 when they touch or overlap.
pub fn segment_box_distance_squared(a: Vec3, b: Vec3, cuboid: &Cuboid, pose: &Pose) -> f64 {
    let (a, b) = (
        pose.inverse_transform_point(a),
        pose.inverse_transform_point(b),
    );
    let h = cuboid.half_extents;
    let (p, d) = ([a.x, a.y, a.z], [b.x - a.x, b.y - a.y, b.z - a.z]);
    let h = [h.x, h.y, h.z];
    let mut cuts = [0.0f64; 8];
    let mut n = 0;
    for k in 0..3 {
        if d[k] != 0.0 {
            for side in [-h[k], h[k]] {
                let t = (side - p[k]) / d[k];
                if t > 0.0 && t < 1.0 {
                    cuts[n] = t;
                    n += 1;
                }
            }
        }
    }
    cuts[n] = 0.0;
    cuts[n + 1] = 1.0;
    let cuts = &mut cuts[..n + 2];
    cuts.sort_unstable_by(f64::total_cmp);
    let mut best = f64::INFINITY;
    for piece in cuts.windows(2) {
        let (t0, t1) = (piece[0], piece[1]);
        let mid = 0.5 * (t0 + t1);
        // g(t) = α t² + 2 β t + γ on this piece.
        let (mut alpha, mut beta, mut gamma) = (0.0, 0.0, 0.0);
        for k in 0..3 {
            let x = p[k] + mid * d[k];
            let offset = if x > h[k] {
                p[k] - h[k]
            } else if x < -h[k] {
                p[k] + h[k]
            } else {
                continue;
            };
            alpha += d[k] * d[k];
            beta += offset * d[k];
            gamma += offset * offset;
        }
        let t = if alpha > 0.0 {
            (-beta / alpha).clamp(t0, t1)
        } else {
            t0
        };
        best = best.min(((alpha * t + 2.0 * beta) * t + gamma).max(0.0));
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    use parry3d_f64::math::Rot3;
    use parry3d_f64::shape::Capsule;
    use rand::{RngExt, SeedableRng};

    /// Against parry's GJK on random segments and rotated boxes, touching
    /// and crossing ones included, and degenerate (point) segments.
    #[test]
    fn segment_box_distance_matches_parry() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let point = |rng: &mut rand_chacha::ChaCha8Rng| {
            Vec3::new(
                rng.random_range(-0.2..0.2),
                rng.random_range(-0.2..0.2),
                rng.random_range(-0.2..0.2),
            )
        };
        let (mut touching, mut apart) = (0, 0);
        for k in 0..20_000 {
            let a = point(&mut rng);
            let b = if k % 10 == 0 { a } else { point(&mut rng) };
            let cuboid = Cuboid::new(Vec3::new(
                rng.random_range(0.005..0.1),
                rng.random_range(0.005..0.1),
                rng.random_range(0.005..0.1),
            ));
            let axis = Vec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            );
            let pose = Pose::from_parts(
                point(&mut rng) * 0.3,
                Rot3::from_scaled_axis(axis * rng.random_range(0.0..3.0)),
            );
            let ours = segment_box_distance_squared(a, b, &cuboid, &pose).sqrt();
            let segment = Capsule::new(a, b, 0.0);
            let gjk = parry3d_f64::query::distance(&Pose::IDENTITY, &segment, &pose, &cuboid)
                .unwrap()
                .distance
                .max(0.0);
            assert!(
                (ours - gjk).abs() < 1e-9,
                "case {k}: closed form {ours}, GJK {gjk}"
            );
            if gjk == 0.0 {
                touching += 1
            } else {
                apart += 1
            }
        }
        assert!(
            touching > 1000 && apart > 1000,
            "{touching} touching, {apart} apart"
        );
    }
}
