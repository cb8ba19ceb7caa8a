//! The emulated drive's object dictionary: storage, sizes, access rights and the checks a
//! real CANopen device makes on SDO writes (read-only objects, lengths, value ranges,
//! PDO mapping rules).

use hexapod_core::canopen::od::{self, ObjectAddress};
use hexapod_core::canopen::sdo::abort;

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

/// Every object of the emulated drive that the SDO server exposes.
#[derive(Clone, Debug)]
pub struct Objects {
    /// 0x1005.
    pub sync_cob_id: u32,
    /// 0x1006, us.
    pub comm_cycle_us: u32,
    /// 0x1016:01.
    pub consumer_heartbeat: u32,
    /// 0x1017, ms.
    pub producer_heartbeat_ms: u16,
    /// 0x1400..0x1403.
    pub rpdo_comm: [PdoComm; 4],
    /// 0x1600..0x1603.
    pub rpdo_map: [PdoMap; 4],
    /// 0x1800..0x1803.
    pub tpdo_comm: [PdoComm; 4],
    /// 0x1A00..0x1A03.
    pub tpdo_map: [PdoMap; 4],
    /// 0x6007.
    pub abort_connection_option: i16,
    /// 0x603F.
    pub error_code: u16,
    /// 0x6040.
    pub controlword: u16,
    /// 0x6041 (refreshed by the drive).
    pub statusword: u16,
    /// 0x605A.
    pub quick_stop_option: i16,
    /// 0x6060.
    pub mode: i8,
    /// 0x6064 (refreshed by the drive).
    pub position: i32,
    /// 0x606C (refreshed by the drive).
    pub velocity: i32,
    /// 0x6072, per mille of rated torque.
    pub max_torque: u16,
    /// 0x6076, mN m.
    pub rated_torque_mnm: u32,
    /// 0x6077 (refreshed by the drive).
    pub torque: i16,
    /// 0x607A.
    pub target_position: i32,
    /// 0x607D:01, 0x607D:02.
    pub position_limits: [i32; 2],
    /// 0x6080, increments/s.
    pub max_motor_speed: u32,
    /// 0x60C2:01, 0x60C2:02.
    pub interpolation_period: (u8, i8),
}

impl Objects {
    /// Power-on defaults: no PDO valid, profile position mode, generous limits.
    pub fn defaults(node_id: u8, rated_torque_mnm: u32) -> Self {
        let n = node_id as u32;
        let comm = |base: u16, transmission| PdoComm {
            cob_id: od::PDO_INVALID | (base as u32 + n),
            transmission,
        };
        Self {
            sync_cob_id: 0x80,
            comm_cycle_us: 0,
            consumer_heartbeat: 0,
            producer_heartbeat_ms: 0,
            rpdo_comm: [0x200, 0x300, 0x400, 0x500].map(|b| comm(b, 255)),
            rpdo_map: [PdoMap::default(); 4],
            // Vendor default: TPDO1 valid with the statusword, event-driven.
            tpdo_comm: [
                PdoComm {
                    cob_id: 0x180 + n,
                    transmission: 255,
                },
                comm(0x280, 255),
                comm(0x380, 255),
                comm(0x480, 255),
            ],
            tpdo_map: [
                PdoMap {
                    count: 1,
                    entries: [od::STATUSWORD.mapping(16), 0, 0, 0],
                },
                PdoMap::default(),
                PdoMap::default(),
                PdoMap::default(),
            ],
            abort_connection_option: 1,
            error_code: 0,
            controlword: 0,
            statusword: 0,
            quick_stop_option: 2,
            mode: 1,
            position: 0,
            velocity: 0,
            max_torque: 3000,
            rated_torque_mnm,
            torque: 0,
            target_position: 0,
            position_limits: [i32::MIN, i32::MAX],
            max_motor_speed: 3_000_000,
            interpolation_period: (1, -3),
        }
    }

