//! `POST /v1/trees/from-points` over HTTP: a synthetic scan of a tree sent
//! as JSON and as binary PLY comes back as a tree close to the true one
//! that `/v1/simulate` takes; bad clouds are named with 4xx, never a panic.

use serde_json::{Value, json};
use treemanip_core::scan::io::ply;
use treemanip_core::scan::{PointCloud, Scan, ScanParams, Skeleton, scan, score};
use treemanip_core::tree::{ScaParams, Tree, generate};

use crate::common::server::Server;

fn scanned() -> (Tree, PointCloud) {
    let tree = generate(16, 5, &ScaParams::default()).unwrap();
    let params = ScanParams {
        samples_per_view: 20_000,
        seed: 5,
        ..ScanParams::default()
    };
    (tree.clone(), scan(&tree, &params).unwrap().cloud)
}

/// A 20-node tree of generator seed `tree_seed` seen from one viewpoint
/// at 3 mm, with `leaves` per twig.
fn one_view(tree_seed: u64, scan_seed: u64, leaves: usize) -> (Tree, Scan) {
    let tree = generate(20, tree_seed, &ScaParams::default()).unwrap();
    let params = ScanParams {
        viewpoints: 1,
        noise: 0.003,
        leaves_per_twig: leaves,
        seed: scan_seed,
        ..ScanParams::default()
    };
    let scanned = scan(&tree, &params).unwrap();
    (tree, scanned)
}

fn ply_bytes(cloud: &PointCloud) -> Vec<u8> {
    let mut bytes = Vec::new();
    ply::write(cloud, &mut bytes).unwrap();
    bytes
}

fn skeleton_of(answer: &Value) -> Skeleton {
    let t = &answer["tree"];
    let positions = t["positions"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| {
            let p: Vec<f64> = serde_json::from_value(p.clone()).unwrap();
            nalgebra::Point3::new(p[0], p[1], p[2])
        })
        .collect();
    let parents = serde_json::from_value(t["parents"].clone()).unwrap();
    let radius: Vec<Option<f64>> = serde_json::from_value(t["radius"].clone()).unwrap();
    let first = radius.iter().flatten().copied().next().unwrap_or(0.01);
    Skeleton {
        positions,
        parents,
        radius: radius.iter().map(|r| r.unwrap_or(first)).collect(),
    }
}

#[test]
fn a_scanned_tree_comes_back_from_json_and_from_ply_and_simulates() {
    let server = Server::start(&[]);
    let (tree, cloud) = scanned();
    let points: Vec<[f64; 3]> = cloud.points.iter().map(|p| [p.x, p.y, p.z]).collect();
    let (status, from_json) = server.json(
        "POST",
        "/v1/trees/from-points",
        &json!({ "points": points }),
    );
    assert_eq!(status, 200, "{from_json}");
    let (status, from_ply) = server.send(
        "POST",
        "/v1/trees/from-points",
        "application/x-ply",
        &ply_bytes(&cloud),
    );
    assert_eq!(status, 200, "{from_ply}");
    // Binary PLY of doubles carries the same numbers as the JSON.
    assert_eq!(from_json, from_ply);
    // Three viewpoints: not seen from one side.
    assert!(
        from_json["seen_from"].is_null(),
        "{}",
        from_json["seen_from"]
    );
    let found = skeleton_of(&from_json);
    let s = score(&Skeleton::of_tree(&tree), &found);
    assert!(s.recall[1] > 0.85 && s.precision[1] > 0.85, "{s:?}");
    assert_eq!(
        from_json["confidence"].as_array().unwrap().len(),
        found.len()
    );
    let used = from_json["points_used"].as_u64().unwrap() as usize;
    assert!(used > cloud.len() * 9 / 10 && used <= cloud.len());

    // The answer is a tree the other endpoints take as it is.
    let (status, sim) = server.json(
        "POST",
        "/v1/simulate",
        &json!({
            "tree": from_json["tree"],
            "contact_node": found.len() - 1,
            "push": [0.03, 0.0, 0.0],
        }),
    );
    assert_eq!(status, 200, "{sim}");

    // Options in the query of a PLY body: a crop that keeps the bottom
    // 30 cm keeps a shorter tree and counts what it dropped.
    let (status, cropped) = server.send(
        "POST",
        "/v1/trees/from-points?crop=-2,-2,-1,2,2,0.3&spacing=0.1",
        "application/octet-stream",
        &ply_bytes(&cloud),
    );
    assert_eq!(status, 200, "{cropped}");
    assert!(cropped["points_dropped"]["outside_crop"].as_u64().unwrap() > 1000);
    let top = skeleton_of(&cropped)
        .positions
        .iter()
        .map(|p| p.z)
        .fold(f64::MIN, f64::max);
    assert!(top <= 0.31, "{top}");
}

