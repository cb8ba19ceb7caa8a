//! Fuzzes the CANopen master with arbitrary frames: each record is
//! `[bus, id_hi, id_lo, len, data...]`.
#![no_main]

use hexapod_core::can_frame::CanFrame;
use hexapod_core::canopen::cia402::DriveRequest;
use hexapod_core::canopen::master::Master;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let mut master = Master::new();
    master.start(0);
    let mut rest = data;
    let mut now_us = 0u64;
    while rest.len() >= 4 {
        let bus = (rest[0] % 3) as usize;
        let id = u16::from_be_bytes([rest[1], rest[2]]) & 0x7FF;
        let len = (rest[3] as usize % 9).min(rest.len() - 4);
        if let Some(frame) = CanFrame::data_frame(id, &rest[4..4 + len]) {
            master.on_frame(bus, &frame, now_us);
        }
        rest = &rest[4 + len..];
        now_us += 1_000;
        master.poll(now_us);
        if now_us % 20_000 == 0 {
            master.sync();
            master.send_commands(&[DriveRequest::Enable; 18], &[0.0; 18]);
        }
    }
    for bus in 0..2 {
        while master.pop_tx(bus).is_some() {}
    }
});
