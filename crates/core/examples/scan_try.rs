use std::time::Instant;
use treemanip_core::scan::*;
use treemanip_core::tree::{ScaParams, generate};

fn main() {
    if std::env::var("LEAFDIAG").is_ok() {
        leafdiag();
        return;
    }
    if std::env::var("LEN").is_ok() {
        lengths();
        return;
    }
    let args: Vec<String> = std::env::args().collect();
    let views: usize = args.get(1).map_or(3, |s| s.parse().unwrap());
    let noise: f64 = args.get(2).map_or(0.002, |s| s.parse().unwrap());
    let leaves: usize = args.get(3).map_or(0, |s| s.parse().unwrap());
    let mut tot = [0.0; 8];
    let mut k = 0.0;
    for (n, seed) in [
        (10, 1u64),
        (15, 2),
        (20, 3),
        (25, 4),
        (30, 5),
        (20, 6),
        (12, 7),
        (28, 8),
    ] {
        let tree = generate(n, seed, &ScaParams::default()).unwrap();
        let scan = scan(
            &tree,
            &ScanParams {
                viewpoints: views,
                noise,
                leaves_per_twig: leaves,
                seed,
                ..ScanParams::default()
            },
        )
        .unwrap();
        let t = Instant::now();
        let ex = match extract(
            &scan.cloud,
            &ExtractParams {
                spacing: std::env::var("SP").map_or(0.12, |s| s.parse().unwrap()),
                ..ExtractParams::default()
            },
        ) {
            Ok(e) => e,
            Err(e) => {
                println!("n={n} seed={seed} ERROR {e}");
                continue;
            }
        };
        let dt = t.elapsed().as_secs_f64();
        let s = score(&Skeleton::of_tree(&tree), &ex.skeleton);
        let f = score(&Skeleton::of_tree(&tree), &ex.fine);
        if std::env::var("DIAG").is_ok() {
            diag(&Skeleton::of_tree(&tree), &ex.skeleton);
        }
        println!(
            "   fine R={:.3}/{:.3} P={:.3}/{:.3}",
            f.recall[0], f.recall[1], f.precision[0], f.precision[1]
        );
        println!(
            "n={n:2} pts={:6} nodes={:3} fine={:4} R={:.3}/{:.3} P={:.3}/{:.3} rad={:.2}/{:.2}/{:.2}mm bp={:.2} topo={:.2} t={:.3}s drop={:?} {:?}",
            scan.cloud.len(),
            ex.skeleton.len(),
            ex.fine.len(),
            s.recall[0],
            s.recall[1],
            s.precision[0],
            s.precision[1],
            s.radius_error_mm[0],
            s.radius_error_mm[1],
            s.radius_error_mm[2],
            s.branch_points_matched,
            s.topology,
            dt,
            ex.dropped,
            ex.warnings
        );
        for (a, b) in tot.iter_mut().zip([
            s.recall[1],
            s.precision[1],
            s.radius_error_mm[1],
            s.branch_points_matched,
            s.topology,
            dt / scan.cloud.len() as f64 * 1e5,
            s.recall[0],
            ex.skeleton.len() as f64 / n as f64,
        ]) {
            *a += b;
        }
        k += 1.0;
    }
    println!(
        "MEAN R1={:.3} P1={:.3} rad>=5={:.2}mm bp={:.2} topo={:.2} s/100k={:.3} R.5={:.3} nodes/true={:.2}",
        tot[0] / k,
        tot[1] / k,
        tot[2] / k,
        tot[3] / k,
        tot[4] / k,
        tot[5] / k,
        tot[6] / k,
        tot[7] / k
    );
}
#[allow(dead_code)]
fn lengths() {
    let mut l = Vec::new();
    for n in 10..=30 {
        for i in 0..20u64 {
            let t = generate(
                n,
                treemanip_core::tree::tree_seed(7, n, i),
                &ScaParams::default(),
            )
            .unwrap();
            for (_, b) in t.branches_iter() {
                l.push(b.length);
            }
        }
    }
    l.sort_by(f64::total_cmp);
    println!(
        "branch length median {:.3} p25 {:.3} p75 {:.3}",
        l[l.len() / 2],
        l[l.len() / 4],
        l[3 * l.len() / 4]
    );
}
#[allow(dead_code)]
fn diag(truth: &Skeleton, found: &Skeleton) {
    use treemanip_core::scan::skeleton::point_segment;
    let (chains, _) = found.chains();
    let ch = found.children();
    let segs: Vec<_> = truth.segments().collect();
    for c in &chains {
        let mut len = 0.0;
        let mut bad = 0.0;
        for w in c.nodes.windows(2) {
            let (a, b) = (found.positions[w[0]], found.positions[w[1]]);
            let l = (b - a).norm();
            for k in 0..10 {
                let q = a + (b - a) * ((k as f64 + 0.5) / 10.0);
                if !segs.iter().any(|(s, e, r)| point_segment(&q, s, e).0 <= *r) {
                    bad += l / 10.0;
                }
            }
            len += l;
        }
        if bad > 0.02 {
            println!(
                "   chain len {:.3} bad {:.3} terminal {} nodes {} start z {:.2}",
                len,
                bad,
                ch[*c.nodes.last().unwrap()].is_empty(),
                c.nodes.len(),
                found.positions[c.nodes[0]].z
            );
        }
    }
}
#[allow(dead_code)]
fn leafdiag() {
    use treemanip_core::scan::leaves::sheets;
    use treemanip_core::scan::neighbours::PointIndex;
    let tree = generate(20, 3, &ScaParams::default()).unwrap();
    let s = scan(
        &tree,
        &ScanParams {
            viewpoints: 1,
            noise: 0.003,
            leaves_per_twig: 8,
            seed: 3,
            ..ScanParams::default()
        },
    )
    .unwrap();
    let v = treemanip_core::scan::voxel::voxelize(&s.cloud.points, 0.004);
    let idx = PointIndex::new(&v.centres);
    let sh = sheets(&v.centres, &idx);
    // label voxels by nearest raw point's origin
    let ridx = PointIndex::new(&s.cloud.points);
    let (mut ll, mut lb, mut bl, mut bb) = (0, 0, 0, 0);
    for (i, c) in v.centres.iter().enumerate() {
        let (j, _) = ridx.nearest(c);
        let leaf = s.origins[j] == Origin::Leaf;
        match (leaf, sh[i]) {
            (true, true) => ll += 1,
            (true, false) => lb += 1,
            (false, true) => bl += 1,
            (false, false) => bb += 1,
        }
    }
    println!("leaf voxels: as sheet {ll}, missed {lb}; bark voxels: as sheet {bl}, kept {bb}");
}
