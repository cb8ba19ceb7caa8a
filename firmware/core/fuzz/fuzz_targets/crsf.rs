//! Fuzzes the CRSF parser and the RC receiver with arbitrary UART bytes.
#![no_main]

use hexapod_core::rc::crsf::CrsfParser;
use hexapod_core::rc::receiver::{RcConfig, RcReceiver};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let mut parser = CrsfParser::new();
    for &b in data {
        let _ = parser.push(b);
    }
    let mut rx = RcReceiver::new(RcConfig::default());
    rx.feed(data, 0);
    let s = rx.state(0);
    assert!(s.command.iter().all(|v| v.is_finite()));
});
