//! LAS and LAZ (the `las` crate, LAZ through its `laz` feature): the
//! points' scaled x, y, z in the file's units (metres for the scanners
//! treemanip expects). The point count in the header is checked against
//! the limit before any point is read.

use std::path::Path;

use nalgebra::Point3;

use super::error::FormatError;
use crate::scan::cloud::PointCloud;

pub fn read(path: &Path, max_points: usize) -> Result<PointCloud, FormatError> {
    let parse = |e: las::Error| FormatError::Parse {
        format: "LAS",
        reason: e.to_string(),
    };
    let mut reader = las::Reader::from_path(path).map_err(parse)?;
    let count = reader.header().number_of_points();
    if count > max_points as u64 {
        return Err(FormatError::TooMany {
            got: count,
            max: max_points,
        });
    }
    let data = reader.read_all().map_err(parse)?;
    let points = data
        .x()
        .zip(data.y())
        .zip(data.z())
        .map(|((x, y), z)| Point3::new(x, y, z))
        .collect();
    Ok(PointCloud::new(points))
}
