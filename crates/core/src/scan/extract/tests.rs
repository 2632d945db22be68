//! The extraction's tests: leaves by colour and by shape, parts bridged.

use super::*;
use nalgebra::Vector3;

use crate::scan::beam_scan::{BeamScan, scanned_stem};
use crate::scan::foliage::is_foliage;
use crate::scan::scanner::{Origin, ScanParams, scan};
use crate::scan::score::score;
use crate::scan::skeleton::point_segment;
use crate::scan::viewpoint::Sensor;
use crate::tree::{ScaParams, generate};

/// A branch of the hand-made trees below.
fn branch(radius: f64, length: f64) -> Option<crate::tree::Branch> {
    Some(crate::tree::Branch {
        radius,
        length,
        stiffness: 10.0,
        damping: 1.0,
    })
}

/// `tree` scanned from three sides, 1 mm noise, bare.
fn three_views(tree: &crate::tree::Tree, seed: u64) -> crate::scan::Scan {
    scan(
        tree,
        &ScanParams {
            viewpoints: 3,
            noise: 0.001,
            samples_per_view: 30_000,
            seed,
            ..ScanParams::default()
        },
    )
    .unwrap()
}

#[test]
fn colours_drop_the_leaves_and_the_tree_comes_back() {
    let tree = generate(18, 12, &ScaParams::default()).unwrap();
    let params = ScanParams {
        leaves_per_twig: 8,
        samples_per_view: 20_000,
        seed: 12,
        ..ScanParams::default()
    };
    let scanned = scan(&tree, &params).unwrap();
    let leaves = scanned
        .origins
        .iter()
        .filter(|o| **o == Origin::Leaf)
        .count();
    let bark = scanned.cloud.len() - leaves;
    let with = extract(&scanned.cloud, &ExtractParams::default()).unwrap();
    // Every leaf point is green, no bark point is.
    assert!(
        with.dropped.foliage > leaves * 95 / 100,
        "{:?} of {leaves}",
        with.dropped
    );
    assert!(with.dropped.foliage <= leaves + bark / 1000);
    let without = extract(
        &PointCloud::new(scanned.cloud.points.clone()),
        &ExtractParams {
            foliage: FoliageFilter::Off,
            ..ExtractParams::default()
        },
    )
    .unwrap();
    assert_eq!(without.dropped.foliage, 0);
    let truth = Skeleton::of_tree(&tree);
    let (a, b) = (
        score(&truth, &with.skeleton),
        score(&truth, &without.skeleton),
    );
    assert!(
        a.precision[1] > 0.9 && a.precision[1] > b.precision[1],
        "{a:?} {b:?}"
    );
}

/// A fork seen apart from its trunk (a band of leaves hides 4 cm of the
/// trunk) is not elongated, but it is a subtree: it is bridged, not
/// dropped as a fragment.
#[test]
fn a_fork_seen_apart_from_its_trunk_is_bridged() {
    let arm = (0.2f64 * 0.2 + 0.2 * 0.2).sqrt();
    let tree = crate::tree::Tree::new(
        vec![
            Point3::origin(),
            Point3::new(0.0, 0.0, 0.6),
            Point3::new(0.2, 0.0, 0.8),
            Point3::new(-0.2, 0.0, 0.8),
        ],
        vec![None, Some(0), Some(1), Some(1)],
        vec![
            None,
            branch(0.02, 0.6),
            branch(0.01, arm),
            branch(0.01, arm),
        ],
    )
    .unwrap();
    let scanned = three_views(&tree, 3);
    let hidden = |p: &Point3<f64>| (0.46..0.50).contains(&p.z);
    let points: Vec<_> = scanned
        .cloud
        .points
        .iter()
        .copied()
        .filter(|p| !hidden(p))
        .collect();
    let found = extract(&PointCloud::new(points), &ExtractParams::default()).unwrap();
    // The fork holds about a third of the points; none is a fragment.
    assert_eq!(found.dropped.fragments, 0, "{:?}", found.dropped);
    let top = found
        .skeleton
        .positions
        .iter()
        .map(|p| p.z)
        .fold(f64::NEG_INFINITY, f64::max);
    assert!(top > 0.75, "the skeleton stops at {top} m");
    let s = score(&Skeleton::of_tree(&tree), &found.skeleton);
    assert!(s.recall[1] > 0.9, "{s:?}");
    assert!(found.warnings.iter().any(|w| w.contains("bridged")));
}

/// A stem with a 25 cm twig from a fork 40 cm up, scanned from three sides,
/// the twig's points removed but for its last 2 cm (the stub).
struct HiddenTwig {
    fork: Point3<f64>,
    tip: Point3<f64>,
    /// The stub's middle.
    stub: Point3<f64>,
    /// What is left of the scan.
    bark: Vec<Point3<f64>>,
}

