//! A reader of CANopen electronic data sheets (CiA 306 EDS, the INI format) for the drive
//! emulator: which objects exist, their data types, access, PDO mappability, limits and
//! default values.
//!
//! The emulated drive's object dictionary is [`CIA402_SERVO_EDS`]
//! (`hal-mock/eds/cia402_servo.eds`), a generic CiA 402 servo drive written from the
//! profile, not from the master's code; CI also parses it with python-canopen
//! (`hal-mock/tools/check_eds.py`).

use std::collections::BTreeMap;
use std::sync::OnceLock;

/// The EDS of the emulated CiA 402 servo drive.
pub const CIA402_SERVO_EDS: &str = include_str!("../eds/cia402_servo.eds");

/// A CiA 301 basic data type.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DataType {
    /// 0x0001.
    Boolean,
    /// 0x0002.
    Integer8,
    /// 0x0003.
    Integer16,
    /// 0x0004.
    Integer32,
    /// 0x0005.
    Unsigned8,
    /// 0x0006.
    Unsigned16,
    /// 0x0007.
    Unsigned32,
}

impl DataType {
    fn from_code(code: u32) -> Option<Self> {
        Some(match code {
            0x0001 => Self::Boolean,
            0x0002 => Self::Integer8,
            0x0003 => Self::Integer16,
            0x0004 => Self::Integer32,
            0x0005 => Self::Unsigned8,
            0x0006 => Self::Unsigned16,
            0x0007 => Self::Unsigned32,
            _ => return None,
        })
    }

    /// Size in bytes.
    pub fn size(self) -> u8 {
        match self {
            Self::Boolean | Self::Integer8 | Self::Unsigned8 => 1,
            Self::Integer16 | Self::Unsigned16 => 2,
            Self::Integer32 | Self::Unsigned32 => 4,
        }
    }

    /// True for the signed integer types.
    pub fn signed(self) -> bool {
        matches!(self, Self::Integer8 | Self::Integer16 | Self::Integer32)
    }

    /// The raw little-endian value (low `size` bytes of `raw`) as a number.
    pub fn to_i64(self, raw: u32) -> i64 {
        match self {
            Self::Integer8 => raw as u8 as i8 as i64,
            Self::Integer16 => raw as u16 as i16 as i64,
            Self::Integer32 => raw as i32 as i64,
            Self::Boolean | Self::Unsigned8 => (raw & 0xFF) as i64,
            Self::Unsigned16 => (raw & 0xFFFF) as i64,
            Self::Unsigned32 => raw as i64,
        }
    }

    /// The range the type can hold.
    fn range(self) -> (i64, i64) {
        match self {
            Self::Boolean => (0, 1),
            Self::Integer8 => (i8::MIN as i64, i8::MAX as i64),
            Self::Integer16 => (i16::MIN as i64, i16::MAX as i64),
            Self::Integer32 => (i32::MIN as i64, i32::MAX as i64),
            Self::Unsigned8 => (0, u8::MAX as i64),
            Self::Unsigned16 => (0, u16::MAX as i64),
            Self::Unsigned32 => (0, u32::MAX as i64),
        }
    }
}

/// Access type of an entry (CiA 306).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Access {
    /// Read only (may change: process inputs).
    ReadOnly,
    /// Write only.
    WriteOnly,
    /// Read and write.
    ReadWrite,
    /// Read and write, a process input (TPDO side).
    ReadWriteInput,
    /// Read and write, a process output (RPDO side).
    ReadWriteOutput,
    /// Constant.
    Const,
}

impl Access {
    fn parse(s: &str) -> Option<Self> {
        Some(match s.to_ascii_lowercase().as_str() {
            "ro" => Self::ReadOnly,
            "wo" => Self::WriteOnly,
            "rw" => Self::ReadWrite,
            "rwr" => Self::ReadWriteInput,
            "rww" => Self::ReadWriteOutput,
            "const" => Self::Const,
            _ => return None,
        })
    }

    /// SDO reads allowed.
    pub fn readable(self) -> bool {
        self != Self::WriteOnly
    }

    /// SDO writes allowed.
    pub fn writable(self) -> bool {
        matches!(
            self,
            Self::WriteOnly | Self::ReadWrite | Self::ReadWriteInput | Self::ReadWriteOutput
        )
    }
}

/// One entry (index, subindex) of the dictionary.
#[derive(Clone, Debug, PartialEq)]
pub struct Entry {
    /// Index.
    pub index: u16,
    /// Subindex.
    pub sub: u8,
    /// `ParameterName`.
    pub name: String,
    /// `DataType`.
    pub data_type: DataType,
    /// `AccessType`.
    pub access: Access,
    /// `DefaultValue` as written (may contain `$NODEID`).
    pub default: String,
    /// `PDOMapping`.
    pub pdo_mapping: bool,
    /// `LowLimit`.
    pub low: Option<i64>,
    /// `HighLimit`.
    pub high: Option<i64>,
}

