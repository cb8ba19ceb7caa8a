//! `sil-tests`: software-in-the-loop scenarios. The controller core of the firmware,
//! unchanged, runs against host-sim's rigid-body robot through hal-mock: CAN frames to and
//! from 18 emulated CiA 402 drives, an IMU model fed by the simulated base, CRSF bytes from
//! an emulated RC link.
//!
//! - [`sim_plant::SimPlant`]: the simulated robot as the drives' joint plant;
//! - [`base_motion`]: the simulated base as the IMU senses it (frames, acceleration);
//! - [`gait_policy::GaitPolicy`]: a scripted tripod gait that walks through the loop;
//! - [`trace::Trace`]: what a run records, and the measures the scenarios assert on;
//! - [`sil::Sil`]: the rig and the scenario steps (boot, stand up, run until a mode).
//!
//! - [`scenario::Scenario`]: data-driven scenarios (`scenarios/*.toml`).
//!
//! The scenarios are the integration tests in `tests/` and the files in `scenarios/`.
#![warn(missing_docs)]

pub mod base_motion;
pub mod gait_policy;
pub mod scenario;
pub mod sil;
pub mod sim_plant;
pub mod trace;
