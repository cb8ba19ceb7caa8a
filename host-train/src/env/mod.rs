//! Environments the trainer can drive: the rapier3d simulator of `host-sim`, or a small
//! deterministic stand-in with the same observation layout.

pub mod fake;

use crate::config::{EnvKind, TrainConfig};
use host_sim::vec_env::VecEnv;

/// Why an environment could not be created.
#[derive(Debug, thiserror::Error)]
pub enum EnvError {
    /// The requested environment is not available in this build.
    #[error("environment `{0}` is not available: {1}")]
    Unavailable(String, String),
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
        EnvKind::Sim => Err(EnvError::Unavailable(
            "sim".into(),
            "host-sim does not provide a VecEnv implementation yet; use env.kind = \"fake\"".into(),
        )),
    }
}
