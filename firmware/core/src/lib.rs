//! `hexapod-core`: the single definition of the robot and the `no_std` controller core.
//!
//! Everything that the simulator, the trainer, the code generator and the firmware must
//! agree on lives here, once: joint order and names, leg geometry, nominal pose, limits,
//! tripod sets, CAN node ids, timing, and the observation layouts (index ranges, scales,
//! noise). The crate builds for `thumbv7em-none-eabihf` without `std` and is unit-tested
//! on the host.
#![cfg_attr(not(any(test, feature = "std")), no_std)]
#![warn(missing_docs)]

pub mod amp;
pub mod attitude;
pub mod can_frame;
pub mod canopen;
pub mod control;
pub mod controller;
pub mod frames;
pub mod hal;
pub mod kinematics;
pub mod math;
pub mod nets;
pub mod nn;
pub mod obs;
pub mod rc;
pub mod robot;
pub mod supervisor;
pub mod timing;

/// The nalgebra the core is written on (the version rapier uses on the host).
pub use nalgebra;
pub use robot::{Joint, Leg, NUM_JOINTS, NUM_LEGS};
