//! The model-based baseline of the paper's comparison: a convex MPC over single-rigid-body
//! dynamics with friction cones ([`srb_qp`]), a tripod gait clock ([`gait`]), Raibert
//! footholds and min-jerk swings ([`footholds`]), and the legs' kinematics mapping forces and
//! foot motions to the drives' position targets ([`joints`]), at the policy rate (50 Hz)
//! through the same action interface as the learned policy. Parameters in [`params`] (body
//! height, lift height and gait period, as the paper tuned on its MPC).
//!
//! It reads the simulator's true state (base pose and velocity, joint angles): state
//! estimation is out of scope. It is blind: the ground is taken as flat, at the height of the
//! stance feet.

pub mod footholds;
pub mod gait;
pub mod joints;
pub mod params;
pub mod robot;
pub mod srb_qp;
#[cfg(test)]
mod tests;

use crate::priors::body::RigidBody;
use hexapod_core::robot::{NUM_JOINTS, Q0_RAD};
use hexapod_core::timing::ACTION_SCALE_RAD;
use host_sim::robot::RobotState;
pub use params::MpcParams;
use rayon::prelude::*;
pub use robot::RobotMpc;

/// The MPC for a batch of robots.
#[derive(Clone, Debug)]
pub struct MpcController {
    params: MpcParams,
    body: RigidBody,
    robots: Vec<RobotMpc>,
}

impl MpcController {
    /// A controller with `params` (checked).
    pub fn new(params: MpcParams) -> anyhow::Result<Self> {
        params.validate().map_err(anyhow::Error::msg)?;
        Ok(Self {
            params,
            body: RigidBody::hexapod(),
            robots: Vec::new(),
        })
    }

    /// The parameters.
    pub fn params(&self) -> &MpcParams {
        &self.params
    }

    /// Fresh state for `n` robots (new episodes).
    pub fn reset(&mut self, n: usize) {
        self.robots = vec![RobotMpc::new(&self.params); n];
    }

    /// Fresh state for robot `i` (its episode ended and the simulator reset it).
    pub fn reset_robot(&mut self, i: usize) {
        if let Some(r) = self.robots.get_mut(i) {
            *r = RobotMpc::new(&self.params);
        }
    }

    /// Robot `i`'s controller.
    pub fn robot(&self, i: usize) -> &RobotMpc {
        &self.robots[i]
    }

    /// Actions (action units, robot-major) for robots in `states` at `commands`, in parallel.
    pub fn actions(&mut self, states: &[RobotState], commands: &[[f32; 3]]) -> Vec<f32> {
        if self.robots.len() != states.len() {
            self.reset(states.len());
        }
        let (p, body) = (&self.params, &self.body);
        let targets: Vec<[f32; NUM_JOINTS]> = self
            .robots
            .par_iter_mut()
            .zip(states.par_iter().zip(commands.par_iter()))
            .map(|(r, (s, c))| r.step(p, body, s, *c))
            .collect();
        targets
            .iter()
            .flat_map(|t| (0..NUM_JOINTS).map(move |j| (t[j] - Q0_RAD[j]) / ACTION_SCALE_RAD))
            .collect()
    }

    /// Steps whose QP was not solved, over all robots since their last reset.
    pub fn qp_failures(&self) -> usize {
        self.robots.iter().map(|r| r.qp_failures).sum()
    }
}
