//! The AMP state (61): what the discriminator sees of one instant of motion.
//!
//! Layout: joint positions 18 (absolute, rad), joint velocities 18 (rad/s), base linear
//! velocity 3 (base frame, m/s), base angular velocity 3 (base frame, rad/s), base height
//! above terrain 1 (m), foot positions in the base frame 6 x 3 (m, by forward kinematics).
//! The motion-prior generator and the simulator both call [`amp_state`], so the prior and
//! policy transitions can never be laid out differently.

use crate::kinematics::foot_positions_base;
use crate::robot::NUM_JOINTS;
use core::ops::Range;

/// Size of one AMP state.
pub const AMP_STATE_DIM: usize = 61;
/// Joint positions.
pub const AMP_JOINT_POS: Range<usize> = 0..18;
/// Joint velocities.
pub const AMP_JOINT_VEL: Range<usize> = 18..36;
/// Base linear velocity, base frame.
pub const AMP_BASE_LIN_VEL: Range<usize> = 36..39;
/// Base angular velocity, base frame.
pub const AMP_BASE_ANG_VEL: Range<usize> = 39..42;
/// Base height above the terrain.
pub const AMP_BASE_HEIGHT: usize = 42;
/// Foot positions in the base frame, leg-major.
pub const AMP_FOOT_POS: Range<usize> = 43..61;

/// Builds the AMP state from the robot's state.
pub fn amp_state(
    q_rad: &[f32; NUM_JOINTS],
    qdot_rad_s: &[f32; NUM_JOINTS],
    lin_vel_base_m_s: [f32; 3],
    ang_vel_base_rad_s: [f32; 3],
    base_height_m: f32,
) -> [f32; AMP_STATE_DIM] {
    let mut s = [0.0; AMP_STATE_DIM];
    s[AMP_JOINT_POS].copy_from_slice(q_rad);
    s[AMP_JOINT_VEL].copy_from_slice(qdot_rad_s);
    s[AMP_BASE_LIN_VEL].copy_from_slice(&lin_vel_base_m_s);
    s[AMP_BASE_ANG_VEL].copy_from_slice(&ang_vel_base_rad_s);
    s[AMP_BASE_HEIGHT] = base_height_m;
    for (leg, foot) in foot_positions_base(q_rad).iter().enumerate() {
        let start = AMP_FOOT_POS.start + 3 * leg;
        s[start..start + 3].copy_from_slice(foot);
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::robot::Q0_RAD;

    #[test]
    fn layout_is_contiguous() {
        assert_eq!(AMP_JOINT_POS.end, AMP_JOINT_VEL.start);
        assert_eq!(AMP_JOINT_VEL.end, AMP_BASE_LIN_VEL.start);
        assert_eq!(AMP_BASE_LIN_VEL.end, AMP_BASE_ANG_VEL.start);
        assert_eq!(AMP_BASE_ANG_VEL.end, AMP_BASE_HEIGHT);
        assert_eq!(AMP_BASE_HEIGHT + 1, AMP_FOOT_POS.start);
        assert_eq!(AMP_FOOT_POS.end, AMP_STATE_DIM);
    }

    #[test]
    fn feet_are_below_the_base_at_the_nominal_pose() {
        let s = amp_state(&Q0_RAD, &[0.0; 18], [0.3, 0.0, 0.0], [0.0; 3], 0.31);
        assert_eq!(s[36], 0.3);
        for leg in 0..6 {
            assert!(s[AMP_FOOT_POS.start + 3 * leg + 2] < -0.25);
        }
    }
}
