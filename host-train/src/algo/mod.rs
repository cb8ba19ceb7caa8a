//! The learning algorithm: rollout storage with GAE, the PPO update, and RMA's adaptation
//! phase.

pub mod adam;
pub mod adaptation;
pub mod ppo;
pub mod storage;
