//! `host-sim`: the rapier3d simulator of the hexapod.
//!
//! Robots are loaded from `assets/hexapod.urdf` as rapier multibodies; the joint drives
//! apply the CSP law of `hexapod_core::timing` at the physics rate. [`vec_env::VecEnv`] is
//! the seam to the learner.
#![warn(missing_docs)]

pub mod bench;
pub mod clearance;
pub mod config;
pub mod course;
pub mod curriculum;
pub mod demo;
pub mod env;
pub mod foot_contact;
pub mod frames;
pub mod gait;
pub mod mujoco_env;
pub mod observe;
pub mod peer;
pub mod plot;
pub mod reference;
pub mod rewards;
pub mod robot;
pub mod terrain;
pub mod trajectory;
pub mod urdf_gen;
pub mod urdf_model;
pub mod vec_env;
