//! Motion priors: a tripod-gait dataset made by trajectory optimization, for the AMP
//! discriminator's style reward.
//!
//! Pipeline per command ([`command`], run by `hexapod priors`): a fixed tripod schedule
//! ([`schedule`]), Raibert footholds and min-jerk swings with clearance ([`feet`]), a convex
//! QP over the single-rigid-body base motion and friction-cone contact forces ([`optimize`],
//! model in [`body`], solved by clarabel through [`qp`]), joint angles by the legs' inverse
//! kinematics with kinematic checks ([`assemble`]), written as a JSON motion clip
//! ([`clip`], frame layout in [`frame`]) with plots ([`plot`]). [`generate`] strings these
//! together and reports solver status, objective and constraint violations per clip.
//!
//! Consumers: [`dataset`] loads a directory of clips and samples (s_t, s_t+1) AMP-state
//! transitions weighted by `MotionWeight`; [`sim_tracking`] plays clips in host-sim through the CSP
//! drives and checks that the robot stays upright and walks at the command; [`expert`] blends
//! the clips into joint targets for any command, the expert `hexapod pretrain` clones.
pub mod assemble;
pub mod body;
pub mod clip;
pub mod command;
pub mod dataset;
pub mod expert;
pub mod feet;
pub mod frame;
pub mod generate;
pub mod geom;
pub mod optimize;
pub mod plot;
pub mod qp;
pub mod schedule;
pub mod sim_tracking;

#[cfg(test)]
mod tests;
