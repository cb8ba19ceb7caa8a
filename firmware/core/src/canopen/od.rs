//! Object dictionary addresses (CiA 301 communication objects, CiA 402 drive objects).

/// An object dictionary entry: index and subindex.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ObjectAddress {
    /// 16-bit index.
    pub index: u16,
    /// 8-bit subindex.
    pub sub: u8,
}

impl ObjectAddress {
    /// An address.
    pub const fn new(index: u16, sub: u8) -> Self {
        Self { index, sub }
    }

    /// The PDO mapping entry for this object with `bits` length (`index << 16 | sub << 8 | bits`).
    pub const fn mapping(self, bits: u8) -> u32 {
        (self.index as u32) << 16 | (self.sub as u32) << 8 | bits as u32
    }

    /// Decodes a PDO mapping entry into (object, length in bits).
    pub const fn from_mapping(entry: u32) -> (Self, u8) {
        (
            Self::new((entry >> 16) as u16, (entry >> 8) as u8),
            entry as u8,
        )
    }
}

/// Device type (u32, ro): bits 0-15 the device profile (402), bits 16-23 the type
/// (CiA 402: 0x01 frequency converter, 0x02 servo drive, 0x03 stepper motor, ...), bits
/// 24-31 manufacturer-specific mode bits.
pub const DEVICE_TYPE: ObjectAddress = ObjectAddress::new(0x1000, 0);
/// Device type value of a CiA 402 servo drive (no mode bits).
pub const DEVICE_TYPE_CIA402_SERVO: u32 = 0x0002_0192;
/// Device profile number of CiA 402 (bits 0-15 of 0x1000).
pub const DEVICE_PROFILE_CIA402: u32 = 402;
/// Type field (bits 16-23 of 0x1000) of a CiA 402 servo drive.
pub const DEVICE_TYPE_SERVO: u32 = 0x02;
/// COB-ID SYNC (u32).
pub const SYNC_COB_ID: ObjectAddress = ObjectAddress::new(0x1005, 0);
/// Communication cycle period (u32, us).
pub const COMM_CYCLE_PERIOD: ObjectAddress = ObjectAddress::new(0x1006, 0);
/// Consumer heartbeat time entry 1 (u32: node id << 16 | time ms).
pub const CONSUMER_HEARTBEAT_1: ObjectAddress = ObjectAddress::new(0x1016, 1);
/// Producer heartbeat time (u16, ms).
pub const PRODUCER_HEARTBEAT: ObjectAddress = ObjectAddress::new(0x1017, 0);
/// RPDO communication parameter index of RPDO `n` (0-based).
pub const fn rpdo_comm(n: u8, sub: u8) -> ObjectAddress {
    ObjectAddress::new(0x1400 + n as u16, sub)
}
/// RPDO mapping parameter of RPDO `n` (0-based).
pub const fn rpdo_map(n: u8, sub: u8) -> ObjectAddress {
    ObjectAddress::new(0x1600 + n as u16, sub)
}
/// TPDO communication parameter of TPDO `n` (0-based).
pub const fn tpdo_comm(n: u8, sub: u8) -> ObjectAddress {
    ObjectAddress::new(0x1800 + n as u16, sub)
}
/// TPDO mapping parameter of TPDO `n` (0-based).
pub const fn tpdo_map(n: u8, sub: u8) -> ObjectAddress {
    ObjectAddress::new(0x1A00 + n as u16, sub)
}
/// PDO communication parameter subindex: COB-ID (bit 31 set = PDO invalid).
pub const PDO_COMM_COB_ID: u8 = 1;
/// PDO communication parameter subindex: transmission type.
pub const PDO_COMM_TRANSMISSION: u8 = 2;
/// Bit 31 of a PDO COB-ID entry: the PDO does not exist / is disabled.
pub const PDO_INVALID: u32 = 1 << 31;
/// Transmission type: synchronous, every SYNC.
pub const TRANSMISSION_SYNC_EVERY: u8 = 1;
/// Transmission type: event-driven (an RPDO acts on reception).
pub const TRANSMISSION_EVENT: u8 = 255;

