//! The joint plant of the software-in-the-loop runs: host-sim's rigid-body robot behind
//! hal-mock's emulated drives.
//!
//! Every 5 ms physics step the robot's 18 joints are driven by the CSP law with the targets
//! the emulated drives hold at that moment; a drive that is not in Operation enabled (or
//! quick stop) applies no torque. The drives read back the simulated joint positions,
//! velocities and torques for their TPDOs, and the IMU model reads the simulated base
//! motion (see [`crate::base_motion`]). The ground is host-sim's terrain: flat, or a lane of
//! its evaluation course (stairs, a ramp) as the paper suite walks them.

use hal_mock::base::BaseState;
use hal_mock::plant::{CspSetpoint, JointPlant, JointState};
use hexapod_core::kinematics::foot_positions_base;
use hexapod_core::robot::{FOOT_RADIUS_M, NUM_JOINTS, Q_SIT_RAD};
use hexapod_core::timing::PHYSICS_DT_S;
use host_sim::robot::{BuildError, ContactState, RobotState, RobotWorld};
use host_sim::terrain::{Terrain, TerrainConfig};
use host_sim::urdf_model::{default_urdf_path, UrdfError, UrdfModel};

use crate::base_motion::{base_state, BaseAccel};
use crate::trace::{Sample, Trace};

/// Solver iterations of the SIL world (the trainer's setting).
pub const SOLVER_ITERATIONS: usize = 1;

/// Why the simulated plant could not be built.
#[derive(Debug, thiserror::Error)]
pub enum PlantError {
    /// The robot description did not load.
    #[error(transparent)]
    Urdf(#[from] UrdfError),
    /// The rapier world could not be built from it.
    #[error(transparent)]
    Build(#[from] BuildError),
}

/// host-sim's robot as the drives' joint plant.
pub struct SimPlant {
    /// The simulated robot.
    pub world: RobotWorld,
    /// The ground the robot stands on (the world's collider was made from it).
    pub ground: Terrain,
    /// Where the base started, world frame, m.
    pub start_pos_m: [f32; 3],
    setpoints: [Option<CspSetpoint>; NUM_JOINTS],
    state: RobotState,
    contacts: ContactState,
    accel: BaseAccel,
    steps: u64,
    /// One sample per physics step.
    pub trace: Trace,
}

impl SimPlant {
    /// The robot on flat ground in the sitting pose, feet just touching the ground.
    pub fn sitting() -> Result<Self, PlantError> {
        Self::sitting_on(Terrain::generate(&TerrainConfig::default()), [0.0, 0.0])
    }

    /// The robot sitting on `ground` with its base over `xy_m` (world, m), facing +x, feet
    /// just touching the ground there (which must be level under the feet, as a course's
    /// start is).
    pub fn sitting_on(ground: Terrain, xy_m: [f32; 2]) -> Result<Self, PlantError> {
        let model = UrdfModel::load(&default_urdf_path())?;
        let mut world = RobotWorld::new(&model, ground.collider(), SOLVER_ITERATIONS)?;
        let z_m = ground.height_at_m(xy_m[0], xy_m[1]) + sitting_height_m();
        world.reset([xy_m[0], xy_m[1], z_m], [0.0, 0.0, 0.0, 1.0], &Q_SIT_RAD);
        Ok(Self::over(world, ground))
    }

    /// A plant over `world` (built on `ground`) as it is now, all drives off.
    pub fn over(world: RobotWorld, ground: Terrain) -> Self {
        let state = world.state();
        let contacts = world.contacts();
        Self {
            world,
            ground,
            start_pos_m: state.base_pos_world_m,
            setpoints: [None; NUM_JOINTS],
            state,
            contacts,
            accel: BaseAccel::new(state.base_lin_vel_world_m_s),
            steps: 0,
            trace: Trace::default(),
        }
    }

    /// Simulated time, s.
    pub fn time_s(&self) -> f32 {
        self.steps as f32 * PHYSICS_DT_S
    }

    /// The robot's state after the last step.
    pub fn state(&self) -> &RobotState {
        &self.state
    }

    /// Base height above the ground under it, m.
    pub fn height_above_ground_m(&self) -> f32 {
        let [x, y, z] = self.state.base_pos_world_m;
        z - self.ground.height_at_m(x, y)
    }

    /// How far the base has come along +x (the start's heading) since the start, m.
    pub fn progress_m(&self) -> f32 {
        self.state.base_pos_world_m[0] - self.start_pos_m[0]
    }

    /// Ground contacts after the last step.
    pub fn contacts(&self) -> &ContactState {
        &self.contacts
    }

    /// Joints whose drive applies torque now.
    pub fn powered_joints(&self) -> usize {
        self.setpoints.iter().filter(|s| s.is_some()).count()
    }

    /// Changes the base velocity (a push), world frame, m/s.
    pub fn push(&mut self, dv_world_m_s: [f32; 3]) {
        self.world.push(dv_world_m_s);
        self.state = self.world.state();
        self.accel.rebase(self.state.base_lin_vel_world_m_s);
    }

    /// One physics step with the drives' current setpoints.
    pub fn step(&mut self) {
        let mut targets = self.state.q_rad;
        // The drives are configured with the core's velocity and torque limits, which
        // host-sim's drive law uses; a drive without setpoint has its power stage off.
        let strength = &mut self.world.drives.motor_strength;
        for ((target, s), sp) in targets.iter_mut().zip(strength).zip(&self.setpoints) {
            *s = match sp {
                Some(sp) => {
                    *target = sp.q_target_rad;
                    1.0
                }
                None => 0.0,
            };
        }
        self.world.step(&targets);
        self.steps += 1;
        self.state = self.world.state();
        self.contacts = self.world.contacts();
        self.accel
            .update(self.state.base_lin_vel_world_m_s, PHYSICS_DT_S);
        self.trace.samples.push(Sample::new(
            self.time_s(),
            &self.state,
            &self.contacts,
            self.powered_joints(),
        ));
    }
}

/// Base height at which the lowest foot of the sitting pose touches flat ground, m.
pub fn sitting_height_m() -> f32 {
    let lowest = foot_positions_base(&Q_SIT_RAD)
        .iter()
        .map(|f| f[2])
        .fold(f32::INFINITY, f32::min);
    FOOT_RADIUS_M - lowest + 0.002
}

impl JointPlant for SimPlant {
    fn joint_state(&self, joint: usize) -> JointState {
        JointState {
            q_rad: self.state.q_rad[joint],
            qdot_rad_s: self.state.qdot_rad_s[joint],
            torque_nm: self.world.torque_nm[joint],
        }
    }

    fn set_setpoint(&mut self, joint: usize, setpoint: Option<CspSetpoint>) {
        self.setpoints[joint] = setpoint;
    }

    fn base_state(&self) -> Option<BaseState> {
        Some(base_state(&self.state, self.accel.world_m_s2()))
    }
}
