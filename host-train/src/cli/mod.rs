//! Subcommands of the `hexapod` binary, one file each.

pub mod eval;
pub mod play;
pub mod plot;
pub mod pretrain;
pub mod priors;
pub mod replay_gif;
pub mod suite;
pub mod terrain_walk;
pub mod train;
