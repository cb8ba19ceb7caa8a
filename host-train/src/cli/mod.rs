//! Subcommands of the `hexapod` binary, one file each.

pub mod eval;
pub mod play;
pub mod plot;
pub mod pretrain;
pub mod priors;
pub mod replay_gif;
pub mod sim2sim;
pub mod suite;
pub mod sweep;
pub mod terrain_walk;
pub mod train;
