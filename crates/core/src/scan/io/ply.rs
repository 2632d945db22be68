//! PLY, ASCII or binary, through ply-rs-bw: the `vertex` element's `x`,
//! `y`, `z` (float or double), `nx`, `ny`, `nz` when present and `red`,
//! `green`, `blue` (uchar) when present. Elements before `vertex` are
//! skipped; the vertex count in the header is checked against the limit
//! before any vertex is read.

use std::io::{BufRead, Write};

use nalgebra::{Point3, Vector3};
use ply_rs_bw::parser::{Parser, Reader};
use ply_rs_bw::ply::{
    Addable, ElementDef, Encoding, Ply, PropertyAccess, PropertyAccessResult, PropertyDef,
    PropertyType, ScalarType,
};
use ply_rs_bw::writer::Writer;

use super::error::FormatError;
use crate::scan::cloud::PointCloud;

const FORMAT: &str = "PLY";

#[derive(Debug, Default, Clone, Copy)]
struct Vertex {
    p: [f64; 3],
    n: [f64; 3],
    c: [u8; 3],
    seen: u16,
}

const X: u16 = 1;
const Y: u16 = 2;
const Z: u16 = 4;
const NX: u16 = 8;
const NY: u16 = 16;
const NZ: u16 = 32;
const RED: u16 = 64;
const GREEN: u16 = 128;
const BLUE: u16 = 256;

impl Vertex {
    fn set(&mut self, name: &str, v: f64) -> PropertyAccessResult {
        let (slot, bit) = match name {
            "x" => (&mut self.p[0], X),
            "y" => (&mut self.p[1], Y),
            "z" => (&mut self.p[2], Z),
            "nx" => (&mut self.n[0], NX),
            "ny" => (&mut self.n[1], NY),
            "nz" => (&mut self.n[2], NZ),
            _ => return PropertyAccessResult::Ignored,
        };
        *slot = v;
        self.seen |= bit;
        PropertyAccessResult::Set
    }
}

impl PropertyAccess for Vertex {
    fn new() -> Self {
        Self::default()
    }
    fn set_float(&mut self, name: &str, v: f32) -> PropertyAccessResult {
        self.set(name, v as f64)
    }
    fn set_double(&mut self, name: &str, v: f64) -> PropertyAccessResult {
        self.set(name, v)
    }
    fn set_int(&mut self, name: &str, v: i32) -> PropertyAccessResult {
        self.set(name, v as f64)
    }
    fn set_short(&mut self, name: &str, v: i16) -> PropertyAccessResult {
        self.set(name, v as f64)
    }
    fn set_uchar(&mut self, name: &str, v: u8) -> PropertyAccessResult {
        let (k, bit) = match name {
            "red" | "diffuse_red" => (0, RED),
            "green" | "diffuse_green" => (1, GREEN),
            "blue" | "diffuse_blue" => (2, BLUE),
            _ => return PropertyAccessResult::Ignored,
        };
        self.c[k] = v;
        self.seen |= bit;
        PropertyAccessResult::Set
    }
    fn get_double(&self, name: &str) -> Option<f64> {
        match name {
            "x" => Some(self.p[0]),
            "y" => Some(self.p[1]),
            "z" => Some(self.p[2]),
            "nx" => Some(self.n[0]),
            "ny" => Some(self.n[1]),
            "nz" => Some(self.n[2]),
            _ => None,
        }
    }
    fn get_uchar(&self, name: &str) -> Option<u8> {
        match name {
            "red" => Some(self.c[0]),
            "green" => Some(self.c[1]),
            "blue" => Some(self.c[2]),
            _ => None,
        }
    }
}

/// Any element that is not `vertex`: read and dropped.
#[derive(Debug, Default)]
struct Skipped;

impl PropertyAccess for Skipped {
    fn new() -> Self {
        Skipped
    }
}

fn parse_error(e: impl std::fmt::Display) -> FormatError {
    FormatError::Parse {
        format: FORMAT,
        reason: e.to_string(),
    }
}

