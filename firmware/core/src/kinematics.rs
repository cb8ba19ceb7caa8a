//! Leg kinematics: foot positions from joint angles (forward) and joint angles from foot
//! positions (inverse, knee-down branch). Angles in radians, positions in metres, base frame.

use crate::math::{FloatFns, Libm};
use crate::robot::{
    Leg, COXA_LENGTH_M, HIP_POS_BASE_M, JOINTS_PER_LEG, MOUNT_YAW_RAD, NUM_JOINTS, NUM_LEGS,
    SHANK_LENGTH_M, THIGH_LENGTH_M,
};
use nalgebra::{Point3, Vector3};

/// The hip (yaw axis on the trunk) of `leg` in the base frame, m.
pub fn hip_position(leg: Leg) -> Point3<f32> {
    HIP_POS_BASE_M[leg.index()].into()
}

/// Foot sphere centre of `leg` in the base frame from its joint angles (hip, thigh, shank).
pub fn foot_position(leg: Leg, q_leg_rad: &Vector3<f32>) -> Point3<f32> {
    foot_position_with::<Libm>(leg, q_leg_rad)
}

/// [`foot_position`] with the float functions of `F`.
pub fn foot_position_with<F: FloatFns>(leg: Leg, q_leg_rad: &Vector3<f32>) -> Point3<f32> {
    let i = leg.index();
    let (hip, thigh, shank) = (q_leg_rad.x, q_leg_rad.y, q_leg_rad.z);
    let yaw = MOUNT_YAW_RAD[i] + hip;
    // In the leg's vertical plane: out along the coxa and thigh, down to the foot.
    let radial_m =
        COXA_LENGTH_M[i] + THIGH_LENGTH_M * F::cos(thigh) + SHANK_LENGTH_M * F::cos(thigh + shank);
    let down_m = THIGH_LENGTH_M * F::sin(thigh) + SHANK_LENGTH_M * F::sin(thigh + shank);
    hip_position(leg) + Vector3::new(radial_m * F::cos(yaw), radial_m * F::sin(yaw), -down_m)
}

/// Foot sphere centre of one leg in the base frame ([`foot_position`] on arrays).
pub fn foot_position_base(leg: Leg, q_leg_rad: [f32; JOINTS_PER_LEG]) -> [f32; 3] {
    foot_position(leg, &q_leg_rad.into()).coords.into()
}

/// Foot sphere centres of all legs in the base frame, from joint angles in joint order.
pub fn foot_positions(q_rad: &[f32; NUM_JOINTS]) -> [Point3<f32>; NUM_LEGS] {
    Leg::ALL.map(|leg| {
        let j = JOINTS_PER_LEG * leg.index();
        foot_position(leg, &Vector3::new(q_rad[j], q_rad[j + 1], q_rad[j + 2]))
    })
}

/// [`foot_positions`] as arrays.
pub fn foot_positions_base(q_rad: &[f32; NUM_JOINTS]) -> [[f32; 3]; NUM_LEGS] {
    foot_positions(q_rad).map(|p| p.coords.into())
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
pub fn inverse_kinematics(leg: Leg, foot_base_m: &Point3<f32>) -> Result<Vector3<f32>, IkError> {
    inverse_kinematics_with::<Libm>(leg, foot_base_m)
}

/// [`inverse_kinematics`] with the float functions of `F`.
pub fn inverse_kinematics_with<F: FloatFns>(
    leg: Leg,
    foot_base_m: &Point3<f32>,
) -> Result<Vector3<f32>, IkError> {
    let i = leg.index();
    let hip_m = hip_position(leg);
    let d = foot_base_m - hip_m;
    let horizontal_m = F::sqrt(d.x * d.x + d.y * d.y);
    if horizontal_m < 1e-6 {
        return Err(IkError::Singular);
    }
    let mut hip = F::atan2(d.y, d.x) - MOUNT_YAW_RAD[i];
    while hip > core::f32::consts::PI {
        hip -= 2.0 * core::f32::consts::PI;
    }
    while hip <= -core::f32::consts::PI {
        hip += 2.0 * core::f32::consts::PI;
    }
    let radial_m = horizontal_m - COXA_LENGTH_M[i];
    let down_m = hip_m.z - foot_base_m.z;
    let (lt, ls) = (THIGH_LENGTH_M, SHANK_LENGTH_M);
    let dist_sq = radial_m * radial_m + down_m * down_m;
    let cos_shank = (dist_sq - lt * lt - ls * ls) / (2.0 * lt * ls);
    if !(-1.0..=1.0).contains(&cos_shank) {
        return Err(IkError::OutOfReach);
    }
    let shank = F::acos(cos_shank);
    let thigh = F::atan2(down_m, radial_m) - F::atan2(ls * F::sin(shank), lt + ls * F::cos(shank));
    Ok(Vector3::new(hip, thigh, shank))
}

/// [`inverse_kinematics`] on arrays.
pub fn leg_inverse_kinematics(
    leg: Leg,
    foot_base_m: [f32; 3],
) -> Result<[f32; JOINTS_PER_LEG], IkError> {
    inverse_kinematics(leg, &foot_base_m.into()).map(Into::into)
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
