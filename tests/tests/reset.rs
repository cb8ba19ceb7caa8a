//! A reset of the controller (what an IWDG or HardFault reset of the STM32 does: the
//! drives keep running and holding the body) mid-walk and mid-stand-up, with physics. The
//! new controller learns each drive's state before it sends a controlword, adopts the
//! drives that hold the body at their positions and sits the robot down from there: the
//! trunk stays clear of the ground and torque goes off only once seated.

use hexapod_core::canopen::cia402::PowerState;
use hexapod_core::controller::ZeroPolicy;
use hexapod_core::hal::{BootInfo, ResetCause};
use hexapod_core::supervisor::{Fault, Mode};
use sil_tests::sil::Sil;
use sil_tests::sim_plant::sitting_height_m;

/// RCC_RSR after an IWDG reset: IWDG1RSTF, PINRSTF, CPURSTF.
const IWDG_RESET: u32 = BootInfo::IWDG1RSTF | BootInfo::PINRSTF | BootInfo::CPURSTF;

/// After the reset at `t_reset`: the drives never lose torque before the robot is seated,
/// the body goes down slowly, the trunk touches nothing while any drive holds it.
fn assert_no_drop(sil: &mut Sil, t_reset: f32, down_s: f32, min_height_m: f32) {
    assert_eq!(
        sil.h.controller.boot_info().cause(),
        ResetCause::IndependentWatchdog
    );
    assert!(
        sil.run_until(1.0, &mut ZeroPolicy, |m| matches!(
            m,
            Mode::SafeSitDown {
                fault: Fault::Restarted,
                ..
            }
        )),
        "{:?}",
        sil.mode()
    );
    assert!(sil.h.controller.master.any_adopted(), "no drive adopted");
    // While the adoption runs, every joint keeps its torque.
    assert_eq!(sil.plant().powered_joints(), 18);
    assert!(sil.run_until(7.0, &mut ZeroPolicy, |m| matches!(m, Mode::Faulted { .. })));
    sil.run(0.5, &mut ZeroPolicy);
    assert_eq!(
        sil.mode(),
        Mode::Faulted {
            fault: Fault::Restarted
        }
    );
    let trace = &sil.plant().trace;
    let off = *trace.torque_off(t_reset).expect("torque goes off");
    let seated = sitting_height_m() + 0.02;
    assert!(
        off.height_m() < seated,
        "torque off at {} m: not seated",
        off.height_m()
    );
    // Until the sit-down has brought the body low, it stays up.
    let lowest_while_up = trace
        .since(t_reset)
        .iter()
        .take_while(|s| s.t_s < t_reset + down_s + 0.5)
        .map(|s| s.height_m())
        .fold(f32::INFINITY, f32::min);
    assert!(
        lowest_while_up > min_height_m,
        "sagged to {lowest_while_up} m before the sit-down"
    );
    let sink = trace.max_sink_speed_m_s(t_reset, off.t_s);
    // Beyond the drives' consumer heartbeat timeout (500 ms) they quick-stop by themselves
    // before the new controller comes; a quick stop holds the actual position, so the
    // loaded joints give way by their following error once and the body settles by about
    // 3 cm. Drives still following their targets are kept on them: no settling.
    let limit = if down_s < 0.5 { 0.15 } else { 0.3 };
    assert!(sink < limit, "sinks at {sink} m/s");
    let sink_later = trace.max_sink_speed_m_s(t_reset + down_s + 0.5, off.t_s);
    assert!(
        sink_later < 0.15,
        "sinks at {sink_later} m/s during the sit-down"
    );
    assert!(
        trace
            .since(t_reset)
            .iter()
            .take_while(|s| s.t_s < off.t_s)
            .all(|s| s.powered_joints == 18),
        "a drive lost torque before the robot was seated"
    );
    if let Some(c) = trace.first_trunk_contact(t_reset) {
        assert!(
            c.t_s >= off.t_s,
            "trunk touched at {:.2} s, torque off at {:.2} s",
            c.t_s,
            off.t_s
        );
    }
    for d in &sil.h.rig.drives {
        assert_eq!(d.power_state(), PowerState::SwitchOnDisabled);
    }
}

fn reset_mid_walk(seed: u64, down_s: f32) {
    let (mut sil, _gait) = Sil::walking_with_gait(seed);
    let t_reset = sil.time_s();
    sil.restart_controller(down_s, IWDG_RESET);
    assert_no_drop(&mut sil, t_reset, down_s, 0.22);
}

#[test]
fn reset_mid_walk_restarting_after_50_ms_never_drops_the_robot() {
    reset_mid_walk(101, 0.05);
}

#[test]
fn reset_mid_walk_restarting_after_300_ms_never_drops_the_robot() {
    reset_mid_walk(102, 0.3);
}

/// Longer than the drives' consumer heartbeat timeout (500 ms): they are in Quick stop
/// active (holding) when the new controller comes.
#[test]
fn reset_mid_walk_restarting_after_800_ms_never_drops_the_robot() {
    reset_mid_walk(103, 0.8);
}

#[test]
fn reset_mid_stand_up_never_drops_the_robot() {
    let mut sil = Sil::new(104).unwrap();
    sil.boot().expect("boots");
    sil.h.rc.set_arm(true);
    assert!(sil.run_until(2.0, &mut ZeroPolicy, |m| matches!(
        m,
        Mode::StandingUp { .. }
    )));
    sil.run(1.5, &mut ZeroPolicy);
    assert!(matches!(sil.mode(), Mode::StandingUp { .. }));
    let h = sil.plant().state().base_pos_world_m[2];
    let t_reset = sil.time_s();
    sil.restart_controller(0.3, IWDG_RESET);
    assert_no_drop(&mut sil, t_reset, 0.3, h - 0.05);
}
