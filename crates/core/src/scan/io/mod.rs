//! Point cloud files: PLY (ply-rs-bw), PCD (pcd-rs), LAS and LAZ (las),
//! and XYZ text (three numbers per line). Every reader stops at
//! `max_points` and names what is wrong with a file.

pub mod error;
pub mod las;
pub mod pcd;
pub mod ply;
pub mod xyz;

use std::path::Path;

use nalgebra::Point3;

use crate::scan::cloud::PointCloud;
pub use error::FormatError;

/// Where the file says its sensor stood, for formats that record it (PCD's
/// `VIEWPOINT`); `None` for the others.
pub fn recorded_viewpoint(path: &Path) -> Result<Option<Point3<f64>>, FormatError> {
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
    if ext.eq_ignore_ascii_case("pcd") {
        pcd::recorded_viewpoint(path).map(Some)
    } else {
        Ok(None)
    }
}

/// Reads a cloud, choosing the format by the file's extension.
pub fn read_path(path: &Path, max_points: usize) -> Result<PointCloud, FormatError> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase();
    let io = |e: std::io::Error| FormatError::Io(format!("{}: {e}", path.display()));
    match ext.as_str() {
        "ply" => {
            let file = std::fs::File::open(path).map_err(io)?;
            ply::read(std::io::BufReader::new(file), max_points)
        }
        "pcd" => pcd::read(path, max_points),
        "las" | "laz" => las::read(path, max_points),
        "xyz" | "txt" | "pts" => {
            let file = std::fs::File::open(path).map_err(io)?;
            xyz::read(std::io::BufReader::new(file), max_points)
        }
        other => Err(FormatError::UnknownFormat(other.to_owned())),
    }
}
