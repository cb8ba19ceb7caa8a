//! Default network shapes of the controller (the paper's Table II).
//!
//! The trainer's config may change hidden sizes and the memory latent size; the generated
//! policy crate carries the shapes it was built with. Inputs are fixed by the observation
//! layout in [`crate::obs`].

use crate::obs::{ACTOR_OBS_DIM, HISTORY_DIM};
use crate::robot::NUM_JOINTS;

/// Estimator: history -> base linear velocity estimate (m/s, base frame, unscaled).
pub const ESTIMATOR_HIDDEN: [usize; 2] = [64, 32];
/// Estimator output size.
pub const ESTIMATOR_OUT: usize = 3;
/// Memory encoder hidden sizes.
pub const MEMORY_HIDDEN: [usize; 3] = [512, 256, 128];
/// Default memory latent size.
pub const MEMORY_LATENT: usize = 16;
/// Low-level actor hidden sizes.
pub const ACTOR_HIDDEN: [usize; 3] = [256, 128, 64];
/// Actor input: actor observation, velocity estimate, memory latent.
pub const ACTOR_IN: usize = ACTOR_OBS_DIM + ESTIMATOR_OUT + MEMORY_LATENT;
/// Actor output: one action per joint.
pub const ACTOR_OUT: usize = NUM_JOINTS;
/// Estimator and memory input.
pub const HISTORY_IN: usize = HISTORY_DIM;
