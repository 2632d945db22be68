//! XYZ text: one point per line, `x y z` (spaces, tabs or commas), any
//! further columns ignored; blank lines and lines starting with `#` or
//! `//` skipped.

use std::io::BufRead;

use nalgebra::Point3;

use super::error::FormatError;
use crate::scan::cloud::PointCloud;

pub fn read(source: impl BufRead, max_points: usize) -> Result<PointCloud, FormatError> {
    let mut points = Vec::new();
    for (no, line) in source.lines().enumerate() {
        let line = line.map_err(|e| FormatError::Io(e.to_string()))?;
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') || line.starts_with("//") {
            continue;
        }
        let mut numbers = line
            .split(|c: char| c.is_whitespace() || c == ',')
            .filter(|s| !s.is_empty())
            .map(str::parse::<f64>);
        let mut next = || match numbers.next() {
            Some(Ok(v)) => Ok(v),
            _ => Err(FormatError::Parse {
                format: "XYZ",
                reason: format!("line {} does not start with three numbers", no + 1),
            }),
        };
        let p = Point3::new(next()?, next()?, next()?);
        if points.len() == max_points {
            return Err(FormatError::TooMany {
                got: max_points as u64 + 1,
                max: max_points,
            });
        }
        points.push(p);
    }
    Ok(PointCloud::new(points))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn columns_separators_and_comments() {
        let cloud = read("# x y z\n1 2 3\n4,5,6,0.5\n\n7\t8\t9\n".as_bytes(), 10).unwrap();
        assert_eq!(cloud.points.len(), 3);
        assert_eq!(cloud.points[1], Point3::new(4.0, 5.0, 6.0));
        assert!(read("1 2\n".as_bytes(), 10).is_err());
        assert!(matches!(
            read("1 2 3\n4 5 6\n".as_bytes(), 1),
            Err(FormatError::TooMany { .. })
        ));
    }
}
