//! Reference states: instants of a motion prior the simulated robot can be started from
//! (reference state initialization, as in AMP and AMP_for_hardware), and that the AMP
//! state of a prior is computed from.

use hexapod_core::amp::{amp_state, AMP_STATE_DIM};
use hexapod_core::robot::NUM_JOINTS;

/// One instant of a reference motion: everything the AMP state and a spawn need.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReferenceState {
    /// Joint angles, rad.
    pub q_rad: [f32; NUM_JOINTS],
    /// Joint velocities, rad/s.
    pub qdot_rad_s: [f32; NUM_JOINTS],
    /// Base linear velocity, base frame, m/s.
    pub lin_vel_base_m_s: [f32; 3],
    /// Base angular velocity, base frame, rad/s.
    pub ang_vel_base_rad_s: [f32; 3],
    /// The world's up direction in the base frame (unit length).
    pub up_base: [f32; 3],
    /// Base origin above the ground under it, m (flat ground).
    pub base_height_m: f32,
}

/// A state an episode may start from (reference state initialization), with the velocity
/// command its motion realizes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReferenceStart {
    /// The motion's state at some instant.
    pub state: ReferenceState,
    /// The motion's velocity (vx m/s, vy m/s, wz rad/s): its clip's command, or what the
    /// simulator measured while tracking it.
    pub command: [f32; 3],
}

impl ReferenceState {
    /// The AMP state of this instant, by the function the simulator uses on its own state.
    pub fn amp_state(&self) -> [f32; AMP_STATE_DIM] {
        amp_state(
            &self.q_rad,
            &self.qdot_rad_s,
            self.lin_vel_base_m_s,
            self.ang_vel_base_rad_s,
            self.up_base,
        )
    }

    /// Linear interpolation from `self` (`u = 0`) to `next` (`u = 1`); the up direction is
    /// renormalized.
    pub fn lerp(&self, next: &Self, u: f32) -> Self {
        fn mix<const N: usize>(a: &[f32; N], b: &[f32; N], u: f32) -> [f32; N] {
            std::array::from_fn(|i| a[i] + u * (b[i] - a[i]))
        }
        let up = mix(&self.up_base, &next.up_base, u);
        let norm = (up[0] * up[0] + up[1] * up[1] + up[2] * up[2])
            .sqrt()
            .max(1e-6);
        Self {
            q_rad: mix(&self.q_rad, &next.q_rad, u),
            qdot_rad_s: mix(&self.qdot_rad_s, &next.qdot_rad_s, u),
            lin_vel_base_m_s: mix(&self.lin_vel_base_m_s, &next.lin_vel_base_m_s, u),
            ang_vel_base_rad_s: mix(&self.ang_vel_base_rad_s, &next.ang_vel_base_rad_s, u),
            up_base: up.map(|x| x / norm),
            base_height_m: self.base_height_m + u * (next.base_height_m - self.base_height_m),
        }
    }

    /// The base orientation with zero yaw whose up direction is `up_base`, (x, y, z, w):
    /// the shortest rotation taking the world's z axis to where the base sees it.
    pub fn tilt_quat_xyzw(&self) -> [f32; 4] {
        // The base sees the world's up as R^T e_z = up_base. With Q the shortest rotation
        // taking e_z to up_base (axis e_z x up, half-angle quaternion), R^T = Q and R is
        // Q's conjugate.
        let [ux, uy, uz] = self.up_base;
        let w = 1.0 + uz;
        let (x, y, z) = (-uy, ux, 0.0);
        let norm = (x * x + y * y + z * z + w * w).sqrt();
        if norm < 1e-6 {
            return [1.0, 0.0, 0.0, 0.0];
        }
        [-x / norm, -y / norm, -z / norm, w / norm]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frames::rotate_inverse;

    #[test]
    fn tilt_quaternion_reproduces_the_up_direction() {
        let s = 0.3f32.sin();
        let c = 0.3f32.cos();
        for up in [
            [0.0, 0.0, 1.0],
            [s, 0.0, c],
            [0.0, -s, c],
            [0.6 * s, 0.8 * s, c],
        ] {
            let r = ReferenceState {
                q_rad: [0.0; NUM_JOINTS],
                qdot_rad_s: [0.0; NUM_JOINTS],
                lin_vel_base_m_s: [0.0; 3],
                ang_vel_base_rad_s: [0.0; 3],
                up_base: up,
                base_height_m: 0.3,
            };
            let seen = rotate_inverse(r.tilt_quat_xyzw(), [0.0, 0.0, 1.0]);
            for k in 0..3 {
                assert!((seen[k] - up[k]).abs() < 1e-5, "{up:?} -> {seen:?}");
            }
        }
    }

    #[test]
    fn interpolation_is_exact_at_the_ends_and_keeps_up_unit() {
        let mut a = ReferenceState {
            q_rad: [0.1; NUM_JOINTS],
            qdot_rad_s: [1.0; NUM_JOINTS],
            lin_vel_base_m_s: [0.3, 0.0, 0.0],
            ang_vel_base_rad_s: [0.0; 3],
            up_base: [0.0, 0.0, 1.0],
            base_height_m: 0.30,
        };
        let mut b = a;
        b.q_rad = [0.3; NUM_JOINTS];
        b.up_base = [0.2f32.sin(), 0.0, 0.2f32.cos()];
        a.base_height_m = 0.32;
        assert_eq!(a.lerp(&b, 0.0), a);
        let m = a.lerp(&b, 0.5);
        assert!((m.q_rad[4] - 0.2).abs() < 1e-6 && (m.base_height_m - 0.31).abs() < 1e-6);
        let n = m.up_base.iter().map(|x| x * x).sum::<f32>();
        assert!((n - 1.0).abs() < 1e-6);
    }
}
