//! Property-based fuzzing of every parser that sees bytes from outside: CRSF, SDO, NMT,
//! EMCY, PDOs, and the CANopen master's frame handler. Random input must never panic, and
//! rejected input must be counted.

use hexapod_core::can_frame::CanFrame;
use hexapod_core::canopen::emcy::Emcy;
use hexapod_core::canopen::master::Master;
use hexapod_core::canopen::nmt::{NmtCommand, NmtState};
use hexapod_core::canopen::od::ObjectAddress;
use hexapod_core::canopen::pdo::{Rpdo1, Tpdo1, Tpdo2};
use hexapod_core::canopen::sdo::{SdoRequest, SdoResponse};
use hexapod_core::controller::{Controller, ControllerConfig, ZeroPolicy};
use hexapod_core::rc::crsf::{encode_rc_channels, CrsfFrame, CrsfParser, NUM_CHANNELS};
use hexapod_core::rc::receiver::{RcConfig, RcReceiver};
use proptest::prelude::*;

fn frame_strategy() -> impl Strategy<Value = (usize, CanFrame)> {
    (
        0usize..3,
        0u16..=0x7FF,
        prop::collection::vec(any::<u8>(), 0..=8),
    )
        .prop_map(|(bus, id, data)| (bus, CanFrame::data_frame(id, &data).unwrap()))
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 512,
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    #[test]
    fn crsf_parser_survives_random_bytes(bytes in prop::collection::vec(any::<u8>(), 0..600)) {
        let mut p = CrsfParser::new();
        let mut frames = 0u32;
        for b in &bytes {
            if p.push(*b).is_some() {
                frames += 1;
            }
        }
        let c = p.counters;
        prop_assert_eq!(c.frames, frames);
        // Every byte is accounted for somewhere or still buffered (< one frame).
        prop_assert!(c.skipped_bytes as usize <= bytes.len());
    }

    #[test]
    fn crsf_finds_a_valid_frame_after_garbage(
        garbage in prop::collection::vec(any::<u8>(), 0..200),
        channels in prop::array::uniform16(0u16..2048),
    ) {
        let mut p = CrsfParser::new();
        for b in &garbage {
            p.push(*b);
        }
        // A run of non-sync bytes flushes any partial frame, then a valid frame decodes.
        for _ in 0..64 {
            p.push(0x00);
        }
        let mut got = None;
        for b in encode_rc_channels(&channels) {
            if let Some(f) = p.push(b) {
                got = Some(f);
            }
        }
        prop_assert_eq!(got, Some(CrsfFrame::RcChannels(channels)));
    }

    #[test]
    fn rc_receiver_never_reports_non_finite_commands(
        bytes in prop::collection::vec(any::<u8>(), 0..400),
        channels in prop::array::uniform16(0u16..2048),
    ) {
        let mut rx = RcReceiver::new(RcConfig::default());
        rx.feed(&bytes, 0);
        rx.feed(&encode_rc_channels(&channels), 1);
        let s = rx.state(1);
        prop_assert!(s.command.iter().all(|v| v.is_finite() && v.abs() <= 1.0 + 1e-6));
        prop_assert_eq!(channels.len(), NUM_CHANNELS);
    }

    #[test]
    fn canopen_codecs_survive_random_payloads(p in prop::collection::vec(any::<u8>(), 0..=8)) {
        let _ = SdoRequest::parse(&p);
        let _ = SdoResponse::parse(&p);
        let _ = NmtCommand::parse(&p);
        let _ = NmtState::parse(&p);
        let _ = Emcy::parse(&p);
        prop_assert_eq!(Rpdo1::decode(&p).is_some(), p.len() == 6);
        prop_assert_eq!(Tpdo1::decode(&p).is_some(), p.len() == 6);
        prop_assert_eq!(Tpdo2::decode(&p).is_some(), p.len() == 6);
    }

    #[test]
    fn sdo_requests_round_trip(index in any::<u16>(), sub in any::<u8>(), value in any::<u32>(), len in 1u8..=4) {
        let req = SdoRequest::download(ObjectAddress::new(index, sub), value, len);
        prop_assert_eq!(SdoRequest::parse(req.frame(5).payload()), Ok(req));
    }

    #[test]
    fn master_survives_random_frames(frames in prop::collection::vec(frame_strategy(), 0..300)) {
        let mut m = Master::new();
        m.start(0);
        for (k, (bus, f)) in frames.iter().enumerate() {
            m.on_frame(*bus, f, k as u64 * 100);
            if k % 20 == 0 {
                m.poll(k as u64 * 100);
                m.sync();
                m.send_commands(&[hexapod_core::canopen::cia402::DriveRequest::Enable; 18], &[f32::NAN; 18]);
            }
        }
        let fb = m.feedback();
        prop_assert!(fb.q_rad.iter().all(|q| q.is_finite()));
        // Whatever was queued is well-formed.
        for bus in 0..2 {
            while let Some(f) = m.pop_tx(bus) {
                prop_assert!(f.cob_id() <= 0x7FF && f.payload().len() <= 8);
            }
        }
    }

    #[test]
    fn controller_survives_random_frames_and_bytes(
        frames in prop::collection::vec(frame_strategy(), 0..200),
        rc in prop::collection::vec(any::<u8>(), 0..300),
    ) {
        let mut c = Controller::new(ControllerConfig::default());
        c.start(0);
        c.on_rc_bytes(&rc, 0);
        for (k, (bus, f)) in frames.iter().enumerate() {
            let now = k as u64 * 1_000;
            if k % 20 == 0 {
                c.begin_cycle(now);
            }
            c.on_can_frame(*bus, f, now);
            if k % 20 == 10 {
                let cmd = c.finish_cycle(now, &mut ZeroPolicy);
                prop_assert!(cmd.targets_rad.iter().all(|t| t.is_finite()));
            }
        }
    }
}

#[test]
fn unknown_nodes_and_wrong_buses_are_counted() {
    let mut m = Master::new();
    m.start(0);
    // TPDO1 of node 40 (not ours), of node 3 on bus 1 (it lives on bus 0), an SDO response
    // nobody asked for, and a short EMCY.
    m.on_frame(0, &CanFrame::data_frame(0x1A8, &[0; 6]).unwrap(), 0);
    m.on_frame(1, &CanFrame::data_frame(0x183, &[0; 6]).unwrap(), 0);
    m.on_frame(
        0,
        &CanFrame::data_frame(0x583, &[0x60, 0, 0, 0, 0, 0, 0, 0]).unwrap(),
        0,
    );
    m.on_frame(0, &CanFrame::data_frame(0x083, &[1, 2]).unwrap(), 0);
    let c = m.counters;
    assert_eq!(
        (c.unknown_node, c.wrong_bus, c.unexpected_sdo, c.malformed),
        (1, 1, 1, 1)
    );
    assert_eq!(m.first_fault(), None, "bad frames do not fault a drive");
}
