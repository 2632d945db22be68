//! Material model: how a branch's radius and length become joint stiffness,
//! damping and mass.
//!
//! The paper derives K_s from the cantilever tip deflection θ = F ℓ² / (2 E I)
//! with torque τ = F ℓ and I = π r⁴ / 4, giving K_s = τ / θ = E π r⁴ / (2 ℓ),
//! and sets K_d = K_s / 10. It does not give E.

use serde::{Deserialize, Serialize};

use super::model::Branch;

/// Young's modulus used by default: 5 GPa, within the 1–10 GPa range of green
/// (fresh, unseasoned) wood of fruit trees. With the generator's default
/// 5 mm tip radius a 15 cm push on a thin branch bends it by tens of degrees
/// while the trunk (r ≈ 2 cm, ~250× stiffer) barely moves. Note that the
/// quasi-static push response depends only on *ratios* of stiffnesses, so E
/// scales forces but not the deformed shape.
pub const DEFAULT_YOUNG_MODULUS: f64 = 5.0e9;

/// K_d / K_s, in seconds (the paper's K_d = K_s / 10).
pub const DEFAULT_DAMPING_RATIO: f64 = 0.1;

/// Density of green wood (kg/m³); only used for URDF inertials, which other
/// simulators need. Our steady-state solver is massless.
pub const DEFAULT_WOOD_DENSITY: f64 = 900.0;

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Wood {
    /// Young's modulus E (Pa).
    pub young_modulus: f64,
    /// K_d / K_s (s).
    pub damping_ratio: f64,
    /// Density ρ (kg/m³).
    pub density: f64,
}

impl Default for Wood {
    fn default() -> Self {
        Self {
            young_modulus: DEFAULT_YOUNG_MODULUS,
            damping_ratio: DEFAULT_DAMPING_RATIO,
            density: DEFAULT_WOOD_DENSITY,
        }
    }
}

impl Wood {
    /// K_s = E π r⁴ / (2 ℓ), in N·m/rad.
    pub fn stiffness(&self, radius: f64, length: f64) -> f64 {
        self.young_modulus * std::f64::consts::PI * radius.powi(4) / (2.0 * length)
    }

    /// A full branch description from its geometry.
    pub fn branch(&self, radius: f64, length: f64) -> Branch {
        self.branch_with_stiffness(radius, length, self.stiffness(radius, length))
    }

    /// A branch whose stiffness is known (measured, identified, or given by
    /// a caller) rather than derived from its geometry; damping follows it.
    pub fn branch_with_stiffness(&self, radius: f64, length: f64, stiffness: f64) -> Branch {
        Branch {
            radius,
            length,
            stiffness,
            damping: self.damping_ratio * stiffness,
        }
    }

    /// Mass of a solid cylinder of this wood (kg).
    pub fn mass(&self, radius: f64, length: f64) -> f64 {
        self.density * std::f64::consts::PI * radius * radius * length
    }
}
