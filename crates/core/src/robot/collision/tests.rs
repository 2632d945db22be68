use super::*;
use rand::{RngExt, SeedableRng};

/// The closed form agrees with parry's general (GJK) test on random
/// capsule pairs, near-touching ones included, under random poses.
#[test]
fn capsule_fast_path_matches_parry() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    let point = |rng: &mut rand_chacha::ChaCha8Rng| {
        Vec3::new(
            rng.random_range(-0.3..0.3),
            rng.random_range(-0.3..0.3),
            rng.random_range(-0.3..0.3),
        )
    };
    let (mut touching, mut apart) = (0, 0);
    for k in 0..20_000 {
        let c1 = Capsule::new(
            point(&mut rng),
            point(&mut rng),
            rng.random_range(0.005..0.1),
        );
        let c2 = Capsule::new(
            point(&mut rng),
            point(&mut rng),
            rng.random_range(0.005..0.1),
        );
        let pose_of = |rng: &mut rand_chacha::ChaCha8Rng| {
            if k % 2 == 0 {
                Pose::IDENTITY
            } else {
                pose(&Isometry3::new(
                    Vector3::new(rng.random_range(-0.1..0.1), 0.05, 0.0),
                    Vector3::new(rng.random_range(-1.0..1.0), 0.3, -0.2),
                ))
            }
        };
        let (pa, pb) = (pose_of(&mut rng), pose_of(&mut rng));
        let gjk = intersection_test(&pa, &c1, &pb, &c2).unwrap().intersecting;
        // Within 1e-9 m of touching, either answer is right.
        let clearance = parry3d_f64::query::distance(&pa, &c1, &pb, &c2)
            .unwrap()
            .distance;
        if capsules_intersect(&pa, &c1, &pb, &c2) != gjk {
            assert!(
                clearance < 1e-9 && !gjk,
                "pair {k}: clearance {clearance}, gjk {gjk}"
            );
        }
        if gjk { touching += 1 } else { apart += 1 }
    }
    assert!(
        touching > 1000 && apart > 1000,
        "{touching} touching, {apart} apart"
    );
}
