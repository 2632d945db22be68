//! [`JointVector`]: one value per joint of an arm (a configuration, a
//! velocity, a limit), for arms of up to [`MAX_DOF`] joints.
//!
//! Why not `Vec<f64>`: RRT*, the collision checker and the push lines copy
//! and compare configurations in their inner loops, so a configuration is a
//! `Copy` value on the stack, as `[f64; 6]` was when only the UR5 existed.
//! It dereferences to `[f64]` of the arm's own length, so indexing,
//! iteration and slicing read as they would on a slice.

use std::ops::{Deref, DerefMut};

use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// Most joints an arm may have (a 7-joint arm on a linear axis has 8).
pub const MAX_DOF: usize = 8;

/// One value per joint, for up to [`MAX_DOF`] joints.
#[derive(Clone, Copy)]
pub struct JointVector {
    values: [f64; MAX_DOF],
    len: u8,
}

impl JointVector {
    /// The values of `values` (usable in constants).
    pub const fn new<const N: usize>(values: [f64; N]) -> Self {
        assert!(N <= MAX_DOF, "at most MAX_DOF joint values");
        let mut out = [0.0; MAX_DOF];
        let mut i = 0;
        while i < N {
            out[i] = values[i];
            i += 1;
        }
        Self {
            values: out,
            len: N as u8,
        }
    }

    /// `dof` zeros. Panics if `dof` exceeds [`MAX_DOF`], which arms are
    /// checked against when they are loaded.
    pub fn zeros(dof: usize) -> Self {
        assert!(dof <= MAX_DOF, "{dof} joints, at most {MAX_DOF}");
        Self {
            values: [0.0; MAX_DOF],
            len: dof as u8,
        }
    }

    /// `dof` values, the i-th `f(i)`.
    pub fn from_fn(dof: usize, mut f: impl FnMut(usize) -> f64) -> Self {
        let mut v = Self::zeros(dof);
        for (i, x) in v.iter_mut().enumerate() {
            *x = f(i);
        }
        v
    }

    /// The values of `values`, or `None` when there are more than
    /// [`MAX_DOF`].
    pub fn try_from_slice(values: &[f64]) -> Option<Self> {
        (values.len() <= MAX_DOF).then(|| Self::from_fn(values.len(), |i| values[i]))
    }

    /// The values of `values`; panics past [`MAX_DOF`] (use
    /// [`Self::try_from_slice`] on input).
    pub fn from_slice(values: &[f64]) -> Self {
        Self::try_from_slice(values).expect("at most MAX_DOF joint values")
    }

    /// The point a fraction `t` of the way from `self` to `other`.
    pub fn lerp(&self, other: &Self, t: f64) -> Self {
        Self::from_fn(self.len(), |i| self[i] + (other[i] - self[i]) * t)
    }

    /// Largest absolute difference of any joint.
    pub fn max_abs_diff(&self, other: &Self) -> f64 {
        self.iter()
            .zip(other.iter())
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max)
    }
}

impl Deref for JointVector {
    type Target = [f64];
    fn deref(&self) -> &[f64] {
        &self.values[..self.len as usize]
    }
}

impl DerefMut for JointVector {
    fn deref_mut(&mut self) -> &mut [f64] {
        &mut self.values[..self.len as usize]
    }
}

impl PartialEq for JointVector {
    fn eq(&self, other: &Self) -> bool {
        **self == **other
    }
}

impl std::fmt::Debug for JointVector {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        (**self).fmt(f)
    }
}

impl<const N: usize> From<[f64; N]> for JointVector {
    fn from(values: [f64; N]) -> Self {
        Self::from_slice(&values)
    }
}

impl<'a> IntoIterator for &'a JointVector {
    type Item = &'a f64;
    type IntoIter = std::slice::Iter<'a, f64>;
    fn into_iter(self) -> Self::IntoIter {
        self.iter()
    }
}

impl Serialize for JointVector {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        (**self).serialize(s)
    }
}

impl<'de> Deserialize<'de> for JointVector {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let values = Vec::<f64>::deserialize(d)?;
        Self::try_from_slice(&values).ok_or_else(|| {
            serde::de::Error::custom(format!("{} joint values, at most {MAX_DOF}", values.len()))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn behaves_as_a_slice_of_its_own_length() {
        let mut q = JointVector::from([1.0, 2.0, 3.0]);
        assert_eq!(q.len(), 3);
        q[1] = 5.0;
        assert_eq!(&*q, &[1.0, 5.0, 3.0]);
        let r = JointVector::from_fn(3, |i| i as f64);
        assert_eq!(q.max_abs_diff(&r), 4.0);
        assert_eq!(q.lerp(&r, 0.5)[2], 2.5);
        assert_ne!(JointVector::zeros(6), JointVector::zeros(7));
        let json = serde_json::to_string(&q).unwrap();
        assert_eq!(json, "[1.0,5.0,3.0]");
        assert_eq!(serde_json::from_str::<JointVector>(&json).unwrap(), q);
        assert!(serde_json::from_str::<JointVector>("[0,0,0,0,0,0,0,0,0]").is_err());
        assert!(JointVector::try_from_slice(&[0.0; 9]).is_none());
    }
}
