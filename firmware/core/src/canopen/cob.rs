//! COB-IDs of the CiA 301 predefined connection set and the classification of received ids.

/// NMT command COB-ID.
pub const NMT: u16 = 0x000;
/// SYNC COB-ID.
pub const SYNC: u16 = 0x080;
/// EMCY base (plus node id).
pub const EMCY_BASE: u16 = 0x080;
/// TPDO1..4 bases (plus node id).
pub const TPDO_BASE: [u16; 4] = [0x180, 0x280, 0x380, 0x480];
/// RPDO1..4 bases (plus node id).
pub const RPDO_BASE: [u16; 4] = [0x200, 0x300, 0x400, 0x500];
/// SDO server -> client (response) base.
pub const SDO_TX_BASE: u16 = 0x580;
/// SDO client -> server (request) base.
pub const SDO_RX_BASE: u16 = 0x600;
/// Heartbeat / boot-up base.
pub const HEARTBEAT_BASE: u16 = 0x700;

/// What a received COB-ID is, with the node id it carries.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Cob {
    /// NMT command.
    Nmt,
    /// SYNC.
    Sync,
    /// Emergency from a node.
    Emcy(u8),
    /// TPDO `n` (0-based) from a node.
    Tpdo(u8, u8),
    /// RPDO `n` (0-based) to a node.
    Rpdo(u8, u8),
    /// SDO response from a node's server.
    SdoTx(u8),
    /// SDO request to a node's server.
    SdoRx(u8),
    /// Heartbeat or boot-up of a node.
    Heartbeat(u8),
}

/// Classifies an 11-bit COB-ID; `None` for ids outside the predefined connection set.
pub fn classify(cob_id: u16) -> Option<Cob> {
    let function = cob_id & 0x780;
    let node = (cob_id & 0x07F) as u8;
    match (function, node) {
        (0x000, 0) => Some(Cob::Nmt),
        (0x080, 0) => Some(Cob::Sync),
        (_, 0) => None,
        (0x080, n) => Some(Cob::Emcy(n)),
        (0x180, n) => Some(Cob::Tpdo(0, n)),
        (0x280, n) => Some(Cob::Tpdo(1, n)),
        (0x380, n) => Some(Cob::Tpdo(2, n)),
        (0x480, n) => Some(Cob::Tpdo(3, n)),
        (0x200, n) => Some(Cob::Rpdo(0, n)),
        (0x300, n) => Some(Cob::Rpdo(1, n)),
        (0x400, n) => Some(Cob::Rpdo(2, n)),
        (0x500, n) => Some(Cob::Rpdo(3, n)),
        (0x580, n) => Some(Cob::SdoTx(n)),
        (0x600, n) => Some(Cob::SdoRx(n)),
        (0x700, n) => Some(Cob::Heartbeat(n)),
        _ => None,
    }
}

impl Cob {
    /// The COB-ID of this object.
    pub fn cob_id(self) -> u16 {
        match self {
            Cob::Nmt => NMT,
            Cob::Sync => SYNC,
            Cob::Emcy(n) => EMCY_BASE + n as u16,
            Cob::Tpdo(k, n) => TPDO_BASE[(k & 3) as usize] + n as u16,
            Cob::Rpdo(k, n) => RPDO_BASE[(k & 3) as usize] + n as u16,
            Cob::SdoTx(n) => SDO_TX_BASE + n as u16,
            Cob::SdoRx(n) => SDO_RX_BASE + n as u16,
            Cob::Heartbeat(n) => HEARTBEAT_BASE + n as u16,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn classify_inverts_cob_id() {
        for n in 1..=127u8 {
            for cob in [
                Cob::Emcy(n),
                Cob::Tpdo(0, n),
                Cob::Tpdo(3, n),
                Cob::Rpdo(0, n),
                Cob::SdoTx(n),
                Cob::SdoRx(n),
                Cob::Heartbeat(n),
            ] {
                assert_eq!(classify(cob.cob_id()), Some(cob));
            }
        }
        assert_eq!(classify(0x000), Some(Cob::Nmt));
        assert_eq!(classify(0x080), Some(Cob::Sync));
        assert_eq!(classify(0x700), None);
        assert_eq!(classify(0x765), Some(Cob::Heartbeat(0x65)));
        assert_eq!(classify(0x7E5), None);
    }
}
