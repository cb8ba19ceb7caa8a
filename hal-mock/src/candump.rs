//! CAN traffic logs in the candump format (`candump -l`), readable by can-utils
//! (`canplayer`, `log2asc`), python-can (`can.CanutilsLogReader`) and SavvyCAN:
//! `(1700000000.000000) can0 181#3706A0860100`. Error frames are logged as SocketCAN
//! reports them, with the error flag in the id: `(1700000000.000000) can0 20000080#...`
//! (CAN_ERR_FLAG | CAN_ERR_BUSERROR).

use hexapod_core::can_frame::CanFrame;
use std::fmt::Write;

/// Seconds added to the simulation clock so logs carry plausible Unix timestamps.
pub const EPOCH_S: u64 = 1_700_000_000;

/// One logged frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LogEntry {
    /// When the frame went on the bus, microseconds of simulation time.
    pub time_us: u64,
    /// Bus index (logged as `can<bus>`).
    pub bus: usize,
    /// The frame (for an error frame: id 0, the 8 bytes of SocketCAN's error report).
    pub frame: CanFrame,
    /// An error frame on the wire (a frame destroyed by a bit error).
    pub error_frame: bool,
}

/// SocketCAN's error frame flag and "bus error" class, as candump logs them.
const ERROR_FRAME_ID: u32 = 0x2000_0080;

impl LogEntry {
    /// A data or remote frame.
    pub fn frame(time_us: u64, bus: usize, frame: CanFrame) -> Self {
        Self {
            time_us,
            bus,
            frame,
            error_frame: false,
        }
    }

    /// An error frame.
    pub fn error(time_us: u64, bus: usize) -> Self {
        Self {
            time_us,
            bus,
            frame: CanFrame::new_truncating(0, &[0; 8]),
            error_frame: true,
        }
    }
}

/// Formats one entry as a candump log line (no newline).
pub fn format_line(e: &LogEntry) -> String {
    let t = EPOCH_S * 1_000_000 + e.time_us;
    if e.error_frame {
        return format!(
            "({}.{:06}) can{} {ERROR_FRAME_ID:08X}#0000000000000000",
            t / 1_000_000,
            t % 1_000_000,
            e.bus
        );
    }
    let mut s = format!(
        "({}.{:06}) can{} {:03X}#",
        t / 1_000_000,
        t % 1_000_000,
        e.bus,
        e.frame.cob_id()
    );
    if e.frame.is_rtr() {
        s.push('R');
    } else {
        for b in e.frame.payload() {
            let _ = write!(s, "{b:02X}");
        }
    }
    s
}

/// Why a log line could not be read.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum CandumpError {
    /// The line does not have the `(time) iface id#data` shape.
    #[error("malformed candump line: {0}")]
    Malformed(String),
}

/// Parses one candump log line (standard ids, data and remote frames).
pub fn parse_line(line: &str) -> Result<LogEntry, CandumpError> {
    let bad = || CandumpError::Malformed(line.to_string());
    let mut parts = line.split_whitespace();
    let time = parts.next().ok_or_else(bad)?;
    let iface = parts.next().ok_or_else(bad)?;
    let frame = parts.next().ok_or_else(bad)?;
    let time = time
        .strip_prefix('(')
        .and_then(|t| t.strip_suffix(')'))
        .ok_or_else(bad)?;
    let (sec, usec) = time.split_once('.').ok_or_else(bad)?;
    let sec: u64 = sec.parse().map_err(|_| bad())?;
    let usec: u64 = usec.parse().map_err(|_| bad())?;
    let bus: usize = iface
        .strip_prefix("can")
        .and_then(|b| b.parse().ok())
        .ok_or_else(bad)?;
    let (id, data) = frame.split_once('#').ok_or_else(bad)?;
    let time_us = (sec * 1_000_000 + usec)
        .checked_sub(EPOCH_S * 1_000_000)
        .ok_or_else(bad)?;
    if id.len() == 8 && u32::from_str_radix(id, 16) == Ok(ERROR_FRAME_ID) {
        return Ok(LogEntry::error(time_us, bus));
    }
    if id.len() > 3 {
        return Err(bad());
    }
    let id = u16::from_str_radix(id, 16).map_err(|_| bad())?;
    let frame = if data == "R" {
        let sid = embedded_can::StandardId::new(id).ok_or_else(bad)?;
        <CanFrame as embedded_can::Frame>::new_remote(sid, 0).ok_or_else(bad)?
    } else {
        if data.len() % 2 != 0 || data.len() > 16 {
            return Err(bad());
        }
        let mut bytes = Vec::with_capacity(8);
        for k in (0..data.len()).step_by(2) {
            bytes.push(u8::from_str_radix(&data[k..k + 2], 16).map_err(|_| bad())?);
        }
        CanFrame::data_frame(id, &bytes).ok_or_else(bad)?
    };
    Ok(LogEntry::frame(time_us, bus, frame))
}

/// The whole log, one line per frame, ordered by time (stable across buses).
pub fn format_log(entries: &[LogEntry]) -> String {
    let mut sorted: Vec<&LogEntry> = entries.iter().collect();
    sorted.sort_by_key(|e| e.time_us);
    let mut out = String::with_capacity(sorted.len() * 40);
    for e in sorted {
        out.push_str(&format_line(e));
        out.push('\n');
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn formats_like_candump() {
        let f = CanFrame::data_frame(0x181, &[0x37, 0x06, 0xA0, 0x86, 0x01, 0x00]).unwrap();
        let e = LogEntry::frame(20_000, 0, f);
        assert_eq!(format_line(&e), "(1700000000.020000) can0 181#3706A0860100");
        assert_eq!(parse_line(&format_line(&e)), Ok(e));
        let sync = LogEntry::frame(1, 1, CanFrame::data_frame(0x80, &[]).unwrap());
        assert_eq!(format_line(&sync), "(1700000000.000001) can1 080#");
        assert_eq!(parse_line(&format_line(&sync)), Ok(sync));
        assert!(parse_line("(1.0) can0 181#ABC").is_err());
        assert!(parse_line("garbage").is_err());
        let err = LogEntry::error(5, 0);
        assert_eq!(
            format_line(&err),
            "(1700000000.000005) can0 20000080#0000000000000000"
        );
        assert_eq!(parse_line(&format_line(&err)), Ok(err));
    }
}