fn hidden_twig() -> HiddenTwig {
    let (fork, tip) = (Point3::new(0.0, 0.0, 0.4), Point3::new(0.25, 0.0, 0.43));
    let tree = crate::tree::Tree::new(
        vec![Point3::origin(), Point3::new(0.0, 0.0, 0.6), fork, tip],
        vec![None, Some(0), Some(0), Some(2)],
        vec![
            None,
            branch(0.02, 0.6),
            branch(0.02, 0.4),
            branch(0.005, (tip - fork).norm()),
        ],
    )
    .unwrap();
    let scanned = three_views(&tree, 5);
    // Along the twig, 0 at the fork and 1 at the tip.
    let along = |p: &Point3<f64>| (p - fork).dot(&(tip - fork)) / (tip - fork).norm_squared();
    let bark = scanned
        .cloud
        .points
        .iter()
        .zip(&scanned.origins)
        .filter(|(p, o)| **o != Origin::Branch(3) || along(p) >= 0.93)
        .map(|(p, _)| *p)
        .collect();
    HiddenTwig {
        fork,
        tip,
        stub: fork + (tip - fork) * 0.965,
        bark,
    }
}

/// How far (m) the skeleton passes from `at`.
fn distance_to(s: &Skeleton, at: &Point3<f64>) -> f64 {
    (0..s.positions.len())
        .filter_map(|j| s.parents[j].map(|p| point_segment(at, &s.positions[p], &s.positions[j]).0))
        .fold(f64::INFINITY, f64::min)
}

/// A twig hidden by its leaves but for its last 2 cm: that stub is too
/// short to look like a branch and 20 cm from the stem, so across bare air
/// it is a fragment; where the leaves dropped from the cloud cover the gap,
/// it is bridged to the stem and the tree reaches it, and the warning says
/// so. Leaves beside the gap, not over it, bridge nothing.
#[test]
fn a_twig_hidden_by_its_leaves_is_bridged_under_them() {
    let HiddenTwig {
        fork,
        tip,
        stub,
        bark,
    } = hidden_twig();
    // Leaves: 2.5 cm discs 2 cm beside the hidden stretch, every 2 cm.
    let leaves_at = |shift: Vector3<f64>| -> Vec<Point3<f64>> {
        let mut out = Vec::new();
        for k in 0..14 {
            let centre =
                fork + (tip - fork) * (0.06 + 0.062 * k as f64) + Vector3::y() * 0.02 + shift;
            for i in -8i32..=8 {
                for j in -8i32..=8 {
                    let (u, v) = (0.003 * i as f64, 0.003 * j as f64);
                    if u * u + v * v <= 0.025 * 0.025 {
                        out.push(centre + Vector3::new(u, 0.0, v));
                    }
                }
            }
        }
        out
    };
    let coloured = |leaves: Vec<Point3<f64>>| {
        let mut cloud =
            PointCloud::new(bark.iter().copied().chain(leaves.iter().copied()).collect());
        cloud.colors = Some(
            std::iter::repeat_n([110, 80, 50], bark.len())
                .chain(std::iter::repeat_n([40, 160, 40], leaves.len()))
                .collect(),
        );
        extract(&cloud, &ExtractParams::default()).unwrap()
    };
    let reaches_stub = |found: &Extraction| distance_to(&found.skeleton, &stub);

    let covered = coloured(leaves_at(Vector3::zeros()));
    assert!(reaches_stub(&covered) < 0.015, "{}", reaches_stub(&covered));
    assert!(
        covered.warnings.iter().any(|w| w.contains("under leaves")),
        "{:?}",
        covered.warnings
    );
    for found in [
        coloured(Vec::new()),
        coloured(leaves_at(Vector3::y() * 0.15)),
    ] {
        assert!(reaches_stub(&found) > 0.05, "{}", reaches_stub(&found));
        assert!(found.dropped.fragments > 0, "{:?}", found.dropped);
        assert!(!found.warnings.iter().any(|w| w.contains("under leaves")));
    }
}

