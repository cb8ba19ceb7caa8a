//! The emulated drive's object dictionary: which objects exist, their data types, access
//! rights, PDO mappability, limits and power-on values all come from the drive's EDS
//! ([`crate::eds::Eds::cia402_servo`]); this file adds the checks a real CANopen device
//! makes beyond the data sheet (CiA 301 PDO rules, supported modes of operation).

use std::collections::BTreeMap;

use hexapod_core::canopen::od::{self, ObjectAddress};
use hexapod_core::canopen::sdo::abort;

use crate::eds::Eds;

/// Communication parameters of one PDO.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PdoComm {
    /// COB-ID entry (bit 31 = invalid).
    pub cob_id: u32,
    /// Transmission type.
    pub transmission: u8,
}

impl PdoComm {
    /// True when the PDO is enabled.
    pub fn valid(&self) -> bool {
        self.cob_id & od::PDO_INVALID == 0
    }
}

/// Mapping parameters of one PDO.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PdoMap {
    /// Number of mapped objects.
    pub count: u8,
    /// Mapping entries (`index << 16 | sub << 8 | bits`).
    pub entries: [u32; 4],
}

impl PdoMap {
    /// The mapped entries.
    pub fn active(&self) -> &[u32] {
        &self.entries[..(self.count as usize).min(4)]
    }
}

/// Which side of the process data a PDO is on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum PdoKind {
    Receive,
    Transmit,
}

/// The object dictionary of one drive.
#[derive(Clone, Debug)]
pub struct Objects {
    eds: &'static Eds,
    node_id: u8,
    values: BTreeMap<(u16, u8), u32>,
}

/// An entry's default value, cut to its size.
fn masked(e: &crate::eds::Entry, node_id: u8) -> u32 {
    let raw = e.default_raw(node_id).unwrap_or(0);
    match e.data_type.size() {
        1 => raw & 0xFF,
        2 => raw & 0xFFFF,
        _ => raw,
    }
}

fn key(a: ObjectAddress) -> (u16, u8) {
    (a.index, a.sub)
}

impl Objects {
    /// Power-on values from the EDS; 0x6076 (motor rated torque) is this drive's rating.
    pub fn defaults(node_id: u8, rated_torque_mnm: u32) -> Self {
        let eds = Eds::cia402_servo();
        let values = eds
            .entries
            .iter()
            .map(|(&k, e)| (k, masked(e, node_id)))
            .collect();
        let mut o = Self {
            eds,
            node_id,
            values,
        };
        o.set_internal(od::MOTOR_RATED_TORQUE, rated_torque_mnm);
        o
    }

    /// NMT reset communication: the communication area (0x1000-0x1FFF) back to its
    /// power-on values.
    pub fn reset_communication(&mut self) {
        for (&(index, sub), e) in self.eds.entries.range((0x1000, 0)..=(0x1FFF, 0xFF)) {
            self.values.insert((index, sub), masked(e, self.node_id));
        }
    }

    /// The raw value of an object (0 if it does not exist).
    pub fn get(&self, a: ObjectAddress) -> u32 {
        self.values.get(&key(a)).copied().unwrap_or(0)
    }

    /// The device updates one of its own objects (process inputs, error code); no checks.
    pub fn set_internal(&mut self, a: ObjectAddress, value: u32) {
        if let Some(v) = self.values.get_mut(&key(a)) {
            *v = value;
        }
    }

    /// 0x6040.
    pub fn controlword(&self) -> u16 {
        self.get(od::CONTROLWORD) as u16
    }
    /// 0x6060.
    pub fn mode(&self) -> i8 {
        self.get(od::MODES_OF_OPERATION) as u8 as i8
    }
    /// 0x605A.
    pub fn quick_stop_option(&self) -> i16 {
        self.get(od::QUICK_STOP_OPTION) as u16 as i16
    }
    /// 0x6007.
    pub fn abort_connection_option(&self) -> i16 {
        self.get(od::ABORT_CONNECTION_OPTION) as u16 as i16
    }
    /// 0x1017, ms.
    pub fn producer_heartbeat_ms(&self) -> u16 {
        self.get(od::PRODUCER_HEARTBEAT) as u16
    }
    /// 0x1016:01 (node id << 16 | time in ms).
    pub fn consumer_heartbeat(&self) -> u32 {
        self.get(od::CONSUMER_HEARTBEAT_1)
    }
    /// 0x1005.
    pub fn sync_cob_id(&self) -> u32 {
        self.get(od::SYNC_COB_ID)
    }
    /// 0x607D:01 and :02, position units.
    pub fn position_limits(&self) -> [i32; 2] {
        [
            self.get(od::SOFTWARE_POSITION_LIMIT_MIN) as i32,
            self.get(od::SOFTWARE_POSITION_LIMIT_MAX) as i32,
        ]
    }
    /// 0x607A, position units.
    pub fn target_position(&self) -> i32 {
        self.get(od::TARGET_POSITION) as i32
    }
    /// 0x6072, per mille of rated torque.
    pub fn max_torque(&self) -> u16 {
        self.get(od::MAX_TORQUE) as u16
    }
    /// 0x6076, mN m.
    pub fn rated_torque_mnm(&self) -> u32 {
        self.get(od::MOTOR_RATED_TORQUE)
    }

