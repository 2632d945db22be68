//! ARCHITECTURE.md kept true: the crates' dependencies point one way, the
//! server's graph has no trainer (burn, gemm) and, by default, no tract,
//! and no file of ours grows past 600 lines.

use std::path::Path;
use std::process::Command;

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

/// `cargo tree` of one package (normal and build edges, this target, its
/// default features only), as `name version` lines without duplicates.
fn dependencies(package: &str) -> Vec<String> {
    dependencies_with(package, &[])
}

/// `cargo tree --locked --target x86_64-unknown-linux-gnu` with `args`, run
/// in the workspace; its output.
fn cargo_tree(args: &[&str]) -> String {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let out = Command::new(cargo)
        .current_dir(ROOT)
        .args(["tree", "--locked", "--target", "x86_64-unknown-linux-gnu"])
        .args(args)
        .output()
        .expect("cargo runs");
    assert!(
        out.status.success(),
        "cargo tree {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// [`dependencies`] with extra `cargo tree` flags (features).
fn dependencies_with(package: &str, flags: &[&str]) -> Vec<String> {
    let mut args = vec![
        "-p",
        package,
        "-e",
        "normal,build",
        "--prefix",
        "none",
        "--no-dedupe",
    ];
    args.extend_from_slice(flags);
    let mut crates: Vec<String> = cargo_tree(&args)
        .lines()
        .filter_map(|l| {
            let mut words = l.split_whitespace();
            Some(format!("{} {}", words.next()?, words.next()?))
        })
        .collect();
    crates.sort();
    crates.dedup();
    crates
}

fn names(crates: &[String]) -> Vec<&str> {
    crates.iter().filter_map(|c| c.split(' ').next()).collect()
}

#[test]
fn the_server_builds_without_the_trainer_and_without_tract() {
    let server = dependencies("treemanip-server");
    let names = names(&server);
    for forbidden in [
        "burn",
        "gemm",
        "cubecl",
        "tract",
        "ort-tract",
        "plotters",
        "treemanip",
    ] {
        let found: Vec<_> = names
            .iter()
            // `treemanip` is the trainer itself; `treemanip-*` are the layers.
            .filter(|n| {
                **n == forbidden
                    || (forbidden != "treemanip" && n.starts_with(&format!("{forbidden}-")))
            })
            .collect();
        assert!(found.is_empty(), "treemanip-server depends on {found:?}");
    }
    assert!(
        names.contains(&"ort") && names.contains(&"axum"),
        "{names:?}"
    );
    println!("treemanip-server: {} crates", server.len());
}

/// `cargo test -p treemanip-core` and `cargo test -p treemanip-server` build
/// their own tests without the trainer or tract: their graphs with
/// dev-dependencies hold neither.
#[test]
fn core_and_server_tests_build_without_the_trainer() {
    for package in ["treemanip-core", "treemanip-server"] {
        let crates: Vec<String> = {
            let mut c: Vec<String> = cargo_tree(&[
                "-p",
                package,
                "-e",
                "normal,build,dev",
                "--prefix",
                "none",
                "--no-dedupe",
            ])
            .lines()
            .filter_map(|l| {
                let mut words = l.split_whitespace();
                Some(format!("{} {}", words.next()?, words.next()?))
            })
            .collect();
            c.sort();
            c.dedup();
            c
        };
        let found: Vec<&str> = names(&crates)
            .into_iter()
            .filter(|n| {
                ["burn", "gemm", "tract", "plotters"]
                    .iter()
                    .any(|f| n == f || n.starts_with(&format!("{f}-")))
                    || *n == "treemanip"
            })
            .collect();
        assert!(found.is_empty(), "{package}'s tests depend on {found:?}");
        println!("{package} with its tests: {} crates", crates.len());
    }
}

/// The container image's binary: `treemanip` without the `train` feature
/// (Dockerfile), which runs `serve` and the dataset Jobs.
#[test]
fn the_image_binary_carries_no_trainer() {
    let dockerfile = std::fs::read_to_string(format!("{ROOT}/Dockerfile")).unwrap();
    assert!(
        dockerfile.contains("-p treemanip --no-default-features --bin treemanip"),
        "the Dockerfile builds another binary"
    );
    let cli = dependencies_with("treemanip", &["--no-default-features"]);
    let names = names(&cli);
    for forbidden in ["burn", "gemm", "tract-onnx", "plotters"] {
        assert!(
            !names.contains(&forbidden),
            "the image's treemanip depends on {forbidden}"
        );
    }
    // The commands the image runs are outside the `train` feature.
    let main = std::fs::read_to_string(format!("{ROOT}/src/bin/treemanip/main.rs")).unwrap();
    for command in ["Serve(", "Dataset(", "Trees(", "Sim("] {
        let line = main
            .lines()
            .position(|l| l.trim_start().starts_with(command))
            .unwrap_or_else(|| panic!("no {command} command"));
        let above: Vec<&str> = main.lines().take(line).collect();
        let gated = above
            .iter()
            .rev()
            .take_while(|l| l.trim_start().starts_with("///") || l.trim_start().starts_with("#["))
            .any(|l| l.contains("feature = \"train\""));
        assert!(!gated, "{command} needs the train feature");
    }
}

/// `cargo run --release --bin treemanip-server` resolves the features of
/// every default member (the trainer included) before it picks the binary:
/// nothing there may turn on `treemanip-infer`'s `tract`.
#[test]
fn the_readme_server_command_resolves_no_tract() {
    let tree = cargo_tree(&["-e", "normal,build,features", "-i", "treemanip-infer"]);
    assert!(tree.contains("treemanip-infer"), "{tree}");
    assert!(!tree.contains("feature \"tract\""), "{tree}");
}

#[test]
fn lower_crates_do_not_depend_on_higher_ones() {
    let layers = [
        "treemanip-core",
        "treemanip-infer",
        "treemanip-server",
        "treemanip",
    ];
    for (k, package) in layers.iter().enumerate() {
        let deps = dependencies(package);
        let names = names(&deps);
        for higher in &layers[k + 1..] {
            assert!(!names.contains(higher), "{package} depends on {higher}");
        }
    }
    let core = dependencies("treemanip-core");
    assert!(!names(&core).contains(&"ort"), "treemanip-core runs models");
}

/// Rust and JavaScript files of ours (vendored files aside).
pub(crate) fn sources(dir: &Path, out: &mut Vec<std::path::PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        if path.is_dir() {
            if !["target", "vendor", ".git", "node_modules"].contains(&name.as_str()) {
                sources(&path, out);
            }
        } else if name.ends_with(".rs") || name.ends_with(".js") {
            out.push(path);
        }
    }
}

#[test]
fn no_file_of_ours_is_over_600_lines() {
    let mut files = Vec::new();
    for dir in [
        "src",
        "crates",
        "tests",
        "benches",
        "fuzz/fuzz_targets",
        "assets/viewer",
    ] {
        sources(&Path::new(ROOT).join(dir), &mut files);
    }
    assert!(files.len() > 50, "{} files", files.len());
    let long: Vec<_> = files
        .iter()
        .filter_map(|f| {
            let lines = std::fs::read_to_string(f).ok()?.lines().count();
            (lines > 600).then(|| format!("{} ({lines} lines)", f.display()))
        })
        .collect();
    assert!(long.is_empty(), "over 600 lines: {long:?}");
}

mod imports;

#[test]
fn no_import_circle_between_files() {
    // The library crates. (The trainer's `src/nn/train/` still has one:
    // its modules share the training state through `train/mod.rs`.)
    for krate in ["crates/core", "crates/infer", "crates/server"] {
        let graph = imports::graph(&Path::new(ROOT).join(krate).join("src"));
        let circles = imports::circles(&graph);
        let edges: usize = graph.edges.values().map(|e| e.len()).sum();
        println!(
            "{krate}: {} files, {edges} edges, {} circles",
            graph.files,
            circles.len()
        );
        assert!(graph.files > 3 && edges > 0, "{krate}: nothing read");
        let named: Vec<String> = circles
            .iter()
            .map(|c| {
                c.iter()
                    .map(|m| m.join("/"))
                    .collect::<Vec<_>>()
                    .join(" <-> ")
            })
            .collect();
        assert!(named.is_empty(), "{krate}: import circles: {named:#?}");
    }
}

/// The checker finds a circle where one is: two files naming each other's
/// items, one through a re-export.
#[test]
fn the_import_checker_sees_a_circle() {
    let dir = crate::common::temp_dir("imports");
    std::fs::create_dir_all(dir.join("a")).unwrap();
    std::fs::write(
        dir.join("lib.rs"),
        "pub mod a;\npub mod b;\npub use b::Thing;\n",
    )
    .unwrap();
    std::fs::write(dir.join("a/mod.rs"), "mod c;\npub use c::Other;\n").unwrap();
    std::fs::write(
        dir.join("a/c.rs"),
        "use crate::Thing;\npub struct Other(Thing);\n",
    )
    .unwrap();
    std::fs::write(dir.join("b.rs"), "pub struct Thing;\nfn f() -> crate::a::Other { todo!() }\n#[cfg(test)]\nmod tests { use super::*; }\n").unwrap();
    let graph = imports::graph(&dir);
    let circles = imports::circles(&graph);
    std::fs::remove_dir_all(&dir).unwrap();
    let as_names: Vec<Vec<String>> = circles
        .iter()
        .map(|c| c.iter().map(|m| m.join("/")).collect())
        .collect();
    assert_eq!(as_names, vec![vec!["a/c".to_owned(), "b".to_owned()]]);
}
