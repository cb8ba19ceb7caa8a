//! The base's motion as the IMU senses it: what a plant that simulates the base hands the
//! harness ([`crate::plant::JointPlant::base_state`]) and the harness feeds the IMU model.

/// The base's motion as the IMU senses it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BaseState {
    /// Orientation, unit quaternion (w, x, y, z), base -> world.
    pub orientation: [f32; 4],
    /// Angular velocity, base frame, rad/s.
    pub ang_vel_base_rad_s: [f32; 3],
    /// Linear acceleration, world frame, m/s^2.
    pub lin_acc_world_m_s2: [f32; 3],
}

impl Default for BaseState {
    fn default() -> Self {
        Self {
            orientation: [1.0, 0.0, 0.0, 0.0],
            ang_vel_base_rad_s: [0.0; 3],
            lin_acc_world_m_s2: [0.0; 3],
        }
    }
}
