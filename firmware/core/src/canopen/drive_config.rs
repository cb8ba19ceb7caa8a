//! The SDO script that configures one drive for cyclic synchronous position control.
//!
//! Run in NMT pre-operational, one expedited transfer at a time:
//! 1. identify: device type (CiA 402, servo drive), supported modes (CSP), rated torque,
//!    encoder resolution and gear ratio (the units [`super::units`] assumes);
//! 2. supervision: producer heartbeat, consumer heartbeat of the master, quick stop on
//!    communication loss (0x6007) and "stay in quick stop, holding" (0x605A);
//! 3. mode: CSP (0x6060 = 8), interpolation period = the policy period (0x60C2);
//! 4. limits: max profile velocity (0x607F, increments/s) and max motor speed (0x6080,
//!    motor rpm) = the joint's velocity limit (the simulator's CSP law uses the same
//!    limit), max torque = the joint's torque limit, software position limits;
//! 5. SYNC COB-ID and cycle period;
//! 6. PDOs, the CiA 301 way: invalidate, clear the mapping count, write entries, set the
//!    count, set the transmission type, validate. Unused PDOs are invalidated.

use super::od::{self, ObjectAddress};
use super::pdo::{RPDO1_MAPPING, TPDO1_MAPPING, TPDO2_MAPPING};
use super::units::{
    rad_s_to_motor_rpm, rad_s_to_velocity_units, rad_to_increments, torque_nm_to_permille,
    GEAR_RATIO, INCREMENTS_PER_REV,
};
use super::{cob, MASTER_NODE_ID};
use crate::robot::{can_node_id, Q_MAX_RAD, Q_MIN_RAD, TORQUE_LIMIT_NM, VELOCITY_LIMIT_RAD_S};
use crate::timing::POLICY_RATE_HZ;

/// Heartbeat period the drives produce, ms.
pub const HEARTBEAT_PRODUCER_MS: u16 = 100;
/// How long a drive waits for the master's heartbeat before its quick stop, ms: five
/// master periods, so a few heartbeats lost on a noisy bus (5 % frame loss) do not stop it.
pub const MASTER_HEARTBEAT_TIMEOUT_MS: u16 = 500;
/// SYNC (and control) period, microseconds.
pub const SYNC_PERIOD_US: u32 = 1_000_000 / POLICY_RATE_HZ;

/// One step of the script.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ConfigStep {
    /// Read and check an object.
    Read(ObjectAddress),
    /// Write `value` with `len` bytes.
    Write(ObjectAddress, u32, u8),
}

/// Why a drive was refused during identification.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum IdentifyError {
    /// Device type is not a CiA 402 servo drive.
    NotAServoDrive(u32),
    /// Cyclic synchronous position is not supported.
    NoCspMode,
    /// Rated torque is zero.
    NoRatedTorque,
    /// Encoder resolution or gear ratio differ from what [`super::units`] assumes.
    Units {
        /// Object read.
        address: ObjectAddress,
        /// Its value.
        value: u32,
    },
}

/// One PDO the script maps.
struct PdoPlan {
    comm_index: u16,
    map_index: u16,
    cob_base: u16,
    mapping: [u32; 2],
    transmission: u8,
}

/// RPDO1, TPDO1, TPDO2 (see [`super::pdo`]).
const PDO_PLANS: [PdoPlan; 3] = [
    PdoPlan {
        comm_index: od::rpdo_comm(0, 0).index,
        map_index: od::rpdo_map(0, 0).index,
        cob_base: cob::RPDO_BASE[0],
        mapping: RPDO1_MAPPING,
        transmission: od::TRANSMISSION_EVENT,
    },
    PdoPlan {
        comm_index: od::tpdo_comm(0, 0).index,
        map_index: od::tpdo_map(0, 0).index,
        cob_base: cob::TPDO_BASE[0],
        mapping: TPDO1_MAPPING,
        transmission: od::TRANSMISSION_SYNC_EVERY,
    },
    PdoPlan {
        comm_index: od::tpdo_comm(1, 0).index,
        map_index: od::tpdo_map(1, 0).index,
        cob_base: cob::TPDO_BASE[1],
        mapping: TPDO2_MAPPING,
        transmission: od::TRANSMISSION_SYNC_EVERY,
    },
];

/// Steps before the PDO section.
const FIXED_STEPS: usize = 21;
/// Steps to map one PDO with two entries.
const PDO_STEPS: usize = 7;
/// PDOs invalidated at the end: TPDO3, TPDO4, RPDO2..4.
const UNUSED_PDOS: usize = 5;
/// Number of steps of the script.
pub const CONFIG_STEPS: usize = FIXED_STEPS + 3 * PDO_STEPS + UNUSED_PDOS;

