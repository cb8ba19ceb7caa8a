//! A classic CAN 2.0A data frame (11-bit id, up to 8 bytes): what CANopen puts on the wire.
//!
//! The controller core and the mock HAL exchange this one `Copy` type; it implements
//! [`embedded_can::Frame`], so firmware drivers convert to and from their own frame types
//! with [`CanFrame::from_frame`] and the trait's constructors.

use embedded_can::{Frame, Id, StandardId};

/// Largest valid 11-bit identifier.
pub const MAX_STANDARD_ID: u16 = 0x7FF;

/// A standard-id CAN frame with at most 8 data bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CanFrame {
    id: u16,
    len: u8,
    remote: bool,
    data: [u8; 8],
}

impl CanFrame {
    /// A data frame; `None` when the id exceeds 11 bits or the payload exceeds 8 bytes.
    pub fn data_frame(cob_id: u16, payload: &[u8]) -> Option<Self> {
        if cob_id > MAX_STANDARD_ID || payload.len() > 8 {
            return None;
        }
        let mut data = [0; 8];
        data[..payload.len()].copy_from_slice(payload);
        Some(Self {
            id: cob_id,
            len: payload.len() as u8,
            remote: false,
            data,
        })
    }

    /// An infallible constructor for frames built from protocol constants: keeps the low
    /// 11 bits of `cob_id` and at most 8 bytes of `payload`.
    pub fn new_truncating(cob_id: u16, payload: &[u8]) -> Self {
        let len = payload.len().min(8);
        let mut data = [0; 8];
        data[..len].copy_from_slice(&payload[..len]);
        Self {
            id: cob_id & MAX_STANDARD_ID,
            len: len as u8,
            remote: false,
            data,
        }
    }

    /// The 11-bit identifier (the CANopen COB-ID).
    pub const fn cob_id(&self) -> u16 {
        self.id
    }

    /// The data bytes (empty for a remote frame).
    pub fn payload(&self) -> &[u8] {
        if self.remote {
            &[]
        } else {
            &self.data[..self.len as usize]
        }
    }

    /// True for a remote transmission request.
    pub const fn is_rtr(&self) -> bool {
        self.remote
    }

    /// Converts any `embedded_can` frame; `None` for extended ids (CANopen uses 11 bits).
    pub fn from_frame<F: Frame>(frame: &F) -> Option<Self> {
        let Id::Standard(id) = frame.id() else {
            return None;
        };
        if frame.is_remote_frame() {
            Self::new_remote(id, frame.dlc())
        } else {
            Self::data_frame(id.as_raw(), frame.data())
        }
    }
}

impl Frame for CanFrame {
    fn new(id: impl Into<Id>, data: &[u8]) -> Option<Self> {
        match id.into() {
            Id::Standard(id) => Self::data_frame(id.as_raw(), data),
            Id::Extended(_) => None,
        }
    }

    fn new_remote(id: impl Into<Id>, dlc: usize) -> Option<Self> {
        match id.into() {
            Id::Standard(id) if dlc <= 8 => Some(Self {
                id: id.as_raw(),
                len: dlc as u8,
                remote: true,
                data: [0; 8],
            }),
            _ => None,
        }
    }

    fn is_extended(&self) -> bool {
        false
    }

    fn is_remote_frame(&self) -> bool {
        self.remote
    }

    fn id(&self) -> Id {
        // `id` is at most 0x7FF by construction.
        Id::Standard(StandardId::new(self.id).unwrap_or(StandardId::ZERO))
    }

    fn dlc(&self) -> usize {
        self.len as usize
    }

    fn data(&self) -> &[u8] {
        self.payload()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rejects_long_payloads_and_ids() {
        assert!(CanFrame::data_frame(0x800, &[]).is_none());
        assert!(CanFrame::data_frame(0x181, &[0; 9]).is_none());
        let f = CanFrame::data_frame(0x181, &[1, 2, 3]).unwrap();
        assert_eq!(f.payload(), &[1, 2, 3]);
        assert_eq!(f.dlc(), 3);
    }

    #[test]
    fn round_trips_through_the_trait() {
        let f = CanFrame::data_frame(0x605, &[0x40, 0x41, 0x60, 0]).unwrap();
        let g = CanFrame::from_frame(&f).unwrap();
        assert_eq!(f, g);
        let ext = embedded_can::ExtendedId::new(0x1234).unwrap();
        assert!(<CanFrame as Frame>::new(ext, &[]).is_none());
        let r = CanFrame::new_remote(StandardId::new(0x701).unwrap(), 1).unwrap();
        assert!(r.is_rtr() && r.payload().is_empty());
    }
}