    /// Communication parameters of RPDO `k` (0-based).
    pub fn rpdo_comm(&self, k: usize) -> PdoComm {
        self.comm(0x1400 + k as u16)
    }
    /// Communication parameters of TPDO `k` (0-based).
    pub fn tpdo_comm(&self, k: usize) -> PdoComm {
        self.comm(0x1800 + k as u16)
    }
    /// Mapping of RPDO `k` (0-based).
    pub fn rpdo_map(&self, k: usize) -> PdoMap {
        self.map(0x1600 + k as u16)
    }
    /// Mapping of TPDO `k` (0-based).
    pub fn tpdo_map(&self, k: usize) -> PdoMap {
        self.map(0x1A00 + k as u16)
    }

    fn comm(&self, index: u16) -> PdoComm {
        PdoComm {
            cob_id: self.get(ObjectAddress::new(index, 1)),
            transmission: self.get(ObjectAddress::new(index, 2)) as u8,
        }
    }

    fn map(&self, index: u16) -> PdoMap {
        let mut m = PdoMap {
            count: self.get(ObjectAddress::new(index, 0)) as u8,
            entries: [0; 4],
        };
        for s in 0..4 {
            m.entries[s] = self.get(ObjectAddress::new(index, s as u8 + 1));
        }
        m
    }

    /// Reads an object by SDO: (value as little-endian u32, size in bytes).
    pub fn read(&self, a: ObjectAddress) -> Result<(u32, u8), u32> {
        let Some(e) = self.eds.entry(a.index, a.sub) else {
            return Err(if self.eds.has_index(a.index) {
                abort::NO_SUBINDEX
            } else {
                abort::NO_OBJECT
            });
        };
        if !e.access.readable() {
            return Err(abort::UNSUPPORTED_ACCESS);
        }
        Ok((self.get(a), e.data_type.size()))
    }

    /// Writes an object by SDO with the checks of a real device; `Err` is the abort code.
    pub fn write(&mut self, a: ObjectAddress, value: u32, len: u8) -> Result<(), u32> {
        let Some(e) = self.eds.entry(a.index, a.sub) else {
            return Err(if self.eds.has_index(a.index) {
                abort::NO_SUBINDEX
            } else {
                abort::NO_OBJECT
            });
        };
        if !e.access.writable() {
            return Err(abort::READ_ONLY);
        }
        if len != e.data_type.size() {
            return Err(abort::LENGTH_MISMATCH);
        }
        let size_bits = 8 * e.data_type.size() as u32;
        let value = if size_bits < 32 {
            value & ((1u32 << size_bits) - 1)
        } else {
            value
        };
        if !e.in_range(value) {
            return Err(abort::VALUE_RANGE);
        }
        match a.index {
            0x1400..=0x1403 | 0x1800..=0x1803 => self.comm_write(a, value)?,
            0x1600..=0x1603 => self.map_write(a, value, PdoKind::Receive)?,
            0x1A00..=0x1A03 => self.map_write(a, value, PdoKind::Transmit)?,
            _ if a == od::MODES_OF_OPERATION => {
                let mode = value as u8 as i8;
                let supported = self.get(od::SUPPORTED_DRIVE_MODES);
                if !(1..=32).contains(&mode) || supported & (1 << (mode - 1)) == 0 {
                    return Err(abort::VALUE_RANGE);
                }
            }
            _ => {}
        }
        self.values.insert(key(a), value);
        Ok(())
    }

    /// An RPDO writes a mapped object (mappability was checked when it was mapped).
    pub fn write_mapped(&mut self, entry: u32, value: u32) {
        let (a, bits) = ObjectAddress::from_mapping(entry);
        if let Some(e) = self.eds.entry(a.index, a.sub) {
            if e.rpdo_mappable() && bits as u32 == 8 * e.data_type.size() as u32 {
                self.values.insert(key(a), value);
            }
        }
    }

    /// The value of a mappable object, as the low `bits` of a u64.
    pub fn mapped_value(&self, entry: u32) -> Option<(u64, u8)> {
        let (a, bits) = ObjectAddress::from_mapping(entry);
        let (v, size) = self.read(a).ok()?;
        (size * 8 == bits).then_some((v as u64, bits))
    }

