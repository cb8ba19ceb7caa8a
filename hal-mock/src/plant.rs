//! The joint plant behind the drive emulators: what turns a CSP setpoint into motion.
//!
//! `host-sim` implements [`JointPlant`] with its rigid-body physics; [`JointModel`] is a
//! stand-alone model (each joint an inertia with viscous friction) for tests without
//! physics. Both evaluate the drive law [`hexapod_core::timing::csp_torque_nm`].

use hexapod_core::robot::{ARMATURE_KG_M2, NUM_JOINTS, Q_SIT_RAD};
use hexapod_core::timing::{csp_torque_nm, CSP_KP1_PER_S, CSP_KP2_NMS_PER_RAD};

use crate::base::BaseState;

/// What an enabled drive asks of its joint: the CSP target and the drive's limits.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CspSetpoint {
    /// Target position, rad.
    pub q_target_rad: f32,
    /// Velocity limit configured on the drive (0x6080), rad/s.
    pub vel_limit_rad_s: f32,
    /// Torque limit configured on the drive (0x6072), N m.
    pub torque_limit_nm: f32,
}

/// A joint's measured state.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct JointState {
    /// Position, rad.
    pub q_rad: f32,
    /// Velocity, rad/s.
    pub qdot_rad_s: f32,
    /// Applied drive torque, N m.
    pub torque_nm: f32,
}

/// The joints the emulated drives act on.
pub trait JointPlant {
    /// The state of joint `joint` (joint order).
    fn joint_state(&self, joint: usize) -> JointState;
    /// The drive's setpoint for `joint`; `None` = torque off (power stage disabled).
    fn set_setpoint(&mut self, joint: usize, setpoint: Option<CspSetpoint>);
    /// The base's motion when the plant simulates it (rigid-body physics); the harness then
    /// feeds it to the IMU model at every tick. `None` (the default): the harness keeps
    /// [`crate::harness::Harness::base`] as the caller sets it.
    fn base_state(&self) -> Option<BaseState> {
        None
    }
}

/// Independent joints: inertia, viscous friction, the CSP law; no gravity or contact.
#[derive(Clone, Debug)]
pub struct JointModel {
    /// Joint states.
    pub states: [JointState; NUM_JOINTS],
    /// Current setpoints.
    pub setpoints: [Option<CspSetpoint>; NUM_JOINTS],
    /// Inertia seen by each drive, kg m^2.
    pub inertia_kg_m2: f32,
    /// Viscous friction, N m s/rad.
    pub friction_nms_per_rad: f32,
}

impl Default for JointModel {
    fn default() -> Self {
        Self::at(&Q_SIT_RAD)
    }
}

impl JointModel {
    /// Joints at rest at `q_rad`.
    pub fn at(q_rad: &[f32; NUM_JOINTS]) -> Self {
        let mut states = [JointState::default(); NUM_JOINTS];
        for (s, &q) in states.iter_mut().zip(q_rad) {
            s.q_rad = q;
        }
        Self {
            states,
            setpoints: [None; NUM_JOINTS],
            inertia_kg_m2: ARMATURE_KG_M2 + 0.04,
            friction_nms_per_rad: 0.1,
        }
    }

    /// Advances every joint by `dt_s` (semi-implicit Euler, the CSP law at each step).
    pub fn step(&mut self, dt_s: f32) {
        for (s, sp) in self.states.iter_mut().zip(&self.setpoints) {
            s.torque_nm = match sp {
                Some(sp) => csp_torque_nm(
                    sp.q_target_rad,
                    s.q_rad,
                    s.qdot_rad_s,
                    CSP_KP1_PER_S,
                    CSP_KP2_NMS_PER_RAD,
                    sp.vel_limit_rad_s,
                    sp.torque_limit_nm,
                    1.0,
                ),
                None => 0.0,
            };
            let qddot =
                (s.torque_nm - self.friction_nms_per_rad * s.qdot_rad_s) / self.inertia_kg_m2;
            s.qdot_rad_s += qddot * dt_s;
            s.q_rad += s.qdot_rad_s * dt_s;
        }
    }
}

impl JointPlant for JointModel {
    fn joint_state(&self, joint: usize) -> JointState {
        self.states[joint]
    }

    fn set_setpoint(&mut self, joint: usize, setpoint: Option<CspSetpoint>) {
        self.setpoints[joint] = setpoint;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use hexapod_core::timing::PHYSICS_DT_S;

    #[test]
    fn tracks_a_step_within_the_velocity_limit() {
        let mut m = JointModel::at(&[0.0; NUM_JOINTS]);
        let sp = CspSetpoint {
            q_target_rad: 0.5,
            vel_limit_rad_s: 2.0,
            torque_limit_nm: 45.0,
        };
        m.set_setpoint(1, Some(sp));
        let mut peak = 0.0f32;
        for _ in 0..400 {
            m.step(PHYSICS_DT_S);
            peak = peak.max(m.states[1].qdot_rad_s);
        }
        assert!((m.states[1].q_rad - 0.5).abs() < 0.01, "{:?}", m.states[1]);
        assert!(peak < 2.2, "velocity limit exceeded: {peak}");
        assert_eq!(
            m.states[0].q_rad, 0.0,
            "a joint without setpoint must not move"
        );
    }
}