    /// Reads an object: (value as little-endian u32, size in bytes).
    pub fn read(&self, a: ObjectAddress) -> Result<(u32, u8), u32> {
        let v = match (a.index, a.sub) {
            (0x1000, 0) => (od::DEVICE_TYPE_CIA402_SERVO, 4),
            (0x1001, 0) => ((self.error_code != 0) as u32, 1),
            (0x1005, 0) => (self.sync_cob_id, 4),
            (0x1006, 0) => (self.comm_cycle_us, 4),
            (0x1016, 0) => (1, 1),
            (0x1016, 1) => (self.consumer_heartbeat, 4),
            (0x1017, 0) => (self.producer_heartbeat_ms as u32, 2),
            (0x1400..=0x1403, s) => comm_read(&self.rpdo_comm[a.index as usize - 0x1400], s)?,
            (0x1800..=0x1803, s) => comm_read(&self.tpdo_comm[a.index as usize - 0x1800], s)?,
            (0x1600..=0x1603, s) => map_read(&self.rpdo_map[a.index as usize - 0x1600], s)?,
            (0x1A00..=0x1A03, s) => map_read(&self.tpdo_map[a.index as usize - 0x1A00], s)?,
            (0x6007, 0) => (self.abort_connection_option as u16 as u32, 2),
            (0x603F, 0) => (self.error_code as u32, 2),
            (0x6040, 0) => (self.controlword as u32, 2),
            (0x6041, 0) => (self.statusword as u32, 2),
            (0x605A, 0) => (self.quick_stop_option as u16 as u32, 2),
            (0x6060, 0) | (0x6061, 0) => (self.mode as u8 as u32, 1),
            (0x6064, 0) => (self.position as u32, 4),
            (0x606C, 0) => (self.velocity as u32, 4),
            (0x6072, 0) => (self.max_torque as u32, 2),
            (0x6076, 0) => (self.rated_torque_mnm, 4),
            (0x6077, 0) => (self.torque as u16 as u32, 2),
            (0x607A, 0) => (self.target_position as u32, 4),
            (0x607D, 0) => (2, 1),
            (0x607D, s @ 1..=2) => (self.position_limits[s as usize - 1] as u32, 4),
            (0x6080, 0) => (self.max_motor_speed, 4),
            (0x60C2, 0) => (2, 1),
            (0x60C2, 1) => (self.interpolation_period.0 as u32, 1),
            (0x60C2, 2) => (self.interpolation_period.1 as u8 as u32, 1),
            // Profile position (bit 0) and cyclic synchronous position (bit 7).
            (0x6502, 0) => (od::SUPPORTS_CSP | 1, 4),
            (0x1000..=0x1FFF | 0x6000..=0x6FFF, _) if self.index_exists(a.index) => {
                return Err(abort::NO_SUBINDEX)
            }
            _ => return Err(abort::NO_OBJECT),
        };
        Ok(v)
    }

    fn index_exists(&self, index: u16) -> bool {
        matches!(
            index,
            0x1000 | 0x1001 | 0x1005 | 0x1006 | 0x1016 | 0x1017 | 0x1400..=0x1403
                | 0x1600..=0x1603 | 0x1800..=0x1803 | 0x1A00..=0x1A03 | 0x6007 | 0x603F
                | 0x6040 | 0x6041 | 0x605A | 0x6060 | 0x6061 | 0x6064 | 0x606C | 0x6072
                | 0x6076 | 0x6077 | 0x607A | 0x607D | 0x6080 | 0x60C2 | 0x6502
        )
    }

    /// Writes an object with the checks of a real device; `Err` is the SDO abort code.
    pub fn write(&mut self, a: ObjectAddress, value: u32, len: u8) -> Result<(), u32> {
        let (_, size) = self.read(a)?;
        if is_read_only(a) {
            return Err(abort::READ_ONLY);
        }
        if len != size {
            return Err(abort::LENGTH_MISMATCH);
        }
        match (a.index, a.sub) {
            (0x1005, 0) => self.sync_cob_id = value,
            (0x1006, 0) => self.comm_cycle_us = value,
            (0x1016, 1) => self.consumer_heartbeat = value,
            (0x1017, 0) => self.producer_heartbeat_ms = value as u16,
            (0x1400..=0x1403, s) => {
                comm_write(&mut self.rpdo_comm[a.index as usize - 0x1400], s, value)?
            }
            (0x1800..=0x1803, s) => {
                comm_write(&mut self.tpdo_comm[a.index as usize - 0x1800], s, value)?
            }
            (0x1600..=0x1603, s) => {
                let i = a.index as usize - 0x1600;
                map_write(
                    &mut self.rpdo_map[i],
                    self.rpdo_comm[i].valid(),
                    s,
                    value,
                    rpdo_mappable,
                )?
            }
            (0x1A00..=0x1A03, s) => {
                let i = a.index as usize - 0x1A00;
                map_write(
                    &mut self.tpdo_map[i],
                    self.tpdo_comm[i].valid(),
                    s,
                    value,
                    tpdo_mappable,
                )?
            }
            (0x6007, 0) => self.abort_connection_option = value as u16 as i16,
            (0x6040, 0) => self.controlword = value as u16,
            (0x605A, 0) => self.quick_stop_option = value as u16 as i16,
            (0x6060, 0) => {
                let mode = value as u8 as i8;
                if mode != od::MODE_CSP && mode != 1 {
                    return Err(abort::VALUE_RANGE);
                }
                self.mode = mode;
            }
            (0x6072, 0) => self.max_torque = value as u16,
            (0x607A, 0) => self.target_position = value as i32,
            (0x607D, s) => self.position_limits[s as usize - 1] = value as i32,
            (0x6080, 0) => self.max_motor_speed = value,
            (0x60C2, 1) => self.interpolation_period.0 = value as u8,
            (0x60C2, 2) => self.interpolation_period.1 = value as u8 as i8,
            _ => return Err(abort::UNSUPPORTED_ACCESS),
        }
        Ok(())
    }

