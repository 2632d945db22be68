use treemanip::tree::{ScaParams, generate};
fn main() {
    let p = ScaParams::default();
    for n in [10usize, 11, 12, 13] {
        let mut keys = std::collections::HashMap::<String, usize>::new();
        let mut first100 = None;
        for s in 0..5000u64 {
            let tr = generate(n, s, &p).unwrap();
            *keys.entry(tr.topology_key()).or_default() += 1;
            if keys.len() == 100 && first100.is_none() {
                first100 = Some(s);
            }
        }
        let mut v: Vec<_> = keys.iter().collect();
        v.sort_by_key(|x| std::cmp::Reverse(*x.1));
        println!(
            "N={n} unique in 5000: {} ; 100 unique reached at seed {:?}; top: {:?}",
            keys.len(),
            first100,
            &v[..3]
        );
    }
}
