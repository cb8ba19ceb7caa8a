//! From desired ground forces and foot motions to the drives' position targets.
//!
//! The drives run the CSP law of [`hexapod_core::timing`]:
//! `tau = kp2 (kp1 (q_d - q) - qdot)`, a PD law of stiffness `kp = kp1 kp2` and damping `kp2`.
//! A target
//!
//! `q_d = q + s (q_ref - q) + tau_ff / kp + qdot_ref / kp1`
//!
//! makes the drive apply `tau_ff + s kp (q_ref - q) + kp2 (qdot_ref - qdot)`: the force
//! feed-forward, a share `s` of the drive's stiffness towards the kinematic pose `q_ref`, and
//! damping about the reference joint velocity. Stance legs get `tau_ff = -J^T f` for the
//! ground force `f` the MPC wants on the foot; swing legs `tau_ff = 0`, `s = 1`. The nominal
//! gains are used (the robot's own may differ: the controller does not know them).

use hexapod_core::kinematics::leg_inverse_kinematics;
use hexapod_core::robot::{Leg, COXA_LENGTH_M, MOUNT_YAW_RAD, SHANK_LENGTH_M, THIGH_LENGTH_M};
use hexapod_core::timing::{CSP_KP1_PER_S, CSP_KP2_NMS_PER_RAD};

/// The drives' nominal stiffness, N m/rad.
pub const KP_NM_PER_RAD: f64 = (CSP_KP1_PER_S * CSP_KP2_NMS_PER_RAD) as f64;
/// The drives' nominal position-loop gain, 1/s.
pub const KP1_PER_S: f64 = CSP_KP1_PER_S as f64;

/// Jacobian `d foot / d q` of one leg in the base frame: rows x, y, z; columns hip, thigh,
/// shank (the derivative of [`hexapod_core::kinematics::foot_position`]).
pub fn jacobian(leg: Leg, q: [f64; 3]) -> [[f64; 3]; 3] {
    let i = leg.index();
    let (l1, l2) = (THIGH_LENGTH_M as f64, SHANK_LENGTH_M as f64);
    let yaw = MOUNT_YAW_RAD[i] as f64 + q[0];
    let (t, ts) = (q[1], q[1] + q[2]);
    let radial = COXA_LENGTH_M[i] as f64 + l1 * t.cos() + l2 * ts.cos();
    let (sy, cy) = yaw.sin_cos();
    // d radial / d (thigh, shank) and d down / d (thigh, shank); foot z = hip z - down.
    let dr = [-l1 * t.sin() - l2 * ts.sin(), -l2 * ts.sin()];
    let dd = [l1 * t.cos() + l2 * ts.cos(), l2 * ts.cos()];
    [
        [-radial * sy, dr[0] * cy, dr[1] * cy],
        [radial * cy, dr[0] * sy, dr[1] * sy],
        [0.0, -dd[0], -dd[1]],
    ]
}

/// Joint torques that make the foot push so that the ground's force on it is `f_base_n`
/// (base frame): `tau = -J^T f`.
pub fn stance_torque_nm(leg: Leg, q: [f64; 3], f_base_n: [f64; 3]) -> [f64; 3] {
    let j = jacobian(leg, q);
    [0, 1, 2].map(|c| -(0..3).map(|r| j[r][c] * f_base_n[r]).sum::<f64>())
}

/// Joint velocities that move the foot at `v_base_m_s` (base frame), or `None` near a
/// singular pose.
pub fn joint_velocity_rad_s(leg: Leg, q: [f64; 3], v_base_m_s: [f64; 3]) -> Option<[f64; 3]> {
    let a = jacobian(leg, q);
    let det = a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1])
        - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
        + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]);
    if det.abs() < 1e-6 {
        return None;
    }
    // Cramer's rule.
    let col = |c: usize| {
        let mut m = a;
        for r in 0..3 {
            m[r][c] = v_base_m_s[r];
        }
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    Some([col(0) / det, col(1) / det, col(2) / det])
}

/// Joint angles that put the foot at `foot_base_m` (base frame), or `None` out of reach.
pub fn inverse_kinematics(leg: Leg, foot_base_m: [f64; 3]) -> Option<[f64; 3]> {
    leg_inverse_kinematics(leg, foot_base_m.map(|v| v as f32))
        .ok()
        .map(|q| q.map(f64::from))
}

/// The drive target of the module docs for one joint.
pub fn drive_target_rad(
    q_rad: f64,
    q_ref_rad: f64,
    position_gain: f64,
    tau_ff_nm: f64,
    qdot_ref_rad_s: f64,
) -> f64 {
    q_rad
        + position_gain * (q_ref_rad - q_rad)
        + tau_ff_nm / KP_NM_PER_RAD
        + qdot_ref_rad_s / KP1_PER_S
}

#[cfg(test)]
mod tests {
    use super::*;
    use hexapod_core::kinematics::foot_position_base;
    use hexapod_core::robot::Q0_LEG_RAD;

    fn fk(leg: Leg, q: [f64; 3]) -> [f64; 3] {
        foot_position_base(leg, q.map(|v| v as f32)).map(f64::from)
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        for leg in Leg::ALL {
            let q = [0.2, Q0_LEG_RAD[1] as f64 - 0.1, Q0_LEG_RAD[2] as f64 + 0.2];
            let j = jacobian(leg, q);
            for c in 0..3 {
                let h = 1e-2;
                let (mut a, mut b) = (q, q);
                a[c] += h;
                b[c] -= h;
                let (fa, fb) = (fk(leg, a), fk(leg, b));
                for r in 0..3 {
                    let fd = (fa[r] - fb[r]) / (2.0 * h);
                    assert!(
                        (fd - j[r][c]).abs() < 2e-4,
                        "{leg:?} {r} {c}: {fd} {}",
                        j[r][c]
                    );
                }
            }
        }
    }

    #[test]
    fn a_vertical_load_loads_the_thigh_and_velocities_invert() {
        let q = Q0_LEG_RAD.map(f64::from);
        // The ground pushes the foot up: the thigh (which lowers the foot for positive angles)
        // must push down, a positive torque.
        let tau = stance_torque_nm(Leg::RightMiddle, q, [0.0, 0.0, 80.0]);
        assert!(tau[1] > 10.0 && tau[0].abs() < 1e-9, "{tau:?}");
        let v = [0.1, -0.05, 0.02];
        let qd = joint_velocity_rad_s(Leg::LeftFront, q, v).unwrap();
        let j = jacobian(Leg::LeftFront, q);
        for r in 0..3 {
            let back: f64 = (0..3).map(|c| j[r][c] * qd[c]).sum();
            assert!((back - v[r]).abs() < 1e-9);
        }
    }
}