/// Step `k` of the script for `joint` (`rated_torque_mnm` as read in step 2).
pub fn config_step(k: usize, joint: usize, rated_torque_mnm: u32) -> Option<ConfigStep> {
    use ConfigStep::{Read, Write};
    let node = can_node_id(joint) as u32;
    let torque_limit = torque_nm_to_permille(TORQUE_LIMIT_NM[joint], rated_torque_mnm);
    let step = match k {
        0 => Read(od::DEVICE_TYPE),
        1 => Read(od::SUPPORTED_DRIVE_MODES),
        2 => Read(od::MOTOR_RATED_TORQUE),
        3 => Read(od::ENCODER_INCREMENTS),
        4 => Read(od::ENCODER_MOTOR_REVOLUTIONS),
        5 => Read(od::GEAR_MOTOR_REVOLUTIONS),
        6 => Read(od::GEAR_SHAFT_REVOLUTIONS),
        7 => Write(od::PRODUCER_HEARTBEAT, HEARTBEAT_PRODUCER_MS as u32, 2),
        8 => Write(
            od::CONSUMER_HEARTBEAT_1,
            (MASTER_NODE_ID as u32) << 16 | MASTER_HEARTBEAT_TIMEOUT_MS as u32,
            4,
        ),
        9 => Write(
            od::ABORT_CONNECTION_OPTION,
            od::ABORT_CONNECTION_QUICK_STOP as u16 as u32,
            2,
        ),
        10 => Write(
            od::QUICK_STOP_OPTION,
            od::QUICK_STOP_STAY_ACTIVE as u16 as u32,
            2,
        ),
        11 => Write(od::MODES_OF_OPERATION, od::MODE_CSP as u8 as u32, 1),
        12 => Write(od::INTERPOLATION_PERIOD_VALUE, SYNC_PERIOD_US / 1000, 1),
        13 => Write(od::INTERPOLATION_PERIOD_INDEX, -3i8 as u8 as u32, 1),
        14 => Write(
            od::MAX_PROFILE_VELOCITY,
            rad_s_to_velocity_units(VELOCITY_LIMIT_RAD_S[joint]).max(0) as u32,
            4,
        ),
        15 => Write(
            od::MAX_MOTOR_SPEED,
            rad_s_to_motor_rpm(VELOCITY_LIMIT_RAD_S[joint]),
            4,
        ),
        16 => Write(
            od::MAX_TORQUE,
            torque_limit.clamp(0, u16::MAX as i32) as u32,
            2,
        ),
        17 => Write(
            od::SOFTWARE_POSITION_LIMIT_MIN,
            rad_to_increments(Q_MIN_RAD[joint]) as u32,
            4,
        ),
        18 => Write(
            od::SOFTWARE_POSITION_LIMIT_MAX,
            rad_to_increments(Q_MAX_RAD[joint]) as u32,
            4,
        ),
        19 => Write(od::SYNC_COB_ID, cob::SYNC as u32, 4),
        20 => Write(od::COMM_CYCLE_PERIOD, SYNC_PERIOD_US, 4),
        k if k < FIXED_STEPS + 3 * PDO_STEPS => {
            let plan = &PDO_PLANS[(k - FIXED_STEPS) / PDO_STEPS];
            let comm = |sub| ObjectAddress::new(plan.comm_index, sub);
            let map = |sub| ObjectAddress::new(plan.map_index, sub);
            let cob_id = plan.cob_base as u32 + node;
            match (k - FIXED_STEPS) % PDO_STEPS {
                0 => Write(comm(od::PDO_COMM_COB_ID), od::PDO_INVALID | cob_id, 4),
                1 => Write(map(0), 0, 1),
                2 => Write(map(1), plan.mapping[0], 4),
                3 => Write(map(2), plan.mapping[1], 4),
                4 => Write(map(0), 2, 1),
                5 => Write(comm(od::PDO_COMM_TRANSMISSION), plan.transmission as u32, 1),
                _ => Write(comm(od::PDO_COMM_COB_ID), cob_id, 4),
            }
        }
        k if k < CONFIG_STEPS => {
            let u = k - FIXED_STEPS - 3 * PDO_STEPS;
            let (address, base) = match u {
                0 => (od::tpdo_comm(2, od::PDO_COMM_COB_ID), cob::TPDO_BASE[2]),
                1 => (od::tpdo_comm(3, od::PDO_COMM_COB_ID), cob::TPDO_BASE[3]),
                _ => {
                    let n = (u - 1) as u8;
                    (
                        od::rpdo_comm(n, od::PDO_COMM_COB_ID),
                        cob::RPDO_BASE[n as usize],
                    )
                }
            };
            Write(address, od::PDO_INVALID | (base as u32 + node), 4)
        }
        _ => return None,
    };
    Some(step)
}

