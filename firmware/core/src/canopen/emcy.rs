//! Emergency messages (COB-ID 0x080 + node): error code, error register, vendor bytes.

use super::cob;
use crate::can_frame::CanFrame;

/// Error code 0x0000: error reset / no error (sent when a fault clears).
pub const ERROR_RESET: u16 = 0x0000;
/// Continuous over-current.
pub const OVER_CURRENT: u16 = 0x2310;
/// DC link over-voltage.
pub const DC_LINK_OVER_VOLTAGE: u16 = 0x3210;
/// Excess temperature of the drive.
pub const DRIVE_OVER_TEMPERATURE: u16 = 0x4310;
/// Life guard or heartbeat consumer error.
pub const HEARTBEAT_ERROR: u16 = 0x8130;
/// Following error.
pub const FOLLOWING_ERROR: u16 = 0x8611;

/// An emergency message.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Emcy {
    /// CiA 301/402 error code.
    pub error_code: u16,
    /// Error register (0x1001).
    pub error_register: u8,
    /// Manufacturer-specific bytes.
    pub vendor: [u8; 5],
}

impl Emcy {
    /// Decodes an EMCY payload; `None` unless it has exactly 8 bytes.
    pub fn parse(p: &[u8]) -> Option<Self> {
        if p.len() != 8 {
            return None;
        }
        Some(Self {
            error_code: u16::from_le_bytes([p[0], p[1]]),
            error_register: p[2],
            vendor: [p[3], p[4], p[5], p[6], p[7]],
        })
    }

    /// The EMCY frame of `node_id`.
    pub fn frame(&self, node_id: u8) -> CanFrame {
        let c = self.error_code.to_le_bytes();
        let v = self.vendor;
        CanFrame::new_truncating(
            cob::EMCY_BASE + (node_id & 0x7F) as u16,
            &[
                c[0],
                c[1],
                self.error_register,
                v[0],
                v[1],
                v[2],
                v[3],
                v[4],
            ],
        )
    }

    /// True for the "error reset / no error" message.
    pub fn is_reset(&self) -> bool {
        self.error_code == ERROR_RESET
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn emcy_round_trip() {
        let e = Emcy {
            error_code: OVER_CURRENT,
            error_register: 0x03,
            vendor: [1, 2, 3, 4, 5],
        };
        let f = e.frame(12);
        assert_eq!(f.cob_id(), 0x08C);
        assert_eq!(Emcy::parse(f.payload()), Some(e));
        assert_eq!(Emcy::parse(&[0; 7]), None);
    }
}
