//! Network management: NMT commands (COB-ID 0x000) and node states (heartbeat byte).

use super::cob;
use crate::can_frame::CanFrame;

/// An NMT command specifier.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum NmtCommand {
    /// Enter operational (PDOs run).
    Start = 0x01,
    /// Enter stopped.
    Stop = 0x02,
    /// Enter pre-operational (SDO only).
    EnterPreOperational = 0x80,
    /// Reset the application.
    ResetNode = 0x81,
    /// Reset the communication parameters.
    ResetCommunication = 0x82,
}

impl NmtCommand {
    /// Decodes a command specifier.
    pub fn from_byte(b: u8) -> Option<Self> {
        match b {
            0x01 => Some(Self::Start),
            0x02 => Some(Self::Stop),
            0x80 => Some(Self::EnterPreOperational),
            0x81 => Some(Self::ResetNode),
            0x82 => Some(Self::ResetCommunication),
            _ => None,
        }
    }

    /// The NMT frame addressing `node_id` (0 = all nodes).
    pub fn frame(self, node_id: u8) -> CanFrame {
        CanFrame::new_truncating(cob::NMT, &[self as u8, node_id])
    }

    /// Decodes an NMT frame payload into (command, addressed node).
    pub fn parse(payload: &[u8]) -> Option<(Self, u8)> {
        match payload {
            [cs, node] => Some((Self::from_byte(*cs)?, *node)),
            _ => None,
        }
    }
}

/// A node's NMT state as its heartbeat reports it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum NmtState {
    /// Boot-up message (sent once after initialisation).
    BootUp = 0x00,
    /// Stopped.
    Stopped = 0x04,
    /// Operational.
    Operational = 0x05,
    /// Pre-operational.
    PreOperational = 0x7F,
}

impl NmtState {
    /// Decodes a heartbeat payload (the toggle bit 7 is ignored).
    pub fn parse(payload: &[u8]) -> Option<Self> {
        match payload {
            [b] => match b & 0x7F {
                0x00 => Some(Self::BootUp),
                0x04 => Some(Self::Stopped),
                0x05 => Some(Self::Operational),
                0x7F => Some(Self::PreOperational),
                _ => None,
            },
            _ => None,
        }
    }

    /// The heartbeat frame of `node_id` reporting this state.
    pub fn heartbeat_frame(self, node_id: u8) -> CanFrame {
        CanFrame::new_truncating(cob::HEARTBEAT_BASE + (node_id & 0x7F) as u16, &[self as u8])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nmt_round_trip() {
        let f = NmtCommand::Start.frame(5);
        assert_eq!(f.cob_id(), 0);
        assert_eq!(NmtCommand::parse(f.payload()), Some((NmtCommand::Start, 5)));
        assert_eq!(NmtCommand::parse(&[0x03, 1]), None);
        assert_eq!(NmtCommand::parse(&[0x01]), None);
    }

    #[test]
    fn heartbeat_round_trip() {
        let f = NmtState::PreOperational.heartbeat_frame(9);
        assert_eq!(f.cob_id(), 0x709);
        assert_eq!(NmtState::parse(f.payload()), Some(NmtState::PreOperational));
        assert_eq!(NmtState::parse(&[0x85]), Some(NmtState::Operational));
        assert_eq!(NmtState::parse(&[0x10]), None);
    }
}
