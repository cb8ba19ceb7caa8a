//! Property-based fuzzing of the drive emulator's frame handling and SDO server, and of the
//! candump line parser: random input never panics, and the server answers every SDO
//! request with exactly one response.

use hal_mock::candump::parse_line;
use hal_mock::drive::Drive;
use hexapod_core::can_frame::CanFrame;
use hexapod_core::canopen::sdo::SdoResponse;
use proptest::prelude::*;

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn drive_survives_random_frames(
        frames in prop::collection::vec((0u16..=0x7FF, prop::collection::vec(any::<u8>(), 0..=8)), 0..200)
    ) {
        let mut d = Drive::new(4);
        let mut out = Vec::new();
        d.power_on(0, &mut out);
        // Make it operational so PDO paths run too.
        d.on_frame(&CanFrame::data_frame(0, &[1, 0]).unwrap(), 0, &mut out);
        for (k, (id, data)) in frames.iter().enumerate() {
            let f = CanFrame::data_frame(*id, data).unwrap();
            d.on_frame(&f, k as u64 * 1_000, &mut out);
            d.tick(k as u64 * 1_000, &mut out);
        }
        prop_assert!(out.iter().all(|f| f.payload().len() <= 8));
    }

    #[test]
    fn sdo_server_answers_every_request(payload in prop::array::uniform8(any::<u8>())) {
        let mut d = Drive::new(0);
        let mut out = Vec::new();
        d.power_on(0, &mut out);
        out.clear();
        d.on_frame(&CanFrame::data_frame(0x601, &payload).unwrap(), 0, &mut out);
        let responses: Vec<_> = out.iter().filter(|f| f.cob_id() == 0x581).collect();
        // An abort request (ccs 4) is the only request that gets no answer.
        let expected = usize::from(payload[0] >> 5 != 4);
        prop_assert_eq!(responses.len(), expected);
        for r in responses {
            prop_assert!(SdoResponse::parse(r.payload()).is_ok());
        }
    }

    #[test]
    fn candump_parser_survives_random_lines(line in ".{0,60}") {
        let _ = parse_line(&line);
    }
}
