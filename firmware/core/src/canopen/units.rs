//! Drive units <-> SI, in one place: position increments, velocity increments/s, torque in
//! per mille of the motor's rated torque (CiA 402 0x6077/0x6072 with 0x6076 in mN m).
//!
//! Every drive has an absolute 19-bit encoder on the joint output, homed so that 0
//! increments is the joint's zero angle (the leg stretched, hip straight), and a 9:1 gear
//! between motor and joint. The drive reports both (0x608F encoder resolution: 2^19
//! increments per 9 motor revolutions; 0x6091 gear ratio 9:1) and the master checks them.
//! The velocity unit is increments/s (0x606C, 0x607F); 0x6080 (max motor speed) is in rpm
//! of the motor, as CiA 402 defines it.

use core::f32::consts::TAU;

/// Encoder increments per joint revolution (19-bit absolute encoder at the output).
pub const INCREMENTS_PER_REV: u32 = 1 << 19;
/// Encoder increments per radian.
pub const INCREMENTS_PER_RAD: f32 = INCREMENTS_PER_REV as f32 / TAU;

/// Motor revolutions per joint revolution.
pub const GEAR_RATIO: u32 = 9;

/// Joint speed to the motor's speed in whole rpm (CiA 402 0x6080), rounded down so that
/// the limit is never above the joint's; saturating, negative and NaN give 0.
pub fn rad_s_to_motor_rpm(rad_s: f32) -> u32 {
    libm::floorf(rad_s * GEAR_RATIO as f32 * 60.0 / TAU) as u32
}

/// Joint angle to position increments (rounded, saturating; NaN gives 0).
pub fn rad_to_increments(rad: f32) -> i32 {
    libm::roundf(rad * INCREMENTS_PER_RAD) as i32
}

/// Position increments to a joint angle.
pub fn increments_to_rad(increments: i32) -> f32 {
    increments as f32 / INCREMENTS_PER_RAD
}

/// Joint speed to the drive's velocity unit (increments/s), rounded and saturating.
pub fn rad_s_to_velocity_units(rad_s: f32) -> i32 {
    libm::roundf(rad_s * INCREMENTS_PER_RAD) as i32
}

/// The drive's velocity unit (increments/s) to rad/s.
pub fn velocity_units_to_rad_s(units: i32) -> f32 {
    units as f32 / INCREMENTS_PER_RAD
}

/// Torque in per mille of rated torque to N m.
pub fn permille_to_torque_nm(permille: i16, rated_torque_mnm: u32) -> f32 {
    permille as f32 * rated_torque_mnm as f32 * 1e-6
}

/// Torque in N m to per mille of rated torque (rounded, saturating; 0 if the rating is 0).
pub fn torque_nm_to_permille(torque_nm: f32, rated_torque_mnm: u32) -> i32 {
    if rated_torque_mnm == 0 {
        return 0;
    }
    libm::roundf(torque_nm * 1e6 / rated_torque_mnm as f32) as i32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn position_round_trip_within_one_increment() {
        for k in -300..=300 {
            let q = k as f32 * 0.01;
            let back = increments_to_rad(rad_to_increments(q));
            assert!((back - q).abs() <= 1.0 / INCREMENTS_PER_RAD, "{q} {back}");
        }
        assert_eq!(rad_to_increments(TAU), INCREMENTS_PER_REV as i32);
        assert_eq!(rad_to_increments(f32::NAN), 0);
        assert_eq!(rad_to_increments(f32::INFINITY), i32::MAX);
    }

    #[test]
    fn torque_per_mille_of_rated() {
        // 22.5 N m rated: 45 N m peak is 2000 per mille.
        assert_eq!(torque_nm_to_permille(45.0, 22_500), 2000);
        assert!((permille_to_torque_nm(-1000, 22_500) + 22.5).abs() < 1e-4);
        assert_eq!(torque_nm_to_permille(1.0, 0), 0);
    }

    #[test]
    fn max_motor_speed_is_in_motor_rpm() {
        // 12 rad/s at the joint = 114.6 rpm at the joint = 1031 rpm at the motor (9:1).
        assert_eq!(rad_s_to_motor_rpm(12.0), 1031);
        assert_eq!(rad_s_to_motor_rpm(-1.0), 0);
    }

    #[test]
    fn velocity_units_are_increments_per_second() {
        assert_eq!(
            rad_s_to_velocity_units(1.0),
            INCREMENTS_PER_RAD.round() as i32
        );
        assert!((velocity_units_to_rad_s(rad_s_to_velocity_units(12.0)) - 12.0).abs() < 1e-4);
    }
}
