//! What a scenario records of the simulated robot, one sample per physics step, and the
//! measures the tests assert on (heights, trunk touchdown speed, when torque went off).

use host_sim::robot::{ContactState, RobotState};

/// The robot at one physics step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    /// Simulated time, s.
    pub t_s: f32,
    /// Base position, world, m.
    pub base_pos_world_m: [f32; 3],
    /// Base linear velocity, world, m/s.
    pub base_vel_world_m_s: [f32; 3],
    /// Angle between the base's z axis and the world's z axis, rad.
    pub tilt_rad: f32,
    /// The trunk touches the ground.
    pub trunk_contact: bool,
    /// Joints whose drive applies torque.
    pub powered_joints: usize,
}

impl Sample {
    /// A sample of the state after a step.
    pub fn new(t_s: f32, s: &RobotState, c: &ContactState, powered_joints: usize) -> Self {
        let [x, y, _, _] = s.base_quat_xyzw;
        // The base's z axis in the world has z component 1 - 2 (x^2 + y^2).
        let cos_tilt = (1.0 - 2.0 * (x * x + y * y)).clamp(-1.0, 1.0);
        Self {
            t_s,
            base_pos_world_m: s.base_pos_world_m,
            base_vel_world_m_s: s.base_lin_vel_world_m_s,
            tilt_rad: cos_tilt.acos(),
            trunk_contact: c.trunk,
            powered_joints,
        }
    }

    /// Base height, m.
    pub fn height_m(&self) -> f32 {
        self.base_pos_world_m[2]
    }
}

/// Samples of a run.
#[derive(Clone, Debug, Default)]
pub struct Trace {
    /// In time order.
    pub samples: Vec<Sample>,
}

impl Trace {
    /// Samples from `t0_s` on.
    pub fn since(&self, t0_s: f32) -> &[Sample] {
        let i = self.samples.partition_point(|s| s.t_s < t0_s);
        &self.samples[i..]
    }

    /// The first sample from `t0_s` on where the trunk touches the ground.
    pub fn first_trunk_contact(&self, t0_s: f32) -> Option<&Sample> {
        self.since(t0_s).iter().find(|s| s.trunk_contact)
    }

    /// The first sample from `t0_s` on with no drive applying torque.
    pub fn torque_off(&self, t0_s: f32) -> Option<&Sample> {
        self.since(t0_s).iter().find(|s| s.powered_joints == 0)
    }

    /// Fastest downward base speed from `t0_s` to `t1_s`, m/s (positive down).
    pub fn max_sink_speed_m_s(&self, t0_s: f32, t1_s: f32) -> f32 {
        self.since(t0_s)
            .iter()
            .take_while(|s| s.t_s <= t1_s)
            .map(|s| -s.base_vel_world_m_s[2])
            .fold(0.0, f32::max)
    }

    /// Lowest base height from `t0_s` on, m.
    pub fn min_height_m(&self, t0_s: f32) -> f32 {
        self.since(t0_s)
            .iter()
            .map(Sample::height_m)
            .fold(f32::INFINITY, f32::min)
    }

    /// Mean forward (world x) speed from `t0_s` to `t1_s`, m/s, from the displacement.
    pub fn mean_speed_x_m_s(&self, t0_s: f32, t1_s: f32) -> Option<f32> {
        let a = self.since(t0_s).first()?;
        let b = self
            .since(t0_s)
            .iter()
            .take_while(|s| s.t_s <= t1_s)
            .last()?;
        (b.t_s > a.t_s).then(|| (b.base_pos_world_m[0] - a.base_pos_world_m[0]) / (b.t_s - a.t_s))
    }

    /// Writes the trace as CSV (for plots when a scenario fails).
    pub fn to_csv(&self) -> String {
        let mut out = String::from(
            "t_s,x_m,y_m,z_m,vx_m_s,vy_m_s,vz_m_s,tilt_rad,trunk_contact,powered_joints\n",
        );
        for s in &self.samples {
            let [x, y, z] = s.base_pos_world_m;
            let [vx, vy, vz] = s.base_vel_world_m_s;
            out += &format!(
                "{:.3},{x:.4},{y:.4},{z:.4},{vx:.4},{vy:.4},{vz:.4},{:.4},{},{}\n",
                s.t_s, s.tilt_rad, s.trunk_contact as u8, s.powered_joints
            );
        }
        out
    }
}
