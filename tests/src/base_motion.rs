//! From host-sim's base state to what hal-mock's IMU model senses, with the frames made
//! explicit: host-sim gives the orientation as a quaternion (x, y, z, w) base -> world and
//! the angular velocity in the world frame; the IMU model wants (w, x, y, z), the angular
//! velocity in the base frame (x forward, y left, z up) and the base's linear acceleration
//! in the world frame, which the simulator does not report: it is differentiated here.

use hal_mock::base::BaseState;
use hal_mock::imu::world_to_base;
use host_sim::robot::RobotState;

/// The IMU's view of the simulated base.
pub fn base_state(s: &RobotState, lin_acc_world_m_s2: [f32; 3]) -> BaseState {
    let [x, y, z, w] = s.base_quat_xyzw;
    let orientation = [w, x, y, z];
    BaseState {
        orientation,
        ang_vel_base_rad_s: world_to_base(orientation, s.base_ang_vel_world_rad_s),
        lin_acc_world_m_s2,
    }
}

/// The base's linear acceleration, world frame, by differencing its velocity over each
/// physics step.
#[derive(Clone, Copy, Debug)]
pub struct BaseAccel {
    prev_vel_world_m_s: [f32; 3],
    acc_world_m_s2: [f32; 3],
}

impl BaseAccel {
    /// Starts at rest with the velocity `vel_world_m_s`.
    pub fn new(vel_world_m_s: [f32; 3]) -> Self {
        Self {
            prev_vel_world_m_s: vel_world_m_s,
            acc_world_m_s2: [0.0; 3],
        }
    }

    /// Takes a velocity jump that is not an acceleration (an impulse set by the test).
    pub fn rebase(&mut self, vel_world_m_s: [f32; 3]) {
        self.prev_vel_world_m_s = vel_world_m_s;
    }

    /// Updates with the velocity after a step of `dt_s`.
    pub fn update(&mut self, vel_world_m_s: [f32; 3], dt_s: f32) {
        for ((a, v), v_prev) in self
            .acc_world_m_s2
            .iter_mut()
            .zip(vel_world_m_s)
            .zip(self.prev_vel_world_m_s)
        {
            *a = (v - v_prev) / dt_s;
        }
        self.prev_vel_world_m_s = vel_world_m_s;
    }

    /// The latest acceleration, world frame, m/s^2.
    pub fn world_m_s2(&self) -> [f32; 3] {
        self.acc_world_m_s2
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn yaw_rate_and_roll_reach_the_base_frame() {
        // Rolled +90 deg about x: the base's y axis points up, so a yaw rate about the
        // world's z axis is a rate about the base's y axis.
        let h = core::f32::consts::FRAC_1_SQRT_2;
        let s = RobotState {
            base_quat_xyzw: [h, 0.0, 0.0, h],
            base_ang_vel_world_rad_s: [0.0, 0.0, 1.0],
            ..Default::default()
        };
        let b = base_state(&s, [0.0; 3]);
        assert_eq!(b.orientation, [h, h, 0.0, 0.0]);
        let [wx, wy, wz] = b.ang_vel_base_rad_s;
        assert!(
            wx.abs() < 1e-6 && (wy - 1.0).abs() < 1e-6 && wz.abs() < 1e-6,
            "{:?}",
            b.ang_vel_base_rad_s
        );
    }

    #[test]
    fn acceleration_is_the_velocity_difference() {
        let mut a = BaseAccel::new([0.0; 3]);
        a.update([0.0, 0.0, -0.05], 0.005);
        assert!((a.world_m_s2()[2] + 10.0).abs() < 1e-4);
        a.rebase([1.0, 0.0, -0.05]);
        a.update([1.0, 0.0, -0.05], 0.005);
        assert_eq!(a.world_m_s2(), [0.0; 3]);
    }
}
