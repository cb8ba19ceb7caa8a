//! `host-train`: motion priors by trajectory optimization, and the PPO + AMP trainer.
#![warn(missing_docs)]

pub mod cli;