/// Checks a value read in the identification steps.
pub fn check_read(address: ObjectAddress, value: u32) -> Result<(), IdentifyError> {
    // Device profile 402 and, in the additional information, the type "servo drive".
    if address == od::DEVICE_TYPE
        && (value & 0xFFFF != od::DEVICE_PROFILE_CIA402
            || (value >> 16) & 0xFF != od::DEVICE_TYPE_SERVO)
    {
        return Err(IdentifyError::NotAServoDrive(value));
    }
    let expected = match address {
        a if a == od::ENCODER_INCREMENTS => Some(INCREMENTS_PER_REV),
        a if a == od::ENCODER_MOTOR_REVOLUTIONS || a == od::GEAR_MOTOR_REVOLUTIONS => {
            Some(GEAR_RATIO)
        }
        a if a == od::GEAR_SHAFT_REVOLUTIONS => Some(1),
        _ => None,
    };
    if expected.is_some_and(|e| e != value) {
        return Err(IdentifyError::Units { address, value });
    }
    if address == od::SUPPORTED_DRIVE_MODES && value & od::SUPPORTS_CSP == 0 {
        return Err(IdentifyError::NoCspMode);
    }
    if address == od::MOTOR_RATED_TORQUE && value == 0 {
        return Err(IdentifyError::NoRatedTorque);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn script_has_the_announced_length_and_maps_pdos() {
        let steps: heapless::Vec<ConfigStep, 64> =
            (0..).map_while(|k| config_step(k, 4, 22_500)).collect();
        assert_eq!(steps.len(), CONFIG_STEPS);
        assert!(steps.contains(&ConfigStep::Write(od::rpdo_map(0, 1), 0x6040_0010, 4)));
        assert!(steps.contains(&ConfigStep::Write(od::tpdo_map(1, 2), 0x6077_0010, 4)));
        // RPDO1 of node 5 is validated at 0x205 with event transmission.
        assert!(steps.contains(&ConfigStep::Write(od::rpdo_comm(0, 1), 0x205, 4)));
        assert!(steps.contains(&ConfigStep::Write(od::rpdo_comm(0, 2), 255, 1)));
        assert!(steps.contains(&ConfigStep::Write(od::tpdo_comm(3, 1), 0x8000_0485, 4)));
        assert!(steps.contains(&ConfigStep::Write(od::rpdo_comm(3, 1), 0x8000_0505, 4)));
        assert!(steps.contains(&ConfigStep::Write(od::MODES_OF_OPERATION, 8, 1)));
        assert!(steps.contains(&ConfigStep::Write(od::INTERPOLATION_PERIOD_VALUE, 20, 1)));
        // Thigh of leg 1: 45 N m of 22.5 N m rated.
        assert!(steps.contains(&ConfigStep::Write(od::MAX_TORQUE, 2000, 2)));
        // 12 rad/s: 1,001,316 increments/s (0x607F) and 1031 motor rpm at 9:1 (0x6080).
        assert!(steps.contains(&ConfigStep::Write(od::MAX_PROFILE_VELOCITY, 1_001_316, 4)));
        assert!(steps.contains(&ConfigStep::Write(od::MAX_MOTOR_SPEED, 1031, 4)));
    }

    #[test]
    fn identification_rejects_other_devices() {
        assert_eq!(check_read(od::DEVICE_TYPE, 0x0002_0192), Ok(()));
        // Mode bits (24-31) are manufacturer-specific.
        assert_eq!(check_read(od::DEVICE_TYPE, 0x0A02_0192), Ok(()));
        assert_eq!(
            check_read(od::DEVICE_TYPE, 0x191),
            Err(IdentifyError::NotAServoDrive(0x191))
        );
        // Profile 402, but a stepper motor drive (0x03) or a frequency converter (0x01).
        assert_eq!(
            check_read(od::DEVICE_TYPE, 0x0003_0192),
            Err(IdentifyError::NotAServoDrive(0x0003_0192))
        );
        assert_eq!(
            check_read(od::DEVICE_TYPE, 0x0001_0192),
            Err(IdentifyError::NotAServoDrive(0x0001_0192))
        );
        assert_eq!(
            check_read(od::GEAR_MOTOR_REVOLUTIONS, 10),
            Err(IdentifyError::Units {
                address: od::GEAR_MOTOR_REVOLUTIONS,
                value: 10
            })
        );
        assert_eq!(
            check_read(od::SUPPORTED_DRIVE_MODES, 0x05),
            Err(IdentifyError::NoCspMode)
        );
        assert_eq!(
            check_read(od::MOTOR_RATED_TORQUE, 0),
            Err(IdentifyError::NoRatedTorque)
        );
    }
}
