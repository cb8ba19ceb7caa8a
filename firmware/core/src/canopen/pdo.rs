//! The process data objects of the cyclic exchange and their payload codecs.
//!
//! | PDO | COB-ID | content | transmission |
//! |---|---|---|---|
//! | RPDO1 | 0x200 + id | controlword u16, target position i32 | 255: acts on reception |
//! | TPDO1 | 0x180 + id | statusword u16, position actual i32 | 1: every SYNC |
//! | TPDO2 | 0x280 + id | velocity actual i32, torque actual i16 | 1: every SYNC |
//!
//! The master sends SYNC, the drives sample and answer with their TPDOs, the control step
//! runs on that feedback and the RPDOs apply the new targets at once, so the policy's
//! action takes effect a few milliseconds after its observation, as in the simulator.

use super::od;

/// RPDO1 mapping entries.
pub const RPDO1_MAPPING: [u32; 2] = [od::CONTROLWORD.mapping(16), od::TARGET_POSITION.mapping(32)];
/// TPDO1 mapping entries.
pub const TPDO1_MAPPING: [u32; 2] = [od::STATUSWORD.mapping(16), od::POSITION_ACTUAL.mapping(32)];
/// TPDO2 mapping entries.
pub const TPDO2_MAPPING: [u32; 2] = [
    od::VELOCITY_ACTUAL.mapping(32),
    od::TORQUE_ACTUAL.mapping(16),
];

/// RPDO1: the command to a drive.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Rpdo1 {
    /// Controlword.
    pub controlword: u16,
    /// Target position, increments.
    pub target_position: i32,
}

/// TPDO1: state and position of a drive.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Tpdo1 {
    /// Statusword.
    pub statusword: u16,
    /// Position actual value, increments.
    pub position: i32,
}

/// TPDO2: velocity and torque of a drive.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Tpdo2 {
    /// Velocity actual value, increments/s.
    pub velocity: i32,
    /// Torque actual value, per mille of rated torque.
    pub torque: i16,
}

fn u16_at(p: &[u8], i: usize) -> u16 {
    u16::from_le_bytes([p[i], p[i + 1]])
}

fn i32_at(p: &[u8], i: usize) -> i32 {
    i32::from_le_bytes([p[i], p[i + 1], p[i + 2], p[i + 3]])
}

impl Rpdo1 {
    /// The 6-byte payload.
    pub fn encode(&self) -> [u8; 6] {
        let c = self.controlword.to_le_bytes();
        let t = self.target_position.to_le_bytes();
        [c[0], c[1], t[0], t[1], t[2], t[3]]
    }

    /// Decodes a payload; `None` unless it has exactly 6 bytes.
    pub fn decode(p: &[u8]) -> Option<Self> {
        (p.len() == 6).then(|| Self {
            controlword: u16_at(p, 0),
            target_position: i32_at(p, 2),
        })
    }
}

impl Tpdo1 {
    /// The 6-byte payload.
    pub fn encode(&self) -> [u8; 6] {
        let s = self.statusword.to_le_bytes();
        let q = self.position.to_le_bytes();
        [s[0], s[1], q[0], q[1], q[2], q[3]]
    }

    /// Decodes a payload; `None` unless it has exactly 6 bytes.
    pub fn decode(p: &[u8]) -> Option<Self> {
        (p.len() == 6).then(|| Self {
            statusword: u16_at(p, 0),
            position: i32_at(p, 2),
        })
    }
}

impl Tpdo2 {
    /// The 6-byte payload.
    pub fn encode(&self) -> [u8; 6] {
        let v = self.velocity.to_le_bytes();
        let t = self.torque.to_le_bytes();
        [v[0], v[1], v[2], v[3], t[0], t[1]]
    }

    /// Decodes a payload; `None` unless it has exactly 6 bytes.
    pub fn decode(p: &[u8]) -> Option<Self> {
        (p.len() == 6).then(|| Self {
            velocity: i32_at(p, 0),
            torque: u16_at(p, 4) as i16,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mapping_entries_are_cia301() {
        assert_eq!(RPDO1_MAPPING, [0x6040_0010, 0x607A_0020]);
        assert_eq!(TPDO1_MAPPING, [0x6041_0010, 0x6064_0020]);
        assert_eq!(TPDO2_MAPPING, [0x606C_0020, 0x6077_0010]);
    }

    #[test]
    fn payloads_round_trip() {
        let r = Rpdo1 {
            controlword: 0x000F,
            target_position: -123_456,
        };
        assert_eq!(Rpdo1::decode(&r.encode()), Some(r));
        let t = Tpdo1 {
            statusword: 0x1637,
            position: 98_765,
        };
        assert_eq!(Tpdo1::decode(&t.encode()), Some(t));
        let t = Tpdo2 {
            velocity: -1_000_000,
            torque: -1500,
        };
        assert_eq!(Tpdo2::decode(&t.encode()), Some(t));
        assert_eq!(Tpdo2::decode(&[0; 5]), None);
    }
}