impl Entry {
    /// The default value for node `node_id`, raw (two's complement in the low bytes).
    pub fn default_raw(&self, node_id: u8) -> Result<u32, EdsError> {
        parse_value(&self.default, node_id).map_err(|_| EdsError::Value {
            index: self.index,
            sub: self.sub,
            value: self.default.clone(),
        })
    }

    /// True when `raw` is within the type's range and the entry's limits.
    pub fn in_range(&self, raw: u32) -> bool {
        let v = self.data_type.to_i64(raw);
        let (lo, hi) = self.data_type.range();
        v >= self.low.unwrap_or(lo).max(lo) && v <= self.high.unwrap_or(hi).min(hi)
    }

    /// May be mapped into an RPDO (written by the master's process data).
    pub fn rpdo_mappable(&self) -> bool {
        self.pdo_mapping
            && matches!(
                self.access,
                Access::WriteOnly | Access::ReadWrite | Access::ReadWriteOutput
            )
    }

    /// May be mapped into a TPDO (read by the master's process data).
    pub fn tpdo_mappable(&self) -> bool {
        self.pdo_mapping
            && matches!(
                self.access,
                Access::ReadOnly | Access::Const | Access::ReadWrite | Access::ReadWriteInput
            )
    }
}

/// Why an EDS was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EdsError {
    /// A line is neither a section, a key=value pair, a comment nor blank.
    #[error("EDS line {line}: cannot read {text:?}")]
    Syntax {
        /// 1-based line number.
        line: usize,
        /// The line.
        text: String,
    },
    /// An object section lacks a key or has an unknown value.
    #[error("EDS object {index:#06x}:{sub}: {what}")]
    Object {
        /// Index.
        index: u16,
        /// Subindex.
        sub: u8,
        /// What is wrong.
        what: String,
    },
    /// A default value does not parse.
    #[error("EDS object {index:#06x}:{sub}: default value {value:?}")]
    Value {
        /// Index.
        index: u16,
        /// Subindex.
        sub: u8,
        /// The value.
        value: String,
    },
}

/// A parsed data sheet.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Eds {
    /// Entries by (index, subindex).
    pub entries: BTreeMap<(u16, u8), Entry>,
}

/// Parses a number as an EDS writes it: decimal, `0x` hex, negative, `$NODEID+x`; `Err(())`
/// for anything else (the caller names the entry).
#[allow(clippy::result_unit_err)]
pub fn parse_value(s: &str, node_id: u8) -> Result<u32, ()> {
    let s = s.trim();
    if s.is_empty() {
        return Ok(0);
    }
    let upper = s.to_ascii_uppercase();
    if let Some(rest) = upper.strip_prefix("$NODEID") {
        let rest = rest.trim().trim_start_matches('+').trim();
        let base = if rest.is_empty() {
            0
        } else {
            parse_value(rest, node_id)?
        };
        return Ok(base.wrapping_add(node_id as u32));
    }
    if let Some(hex) = upper.strip_prefix("0X") {
        return u32::from_str_radix(hex, 16).map_err(|_| ());
    }
    if let Some(neg) = s.strip_prefix('-') {
        let v: i64 = neg.parse().map_err(|_| ())?;
        return Ok((-v) as i32 as u32);
    }
    s.parse::<u32>().map_err(|_| ())
}

fn parse_number(s: &str) -> Option<i64> {
    let s = s.trim();
    if let Some(hex) = s.strip_prefix("0x").or_else(|| s.strip_prefix("0X")) {
        return i64::from_str_radix(hex, 16).ok();
    }
    s.parse().ok()
}

/// `[1000]` -> (0x1000, None), `[1018sub2]` -> (0x1018, Some(2)); other sections -> None.
fn object_section(name: &str) -> Option<(u16, Option<u8>)> {
    let lower = name.to_ascii_lowercase();
    let (idx, sub) = match lower.split_once("sub") {
        Some((i, s)) => (i, Some(u8::from_str_radix(s, 16).ok()?)),
        None => (lower.as_str(), None),
    };
    if idx.len() != 4 {
        return None;
    }
    Some((u16::from_str_radix(idx, 16).ok()?, sub))
}

