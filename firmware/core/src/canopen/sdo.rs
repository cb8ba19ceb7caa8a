//! Expedited SDO transfers (CiA 301): request and response frames, abort codes.
//!
//! Only expedited transfers (up to 4 data bytes) are needed for drive configuration; a
//! segmented or block transfer initiation is answered with an abort by the server and
//! reported as an error by the client.

use super::cob;
use super::od::ObjectAddress;
use crate::can_frame::CanFrame;

/// SDO abort codes (CiA 301 table 22) used here.
pub mod abort {
    /// Toggle bit not alternated.
    pub const TOGGLE_BIT: u32 = 0x0503_0000;
    /// SDO protocol timed out.
    pub const TIMEOUT: u32 = 0x0504_0000;
    /// Client/server command specifier not valid or unknown.
    pub const INVALID_COMMAND: u32 = 0x0504_0001;
    /// Unsupported access to an object.
    pub const UNSUPPORTED_ACCESS: u32 = 0x0601_0000;
    /// Attempt to write a read-only object.
    pub const READ_ONLY: u32 = 0x0601_0002;
    /// Object does not exist in the object dictionary.
    pub const NO_OBJECT: u32 = 0x0602_0000;
    /// Object cannot be mapped to the PDO.
    pub const NOT_MAPPABLE: u32 = 0x0604_0041;
    /// The number and length of the objects to be mapped would exceed the PDO length.
    pub const PDO_TOO_LONG: u32 = 0x0604_0042;
    /// Data type does not match, length of service parameter does not match.
    pub const LENGTH_MISMATCH: u32 = 0x0607_0010;
    /// Subindex does not exist.
    pub const NO_SUBINDEX: u32 = 0x0609_0011;
    /// Value range of parameter exceeded.
    pub const VALUE_RANGE: u32 = 0x0609_0030;
    /// General error.
    pub const GENERAL: u32 = 0x0800_0000;
    /// Data cannot be transferred or stored because of the present device state.
    pub const DEVICE_STATE: u32 = 0x0800_0022;
}

/// A client -> server SDO request (COB-ID 0x600 + node).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SdoRequest {
    /// Expedited download (write) of 1..=4 bytes, little-endian in `data`.
    Download {
        /// Target object.
        address: ObjectAddress,
        /// Value bytes, little-endian, `len` of them used.
        data: [u8; 4],
        /// Number of bytes (1..=4).
        len: u8,
    },
    /// Upload (read) initiation.
    Upload {
        /// Object to read.
        address: ObjectAddress,
    },
    /// Abort of the running transfer.
    Abort {
        /// Object concerned.
        address: ObjectAddress,
        /// Abort code.
        code: u32,
    },
}

/// A server -> client SDO response (COB-ID 0x580 + node).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SdoResponse {
    /// Download confirmed.
    DownloadAck {
        /// Object written.
        address: ObjectAddress,
    },
    /// Expedited upload response with 1..=4 bytes.
    Upload {
        /// Object read.
        address: ObjectAddress,
        /// Value bytes, little-endian.
        data: [u8; 4],
        /// Number of valid bytes.
        len: u8,
    },
    /// Transfer aborted by the server.
    Abort {
        /// Object concerned.
        address: ObjectAddress,
        /// Abort code.
        code: u32,
    },
}

/// Why an SDO frame could not be decoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SdoParseError {
    /// Not 8 bytes (CiA 301 SDO frames always carry 8).
    BadLength,
    /// Unknown or unsupported command specifier (e.g. segmented transfer).
    UnsupportedCommand(u8),
}

fn address_of(p: &[u8]) -> ObjectAddress {
    ObjectAddress::new(u16::from_le_bytes([p[1], p[2]]), p[3])
}

fn data_of(p: &[u8]) -> [u8; 4] {
    [p[4], p[5], p[6], p[7]]
}

fn frame(cob_id: u16, cs: u8, address: ObjectAddress, data: [u8; 4]) -> CanFrame {
    let i = address.index.to_le_bytes();
    CanFrame::new_truncating(
        cob_id,
        &[
            cs,
            i[0],
            i[1],
            address.sub,
            data[0],
            data[1],
            data[2],
            data[3],
        ],
    )
}

/// Expedited-size command bits: `n` (unused bytes) in bits 3..2, e = 1, s = 1.
fn expedited_bits(len: u8) -> u8 {
    ((4 - len.clamp(1, 4)) << 2) | 0b11
}

fn expedited_len(cs: u8) -> Option<u8> {
    match cs & 0b11 {
        0b11 => Some(4 - ((cs >> 2) & 0b11)),
        // e = 1, s = 0: size not indicated, all 4 bytes.
        0b10 => Some(4),
        _ => None,
    }
}

impl SdoRequest {
    /// A download of a `u32`/`i32` (4 bytes), `u16`/`i16` (2) or `u8`/`i8` (1) value.
    pub fn download(address: ObjectAddress, value: u32, len: u8) -> Self {
        let len = len.clamp(1, 4);
        Self::Download {
            address,
            data: mask(value.to_le_bytes(), len),
            len,
        }
    }

    /// The request frame to `node_id`'s SDO server.
    pub fn frame(&self, node_id: u8) -> CanFrame {
        let cob_id = cob::SDO_RX_BASE + node_id as u16;
        match *self {
            Self::Download { address, data, len } => {
                frame(cob_id, 0x20 | expedited_bits(len), address, mask(data, len))
            }
            Self::Upload { address } => frame(cob_id, 0x40, address, [0; 4]),
            Self::Abort { address, code } => frame(cob_id, 0x80, address, code.to_le_bytes()),
        }
    }

