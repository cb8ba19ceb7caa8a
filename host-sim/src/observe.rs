//! One robot's observations from its kinematic state, built with hexapod-core's layout
//! functions: what [`crate::env::HexapodEnv`] and the MuJoCo environment
//! ([`crate::mujoco_env`]) both feed the policy, so there is one definition of them.

use crate::frames::rotate_inverse;
use crate::robot::{ContactState, RobotState};
use hexapod_core::amp::{amp_state, AMP_STATE_DIM};
use hexapod_core::obs::{proprio_obs, PrivilegedState, PRIVILEGED_DIM, PROPRIO_DIM};

/// Base linear velocity in the base frame, m/s.
pub fn lin_vel_base_m_s(s: &RobotState) -> [f32; 3] {
    rotate_inverse(s.base_quat_xyzw, s.base_lin_vel_world_m_s)
}

/// Base angular velocity in the base frame, rad/s.
pub fn ang_vel_base_rad_s(s: &RobotState) -> [f32; 3] {
    rotate_inverse(s.base_quat_xyzw, s.base_ang_vel_world_rad_s)
}

/// o^p without noise: angular velocity and projected gravity in the base frame, joints.
pub fn proprio(s: &RobotState) -> [f32; PROPRIO_DIM] {
    let gravity = rotate_inverse(s.base_quat_xyzw, [0.0, 0.0, -1.0]);
    proprio_obs(ang_vel_base_rad_s(s), gravity, &s.q_rad, &s.qdot_rad_s)
}

/// The AMP state of the current instant.
pub fn amp(s: &RobotState) -> [f32; AMP_STATE_DIM] {
    let up = rotate_inverse(s.base_quat_xyzw, [0.0, 0.0, 1.0]);
    amp_state(
        &s.q_rad,
        &s.qdot_rad_s,
        lin_vel_base_m_s(s),
        ang_vel_base_rad_s(s),
        up,
    )
}

/// The privileged state s^p: base velocity, height above the ground, foot friction, foot
/// forces, the last push (velocity change and its direction) and the collision flags.
pub fn privileged(
    s: &RobotState,
    base_height_m: f32,
    friction: f32,
    contacts: &ContactState,
    push_m_s: [f32; 3],
) -> [f32; PRIVILEGED_DIM] {
    PrivilegedState {
        lin_vel_base_m_s: lin_vel_base_m_s(s),
        base_height_m,
        friction,
        foot_force_world_n: contacts.foot_force_world_n,
        push_world_m_s: push_m_s,
        trunk_collision: contacts.trunk,
        thigh_collisions: contacts.thighs,
        shank_collisions: contacts.shanks,
    }
    .to_obs()
}
