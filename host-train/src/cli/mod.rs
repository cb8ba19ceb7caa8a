//! Subcommands of the `hexapod` binary, one file each.

pub mod average;
pub mod eval;
pub mod play;
pub mod plot;
pub mod pretrain;
pub mod priors;
pub mod recording;
pub mod replay_gif;
#[cfg(feature = "rerun")]
pub mod rerun_writer;
pub mod rma_adapt;
pub mod sim2sim;
pub mod style_probe;
pub mod suite;
pub mod sweep;
pub mod terrain_mesh;
pub mod terrain_walk;
pub mod train;
