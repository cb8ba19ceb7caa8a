//! Control timing and the joint-drive law shared by the simulator and the firmware.

/// Physics (and drive servo) period in seconds.
pub const PHYSICS_DT_S: f32 = 0.005;
/// Physics steps per policy step.
pub const DECIMATION: usize = 4;
/// Policy period in seconds (50 Hz).
pub const POLICY_DT_S: f32 = PHYSICS_DT_S * DECIMATION as f32;
/// Policy rate in hertz.
pub const POLICY_RATE_HZ: u32 = 50;
/// Episode length in seconds.
pub const EPISODE_LENGTH_S: f32 = 20.0;
/// Episode length in policy steps.
pub const EPISODE_LENGTH_STEPS: usize = 1000;

/// Action scale: `q_d = q0 + ACTION_SCALE_RAD * a`.
pub const ACTION_SCALE_RAD: f32 = 0.25;
/// Position loop gain of the cyclic synchronous position law, 1/s.
pub const CSP_KP1_PER_S: f32 = 50.0;
/// Velocity loop gain of the cyclic synchronous position law, N m s/rad.
pub const CSP_KP2_NMS_PER_RAD: f32 = 2.0;

/// The paper's CSP drive law, evaluated at the physics rate:
/// `tau = kp2 * (clamp(kp1 * (q_d - q), +-vel_limit) - qdot)`, clamped to `+-torque_limit`
/// and scaled by `motor_strength` (randomized in training, 1 on the robot).
///
/// `kp1_per_s` and `kp2_nms_per_rad` are the (possibly randomized) gains; the nominal
/// equivalent PD stiffness is `kp1 * kp2 = 100 N m/rad` and damping `kp2 = 2 N m s/rad`.
#[inline]
#[allow(clippy::too_many_arguments)]
pub fn csp_torque_nm(
    q_target_rad: f32,
    q_rad: f32,
    qdot_rad_s: f32,
    kp1_per_s: f32,
    kp2_nms_per_rad: f32,
    vel_limit_rad_s: f32,
    torque_limit_nm: f32,
    motor_strength: f32,
) -> f32 {
    let vel_cmd = (kp1_per_s * (q_target_rad - q_rad)).clamp(-vel_limit_rad_s, vel_limit_rad_s);
    let tau = motor_strength * kp2_nms_per_rad * (vel_cmd - qdot_rad_s);
    let limit = motor_strength * torque_limit_nm;
    tau.clamp(-limit, limit)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn policy_runs_at_50_hz() {
        assert!((POLICY_DT_S - 0.02).abs() < 1e-7);
        assert_eq!(
            (EPISODE_LENGTH_S / POLICY_DT_S).round() as usize,
            EPISODE_LENGTH_STEPS
        );
    }

    #[test]
    fn csp_law_is_pd_when_unsaturated() {
        let tau = csp_torque_nm(0.1, 0.0, 0.5, 50.0, 2.0, 100.0, 1000.0, 1.0);
        assert!((tau - (100.0 * 0.1 - 2.0 * 0.5)).abs() < 1e-5);
    }

    #[test]
    fn csp_law_limits_velocity_then_torque() {
        // 1 rad error asks 50 rad/s; the velocity limit 10 rad/s caps it: 2 * 10 = 20 N m.
        let tau = csp_torque_nm(1.0, 0.0, 0.0, 50.0, 2.0, 10.0, 1000.0, 1.0);
        assert!((tau - 20.0).abs() < 1e-5);
        let tau = csp_torque_nm(1.0, 0.0, 0.0, 50.0, 2.0, 10.0, 15.0, 0.8);
        assert!((tau - 12.0).abs() < 1e-5);
    }
}
