//! Motion priors: a tripod-gait dataset made by trajectory optimization, for the AMP
//! discriminator's style reward.
//!
//! Pipeline per command (see `hexapod priors`): a fixed tripod schedule
//! ([`schedule`]), Raibert footholds and swing trajectories ([`feet`]), a convex QP over the
//! single-rigid-body base motion and friction-cone contact forces ([`optimize`], solved by
//! clarabel through [`qp`]), joint angles by the legs' inverse kinematics, written as a
//! JSON motion clip.
pub mod assemble;
pub mod body;
pub mod clip;
pub mod command;
pub mod dataset;
pub mod feet;
pub mod frame;
pub mod generate;
pub mod geom;
pub mod optimize;
pub mod plot;
pub mod qp;
pub mod replay;
pub mod schedule;

#[cfg(test)]
mod tests;
