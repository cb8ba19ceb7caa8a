//! Leg kinematics: foot positions from joint angles (forward) and joint angles from foot
//! positions (inverse, knee-down branch). Angles in radians, positions in metres, base frame.

use crate::robot::{
    Leg, COXA_LENGTH_M, HIP_POS_BASE_M, JOINTS_PER_LEG, MOUNT_YAW_RAD, NUM_JOINTS, NUM_LEGS,
    SHANK_LENGTH_M, THIGH_LENGTH_M,
};
use libm::{acosf, atan2f, cosf, sinf, sqrtf};

/// Foot sphere centre of one leg in the base frame.
pub fn foot_position_base(leg: Leg, q_leg_rad: [f32; JOINTS_PER_LEG]) -> [f32; 3] {
    let i = leg.index();
    let [hip, thigh, shank] = q_leg_rad;
    let yaw = MOUNT_YAW_RAD[i] + hip;
    let radial_m =
        COXA_LENGTH_M[i] + THIGH_LENGTH_M * cosf(thigh) + SHANK_LENGTH_M * cosf(thigh + shank);
    let down_m = THIGH_LENGTH_M * sinf(thigh) + SHANK_LENGTH_M * sinf(thigh + shank);
    let hip_pos = HIP_POS_BASE_M[i];
    [
        hip_pos[0] + radial_m * cosf(yaw),
        hip_pos[1] + radial_m * sinf(yaw),
        hip_pos[2] - down_m,
    ]
}

/// Foot sphere centres of all legs in the base frame, from joint angles in joint order.
pub fn foot_positions_base(q_rad: &[f32; NUM_JOINTS]) -> [[f32; 3]; NUM_LEGS] {
    let mut out = [[0.0; 3]; NUM_LEGS];
    for leg in Leg::ALL {
        let j = JOINTS_PER_LEG * leg.index();
        out[leg.index()] = foot_position_base(leg, [q_rad[j], q_rad[j + 1], q_rad[j + 2]]);
    }
    out
}

/// Why a foot position has no joint solution.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum IkError {
    /// The foot is farther from the thigh axis than thigh plus shank.
    OutOfReach,
    /// The foot is on the hip yaw axis (yaw undefined).
    Singular,
}

/// Joint angles (hip, thigh, shank) that put the foot of `leg` at `foot_base_m`,
/// knee-down branch (shank angle >= 0). Hip yaw is wrapped to (-pi, pi].
pub fn leg_inverse_kinematics(
    leg: Leg,
    foot_base_m: [f32; 3],
) -> Result<[f32; JOINTS_PER_LEG], IkError> {
    let i = leg.index();
    let hip_pos = HIP_POS_BASE_M[i];
    let dx = foot_base_m[0] - hip_pos[0];
    let dy = foot_base_m[1] - hip_pos[1];
    let horizontal_m = sqrtf(dx * dx + dy * dy);
    if horizontal_m < 1e-6 {
        return Err(IkError::Singular);
    }
    let mut hip = atan2f(dy, dx) - MOUNT_YAW_RAD[i];
    while hip > core::f32::consts::PI {
        hip -= 2.0 * core::f32::consts::PI;
    }
    while hip <= -core::f32::consts::PI {
        hip += 2.0 * core::f32::consts::PI;
    }
    let radial_m = horizontal_m - COXA_LENGTH_M[i];
    let down_m = hip_pos[2] - foot_base_m[2];
    let (lt, ls) = (THIGH_LENGTH_M, SHANK_LENGTH_M);
    let dist_sq = radial_m * radial_m + down_m * down_m;
    let cos_shank = (dist_sq - lt * lt - ls * ls) / (2.0 * lt * ls);
    if !(-1.0..=1.0).contains(&cos_shank) {
        return Err(IkError::OutOfReach);
    }
    let shank = acosf(cos_shank);
    let thigh = atan2f(down_m, radial_m) - atan2f(ls * sinf(shank), lt + ls * cosf(shank));
    Ok([hip, thigh, shank])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::robot::{FOOT_RADIUS_M, Q0_LEG_RAD, Q0_RAD};

    #[test]
    fn nominal_pose_stands_about_31_cm() {
        let feet = foot_positions_base(&Q0_RAD);
        for foot in feet {
            let height_m = -foot[2] + FOOT_RADIUS_M;
            assert!((height_m - 0.308).abs() < 0.002, "{height_m}");
        }
        // Middle feet are 0.137 m further out than front and rear feet (measured from the hip).
        assert!(feet[1][1] < feet[0][1] - 0.1);
    }

    #[test]
    fn ik_inverts_fk() {
        for leg in Leg::ALL {
            for (dh, dt, ds) in [(0.0, 0.0, 0.0), (0.3, -0.2, 0.4), (-0.5, 0.5, -0.3)] {
                let q = [Q0_LEG_RAD[0] + dh, Q0_LEG_RAD[1] + dt, Q0_LEG_RAD[2] + ds];
                let foot = foot_position_base(leg, q);
                let q_back = leg_inverse_kinematics(leg, foot).unwrap();
                for k in 0..3 {
                    assert!((q[k] - q_back[k]).abs() < 1e-3, "{leg:?} {q:?} {q_back:?}");
                }
            }
        }
    }

    #[test]
    fn ik_rejects_unreachable_feet() {
        assert_eq!(
            leg_inverse_kinematics(Leg::LeftMiddle, [0.0, 2.0, 0.0]),
            Err(IkError::OutOfReach)
        );
    }
}