    /// The value of a mappable object, as the low `bits` of a u64.
    pub fn mapped_value(&self, entry: u32) -> Option<(u64, u8)> {
        let (a, bits) = ObjectAddress::from_mapping(entry);
        let (v, size) = self.read(a).ok()?;
        (size * 8 == bits).then_some((v as u64, bits))
    }
}

fn is_read_only(a: ObjectAddress) -> bool {
    matches!(
        (a.index, a.sub),
        (0x1000, _)
            | (0x1001, _)
            | (0x1016, 0)
            | (0x603F, _)
            | (0x6041, _)
            | (0x6061, _)
            | (0x6064, _)
            | (0x606C, _)
            | (0x6076, _)
            | (0x6077, _)
            | (0x607D, 0)
            | (0x60C2, 0)
            | (0x6502, _)
    ) || (matches!(a.index, 0x1400..=0x1403 | 0x1800..=0x1803) && a.sub == 0)
}

fn comm_read(c: &PdoComm, sub: u8) -> Result<(u32, u8), u32> {
    match sub {
        0 => Ok((2, 1)),
        1 => Ok((c.cob_id, 4)),
        2 => Ok((c.transmission as u32, 1)),
        _ => Err(abort::NO_SUBINDEX),
    }
}

fn comm_write(c: &mut PdoComm, sub: u8, value: u32) -> Result<(), u32> {
    match sub {
        1 => {
            // CiA 301: the COB-ID may change only while the PDO is invalid.
            let changes_id = (value & 0x7FF) != (c.cob_id & 0x7FF);
            if c.valid() && value & od::PDO_INVALID == 0 && changes_id {
                return Err(abort::DEVICE_STATE);
            }
            c.cob_id = value;
        }
        2 => {
            let t = value as u8;
            if (241..=253).contains(&t) {
                return Err(abort::VALUE_RANGE);
            }
            c.transmission = t;
        }
        _ => return Err(abort::NO_SUBINDEX),
    }
    Ok(())
}

fn map_read(m: &PdoMap, sub: u8) -> Result<(u32, u8), u32> {
    match sub {
        0 => Ok((m.count as u32, 1)),
        1..=4 => Ok((m.entries[sub as usize - 1], 4)),
        _ => Err(abort::NO_SUBINDEX),
    }
}

fn map_write(
    m: &mut PdoMap,
    pdo_valid: bool,
    sub: u8,
    value: u32,
    mappable: fn(ObjectAddress, u8) -> bool,
) -> Result<(), u32> {
    if pdo_valid {
        return Err(abort::DEVICE_STATE);
    }
    match sub {
        0 => {
            let count = value as u8;
            if count > 4 {
                return Err(abort::VALUE_RANGE);
            }
            let mut bits = 0u32;
            for &e in &m.entries[..count as usize] {
                let (a, b) = ObjectAddress::from_mapping(e);
                if !mappable(a, b) {
                    return Err(abort::NOT_MAPPABLE);
                }
                bits += b as u32;
            }
            if bits > 64 {
                return Err(abort::PDO_TOO_LONG);
            }
            m.count = count;
        }
        1..=4 => {
            if m.count != 0 {
                return Err(abort::DEVICE_STATE);
            }
            let (a, b) = ObjectAddress::from_mapping(value);
            if !mappable(a, b) {
                return Err(abort::NOT_MAPPABLE);
            }
            m.entries[sub as usize - 1] = value;
        }
        _ => return Err(abort::NO_SUBINDEX),
    }
    Ok(())
}

fn rpdo_mappable(a: ObjectAddress, bits: u8) -> bool {
    a == od::CONTROLWORD && bits == 16 || a == od::TARGET_POSITION && bits == 32
}

fn tpdo_mappable(a: ObjectAddress, bits: u8) -> bool {
    matches!(
        (a.index, a.sub, bits),
        (0x6041, 0, 16)
            | (0x6064, 0, 32)
            | (0x606C, 0, 32)
            | (0x6077, 0, 16)
            | (0x6061, 0, 8)
            | (0x603F, 0, 16)
    )
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
        assert_eq!(o.tpdo_map[0].active(), &[0x6064_0020, 0x606C_0020]);
    }
}