/// The same twig hidden but for its last 2 cm, now behind a board 40 cm
/// in front of it (no leaves): told where the sensor stood, the extraction
/// bridges the gap in the board's shadow and the tree reaches the stub;
/// not told, or told a place from which the gap was in plain view, the
/// stub stays a fragment.
#[test]
fn a_twig_hidden_behind_what_the_sensor_saw_is_bridged() {
    let HiddenTwig {
        stub,
        bark: mut points,
        ..
    } = hidden_twig();
    // The board: 26 cm by 12 cm, 4 mm apart, in the plane y = -0.4.
    for i in 0..=65 {
        for k in 0..=30 {
            points.push(Point3::new(0.004 * i as f64, -0.4, 0.36 + 0.004 * k as f64));
        }
    }
    let cloud = PointCloud::new(points);
    let from = |viewpoints: Vec<Point3<f64>>| {
        extract(
            &cloud,
            &ExtractParams {
                foliage: crate::scan::FoliageFilter::Off,
                viewpoints,
                ..ExtractParams::default()
            },
        )
        .unwrap()
    };
    let reaches_stub = |found: &Extraction| distance_to(&found.skeleton, &stub);
    let behind = from(vec![Point3::new(0.12, -1.5, 0.42)]);
    assert!(reaches_stub(&behind) < 0.015, "{}", reaches_stub(&behind));
    assert!(
        behind
            .warnings
            .iter()
            .any(|w| w.contains("behind what the sensor saw")),
        "{:?}",
        behind.warnings
    );
    for found in [from(Vec::new()), from(vec![Point3::new(0.12, 1.5, 0.42)])] {
        assert!(reaches_stub(&found) > 0.05, "{}", reaches_stub(&found));
        assert!(found.dropped.fragments > 0, "{:?}", found.dropped);
    }
    let bad = extract(
        &cloud,
        &ExtractParams {
            viewpoints: vec![Point3::new(f64::NAN, 0.0, 0.0)],
            ..ExtractParams::default()
        },
    );
    assert!(
        matches!(
            bad,
            Err(CloudError::BadParameter {
                field: "viewpoints",
                ..
            })
        ),
        "{bad:?}"
    );
    // The trunk's foot: a world frame's origin sent as a camera's.
    let among = extract(
        &cloud,
        &ExtractParams {
            viewpoints: vec![Point3::new(0.2, 0.0, 0.8), Point3::origin()],
            ..ExtractParams::default()
        },
    );
    assert!(
        matches!(
            among,
            Err(CloudError::ViewpointAmongPoints { index: 1, .. })
        ),
        "{among:?}"
    );
}

/// Without colours, a leafy cloud loses its leaves by shape (counted
/// as foliage, said in a warning) and the tree comes back more
/// precisely; a bare cloud keeps every point; `Off` keeps the leaves.
#[test]
fn without_colours_leaves_go_by_shape_and_bare_bark_stays() {
    let tree = generate(22, 31, &ScaParams::default()).unwrap();
    let leafy = scan(
        &tree,
        &ScanParams {
            leaves_per_twig: 8,
            noise: 0.003,
            seed: 9,
            ..ScanParams::default()
        },
    )
    .unwrap();
    let leaves = leafy.origins.iter().filter(|o| **o == Origin::Leaf).count();
    let cloud = PointCloud::new(leafy.cloud.points.clone());
    let truth = Skeleton::of_tree(&tree);
    let by_shape = extract(&cloud, &ExtractParams::default()).unwrap();
    assert!(
        by_shape.dropped.foliage > leaves * 7 / 10,
        "{:?} of {leaves}",
        by_shape.dropped
    );
    assert!(
        by_shape
            .warnings
            .iter()
            .any(|w| w.contains("look like leaves"))
    );
    let kept = extract(
        &cloud,
        &ExtractParams {
            foliage: FoliageFilter::Off,
            ..ExtractParams::default()
        },
    )
    .unwrap();
    assert_eq!(kept.dropped.foliage, 0);
    let (a, b) = (
        score(&truth, &by_shape.skeleton),
        score(&truth, &kept.skeleton),
    );
    assert!(a.precision[1] > b.precision[1] + 0.05, "{a:?} {b:?}");

    let bare = scan(
        &tree,
        &ScanParams {
            seed: 9,
            ..ScanParams::default()
        },
    )
    .unwrap();
    let found = extract(
        &PointCloud::new(bare.cloud.points),
        &ExtractParams::default(),
    )
    .unwrap();
    assert_eq!(found.dropped.foliage, 0, "{:?}", found.dropped);
    assert!(!found.warnings.iter().any(|w| w.contains("leaves")));
}

/// A cloud from one viewpoint says so, with a viewpoint in the sensor's
/// direction; the same tree from three sides does not.
#[test]
fn a_cloud_seen_from_one_side_says_where_from() {
    let tree = generate(20, 5, &ScaParams::default()).unwrap();
    let one = scan(
        &tree,
        &ScanParams {
            viewpoints: 1,
            seed: 4,
            ..ScanParams::default()
        },
    )
    .unwrap();
    let found = extract(&one.cloud, &ExtractParams::default()).unwrap();
    let seen = found.seen_from.expect("one side");
    let trunk = tree.positions()[0];
    let flat = |p: &Point3<f64>| Vector3::new(p.x - trunk.x, p.y - trunk.y, 0.0).normalize();
    let angle = flat(&seen).dot(&flat(&one.viewpoints[0])).acos();
    assert!(
        angle < 0.35,
        "{seen} for {}: {angle} rad",
        one.viewpoints[0]
    );
    assert!(
        found
            .warnings
            .iter()
            .any(|w| w.contains("seen from one side"))
    );
    let three = scan(
        &tree,
        &ScanParams {
            seed: 4,
            ..ScanParams::default()
        },
    )
    .unwrap();
    let found = extract(&three.cloud, &ExtractParams::default()).unwrap();
    assert_eq!(found.seen_from, None);
    assert!(!found.warnings.iter().any(|w| w.contains("one side")));
}

