//! Embeds ONNX Runtime's shared library (from PyPI's `onnxruntime` wheel,
//! fetched by `scripts/fetch-onnxruntime`) in the binaries, so that the
//! default backend is native ONNX Runtime with nothing to install. Set
//! `TREEMANIP_ORT_LIB` to use a library already on disk, or
//! `TREEMANIP_EMBED_ORT=0` to build without it (the server then needs
//! `--ort-dylib`, or the `tract` feature). When the library cannot be had (no network, no
//! Python), the build goes on without it and says so.

use std::path::{Path, PathBuf};
use std::process::Command;

const VERSION: &str = "1.31.1";

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-changed=../../scripts/fetch-onnxruntime");
    println!("cargo:rerun-if-env-changed=TREEMANIP_ORT_LIB");
    println!("cargo:rerun-if-env-changed=TREEMANIP_EMBED_ORT");
    println!("cargo:rustc-check-cfg=cfg(embedded_ort)");
    // The version the library must be, embedded or not (`ORT_VERSION`).
    println!("cargo:rustc-env=TREEMANIP_ORT_VERSION={VERSION}");
    if std::env::var("TREEMANIP_EMBED_ORT").is_ok_and(|v| v == "0") {
        return;
    }
    let out = PathBuf::from(std::env::var("OUT_DIR").expect("cargo sets OUT_DIR"));
    let embedded = out.join("libonnxruntime.so");
    let library = std::env::var_os("TREEMANIP_ORT_LIB")
        .map(PathBuf::from)
        .or_else(|| {
            // The target directory's copy (where `scripts/fetch-onnxruntime`
            // puts it by default), shared by every profile's build.
            let shared = out
                .ancestors()
                .nth(4)
                .map_or_else(|| out.clone(), Path::to_path_buf);
            fetch(&shared.join("onnxruntime"))
        });
    match library {
        Some(lib) if std::fs::copy(&lib, &embedded).is_ok() => {
            println!("cargo:rustc-cfg=embedded_ort");
        }
        _ => println!(
            "cargo:warning=ONNX Runtime {VERSION} could not be fetched from PyPI: building without it (the server then needs --ort-dylib, or the `tract` feature)"
        ),
    }
}

/// The library from PyPI's wheel, cached in `dest`.
fn fetch(dest: &Path) -> Option<PathBuf> {
    let cached = dest.join(format!("libonnxruntime.so.{VERSION}"));
    if cached.is_file() {
        return Some(cached);
    }
    let out = Command::new("bash")
        .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scripts/fetch-onnxruntime"))
        .arg(dest)
        .output()
        .ok()?;
    (out.status.success() && cached.is_file()).then_some(cached)
}