/// Reads a PLY cloud.
pub fn read(source: impl BufRead, max_points: usize) -> Result<PointCloud, FormatError> {
    let mut reader = Reader::new(source);
    let vertex_parser = Parser::<Vertex>::new();
    let header = vertex_parser
        .read_header(&mut reader)
        .map_err(parse_error)?;
    let Some(def) = header.elements.get("vertex") else {
        return Err(FormatError::Missing {
            format: FORMAT,
            what: "vertex element",
        });
    };
    if def.count > max_points {
        return Err(FormatError::TooMany {
            got: def.count as u64,
            max: max_points,
        });
    }
    for p in ["x", "y", "z"] {
        if !def.properties.contains_key(p) {
            return Err(FormatError::Missing {
                format: FORMAT,
                what: match p {
                    "x" => "x property",
                    "y" => "y property",
                    _ => "z property",
                },
            });
        }
    }
    let skip_parser = Parser::<Skipped>::new();
    let mut vertices = Vec::new();
    for (name, element) in &header.elements {
        if name == "vertex" {
            vertices = vertex_parser
                .read_payload_for_element(&mut reader, element, &header)
                .map_err(parse_error)?;
            break;
        }
        skip_parser
            .read_payload_for_element(&mut reader, element, &header)
            .map_err(parse_error)?;
    }
    let has = |bits: u16| vertices.first().is_some_and(|v| v.seen & bits == bits);
    let normals = has(NX | NY | NZ).then(|| {
        vertices
            .iter()
            .map(|v| Vector3::new(v.n[0], v.n[1], v.n[2]))
            .collect()
    });
    let colors = has(RED | GREEN | BLUE).then(|| vertices.iter().map(|v| v.c).collect());
    Ok(PointCloud {
        points: vertices
            .iter()
            .map(|v| Point3::new(v.p[0], v.p[1], v.p[2]))
            .collect(),
        normals,
        colors,
    })
}

/// Writes a binary little-endian PLY with `x`, `y`, `z` as doubles (and
/// normals and colours when the cloud has them).
pub fn write(cloud: &PointCloud, out: &mut impl Write) -> Result<(), FormatError> {
    cloud
        .check(usize::MAX)
        .map_err(|e| FormatError::Invalid(e.to_string()))?;
    let mut ply = Ply::<Vertex>::new();
    ply.header.encoding = Encoding::BinaryLittleEndian;
    let mut element = ElementDef::new("vertex".to_owned());
    let mut add = |name: &str, t: ScalarType| {
        element
            .properties
            .add(PropertyDef::new(name.to_owned(), PropertyType::Scalar(t)));
    };
    for name in ["x", "y", "z"] {
        add(name, ScalarType::Double);
    }
    if cloud.normals.is_some() {
        for name in ["nx", "ny", "nz"] {
            add(name, ScalarType::Double);
        }
    }
    if cloud.colors.is_some() {
        for name in ["red", "green", "blue"] {
            add(name, ScalarType::UChar);
        }
    }
    ply.header.elements.add(element);
    let vertices: Vec<Vertex> = cloud
        .points
        .iter()
        .enumerate()
        .map(|(i, p)| Vertex {
            p: [p.x, p.y, p.z],
            n: cloud
                .normals
                .as_ref()
                .map_or([0.0; 3], |n| [n[i].x, n[i].y, n[i].z]),
            c: cloud.colors.as_ref().map_or([0; 3], |c| c[i]),
            seen: 0,
        })
        .collect();
    ply.payload.insert("vertex".to_owned(), vertices);
    Writer::new()
        .write_ply(out, &mut ply)
        .map_err(|e| FormatError::Io(e.to_string()))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_written_cloud_reads_back_bit_for_bit() {
        let cloud = PointCloud {
            points: vec![Point3::new(0.1, -2.5, 3.25), Point3::new(1e-3, 0.0, 7.0)],
            normals: Some(vec![Vector3::z(), Vector3::x()]),
            colors: Some(vec![[1, 2, 3], [200, 100, 50]]),
        };
        let mut bytes = Vec::new();
        write(&cloud, &mut bytes).unwrap();
        let back = read(&bytes[..], 10).unwrap();
        assert_eq!(back, cloud);
        assert!(matches!(
            read(&bytes[..], 1),
            Err(FormatError::TooMany { got: 2, max: 1 })
        ));
        // Colours that do not match the points are refused, not indexed.
        let mut bad = cloud.clone();
        bad.points.push(Point3::origin());
        assert!(matches!(
            write(&bad, &mut Vec::new()),
            Err(FormatError::Invalid(_))
        ));
    }

    #[test]
    fn ascii_with_faces_first_and_float_coordinates_reads() {
        let text = "ply\nformat ascii 1.0\nelement face 1\nproperty list uchar int vertex_indices\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nproperty float intensity\nend_header\n3 0 1 1\n0.5 1 2 9\n3 4 5 9\n";
        let cloud = read(text.as_bytes(), 10).unwrap();
        assert_eq!(cloud.points[1], Point3::new(3.0, 4.0, 5.0));
        assert!(cloud.normals.is_none() && cloud.colors.is_none());
    }

    #[test]
    fn broken_files_are_named_not_panicked_on() {
        for bad in [
            "",
            "ply\n",
            "ply\nformat ascii 1.0\nend_header\n",
            "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nend_header\n1 2\n",
            "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty double x\nproperty double y\nproperty double z\nend_header\n\x01\x02",
            "ply\nformat ascii 1.0\nelement vertex 99999999999\nproperty float x\nproperty float y\nproperty float z\nend_header\n",
        ] {
            assert!(read(bad.as_bytes(), 1000).is_err(), "{bad:?}");
        }
    }
}