/// Told a camera made it, a one-view cloud's skeleton moves back onto the
/// branches (closer at 0.5 r); a three-view cloud's does not move.
#[test]
fn a_camera_cloud_has_its_axes_moved_back_from_the_near_side() {
    let tree = generate(24, 6, &ScaParams::default()).unwrap();
    let truth = Skeleton::of_tree(&tree);
    let camera = ExtractParams {
        sensor: Sensor::Camera,
        ..ExtractParams::default()
    };
    let one = scan(
        &tree,
        &ScanParams {
            viewpoints: 1,
            noise: 0.003,
            seed: 6,
            ..ScanParams::default()
        },
    )
    .unwrap();
    let moved = extract(&one.cloud, &camera).unwrap();
    let kept = extract(&one.cloud, &ExtractParams::default()).unwrap();
    let (a, b) = (
        score(&truth, &moved.skeleton),
        score(&truth, &kept.skeleton),
    );
    assert!(
        a.recall[0] > b.recall[0] + 0.05 && a.precision[0] > b.precision[0] + 0.05,
        "{a:?} {b:?}"
    );
    let three = scan(
        &tree,
        &ScanParams {
            noise: 0.003,
            seed: 6,
            ..ScanParams::default()
        },
    )
    .unwrap();
    let moved = extract(&three.cloud, &camera).unwrap();
    let kept = extract(&three.cloud, &ExtractParams::default()).unwrap();
    assert_eq!(moved.skeleton, kept.skeleton);
}

#[test]
fn excess_green_tells_leaves_from_bark_and_fruit() {
    assert!(is_foliage([74, 122, 46]));
    assert!(is_foliage([40, 70, 25]));
    assert!(!is_foliage([92, 68, 48]));
    assert!(!is_foliage([168, 42, 36]));
    assert!(!is_foliage([5, 20, 3]), "too dark to tell");
}

/// A stem of radius `r` (m) on the z axis, 0.5 m tall, scanned from one
/// side (+y, 1.5 m out) by a laser whose footprint (a disc of radius `w`)
/// returns the mean range of what it grazes, with 1 mm range noise.
fn laser_scanned_stem(r: f64, w: f64) -> PointCloud {
    let scan = BeamScan {
        beam: w,
        step: 0.0015,
        rows: 250,
        noise: 0.001,
    };
    PointCloud::new(scanned_stem(r, &scan))
}

/// Told the beam, a laser's one-sided stem comes back with its radius and
/// on its axis; not told, the circles through its widened arcs are too
/// large and stand behind the axis.
#[test]
fn a_laser_cloud_has_its_radii_from_the_silhouettes_less_the_beam() {
    let (r, w) = (0.012, 0.003);
    let cloud = laser_scanned_stem(r, w);
    let median_radius = |e: &Extraction| {
        let mut v = e.skeleton.radius[1..].to_vec();
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let mean_behind = |e: &Extraction| {
        let ys: Vec<f64> = e.skeleton.positions[1..].iter().map(|p| -p.y).collect();
        ys.iter().sum::<f64>() / ys.len() as f64
    };
    let laser = ExtractParams {
        sensor: Sensor::Laser { beam_radius: w },
        ..ExtractParams::default()
    };
    let told = extract(&cloud, &laser).unwrap();
    let plain = extract(&cloud, &ExtractParams::default()).unwrap();
    assert!(told.seen_from.is_some() && plain.seen_from.is_some());
    assert!(
        told.warnings.iter().any(|w| w.contains("silhouettes")),
        "{:?}",
        told.warnings
    );
    assert!(
        (median_radius(&told) - r).abs() < 0.0006,
        "{}",
        median_radius(&told)
    );
    assert!(
        median_radius(&plain) > r + 0.001,
        "{}",
        median_radius(&plain)
    );
    assert!(mean_behind(&told).abs() < 0.001, "{}", mean_behind(&told));
    assert!(mean_behind(&plain) > 0.001, "{}", mean_behind(&plain));
    // A beam wider than a branch is refused by name.
    let wide = ExtractParams {
        sensor: Sensor::Laser { beam_radius: 0.2 },
        ..ExtractParams::default()
    };
    match extract(&cloud, &wide) {
        Err(CloudError::BadParameter { field, .. }) => assert_eq!(field, "beam_radius"),
        other => panic!("{other:?}"),
    }
}
