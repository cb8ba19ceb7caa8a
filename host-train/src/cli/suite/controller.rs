//! What drives the suite's robots: a learned policy (a checkpoint's actor, its action mean) or
//! the model-based MPC ([`crate::mpc`]), behind one interface.

use crate::algo::ppo::Ppo;
use crate::mpc::MpcController;
use host_sim::env::HexapodEnv;
use host_sim::vec_env::{Observations, VecEnv};

/// A controller of a batch of robots at the policy rate.
pub trait SuiteController {
    /// The environment was reset: every robot starts a new episode.
    fn start(&mut self, _env: &HexapodEnv) {}

    /// Actions (action units, robot-major) for the robots in `env`, whose observations are
    /// `obs` and whose commands are set.
    fn act(&mut self, obs: &Observations, env: &HexapodEnv) -> anyhow::Result<Vec<f32>>;

    /// Robot `i`'s episode ended; the environment has already reset it.
    fn episode_ended(&mut self, _i: usize) {}
}

/// The learned policy: its deterministic action (the mean); memory is in the observations.
impl SuiteController for Ppo {
    fn act(&mut self, obs: &Observations, _env: &HexapodEnv) -> anyhow::Result<Vec<f32>> {
        Ok(Ppo::act(self, obs, true)?.actions)
    }
}

/// The MPC: it reads the true state and the commands from the simulator.
impl SuiteController for MpcController {
    fn start(&mut self, env: &HexapodEnv) {
        self.reset(env.num_envs());
    }

    fn act(&mut self, _obs: &Observations, env: &HexapodEnv) -> anyhow::Result<Vec<f32>> {
        let n = env.num_envs();
        let states: Vec<_> = (0..n).map(|i| env.robot_state(i)).collect();
        let commands: Vec<[f32; 3]> = (0..n).map(|i| env.command(i)).collect();
        Ok(self.actions(&states, &commands))
    }

    fn episode_ended(&mut self, i: usize) {
        self.reset_robot(i);
    }
}
