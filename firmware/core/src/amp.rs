//! The AMP state (61): what the discriminator sees of one instant of motion.
//!
//! Layout: joint positions 18 (absolute, rad), joint velocities 18 (rad/s), base linear
//! velocity 3 (base frame, m/s), base angular velocity 3 (base frame, rad/s), base height
//! above the stance feet 1 (m), foot positions in the base frame 6 x 3 (m, by forward
//! kinematics). The motion-prior generator and the simulator both call [`amp_state`], so
//! the prior and policy transitions can never be laid out differently.
//!
//! The paper's height is "relative to the terrain"; here it is measured from the feet the
//! robot stands on ([`base_height_above_feet_m`]): the height of the base above the mean of
//! its three lowest feet, along gravity. On flat ground with a tripod down this is the
//! height above the ground (less the foot radius); unlike the height above the one point
//! under the base, it means the same on a 20 cm stair or a 30 deg slope as on the flat
//! ground the priors were made on, so the style term stays informative on every terrain.

use crate::kinematics::foot_positions_base;
use crate::robot::{NUM_JOINTS, NUM_LEGS};
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
/// Base height above the stance feet ([`base_height_above_feet_m`]).
pub const AMP_BASE_HEIGHT: usize = 42;
/// Foot positions in the base frame, leg-major.
pub const AMP_FOOT_POS: Range<usize> = 43..61;

/// The layout's feature groups by name, in order (they tile the state); the names are the
/// trainer's metric names (`amp_saliency/<name>`).
pub const AMP_GROUPS: [(&str, Range<usize>); 6] = [
    ("joint_pos", AMP_JOINT_POS),
    ("joint_vel", AMP_JOINT_VEL),
    ("base_lin_vel", AMP_BASE_LIN_VEL),
    ("base_ang_vel", AMP_BASE_ANG_VEL),
    ("base_height", AMP_BASE_HEIGHT..AMP_BASE_HEIGHT + 1),
    ("foot_pos", AMP_FOOT_POS),
];

/// Number of feet whose mean height defines the stance level: one tripod.
pub const STANCE_FEET: usize = 3;

/// Height of the base origin above the mean of its [`STANCE_FEET`] lowest feet, measured
/// along `up_base` (the world's up direction in the base frame, unit length: minus the
/// projected gravity), m.
pub fn base_height_above_feet_m(feet_base_m: &[[f32; 3]; NUM_LEGS], up_base: [f32; 3]) -> f32 {
    // Height of each foot relative to the base origin, along up (negative: below).
    let mut heights = [0.0f32; NUM_LEGS];
    for (h, f) in heights.iter_mut().zip(feet_base_m) {
        *h = f[0] * up_base[0] + f[1] * up_base[1] + f[2] * up_base[2];
    }
    // Insertion sort, ascending (six values, no allocation).
    for i in 1..NUM_LEGS {
        let mut k = i;
        while k > 0 && heights[k - 1] > heights[k] {
            heights.swap(k - 1, k);
            k -= 1;
        }
    }
    let mean: f32 = heights[..STANCE_FEET].iter().sum::<f32>() / STANCE_FEET as f32;
    -mean
}

/// Builds the AMP state from the robot's state; `up_base` is the world's up direction in
/// the base frame (unit length), from the base orientation.
pub fn amp_state(
    q_rad: &[f32; NUM_JOINTS],
    qdot_rad_s: &[f32; NUM_JOINTS],
    lin_vel_base_m_s: [f32; 3],
    ang_vel_base_rad_s: [f32; 3],
    up_base: [f32; 3],
) -> [f32; AMP_STATE_DIM] {
    let mut s = [0.0; AMP_STATE_DIM];
    s[AMP_JOINT_POS].copy_from_slice(q_rad);
    s[AMP_JOINT_VEL].copy_from_slice(qdot_rad_s);
    s[AMP_BASE_LIN_VEL].copy_from_slice(&lin_vel_base_m_s);
    s[AMP_BASE_ANG_VEL].copy_from_slice(&ang_vel_base_rad_s);
    let feet = foot_positions_base(q_rad);
    s[AMP_BASE_HEIGHT] = base_height_above_feet_m(&feet, up_base);
    for (leg, foot) in feet.iter().enumerate() {
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
        let mut next = 0;
        for (_, range) in AMP_GROUPS.iter() {
            assert_eq!(range.start, next);
            next = range.end;
        }
        assert_eq!(next, AMP_STATE_DIM);
    }

    #[test]
    fn feet_are_below_the_base_at_the_nominal_pose() {
        let s = amp_state(
            &Q0_RAD,
            &[0.0; 18],
            [0.3, 0.0, 0.0],
            [0.0; 3],
            [0.0, 0.0, 1.0],
        );
        assert_eq!(s[36], 0.3);
        for leg in 0..6 {
            assert!(s[AMP_FOOT_POS.start + 3 * leg + 2] < -0.25);
        }
        // Upright: the height is minus the feet's mean z in the base frame.
        let mean_z = (0..6)
            .map(|l| s[AMP_FOOT_POS.start + 3 * l + 2])
            .sum::<f32>()
            / 6.0;
        assert!((s[AMP_BASE_HEIGHT] + mean_z).abs() < 1e-6);
    }

    #[test]
    fn height_uses_the_three_lowest_feet_along_gravity() {
        let mut feet = [[0.0f32, 0.0, -0.30]; 6];
        // A swing tripod 5 cm higher does not change the stance height.
        for f in feet.iter_mut().step_by(2) {
            f[2] = -0.25;
        }
        assert!((base_height_above_feet_m(&feet, [0.0, 0.0, 1.0]) - 0.30).abs() < 1e-6);
        // Pitched by 30 deg on a slope with the feet where the body's frame puts them on
        // flat ground: measured along gravity, not along the base's z axis.
        let (s, c) = (0.5f32, 0.75f32.sqrt());
        let flat = [
            [0.2f32, 0.0, -0.3],
            [-0.2, 0.0, -0.3],
            [0.0, 0.2, -0.3],
            [0.0, -0.2, -0.3],
            [0.2, 0.1, -0.3],
            [-0.2, 0.1, -0.3],
        ];
        let up = [-s, 0.0, c];
        let expected = {
            let mut h: Vec<f32> = flat
                .iter()
                .map(|f| -(f[0] * up[0] + f[2] * up[2]))
                .collect();
            h.sort_by(|a, b| b.partial_cmp(a).unwrap());
            (h[0] + h[1] + h[2]) / 3.0
        };
        assert!((base_height_above_feet_m(&flat, up) - expected).abs() < 1e-6);
    }
}
