//! The learning algorithm: rollout storage with GAE, and the PPO update.

pub mod adam;
pub mod ppo;
pub mod storage;
