//! PCD (the Point Cloud Library's format, through pcd-rs): ASCII, binary
//! or compressed, the `x`, `y`, `z` fields of any numeric type. The point
//! count in the header is checked against the limit before any point is
//! read. The header's `VIEWPOINT` (where the sensor stood) is read only on
//! request ([`recorded_viewpoint`]): a cloud moved into a world frame often
//! keeps its default `0 0 0`.

use std::path::Path;

use nalgebra::Point3;
use pcd_rs::{DynReader, Field};

use super::error::FormatError;
use crate::scan::cloud::PointCloud;

const FORMAT: &str = "PCD";

pub fn read(path: &Path, max_points: usize) -> Result<PointCloud, FormatError> {
    let parse = |e: pcd_rs::Error| FormatError::Parse {
        format: FORMAT,
        reason: e.to_string(),
    };
    let reader = DynReader::open(path).map_err(parse)?;
    let meta = reader.meta();
    if meta.num_points > max_points as u64 {
        return Err(FormatError::TooMany {
            got: meta.num_points,
            max: max_points,
        });
    }
    let index = |name: &'static str| {
        meta.field_defs
            .fields
            .iter()
            .position(|f| f.name == name)
            .ok_or(FormatError::Missing {
                format: FORMAT,
                what: name,
            })
    };
    let (ix, iy, iz) = (index("x")?, index("y")?, index("z")?);
    let mut points = Vec::with_capacity(meta.num_points as usize);
    for record in reader {
        let record = record.map_err(parse)?;
        let get = |i: usize| record.0.get(i).and_then(first).unwrap_or(f64::NAN);
        points.push(Point3::new(get(ix), get(iy), get(iz)));
    }
    Ok(PointCloud::new(points))
}

/// Where the file's `VIEWPOINT` says the sensor stood (its translation;
/// the orientation does not matter to an extraction).
pub fn recorded_viewpoint(path: &Path) -> Result<Point3<f64>, FormatError> {
    let reader = DynReader::open(path).map_err(|e| FormatError::Parse {
        format: FORMAT,
        reason: e.to_string(),
    })?;
    let v = &reader.meta().viewpoint;
    Ok(Point3::new(v.tx, v.ty, v.tz))
}

fn first(field: &Field) -> Option<f64> {
    Some(match field {
        Field::I8(v) => *v.first()? as f64,
        Field::I16(v) => *v.first()? as f64,
        Field::I32(v) => *v.first()? as f64,
        Field::I64(v) => *v.first()? as f64,
        Field::U8(v) => *v.first()? as f64,
        Field::U16(v) => *v.first()? as f64,
        Field::U32(v) => *v.first()? as f64,
        Field::U64(v) => *v.first()? as f64,
        Field::F32(v) => *v.first()? as f64,
        Field::F64(v) => *v.first()?,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ascii_pcd_with_extra_fields_reads_x_y_z() {
        let scratch = tempfile::tempdir().unwrap();
        let path = scratch.path().join("cloud.pcd");
        std::fs::write(
            &path,
            "# .PCD v0.7\nVERSION 0.7\nFIELDS intensity x y z\nSIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 1\nWIDTH 2\nHEIGHT 1\nVIEWPOINT -1.5 0.25 0.8 1 0 0 0\nPOINTS 2\nDATA ascii\n7 0.5 1 2\n8 3 4 5.25\n",
        )
        .unwrap();
        assert_eq!(
            recorded_viewpoint(&path).unwrap(),
            Point3::new(-1.5, 0.25, 0.8)
        );
        let cloud = read(&path, 10).unwrap();
        assert_eq!(
            cloud.points,
            vec![Point3::new(0.5, 1.0, 2.0), Point3::new(3.0, 4.0, 5.25)]
        );
        assert!(matches!(
            read(&path, 1),
            Err(FormatError::TooMany { got: 2, max: 1 })
        ));
        std::fs::write(&path, "not a pcd").unwrap();
        assert!(read(&path, 10).is_err());
    }
}