impl Eds {
    /// Parses EDS text.
    pub fn parse(text: &str) -> Result<Self, EdsError> {
        let mut sections: Vec<(String, BTreeMap<String, String>)> = Vec::new();
        for (n, raw) in text.lines().enumerate() {
            let line = raw.trim();
            if line.is_empty() || line.starts_with(';') {
                continue;
            }
            if let Some(name) = line.strip_prefix('[').and_then(|l| l.strip_suffix(']')) {
                sections.push((name.trim().to_string(), BTreeMap::new()));
            } else if let (Some((k, v)), Some(last)) = (line.split_once('='), sections.last_mut()) {
                last.1
                    .insert(k.trim().to_ascii_lowercase(), v.trim().to_string());
            } else {
                return Err(EdsError::Syntax {
                    line: n + 1,
                    text: raw.to_string(),
                });
            }
        }
        let mut eds = Eds::default();
        for (name, keys) in &sections {
            let Some((index, sub)) = object_section(name) else {
                continue;
            };
            let object_type = keys
                .get("objecttype")
                .and_then(|v| parse_number(v))
                .unwrap_or(0x7);
            // Arrays and records: their entries are the subN sections.
            if sub.is_none() && object_type != 0x7 {
                continue;
            }
            let sub = sub.unwrap_or(0);
            let bad = |what: &str| EdsError::Object {
                index,
                sub,
                what: what.to_string(),
            };
            let data_type = keys
                .get("datatype")
                .and_then(|v| parse_number(v))
                .and_then(|c| DataType::from_code(c as u32))
                .ok_or_else(|| bad("DataType missing or not a basic type"))?;
            let access = keys
                .get("accesstype")
                .and_then(|v| Access::parse(v))
                .ok_or_else(|| bad("AccessType missing or unknown"))?;
            let entry = Entry {
                index,
                sub,
                name: keys.get("parametername").cloned().unwrap_or_default(),
                data_type,
                access,
                default: keys.get("defaultvalue").cloned().unwrap_or_default(),
                pdo_mapping: keys
                    .get("pdomapping")
                    .is_some_and(|v| parse_number(v) == Some(1)),
                low: keys.get("lowlimit").and_then(|v| parse_number(v)),
                high: keys.get("highlimit").and_then(|v| parse_number(v)),
            };
            entry.default_raw(1)?;
            eds.entries.insert((index, sub), entry);
        }
        Ok(eds)
    }

    /// The entry at (index, subindex).
    pub fn entry(&self, index: u16, sub: u8) -> Option<&Entry> {
        self.entries.get(&(index, sub))
    }

    /// True when some subindex of `index` exists.
    pub fn has_index(&self, index: u16) -> bool {
        self.entries
            .range((index, 0)..=(index, u8::MAX))
            .next()
            .is_some()
    }

    /// The emulated servo drive's data sheet, parsed once.
    pub fn cia402_servo() -> &'static Eds {
        static EDS: OnceLock<Eds> = OnceLock::new();
        EDS.get_or_init(|| Eds::parse(CIA402_SERVO_EDS).expect("hal-mock/eds/cia402_servo.eds"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_servo_eds_defines_the_profile_objects_with_their_types() {
        let eds = Eds::cia402_servo();
        let e = eds.entry(0x6080, 0).unwrap();
        assert_eq!(e.name, "Max motor speed");
        assert_eq!(e.data_type, DataType::Unsigned32);
        assert_eq!(eds.entry(0x6041, 0).unwrap().access, Access::ReadOnly);
        assert!(eds.entry(0x6040, 0).unwrap().rpdo_mappable());
        assert!(!eds.entry(0x6041, 0).unwrap().rpdo_mappable());
        assert!(eds.entry(0x6064, 0).unwrap().tpdo_mappable());
        assert_eq!(
            eds.entry(0x1400, 1).unwrap().default_raw(5),
            Ok(0x8000_0205)
        );
        assert_eq!(
            eds.entry(0x60C2, 2).unwrap().default_raw(5),
            Ok(-3i32 as u32)
        );
        assert_eq!(
            eds.entry(0x1000, 0).unwrap().default_raw(1),
            Ok(0x0002_0192)
        );
        assert!(eds.has_index(0x1018) && eds.entry(0x1018, 0).is_some());
        assert!(eds.entry(0x1018, 5).is_none());
        assert!(!eds.entry(0x6007, 0).unwrap().in_range(7));
    }

    #[test]
    fn syntax_errors_name_the_line() {
        assert!(matches!(
            Eds::parse("[1000]\nnot a pair\n"),
            Err(EdsError::Syntax { line: 2, .. })
        ));
        assert!(matches!(
            Eds::parse("[1000]\nDataType=0x0007\nAccessType=xx\n"),
            Err(EdsError::Object { index: 0x1000, .. })
        ));
    }
}
