//! `host-train`: motion priors by trajectory optimization, and the PPO + AMP trainer.
#![warn(missing_docs)]

pub mod algo;
pub mod alloc;
pub mod amp;
pub mod checkpoint;
pub mod checkpoint_average;
pub mod cli;
pub mod config;
pub mod curriculum_carry;
pub mod env;
pub mod error;
pub mod metrics;
pub mod mpc;
pub mod nn;
pub mod priors;
pub mod runner;
pub mod sweep;
pub mod threads;
