//! The fuzz targets' seed corpora (`fuzz/corpus/<target>/`), replayed as
//! ordinary tests: every input returns without a panic (and, through the
//! router, without a 5xx). The long runs are `cargo fuzz run <target>`
//! (see fuzz/README.md).

use std::path::Path;

fn replay(target: &str, run: fn(&[u8])) {
    let dir = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
        .join("fuzz/corpus")
        .join(target);
    let mut count = 0;
    for entry in std::fs::read_dir(&dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display())) {
        let path = entry.unwrap().path();
        let data = std::fs::read(&path).unwrap();
        run(&data);
        count += 1;
    }
    assert!(
        count >= 3,
        "{target}: only {count} seeds in {}",
        dir.display()
    );
}

#[test]
fn tree_json_corpus() {
    replay("tree_json", treemanip_server::fuzz::tree_json);
}

#[test]
fn urdf_corpus() {
    replay("urdf", treemanip_server::fuzz::urdf);
}

#[test]
fn npz_corpus() {
    replay("npz", treemanip_server::fuzz::npz);
}

#[test]
fn request_corpus() {
    replay("request", treemanip_server::fuzz::request);
}

#[test]
fn ply_corpus() {
    replay("ply", treemanip_server::fuzz::ply);
}