#[test]
fn bad_clouds_are_named() {
    let server = Server::start(&["--max-cloud-points", "40000"]);
    let post = |body: Value| server.json("POST", "/v1/trees/from-points", &body);
    let check = |(status, body): (u16, Value), want: u16, words: &str| {
        assert_eq!(status, want, "{body}");
        let message = body["error"]["message"].as_str().unwrap().to_owned();
        assert!(message.contains(words), "{message}");
    };
    check(post(json!({ "points": [] })), 422, "empty");
    let plane: Vec<[f64; 3]> = (0..400)
        .map(|i| [(i % 20) as f64 * 0.01, (i / 20) as f64 * 0.01, 0.0])
        .collect();
    check(post(json!({ "points": plane })), 422, "plane");
    let line: Vec<[f64; 3]> = (0..400).map(|i| [0.0, 0.0, i as f64 * 0.001]).collect();
    check(post(json!({ "points": line })), 422, "line");
    check(
        post(json!({ "points": [[0.0, 0.0, 0.0], [1.0, 2.0]] })),
        422,
        "3 numbers",
    );
    // JSON has no NaN: the body does not parse.
    let (status, _) = server.send(
        "POST",
        "/v1/trees/from-points",
        "application/json",
        br#"{"points": [[NaN, 0, 0]]}"#,
    );
    assert_eq!(status, 400);
    let (_, cloud) = scanned();
    let doubled = PointCloud::new([cloud.points.clone(), cloud.points.clone()].concat());
    assert!(doubled.len() > 40_000);
    check(
        server.send(
            "POST",
            "/v1/trees/from-points",
            "application/x-ply",
            &ply_bytes(&doubled),
        ),
        413,
        "limit of 40000",
    );
    let points: Vec<[f64; 3]> = cloud.points.iter().map(|p| [p.x, p.y, p.z]).collect();
    check(
        post(json!({ "points": points, "root": [5.0, 5.0, 0.0] })),
        422,
        "from the nearest point",
    );
    // Two trees side by side: half the points of the scan, and a copy of
    // them 1.5 m away.
    let half: Vec<_> = cloud.points.iter().step_by(2).copied().collect();
    let two: Vec<[f64; 3]> = half
        .iter()
        .chain(
            half.iter()
                .map(|p| p + nalgebra::Vector3::new(1.5, 0.0, 0.0))
                .collect::<Vec<_>>()
                .iter(),
        )
        .map(|p| [p.x, p.y, p.z])
        .collect();
    check(post(json!({ "points": two })), 422, "several trees");
    // With a root the user picks one of them.
    let root = [half[0].x, half[0].y, half[0].z];
    let (status, body) = post(json!({ "points": two, "root": root }));
    assert_eq!(status, 200, "{body}");
    assert!(body["points_dropped"]["fragments"].as_u64().unwrap() > 5000);
    check(
        server.send(
            "POST",
            "/v1/trees/from-points",
            "application/x-ply",
            b"ply\nformat ascii 1.0\nend_header\n",
        ),
        422,
        "PLY",
    );
    check(
        server.send("POST", "/v1/trees/from-points", "text/plain", b"1 2 3"),
        415,
        "PLY",
    );
    check(
        server.send(
            "POST",
            "/v1/trees/from-points?root=1,2",
            "application/x-ply",
            &ply_bytes(&cloud),
        ),
        422,
        "`root` must be 3",
    );
}

