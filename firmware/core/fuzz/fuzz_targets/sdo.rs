//! Fuzzes the SDO, NMT, EMCY and PDO codecs with arbitrary payloads.
#![no_main]

use hexapod_core::canopen::emcy::Emcy;
use hexapod_core::canopen::nmt::{NmtCommand, NmtState};
use hexapod_core::canopen::pdo::{Rpdo1, Tpdo1, Tpdo2};
use hexapod_core::canopen::sdo::{SdoRequest, SdoResponse};
use hexapod_core::canopen::sdo_client::SdoClient;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = SdoRequest::parse(data);
    let _ = NmtCommand::parse(data);
    let _ = NmtState::parse(data);
    let _ = Emcy::parse(data);
    let _ = Rpdo1::decode(data);
    let _ = Tpdo1::decode(data);
    let _ = Tpdo2::decode(data);
    if let Ok(response) = SdoResponse::parse(data) {
        // A re-encoded response parses to itself.
        assert_eq!(SdoResponse::parse(response.frame(1).payload()), Ok(response));
    }
    let mut client = SdoClient::idle();
    let _ = client.on_response(data);
});
