//! CANopen (CiA 301) and the CiA 402 drive profile: the master of the 18 joint drives.
//!
//! Wire protocol pieces, each in its own file, shared by the master here and by the drive
//! emulators in `hal-mock`:
//! - [`cob`]: COB-IDs and the classification of received identifiers;
//! - [`nmt`]: network management commands and node states (heartbeat payloads);
//! - [`sdo`]: expedited SDO requests, responses and abort codes; [`sdo_client`] runs one
//!   transfer at a time with a timeout;
//! - [`od`]: object dictionary addresses the master uses;
//! - [`cia402`]: controlword commands and the statusword power state machine;
//! - [`pdo`]: the PDO mapping (RPDO1: controlword + target; TPDO1: statusword + position;
//!   TPDO2: velocity + torque) and payload codecs;
//! - [`emcy`]: emergency messages;
//! - [`units`]: the one place drive increments become radians;
//! - [`drive_config`]: the SDO script that configures a drive;
//! - [`master`]: the master's state machine over all nodes.

pub mod cia402;
pub mod cob;
pub mod drive_config;
pub mod emcy;
pub mod master;
pub mod nmt;
pub mod od;
pub mod pdo;
pub mod sdo;
pub mod sdo_client;
pub mod units;

/// The controller's own node id: it produces a heartbeat the drives consume.
pub const MASTER_NODE_ID: u8 = 0x7F;