/// A leafy cloud without colours loses its leaves by shape by default
/// (counted under `foliage`, said in a warning); `"foliage": "off"` (JSON)
/// and `foliage=off` (query) keep them; an unknown mode is named.
#[test]
fn leaves_go_by_shape_unless_foliage_is_off() {
    let server = Server::start(&[]);
    let tree = generate(18, 8, &ScaParams::default()).unwrap();
    let cloud = scan(
        &tree,
        &ScanParams {
            leaves_per_twig: 8,
            noise: 0.003,
            samples_per_view: 20_000,
            seed: 8,
            ..ScanParams::default()
        },
    )
    .unwrap()
    .cloud;
    let cloud = PointCloud::new(cloud.points);
    let points: Vec<[f64; 3]> = cloud.points.iter().map(|p| [p.x, p.y, p.z]).collect();
    let (status, auto) = server.json(
        "POST",
        "/v1/trees/from-points",
        &json!({ "points": points }),
    );
    assert_eq!(status, 200, "{auto}");
    let dropped = auto["points_dropped"]["foliage"].as_u64().unwrap() as usize;
    assert!(dropped > cloud.len() / 5, "{dropped} of {}", cloud.len());
    assert!(
        auto["warnings"]
            .as_array()
            .unwrap()
            .iter()
            .any(|w| w.as_str().unwrap().contains("look like leaves")),
        "{}",
        auto["warnings"]
    );
    let (status, off) = server.json(
        "POST",
        "/v1/trees/from-points",
        &json!({ "points": points, "foliage": "off" }),
    );
    assert_eq!(status, 200, "{off}");
    assert_eq!(off["points_dropped"]["foliage"], 0);
    let (status, off_query) = server.send(
        "POST",
        "/v1/trees/from-points?foliage=off",
        "application/x-ply",
        &ply_bytes(&cloud),
    );
    assert_eq!(status, 200, "{off_query}");
    assert_eq!(off_query["points_dropped"]["foliage"], 0);
    let truth = Skeleton::of_tree(&tree);
    let (a, b) = (
        score(&truth, &skeleton_of(&auto)),
        score(&truth, &skeleton_of(&off)),
    );
    assert!(a.precision[1] > b.precision[1], "{a:?} {b:?}");
    let (status, bad) = server.json(
        "POST",
        "/v1/trees/from-points",
        &json!({ "points": points, "foliage": "maybe" }),
    );
    assert!(status == 400 || status == 422, "{status} {bad}");
    assert!(
        bad["error"]["message"]
            .as_str()
            .unwrap()
            .contains("expected one of `auto`, `shape`, `off`"),
        "{bad}"
    );
}

