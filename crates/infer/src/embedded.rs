//! The ONNX Runtime library carried in this binary (see `build.rs`):
//! written once to a cache file, named by its size and hash so that
//! binaries of other versions never share one, and loaded from there.

use std::path::PathBuf;

#[cfg(embedded_ort)]
static LIBRARY: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/libonnxruntime.so"));
#[cfg(not(embedded_ort))]
static LIBRARY: &[u8] = &[];

/// Whether this build carries ONNX Runtime.
pub const EMBEDDED: bool = cfg!(embedded_ort);

/// The embedded library's path on disk (written on first use), or `None`
/// when this build carries none or it cannot be written.
pub fn library() -> Option<PathBuf> {
    if LIBRARY.is_empty() {
        return None;
    }
    // FNV-1a over a sample of the bytes: cheap, and enough to tell builds apart.
    let mut hash: u64 = 0xcbf29ce484222325;
    for b in LIBRARY
        .iter()
        .step_by(4099)
        .chain(LIBRARY.iter().rev().take(4096))
    {
        hash = (hash ^ u64::from(*b)).wrapping_mul(0x100000001b3);
    }
    let dir = std::env::var_os("XDG_CACHE_HOME")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache")))
        .filter(|d| std::fs::create_dir_all(d).is_ok())
        .unwrap_or_else(std::env::temp_dir)
        .join("treemanip");
    let path = dir.join(format!("libonnxruntime-{}-{hash:016x}.so", LIBRARY.len()));
    if std::fs::metadata(&path).is_ok_and(|m| m.len() == LIBRARY.len() as u64) {
        return Some(path);
    }
    // Written under a unique name, then renamed: concurrent processes never
    // see a half-written file.
    let tmp = dir.join(format!("libonnxruntime-{}.tmp", std::process::id()));
    let written = std::fs::create_dir_all(&dir)
        .and_then(|()| std::fs::write(&tmp, LIBRARY))
        .and_then(|()| std::fs::rename(&tmp, &path));
    match written {
        Ok(()) => Some(path),
        Err(e) => {
            tracing::warn!(dir = %dir.display(), error = %e, "cannot write the embedded ONNX Runtime library");
            let _ = std::fs::remove_file(&tmp);
            None
        }
    }
}
