//! One robot's observations from its kinematic state, built with hexapod-core's layout
//! functions: what [`crate::env::HexapodEnv`] and the MuJoCo environment
//! ([`crate::mujoco_env`]) both feed the policy, so there is one definition of them.

use crate::frames::rotate_inverse;
use crate::robot::{ContactState, RobotState};
use hexapod_core::amp::{amp_state, AMP_STATE_DIM};
use hexapod_core::obs::{
    proprio_obs, CONTACT_FORCE_SCALE, LIN_VEL_SCALE, PRIVILEGED_DIM, PRIV_BASE_HEIGHT,
    PRIV_COLLISIONS, PRIV_CONTACT_FORCES, PRIV_FRICTION, PRIV_LIN_VEL, PRIV_PERTURBATION,
    PROPRIO_DIM,
};
use hexapod_core::robot::NUM_LEGS;

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
    let mut p = [0.0; PRIVILEGED_DIM];
    let lin_vel = lin_vel_base_m_s(s);
    for k in 0..3 {
        p[PRIV_LIN_VEL.start + k] = lin_vel[k] * LIN_VEL_SCALE;
    }
    p[PRIV_BASE_HEIGHT] = base_height_m;
    p[PRIV_FRICTION] = friction;
    for leg in 0..NUM_LEGS {
        for k in 0..3 {
            p[PRIV_CONTACT_FORCES.start + 3 * leg + k] =
                contacts.foot_force_world_n[leg][k] * CONTACT_FORCE_SCALE;
        }
    }
    let norm =
        (push_m_s[0] * push_m_s[0] + push_m_s[1] * push_m_s[1] + push_m_s[2] * push_m_s[2]).sqrt();
    for k in 0..3 {
        p[PRIV_PERTURBATION.start + k] = push_m_s[k];
        p[PRIV_PERTURBATION.start + 3 + k] = if norm > 1e-6 { push_m_s[k] / norm } else { 0.0 };
    }
    p[PRIV_COLLISIONS.start] = contacts.trunk as u8 as f32;
    for leg in 0..NUM_LEGS {
        p[PRIV_COLLISIONS.start + 1 + leg] = contacts.thighs[leg] as u8 as f32;
        p[PRIV_COLLISIONS.start + 7 + leg] = contacts.shanks[leg] as u8 as f32;
    }
    p
}