/// A cloud from one camera: `"sensor": "camera"` (JSON) and `sensor=camera`
/// (query) move the axes back from the near surface and say so, and the
/// tree comes back closer to the truth at 0.5 r; by default the answer
/// only says the cloud was seen from one side; an unknown sensor is named.
#[test]
fn a_camera_cloud_seen_from_one_side_has_its_axes_moved_back() {
    let server = Server::start(&[]);
    let (tree, cloud) = one_view(5, 4, 0);
    let camera_at = cloud.viewpoints[0];
    let cloud = PointCloud::new(cloud.cloud.points);
    let points: Vec<[f64; 3]> = cloud.points.iter().map(|p| [p.x, p.y, p.z]).collect();
    let says = |answer: &Value, what: &str| {
        answer["warnings"]
            .as_array()
            .unwrap()
            .iter()
            .any(|w| w.as_str().unwrap().contains(what))
    };
    let (status, plain) = server.json(
        "POST",
        "/v1/trees/from-points",
        &json!({ "points": points }),
    );
    assert_eq!(status, 200, "{plain}");
    assert!(says(&plain, "seen from one side"), "{}", plain["warnings"]);
    // From where: within 20° of the camera's direction from the trunk.
    let seen: Vec<f64> = serde_json::from_value(plain["seen_from"].clone()).unwrap();
    let trunk = tree.positions()[0];
    let flat = |x: f64, y: f64| {
        let (dx, dy) = (x - trunk.x, y - trunk.y);
        let n = (dx * dx + dy * dy).sqrt();
        (dx / n, dy / n)
    };
    let (a, b) = (flat(seen[0], seen[1]), flat(camera_at.x, camera_at.y));
    assert!(
        a.0 * b.0 + a.1 * b.1 > 0.35f64.cos(),
        "{seen:?} for {camera_at}"
    );
    assert!(!says(&plain, "moved back"), "{}", plain["warnings"]);
    let (status, camera) = server.json(
        "POST",
        "/v1/trees/from-points",
        &json!({ "points": points, "sensor": "camera" }),
    );
    assert_eq!(status, 200, "{camera}");
    assert!(says(&camera, "moved back"), "{}", camera["warnings"]);
    let (status, camera_query) = server.send(
        "POST",
        "/v1/trees/from-points?sensor=camera",
        "application/x-ply",
        &ply_bytes(&cloud),
    );
    assert_eq!(status, 200, "{camera_query}");
    assert!(says(&camera_query, "moved back"));
    let truth = Skeleton::of_tree(&tree);
    let (a, b) = (
        score(&truth, &skeleton_of(&camera)),
        score(&truth, &skeleton_of(&plain)),
    );
    assert!(
        a.recall[0] > b.recall[0] && a.precision[0] > b.precision[0],
        "{a:?} {b:?}"
    );
    let (status, bad) = server.json(
        "POST",
        "/v1/trees/from-points",
        &json!({ "points": points, "sensor": "lidar" }),
    );
    assert!(status == 400 || status == 422, "{status} {bad}");
    assert!(
        bad["error"]["message"]
            .as_str()
            .unwrap()
            .contains("unknown variant `lidar`, expected one of `unknown`, `camera`, `laser`"),
        "{bad}"
    );
    // A laser with its beam: radii and axes from the silhouettes, the same
    // tree from JSON and from the query; a beam without a laser, or wider
    // than the extraction takes, is named.
    let (status, laser) = server.json(
        "POST",
        "/v1/trees/from-points",
        &json!({ "points": points, "sensor": "laser", "beam_radius": 0.001 }),
    );
    assert_eq!(status, 200, "{laser}");
    assert!(says(&laser, "silhouettes"), "{}", laser["warnings"]);
    assert_ne!(laser["tree"], plain["tree"]);
    let (status, laser_query) = server.send(
        "POST",
        "/v1/trees/from-points?sensor=laser&beam_radius=0.001",
        "application/x-ply",
        &ply_bytes(&cloud),
    );
    assert_eq!(status, 200, "{laser_query}");
    assert_eq!(laser_query["tree"], laser["tree"]);
    for (body, says_what) in [
        (
            json!({ "points": points, "sensor": "camera", "beam_radius": 0.001 }),
            "a laser's",
        ),
        (
            json!({ "points": points, "beam_radius": 0.001 }),
            "a laser's",
        ),
        (
            json!({ "points": points, "sensor": "laser", "beam_radius": 0.2 }),
            "between 0 and 0.05 m",
        ),
    ] {
        let (status, bad) = server.json("POST", "/v1/trees/from-points", &body);
        assert_eq!(status, 422, "{bad}");
        assert_eq!(bad["error"]["details"]["field"], "beam_radius", "{bad}");
        assert!(
            bad["error"]["message"]
                .as_str()
                .unwrap()
                .contains(says_what),
            "{bad}"
        );
    }
}

