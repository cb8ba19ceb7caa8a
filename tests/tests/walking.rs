//! Walking with the generated fixed-point policy (`firmware/policy`, from the shipped
//! `assets/policies/terrain-averaged`) on an RC forward command for 10 s on flat ground, through
//! the whole firmware loop: no fall, and a mean forward speed within 25 % of the command.

use hexapod_core::control::Policy;
use hexapod_core::controller::ZeroPolicy;
use hexapod_core::supervisor::Mode;
use sil_tests::gait_policy::GaitPolicy;
use sil_tests::sil::{generated_policy, Sil};
use sil_tests::trace::Trace;

/// Forward stick 0.6 of full travel: 0.3 m/s with the default RC mapping.
const STICK_FORWARD: f32 = 0.6;

/// Walks 10 s with `policy` on the forward command; returns the trace, the commanded
/// speed and the start.
fn walk_10_s(seed: u64, policy: &mut impl Policy) -> (Trace, f32, f32) {
    let mut sil = Sil::new(seed).unwrap();
    sil.stand_up().expect("stands up");
    sil.run(0.5, &mut ZeroPolicy);
    sil.h.rc.set_sticks(STICK_FORWARD, 0.0, 0.0);
    let t0 = sil.time_s();
    for _ in 0..20 {
        sil.run(0.5, policy);
        assert_eq!(
            sil.mode(),
            Mode::Walking,
            "at {:.1} s: {:?}",
            sil.time_s(),
            sil.h.controller.master.counters
        );
    }
    let command = sil.h.controller.rc_state(sil.h.now_us).command;
    assert!(command[0] > 0.25 && command[0] < 0.35, "{command:?}");
    (sil.h.plant.trace.clone(), command[0], t0)
}

fn assert_speed(trace: &Trace, command_m_s: f32, t0_s: f32) {
    // Skip the first second (the gait starting up).
    let v = trace.mean_speed_x_m_s(t0_s + 1.0, t0_s + 10.0).unwrap();
    eprintln!("mean forward speed {v:.3} m/s, command {command_m_s:.3} m/s");
    assert!(
        (v - command_m_s).abs() <= 0.25 * command_m_s,
        "mean forward speed {v:.3} m/s for a command of {command_m_s:.3} m/s"
    );
}

#[test]
fn walks_10_s_on_a_forward_command_without_falling() {
    let mut policy = generated_policy().expect("valid generated policy");
    let (trace, command, t0) = walk_10_s(41, &mut policy);
    let walk = trace.since(t0);
    assert!(walk.len() >= 2000);
    assert!(
        trace.first_trunk_contact(t0).is_none(),
        "trunk touched the ground"
    );
    let tilt = walk.iter().map(|s| s.tilt_rad).fold(0.0, f32::max);
    assert!(tilt < 0.5, "tilted {tilt} rad");
    assert!(
        trace.min_height_m(t0) > 0.15,
        "base down to {}",
        trace.min_height_m(t0)
    );
    assert_speed(&trace, command, t0);
}

#[test]
fn walks_at_the_commanded_speed() {
    let mut policy = generated_policy().expect("valid generated policy");
    let (trace, command, t0) = walk_10_s(42, &mut policy);
    assert_speed(&trace, command, t0);
}

#[test]
fn the_scripted_tripod_gait_walks_at_the_commanded_speed_through_the_loop() {
    let (trace, command, t0) = walk_10_s(43, &mut GaitPolicy::default());
    assert!(
        trace.first_trunk_contact(t0).is_none(),
        "trunk touched the ground"
    );
    assert_speed(&trace, command, t0);
}
