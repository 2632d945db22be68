use treemanip::tree::{ScaParams, generate};
fn main() {
    let p = ScaParams::default();
    let t = std::time::Instant::now();
    for n in [10usize, 15, 20, 25, 30] {
        let mut hs = vec![];
        let mut leaves = vec![];
        let mut depth = vec![];
        let mut fails = 0;
        let mut keys = std::collections::HashSet::new();
        for s in 0..100u64 {
            match generate(n, s, &p) {
                Ok(tr) => {
                    hs.push(tr.height());
                    leaves.push((0..n).filter(|&j| tr.is_leaf(j)).count());
                    depth.push((0..n).map(|j| tr.depth(j)).max().unwrap());
                    keys.insert(tr.topology_key());
                }
                Err(e) => {
                    fails += 1;
                    eprintln!("{e}");
                }
            }
        }
        let mean = |v: &Vec<usize>| v.iter().sum::<usize>() as f64 / v.len() as f64;
        println!(
            "N={n} fails={fails} unique={} height {:.2}-{:.2} leaves {:.1} maxdepth {:.1}",
            keys.len(),
            hs.iter().cloned().fold(9.0, f64::min),
            hs.iter().cloned().fold(0.0, f64::max),
            mean(&leaves),
            mean(&depth)
        );
    }
    println!("{:?}", t.elapsed());
}
