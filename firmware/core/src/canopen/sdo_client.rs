//! SDO client: one expedited transfer in flight per node, matched by address, with a timeout.

use super::od::ObjectAddress;
use super::sdo::{abort, SdoParseError, SdoRequest, SdoResponse};
use crate::can_frame::CanFrame;

/// How long the client waits for a response, microseconds.
pub const SDO_TIMEOUT_US: u64 = 50_000;

/// How a transfer ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SdoOutcome {
    /// The server confirmed a download.
    Written(ObjectAddress),
    /// The server returned `len` bytes, little-endian in a `u32`.
    Read(ObjectAddress, u32, u8),
    /// The server aborted with a code.
    Aborted(ObjectAddress, u32),
    /// No response within [`SDO_TIMEOUT_US`]; the client sent an abort.
    TimedOut(ObjectAddress),
}

/// A response the client could not use.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SdoClientError {
    /// The frame is not a valid SDO response.
    Malformed(SdoParseError),
    /// No transfer is running, or the response names another object.
    Unexpected,
}

#[derive(Clone, Copy, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
struct Pending {
    request: SdoRequest,
    deadline_us: u64,
}

/// The client side of one node's SDO channel.
#[derive(Clone, Copy, Debug, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SdoClient {
    pending: Option<Pending>,
}

impl SdoClient {
    /// A client with no transfer running.
    pub const fn idle() -> Self {
        Self { pending: None }
    }

    /// True when no transfer is running.
    pub fn is_idle(&self) -> bool {
        self.pending.is_none()
    }

    /// Starts a transfer; returns the request frame, or `None` if one is already running.
    pub fn start(&mut self, request: SdoRequest, node_id: u8, now_us: u64) -> Option<CanFrame> {
        if self.pending.is_some() {
            return None;
        }
        self.pending = Some(Pending {
            request,
            deadline_us: now_us.saturating_add(SDO_TIMEOUT_US),
        });
        Some(request.frame(node_id))
    }

    /// Drops a running transfer without a response (e.g. the node was reset).
    pub fn cancel(&mut self) {
        self.pending = None;
    }

    /// Handles a response frame payload from the node's server.
    pub fn on_response(&mut self, payload: &[u8]) -> Result<SdoOutcome, SdoClientError> {
        let response = SdoResponse::parse(payload).map_err(SdoClientError::Malformed)?;
        let pending = self.pending.ok_or(SdoClientError::Unexpected)?;
        let address = pending.request.address();
        if response.address() != address {
            return Err(SdoClientError::Unexpected);
        }
        let outcome = match (pending.request, response) {
            (_, SdoResponse::Abort { code, .. }) => SdoOutcome::Aborted(address, code),
            (SdoRequest::Download { .. }, SdoResponse::DownloadAck { .. }) => {
                SdoOutcome::Written(address)
            }
            (SdoRequest::Upload { .. }, SdoResponse::Upload { data, len, .. }) => {
                SdoOutcome::Read(address, u32::from_le_bytes(data), len)
            }
            _ => return Err(SdoClientError::Unexpected),
        };
        self.pending = None;
        Ok(outcome)
    }

    /// Expires a transfer past its deadline: returns the outcome and the abort frame to send.
    pub fn poll_timeout(&mut self, node_id: u8, now_us: u64) -> Option<(SdoOutcome, CanFrame)> {
        let pending = self.pending?;
        if now_us < pending.deadline_us {
            return None;
        }
        self.pending = None;
        let address = pending.request.address();
        let abort = SdoRequest::Abort {
            address,
            code: abort::TIMEOUT,
        };
        Some((SdoOutcome::TimedOut(address), abort.frame(node_id)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::canopen::od;

    #[test]
    fn matches_responses_to_the_running_request() {
        let mut c = SdoClient::default();
        let f = c
            .start(
                SdoRequest::Upload {
                    address: od::DEVICE_TYPE,
                },
                4,
                0,
            )
            .unwrap();
        assert_eq!(f.cob_id(), 0x604);
        assert!(c
            .start(
                SdoRequest::Upload {
                    address: od::STATUSWORD
                },
                4,
                0
            )
            .is_none());
        let wrong = SdoResponse::DownloadAck {
            address: od::STATUSWORD,
        }
        .frame(4);
        assert_eq!(
            c.on_response(wrong.payload()),
            Err(SdoClientError::Unexpected)
        );
        let ok = SdoResponse::Upload {
            address: od::DEVICE_TYPE,
            data: [0x92, 1, 2, 0],
            len: 4,
        };
        assert_eq!(
            c.on_response(ok.frame(4).payload()),
            Ok(SdoOutcome::Read(od::DEVICE_TYPE, 0x0002_0192, 4))
        );
        assert!(c.is_idle());
        assert_eq!(
            c.on_response(ok.frame(4).payload()),
            Err(SdoClientError::Unexpected)
        );
    }

    #[test]
    fn times_out_with_an_abort_frame() {
        let mut c = SdoClient::default();
        c.start(SdoRequest::download(od::MAX_TORQUE, 1000, 2), 2, 1_000)
            .unwrap();
        assert!(c.poll_timeout(2, 1_000 + SDO_TIMEOUT_US - 1).is_none());
        let (outcome, frame) = c.poll_timeout(2, 1_000 + SDO_TIMEOUT_US).unwrap();
        assert_eq!(outcome, SdoOutcome::TimedOut(od::MAX_TORQUE));
        assert_eq!(frame.payload()[0], 0x80);
        assert_eq!(&frame.payload()[4..], &abort::TIMEOUT.to_le_bytes());
        assert!(c.is_idle());
    }

    #[test]
    fn aborts_are_reported() {
        let mut c = SdoClient::default();
        c.start(SdoRequest::download(od::STATUSWORD, 0, 2), 2, 0)
            .unwrap();
        let r = SdoResponse::Abort {
            address: od::STATUSWORD,
            code: abort::READ_ONLY,
        }
        .frame(2);
        assert_eq!(
            c.on_response(r.payload()),
            Ok(SdoOutcome::Aborted(od::STATUSWORD, abort::READ_ONLY))
        );
    }
}