    /// Decodes a request payload (server side).
    pub fn parse(p: &[u8]) -> Result<Self, SdoParseError> {
        if p.len() != 8 {
            return Err(SdoParseError::BadLength);
        }
        let cs = p[0];
        let address = address_of(p);
        match cs >> 5 {
            1 => match expedited_len(cs) {
                Some(len) => Ok(Self::Download {
                    address,
                    data: mask(data_of(p), len),
                    len,
                }),
                None => Err(SdoParseError::UnsupportedCommand(cs)),
            },
            2 => Ok(Self::Upload { address }),
            4 => Ok(Self::Abort {
                address,
                code: u32::from_le_bytes(data_of(p)),
            }),
            _ => Err(SdoParseError::UnsupportedCommand(cs)),
        }
    }

    /// The object the request concerns.
    pub fn address(&self) -> ObjectAddress {
        match *self {
            Self::Download { address, .. }
            | Self::Upload { address }
            | Self::Abort { address, .. } => address,
        }
    }
}

impl SdoResponse {
    /// The response frame from `node_id`'s SDO server.
    pub fn frame(&self, node_id: u8) -> CanFrame {
        let cob_id = cob::SDO_TX_BASE + node_id as u16;
        match *self {
            Self::DownloadAck { address } => frame(cob_id, 0x60, address, [0; 4]),
            Self::Upload { address, data, len } => {
                frame(cob_id, 0x40 | expedited_bits(len), address, mask(data, len))
            }
            Self::Abort { address, code } => frame(cob_id, 0x80, address, code.to_le_bytes()),
        }
    }

    /// Decodes a response payload (client side).
    pub fn parse(p: &[u8]) -> Result<Self, SdoParseError> {
        if p.len() != 8 {
            return Err(SdoParseError::BadLength);
        }
        let cs = p[0];
        let address = address_of(p);
        match cs >> 5 {
            3 => Ok(Self::DownloadAck { address }),
            2 => match expedited_len(cs) {
                Some(len) => Ok(Self::Upload {
                    address,
                    data: mask(data_of(p), len),
                    len,
                }),
                None => Err(SdoParseError::UnsupportedCommand(cs)),
            },
            4 => Ok(Self::Abort {
                address,
                code: u32::from_le_bytes(data_of(p)),
            }),
            _ => Err(SdoParseError::UnsupportedCommand(cs)),
        }
    }

    /// The object the response concerns.
    pub fn address(&self) -> ObjectAddress {
        match *self {
            Self::DownloadAck { address }
            | Self::Upload { address, .. }
            | Self::Abort { address, .. } => address,
        }
    }
}

/// Zeroes the bytes past `len`.
fn mask(mut data: [u8; 4], len: u8) -> [u8; 4] {
    for b in data.iter_mut().skip(len as usize) {
        *b = 0;
    }
    data
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::canopen::od;

    #[test]
    fn download_frame_matches_cia301() {
        let f = SdoRequest::download(od::PRODUCER_HEARTBEAT, 100, 2).frame(3);
        assert_eq!(f.cob_id(), 0x603);
        assert_eq!(f.payload(), &[0x2B, 0x17, 0x10, 0x00, 100, 0, 0, 0]);
        let f = SdoRequest::download(od::MODES_OF_OPERATION, 8, 1).frame(3);
        assert_eq!(f.payload()[0], 0x2F);
        let f = SdoRequest::download(od::COMM_CYCLE_PERIOD, 20_000, 4).frame(3);
        assert_eq!(f.payload()[0], 0x23);
    }

    #[test]
    fn requests_and_responses_round_trip() {
        let a = od::TARGET_POSITION;
        for req in [
            SdoRequest::download(a, 0xDEAD_BEEF, 4),
            SdoRequest::download(a, 0x1234, 2),
            SdoRequest::download(a, 0x12, 1),
            SdoRequest::Upload { address: a },
            SdoRequest::Abort {
                address: a,
                code: abort::NO_OBJECT,
            },
        ] {
            assert_eq!(SdoRequest::parse(req.frame(1).payload()), Ok(req));
        }
        for resp in [
            SdoResponse::DownloadAck { address: a },
            SdoResponse::Upload {
                address: a,
                data: [1, 2, 3, 0],
                len: 3,
            },
            SdoResponse::Abort {
                address: a,
                code: abort::READ_ONLY,
            },
        ] {
            assert_eq!(SdoResponse::parse(resp.frame(1).payload()), Ok(resp));
        }
    }

    #[test]
    fn segmented_and_short_frames_are_rejected() {
        // Upload response without the expedited bit: segmented transfer.
        assert_eq!(
            SdoResponse::parse(&[0x41, 0, 0x10, 0, 20, 0, 0, 0]),
            Err(SdoParseError::UnsupportedCommand(0x41))
        );
        assert_eq!(
            SdoRequest::parse(&[0x40, 0, 0x10]),
            Err(SdoParseError::BadLength)
        );
        assert_eq!(
            SdoRequest::parse(&[0xC0, 0, 0x10, 0, 0, 0, 0, 0]),
            Err(SdoParseError::UnsupportedCommand(0xC0))
        );
    }
}