/// A leafy cloud from one camera: told where the camera stood (`viewpoints`
/// in JSON, or in the query with a PLY body), the extraction bridges gaps
/// hidden behind what it saw, says so, and the tree comes back with more
/// of the true branches; bad viewpoints are named.
#[test]
fn a_cloud_told_where_its_camera_stood_bridges_what_was_hidden() {
    let server = Server::start(&[]);
    let (tree, scanned) = one_view(2, 2, 8);
    let eye = scanned.viewpoints[0];
    let cloud = scanned.cloud;
    let points: Vec<[f64; 3]> = cloud.points.iter().map(|p| [p.x, p.y, p.z]).collect();
    let colors: Vec<[u8; 3]> = cloud.colors.clone().unwrap();
    let hidden = |answer: &Value| {
        answer["warnings"]
            .as_array()
            .unwrap()
            .iter()
            .any(|w| w.as_str().unwrap().contains("behind what the sensor saw"))
    };
    let (status, blind) = server.json(
        "POST",
        "/v1/trees/from-points",
        &json!({ "points": points, "colors": colors }),
    );
    assert_eq!(status, 200, "{blind}");
    assert!(!hidden(&blind), "{}", blind["warnings"]);
    let asks = |answer: &Value| {
        answer["warnings"]
            .as_array()
            .unwrap()
            .iter()
            .any(|w| w.as_str().unwrap().contains("send where the sensor stood"))
    };
    assert!(asks(&blind), "{}", blind["warnings"]);
    let (status, told) = server.json(
        "POST",
        "/v1/trees/from-points",
        &json!({ "points": points, "colors": colors, "viewpoints": [[eye.x, eye.y, eye.z]] }),
    );
    assert_eq!(status, 200, "{told}");
    assert!(hidden(&told), "{}", told["warnings"]);
    assert!(!asks(&told), "{}", told["warnings"]);
    let truth = Skeleton::of_tree(&tree);
    let (a, b) = (
        score(&truth, &skeleton_of(&told)),
        score(&truth, &skeleton_of(&blind)),
    );
    assert!(a.recall[1] > b.recall[1], "{a:?} {b:?}");
    let (status, query) = server.send(
        "POST",
        &format!(
            "/v1/trees/from-points?viewpoints={},{},{}",
            eye.x, eye.y, eye.z
        ),
        "application/x-ply",
        &ply_bytes(&cloud),
    );
    assert_eq!(status, 200, "{query}");
    assert_eq!(query["tree"], told["tree"]);
    for (body, field) in [
        (
            json!({ "points": points, "viewpoints": [[0.0, 1.0]] }),
            "viewpoints",
        ),
        (
            json!({ "points": points, "viewpoints": vec![[0.0, 0.0, 1.0]; 17] }),
            "16",
        ),
        (
            json!({ "points": points, "viewpoints": [[0.0, 0.0, 0.0]] }),
            "lies among the points",
        ),
    ] {
        let (status, bad) = server.json("POST", "/v1/trees/from-points", &body);
        assert!(status == 400 || status == 422, "{status} {bad}");
        assert!(
            bad["error"]["message"].as_str().unwrap().contains(field),
            "{bad}"
        );
        assert_eq!(bad["error"]["details"]["field"], "viewpoints", "{bad}");
    }
    // In the query: not triples, or more views than the extraction takes
    // (its own check, the same as for JSON).
    let seventeen = vec!["0,0,1"; 17].join(",");
    for query in ["0,0", seventeen.as_str()] {
        let (status, bad) = server.send(
            "POST",
            &format!("/v1/trees/from-points?viewpoints={query}"),
            "application/x-ply",
            &ply_bytes(&cloud),
        );
        assert_eq!(status, 422, "{bad}");
        assert_eq!(bad["error"]["details"]["field"], "viewpoints", "{bad}");
    }
}
