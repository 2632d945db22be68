//! Axis-aligned bounding boxes: the prefilter in front of every exact
//! shape query (nalgebra vectors, unlike parry's `Aabb`, so the collision
//! code builds them without converting).

use nalgebra::Vector3;

/// An axis-aligned box, for the prefilter.
#[derive(Debug, Clone, Copy)]
pub struct Aabb {
    pub min: Vector3<f64>,
    pub max: Vector3<f64>,
}

impl Aabb {
    pub fn overlaps(&self, other: &Aabb) -> bool {
        self.min.x <= other.max.x
            && other.min.x <= self.max.x
            && self.min.y <= other.max.y
            && other.min.y <= self.max.y
            && self.min.z <= other.max.z
            && other.min.z <= self.max.z
    }

    /// The smallest box holding both (`EMPTY` is the identity).
    pub fn union(&self, other: &Aabb) -> Aabb {
        Aabb {
            min: self.min.inf(&other.min),
            max: self.max.sup(&other.max),
        }
    }

    /// Holds nothing and overlaps nothing.
    pub const EMPTY: Aabb = Aabb {
        min: Vector3::new(f64::INFINITY, f64::INFINITY, f64::INFINITY),
        max: Vector3::new(f64::NEG_INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY),
    };

    pub fn of_capsule(a: &Vector3<f64>, b: &Vector3<f64>, r: f64) -> Self {
        let pad = Vector3::repeat(r);
        Self {
            min: a.inf(b) - pad,
            max: a.sup(b) + pad,
        }
    }
}

impl Aabb {
    /// This box grown by `by` on every side.
    pub fn grown(&self, by: f64) -> Aabb {
        let pad = Vector3::repeat(by);
        Aabb {
            min: self.min - pad,
            max: self.max + pad,
        }
    }

    /// Squared distance between two boxes: a lower bound on that between
    /// any shapes inside them.
    pub fn distance_squared(&self, other: &Aabb) -> f64 {
        (self.min - other.max)
            .sup(&(other.min - self.max))
            .sup(&Vector3::zeros())
            .norm_squared()
    }
}
