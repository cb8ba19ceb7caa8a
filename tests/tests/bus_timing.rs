//! The CAN buses with their real timing (1 Mbit/s, bit stuffing, arbitration by identifier)
//! under the whole loop with physics: the feedback latency (SYNC to the last TPDO) and the
//! bus load per SYNC period, and walking through 5 % burst loss with error frames.

use hexapod_core::controller::ZeroPolicy;
use hexapod_core::supervisor::Mode;
use sil_tests::gait_policy::GaitPolicy;
use sil_tests::sil::Sil;

#[test]
fn feedback_latency_and_bus_load_per_cycle() {
    let mut sil = Sil::new(121).unwrap();
    sil.stand_up().expect("stands up");
    for bus in &mut sil.h.rig.buses {
        bus.stats.cycles.clear();
    }
    let mut gait = GaitPolicy::default();
    sil.h.rc.set_sticks(0.6, 0.0, 0.0);
    sil.run(2.0, &mut gait);
    assert_eq!(sil.mode(), Mode::Walking);
    for (b, bus) in sil.h.rig.buses.iter().enumerate() {
        let s = &bus.stats;
        let (lat_mean, lat_max) = s.feedback_latency_us().expect("feedback");
        let (load_mean, load_max) = s.load(100).expect("cycles");
        let stuff = s.stuff_bits as f64 / s.bits as f64;
        println!(
            "bus {b}: feedback latency mean {lat_mean:.0} us, worst {lat_max:.0} us; \
             load per 20 ms cycle mean {:.1} %, worst {:.1} %; stuff bits {:.1} % of the bits",
            100.0 * load_mean,
            100.0 * load_max,
            100.0 * stuff
        );
        // 18 feedback PDOs (6 bytes, 95 bits + stuffing) at 1 us per bit after the SYNC.
        assert!((1_700.0..2_600.0).contains(&lat_mean), "{lat_mean}");
        assert!(lat_max < 3_000.0, "{lat_max}");
        // SYNC, 18 TPDOs, 9 RPDOs and the heartbeats: about 16 % of the bus at 50 Hz.
        assert!((0.12..0.22).contains(&load_mean), "{load_mean}");
        assert!(s.cycles.iter().all(|c| c.tpdos == 18));
    }
}

#[test]
fn configuration_never_needs_more_than_the_bus() {
    let mut sil = Sil::new(122).unwrap();
    sil.boot().expect("boots");
    for (b, bus) in sil.h.rig.buses.iter().enumerate() {
        let (_, load_max) = bus.stats.load(usize::MAX).expect("cycles");
        println!(
            "bus {b}: worst cycle load during bring-up {:.1} %",
            100.0 * load_max
        );
        assert!(load_max <= 1.0, "{load_max}");
    }
}

#[test]
fn walks_through_5_percent_burst_loss_and_error_frames() {
    let mut sil = Sil::new(123).unwrap();
    sil.stand_up().expect("stands up");
    sil.run(0.5, &mut ZeroPolicy);
    for bus in &mut sil.h.rig.buses {
        bus.faults.loss_probability = 0.05;
        bus.faults.loss_burst_frames = 3.0;
        bus.faults.error_probability = 0.02;
        bus.faults.error_burst_frames = 2.0;
        bus.stats.cycles.clear();
    }
    let frames0: u64 = sil.h.rig.buses.iter().map(|b| b.stats.frames).sum();
    let lost0: u64 = sil.h.rig.buses.iter().map(|b| b.stats.lost).sum();
    let mut gait = GaitPolicy::default();
    sil.h.rc.set_sticks(0.6, 0.0, 0.0);
    let t0 = sil.time_s();
    for _ in 0..8 {
        sil.run(0.5, &mut gait);
        assert_eq!(sil.mode(), Mode::Walking, "at {:.1} s", sil.time_s());
    }
    let frames: u64 = sil.h.rig.buses.iter().map(|b| b.stats.frames).sum::<u64>() - frames0;
    let lost: u64 = sil.h.rig.buses.iter().map(|b| b.stats.lost).sum::<u64>() - lost0;
    let errors: u64 = sil.h.rig.buses.iter().map(|b| b.stats.error_frames).sum();
    let rate = lost as f64 / frames as f64;
    let (lat_mean, lat_max) = sil.h.rig.buses[0].stats.feedback_latency_us().unwrap();
    println!(
        "lost {lost} of {frames} frames ({:.1} %), {errors} error frames; feedback latency \
         mean {lat_mean:.0} us, worst {lat_max:.0} us; {} cycles ran on incomplete feedback",
        100.0 * rate,
        sil.h.controller.stats.incomplete_feedback
    );
    assert!((0.035..0.065).contains(&rate), "{rate}");
    assert!(errors > 50);
    let trace = &sil.plant().trace;
    assert!(trace.first_trunk_contact(t0).is_none());
    assert!(
        trace.min_height_m(t0) > 0.2,
        "sagged to {}",
        trace.min_height_m(t0)
    );
}
