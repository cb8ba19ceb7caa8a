//! Environments the trainer can drive: the rapier3d simulator of `host-sim`, or a small
//! deterministic stand-in with the same observation layout.

pub mod fake;

use crate::config::{EnvKind, TrainConfig};
use host_sim::vec_env::VecEnv;

/// Why an environment could not be created.
#[derive(Debug, thiserror::Error)]
pub enum EnvError {
    /// The simulator could not be built.
    #[error("simulator: {0}")]
    Sim(#[from] host_sim::env::EnvError),
}

/// Creates the environment a config asks for.
pub fn make_env(cfg: &TrainConfig) -> Result<Box<dyn VecEnv>, EnvError> {
    match cfg.env.kind {
        EnvKind::Fake => Ok(Box::new(fake::PointMassEnv::new(
            cfg.env.num_envs,
            cfg.env.fake_episode_steps,
            cfg.rewards.task,
            cfg.rewards.penalties,
            cfg.env.seed,
        ))),
        EnvKind::Sim => Ok(Box::new(host_sim::env::HexapodEnv::new(
            cfg.resolved_sim(),
        )?)),
    }
}
