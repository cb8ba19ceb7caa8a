//! The single-rigid-body model of the robot and its nominal stance, from hexapod-core.
//!
//! Translation uses the total mass `TOTAL_MASS_KG`; rotation uses the inertia of the trunk
//! box (`TRUNK_SIZE_M`, `TRUNK_MASS_KG`) about its centre, which the model takes as the
//! centre of mass (the legs are light and nearly symmetric). The nominal stance is the
//! forward kinematics of `Q0_RAD` with the feet on flat ground.

use hexapod_core::kinematics::foot_positions_base;
use hexapod_core::robot::{
    FOOT_RADIUS_M, NUM_LEGS, Q0_RAD, TOTAL_MASS_KG, TRUNK_MASS_KG, TRUNK_SIZE_M,
};

/// Gravity acceleration.
pub const GRAVITY_M_S2: f64 = 9.81;

/// Mass and inertia of the single-rigid-body model.
#[derive(Clone, Copy, Debug)]
pub struct RigidBody {
    /// Mass.
    pub mass_kg: f64,
    /// Principal moments of inertia about x, y, z (base frame).
    pub inertia_kg_m2: [f64; 3],
}

impl RigidBody {
    /// The robot's model.
    pub fn hexapod() -> Self {
        let [a, b, c] = TRUNK_SIZE_M.map(f64::from);
        let m = TRUNK_MASS_KG as f64;
        Self {
            mass_kg: TOTAL_MASS_KG as f64,
            inertia_kg_m2: [
                m / 12.0 * (b * b + c * c),
                m / 12.0 * (a * a + c * c),
                m / 12.0 * (a * a + b * b),
            ],
        }
    }
}

/// Nominal base height: the feet of `Q0_RAD` touching flat ground (foot sphere centre at
/// `FOOT_RADIUS_M`).
pub fn nominal_base_height_m() -> f64 {
    let feet = foot_positions_base(&Q0_RAD);
    let mean_z = feet.iter().map(|f| f[2] as f64).sum::<f64>() / NUM_LEGS as f64;
    FOOT_RADIUS_M as f64 - mean_z
}

/// Nominal foot sphere centres in the ground-level command frame (x, y of the forward
/// kinematics of `Q0_RAD`; z = `FOOT_RADIUS_M`).
pub fn nominal_feet_m() -> [[f64; 3]; NUM_LEGS] {
    foot_positions_base(&Q0_RAD).map(|f| [f[0] as f64, f[1] as f64, FOOT_RADIUS_M as f64])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nominal_height_is_about_31_cm() {
        let h = nominal_base_height_m();
        assert!((h - 0.308).abs() < 0.003, "{h}");
    }

    #[test]
    fn inertia_is_largest_about_z() {
        let b = RigidBody::hexapod();
        assert!((b.mass_kg - 25.5).abs() < 1e-3);
        let [ixx, iyy, izz] = b.inertia_kg_m2;
        assert!(ixx < iyy && iyy < izz);
    }
}
