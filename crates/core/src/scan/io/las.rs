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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_written_las_reads_back_and_the_limit_holds() {
        let scratch = tempfile::tempdir().unwrap();
        let path = scratch.path().join("cloud.las");
        let points = [(0.5, -1.25, 2.0), (10.125, 3.0, -0.5), (0.0, 0.0, 0.001)];
        {
            let mut writer = las::Writer::from_path(&path, las::Header::default()).unwrap();
            for &(x, y, z) in &points {
                writer
                    .write_point(las::Point {
                        x,
                        y,
                        z,
                        ..Default::default()
                    })
                    .unwrap();
            }
            writer.close().unwrap();
        }
        let cloud = read(&path, 10).unwrap();
        for (p, &(x, y, z)) in cloud.points.iter().zip(&points) {
            // LAS stores millimetre integers by default.
            assert!((p - Point3::new(x, y, z)).norm() < 1e-3, "{p}");
        }
        assert!(matches!(
            read(&path, 2),
            Err(FormatError::TooMany { got: 3, max: 2 })
        ));
    }
}
