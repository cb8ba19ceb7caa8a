//! `hal-mock`: host implementations of `hexapod-core`'s hardware traits for tests and
//! software-in-the-loop runs.
//!
//! - [`bus::VirtualBus`]: in-memory CAN bus with frame loss, latency and bus-off;
//! - [`drive::Drive`]: a CiA 402 drive emulator (NMT, SDO server, PDOs, power state
//!   machine, heartbeat, EMCY) over a [`plant::JointPlant`], its object dictionary from an
//!   EDS ([`eds`]);
//! - [`rig::DriveRig`]: two buses with the robot's 18 drives;
//! - [`imu::ImuModel`]: IMU readings from a simulated state, with noise, bias, staleness;
//! - [`rc::RcSource`]: a CRSF receiver stream, with link loss;
//! - [`clock::MockClock`]: a settable clock;
//! - [`candump`]: traffic logs in the candump format;
//! - [`base::BaseState`]: the base's motion the IMU senses;
//! - [`harness::Harness`]: controller core + rig + sensors + plant in 1 ms steps.

pub mod base;
pub mod bus;
pub mod candump;
pub mod clock;
pub mod drive;
pub mod eds;
pub mod harness;
pub mod imu;
pub mod plant;
pub mod rc;
pub mod rig;
pub mod rng;