/// Abort connection option code (i16): what the drive does on a communication error.
pub const ABORT_CONNECTION_OPTION: ObjectAddress = ObjectAddress::new(0x6007, 0);
/// Abort connection option: execute a quick stop.
pub const ABORT_CONNECTION_QUICK_STOP: i16 = 3;
/// Error code (u16, ro): the last fault.
pub const ERROR_CODE: ObjectAddress = ObjectAddress::new(0x603F, 0);
/// Controlword (u16).
pub const CONTROLWORD: ObjectAddress = ObjectAddress::new(0x6040, 0);
/// Statusword (u16, ro).
pub const STATUSWORD: ObjectAddress = ObjectAddress::new(0x6041, 0);
/// Quick stop option code (i16).
pub const QUICK_STOP_OPTION: ObjectAddress = ObjectAddress::new(0x605A, 0);
/// Quick stop option: slow down on the quick stop ramp and stay in Quick stop active
/// (the drive keeps holding position with torque on).
pub const QUICK_STOP_STAY_ACTIVE: i16 = 6;
/// Modes of operation (i8).
pub const MODES_OF_OPERATION: ObjectAddress = ObjectAddress::new(0x6060, 0);
/// Modes of operation display (i8, ro).
pub const MODES_OF_OPERATION_DISPLAY: ObjectAddress = ObjectAddress::new(0x6061, 0);
/// Cyclic synchronous position mode.
pub const MODE_CSP: i8 = 8;
/// Position actual value (i32, increments, ro).
pub const POSITION_ACTUAL: ObjectAddress = ObjectAddress::new(0x6064, 0);
/// Velocity actual value (i32, increments/s, ro).
pub const VELOCITY_ACTUAL: ObjectAddress = ObjectAddress::new(0x606C, 0);
/// Max torque (u16, per mille of rated torque).
pub const MAX_TORQUE: ObjectAddress = ObjectAddress::new(0x6072, 0);
/// Motor rated torque (u32, mN m, ro).
pub const MOTOR_RATED_TORQUE: ObjectAddress = ObjectAddress::new(0x6076, 0);
/// Torque actual value (i16, per mille of rated torque, ro).
pub const TORQUE_ACTUAL: ObjectAddress = ObjectAddress::new(0x6077, 0);
/// Target position (i32, increments).
pub const TARGET_POSITION: ObjectAddress = ObjectAddress::new(0x607A, 0);
/// Software position limit, minimum (i32, increments).
pub const SOFTWARE_POSITION_LIMIT_MIN: ObjectAddress = ObjectAddress::new(0x607D, 1);
/// Software position limit, maximum (i32, increments).
pub const SOFTWARE_POSITION_LIMIT_MAX: ObjectAddress = ObjectAddress::new(0x607D, 2);
/// Max profile velocity (u32, velocity units = increments/s); in CSP the drive's speed
/// limit together with [`MAX_MOTOR_SPEED`].
pub const MAX_PROFILE_VELOCITY: ObjectAddress = ObjectAddress::new(0x607F, 0);
/// Max motor speed (u32, rpm of the motor shaft, CiA 402).
pub const MAX_MOTOR_SPEED: ObjectAddress = ObjectAddress::new(0x6080, 0);
/// Position encoder resolution, encoder increments (u32).
pub const ENCODER_INCREMENTS: ObjectAddress = ObjectAddress::new(0x608F, 1);
/// Position encoder resolution, motor revolutions (u32).
pub const ENCODER_MOTOR_REVOLUTIONS: ObjectAddress = ObjectAddress::new(0x608F, 2);
/// Gear ratio, motor revolutions (u32).
pub const GEAR_MOTOR_REVOLUTIONS: ObjectAddress = ObjectAddress::new(0x6091, 1);
/// Gear ratio, shaft revolutions (u32).
pub const GEAR_SHAFT_REVOLUTIONS: ObjectAddress = ObjectAddress::new(0x6091, 2);
/// Interpolation time period value (u8).
pub const INTERPOLATION_PERIOD_VALUE: ObjectAddress = ObjectAddress::new(0x60C2, 1);
/// Interpolation time period index (i8, power of ten of seconds: -3 = ms).
pub const INTERPOLATION_PERIOD_INDEX: ObjectAddress = ObjectAddress::new(0x60C2, 2);
/// Supported drive modes (u32, ro): bit 7 = CSP.
pub const SUPPORTED_DRIVE_MODES: ObjectAddress = ObjectAddress::new(0x6502, 0);
/// Bit of [`SUPPORTED_DRIVE_MODES`] announcing cyclic synchronous position.
pub const SUPPORTS_CSP: u32 = 1 << 7;