    fn comm_write(&mut self, a: ObjectAddress, value: u32) -> Result<(), u32> {
        let c = self.comm(a.index);
        match a.sub {
            1 => {
                // CiA 301: the COB-ID may change only while the PDO is invalid.
                let changes_id = (value & 0x7FF) != (c.cob_id & 0x7FF);
                if c.valid() && value & od::PDO_INVALID == 0 && changes_id {
                    return Err(abort::DEVICE_STATE);
                }
            }
            2 if (241..=253).contains(&(value as u8)) => {
                return Err(abort::VALUE_RANGE);
            }
            _ => {}
        }
        Ok(())
    }

    fn mappable(&self, entry: u32, kind: PdoKind) -> bool {
        let (a, bits) = ObjectAddress::from_mapping(entry);
        self.eds.entry(a.index, a.sub).is_some_and(|e| {
            let side = match kind {
                PdoKind::Receive => e.rpdo_mappable(),
                PdoKind::Transmit => e.tpdo_mappable(),
            };
            side && bits as u32 == 8 * e.data_type.size() as u32
        })
    }

    fn map_write(&mut self, a: ObjectAddress, value: u32, kind: PdoKind) -> Result<(), u32> {
        let comm_index = match kind {
            PdoKind::Receive => a.index - 0x1600 + 0x1400,
            PdoKind::Transmit => a.index - 0x1A00 + 0x1800,
        };
        if self.comm(comm_index).valid() {
            return Err(abort::DEVICE_STATE);
        }
        let m = self.map(a.index);
        match a.sub {
            0 => {
                let count = value as u8;
                let mut bits = 0u32;
                for &e in &m.entries[..count.min(4) as usize] {
                    if !self.mappable(e, kind) {
                        return Err(abort::NOT_MAPPABLE);
                    }
                    bits += e & 0xFF;
                }
                if bits > 64 {
                    return Err(abort::PDO_TOO_LONG);
                }
            }
            _ => {
                if m.count != 0 {
                    return Err(abort::DEVICE_STATE);
                }
                if !self.mappable(value, kind) {
                    return Err(abort::NOT_MAPPABLE);
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn write_checks_like_a_device() {
        let mut o = Objects::defaults(3, 22_500);
        assert_eq!(o.write(od::STATUSWORD, 0, 2), Err(abort::READ_ONLY));
        assert_eq!(o.write(od::CONTROLWORD, 0, 4), Err(abort::LENGTH_MISMATCH));
        assert_eq!(
            o.write(ObjectAddress::new(0x2000, 0), 0, 4),
            Err(abort::NO_OBJECT)
        );
        assert_eq!(
            o.write(ObjectAddress::new(0x6040, 3), 0, 2),
            Err(abort::NO_SUBINDEX)
        );
        assert_eq!(
            o.write(od::MODES_OF_OPERATION, 3, 1),
            Err(abort::VALUE_RANGE)
        );
        assert_eq!(o.write(od::MODES_OF_OPERATION, 8, 1), Ok(()));
        // Outside the EDS's limits (0x6007: 0..=3).
        assert_eq!(
            o.write(od::ABORT_CONNECTION_OPTION, 9, 2),
            Err(abort::VALUE_RANGE)
        );
        // TPDO1 is valid by default: its mapping is locked.
        assert_eq!(o.write(od::tpdo_map(0, 0), 0, 1), Err(abort::DEVICE_STATE));
        o.write(od::tpdo_comm(0, 1), od::PDO_INVALID | 0x183, 4)
            .unwrap();
        o.write(od::tpdo_map(0, 0), 0, 1).unwrap();
        assert_eq!(
            o.write(od::tpdo_map(0, 1), 0x6040_0010, 4),
            Err(abort::NOT_MAPPABLE)
        );
        o.write(od::tpdo_map(0, 1), 0x6064_0020, 4).unwrap();
        o.write(od::tpdo_map(0, 2), 0x606C_0020, 4).unwrap();
        o.write(od::tpdo_map(0, 3), 0x6064_0020, 4).unwrap();
        assert_eq!(o.write(od::tpdo_map(0, 0), 3, 1), Err(abort::PDO_TOO_LONG));
        o.write(od::tpdo_map(0, 0), 2, 1).unwrap();
        assert_eq!(o.tpdo_map(0).active(), &[0x6064_0020, 0x606C_0020]);
        // The statusword is not an RPDO object.
        assert!(!o.mappable(0x6041_0010, PdoKind::Receive));
        assert!(o.mappable(0x607A_0020, PdoKind::Receive));
    }

    #[test]
    fn reset_communication_keeps_the_profile_area() {
        let mut o = Objects::defaults(3, 22_500);
        o.write(od::PRODUCER_HEARTBEAT, 100, 2).unwrap();
        o.write(od::MODES_OF_OPERATION, 8, 1).unwrap();
        o.reset_communication();
        assert_eq!(o.producer_heartbeat_ms(), 0);
        assert_eq!(o.mode(), 8);
        assert_eq!(o.rated_torque_mnm(), 22_500);
    }
}
