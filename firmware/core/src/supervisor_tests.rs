//! Tests of the supervisor: every transition and every fault reaction.
#![allow(clippy::needless_range_loop)]

use super::*;

struct World {
    q: [f32; NUM_JOINTS],
    now_us: u64,
    configuring: bool,
    enabled: bool,
    drive_fault: Option<(usize, NodeFault)>,
    imu_fresh: bool,
    tilt_rad: f32,
    rc: RcState,
    overrun: bool,
}

const ARMED: RcState = RcState {
    command: [0.3, 0.0, 0.0],
    arm: true,
    link_ok: true,
};
const DISARMED: RcState = RcState {
    command: [0.0; 3],
    arm: false,
    link_ok: true,
};
const WALK_TARGETS: [f32; NUM_JOINTS] = [0.1; NUM_JOINTS];

impl World {
    fn new() -> Self {
        Self {
            q: Q_SIT_RAD,
            now_us: 0,
            configuring: true,
            enabled: false,
            drive_fault: None,
            imu_fresh: true,
            tilt_rad: 0.0,
            rc: DISARMED,
            overrun: false,
        }
    }

    /// One 20 ms cycle; the policy answers `policy`.
    fn cycle(
        &mut self,
        s: &mut Supervisor,
        policy: Result<[f32; NUM_JOINTS], ()>,
    ) -> (Command, bool) {
        self.now_us += 20_000;
        let q = self.q;
        let inputs = Inputs {
            now_us: self.now_us,
            configuring: self.configuring,
            drives_enabled: self.enabled,
            drives_adopted: false,
            adopted_rad: &q,
            drive_fault: self.drive_fault,
            q_rad: &q,
            imu_fresh: self.imu_fresh,
            tilt_rad: self.tilt_rad,
            rc: self.rc,
            overrun: self.overrun,
        };
        let mut called = false;
        let cmd = s.step(&inputs, || {
            called = true;
            policy
        });
        // The joints follow enabled targets perfectly.
        if cmd.requests[0] == DriveRequest::Enable && self.enabled {
            self.q = cmd.targets_rad;
        }
        (cmd, called)
    }

    fn run(&mut self, s: &mut Supervisor, seconds: f32) -> Command {
        let mut last = None;
        for _ in 0..(seconds / 0.02) as usize {
            last = Some(self.cycle(s, Ok(WALK_TARGETS)).0);
        }
        last.unwrap()
    }
}

/// A supervisor walking, with its world.
fn walking() -> (Supervisor, World) {
    let mut s = Supervisor::new(SupervisorConfig::default());
    let mut w = World::new();
    s.start();
    w.cycle(&mut s, Ok(WALK_TARGETS));
    w.configuring = false;
    w.cycle(&mut s, Ok(WALK_TARGETS));
    assert_eq!(s.mode(), Mode::Disabled);
    w.rc = ARMED;
    w.cycle(&mut s, Ok(WALK_TARGETS));
    assert!(matches!(s.mode(), Mode::Enabling { .. }));
    w.enabled = true;
    w.cycle(&mut s, Ok(WALK_TARGETS));
    assert!(matches!(s.mode(), Mode::StandingUp { .. }));
    w.run(&mut s, 3.1);
    assert_eq!(s.mode(), Mode::Walking);
    (s, w)
}

#[test]
fn full_cycle_boot_to_walk_to_disabled() {
    let (mut s, mut w) = walking();
    let (cmd, called) = w.cycle(&mut s, Ok(WALK_TARGETS));
    assert!(called);
    assert_eq!(cmd.targets_rad, WALK_TARGETS);
    assert_eq!(cmd.requests, [DriveRequest::Enable; NUM_JOINTS]);
    w.rc = DISARMED;
    let (_, called) = w.cycle(&mut s, Ok(WALK_TARGETS));
    assert!(!called);
    assert!(matches!(s.mode(), Mode::SittingDown { .. }));
    let cmd = w.run(&mut s, 3.6);
    assert_eq!(s.mode(), Mode::Disabled);
    assert_eq!(cmd.requests, [DriveRequest::Disable; NUM_JOINTS]);
    for j in 0..NUM_JOINTS {
        assert!(
            (w.q[j] - Q_SIT_RAD[j]).abs() < 1e-5,
            "sat down before torque off"
        );
    }
}

#[test]
fn stand_up_is_smooth_and_ends_at_the_nominal_pose() {
    let mut s = Supervisor::new(SupervisorConfig::default());
    let mut w = World::new();
    s.start();
    w.configuring = false;
    w.cycle(&mut s, Ok(WALK_TARGETS));
    w.rc = ARMED;
    w.enabled = true;
    w.cycle(&mut s, Ok(WALK_TARGETS));
    let mut prev = w.q;
    let mut max_step = 0.0f32;
    for _ in 0..160 {
        let (cmd, called) = w.cycle(&mut s, Ok(WALK_TARGETS));
        if s.mode() == Mode::Walking {
            break;
        }
        assert!(!called);
        for j in 0..NUM_JOINTS {
            max_step = max_step.max((cmd.targets_rad[j] - prev[j]).abs());
        }
        prev = cmd.targets_rad;
    }
    assert_eq!(s.mode(), Mode::Walking);
    assert_eq!(*s.targets_rad(), Q0_RAD);
    // 2.1 rad over 3 s with a cosine profile: at most pi/2 * 2.1 / 150 per 20 ms.
    assert!(max_step < 0.025, "{max_step}");
}

#[test]
fn arm_switch_left_on_at_boot_does_not_enable() {
    let mut s = Supervisor::new(SupervisorConfig::default());
    let mut w = World::new();
    w.rc = ARMED;
    s.start();
    w.configuring = false;
    w.run(&mut s, 1.0);
    assert_eq!(s.mode(), Mode::Disabled);
    w.rc = DISARMED;
    w.cycle(&mut s, Ok(WALK_TARGETS));
    w.rc = ARMED;
    w.cycle(&mut s, Ok(WALK_TARGETS));
    assert!(matches!(s.mode(), Mode::Enabling { .. }));
}

fn assert_safe_sit_down(s: &mut Supervisor, w: &mut World, expect: Fault) {
    assert!(
        matches!(s.mode(), Mode::SafeSitDown { fault, .. } if fault == expect),
        "{:?}",
        s.mode()
    );
    let cmd = w.run(s, 4.0);
    assert_eq!(
        cmd.requests,
        [DriveRequest::Enable; NUM_JOINTS],
        "torque stays on while lowering"
    );
    w.run(s, 1.6);
    assert_eq!(s.mode(), Mode::Faulted { fault: expect });
    for j in 0..NUM_JOINTS {
        assert!(
            (w.q[j] - Q_SIT_RAD[j]).abs() < 1e-5,
            "sat down before torque off"
        );
    }
}

#[test]
fn drive_emcy_sits_down_slowly() {
    let (mut s, mut w) = walking();
    w.cycle(&mut s, Ok(WALK_TARGETS));
    let fault = NodeFault::Emergency { error_code: 0x2310 };
    w.drive_fault = Some((4, fault));
    let (cmd, called) = w.cycle(&mut s, Ok(WALK_TARGETS));
    assert!(!called);
    assert_eq!(
        cmd.targets_rad, WALK_TARGETS,
        "starts from the last targets: no jump"
    );
    assert_safe_sit_down(&mut s, &mut w, Fault::Drive { joint: 4, fault });
}

#[test]
fn lost_heartbeat_sits_down_and_is_not_recoverable() {
    let (mut s, mut w) = walking();
    w.drive_fault = Some((10, NodeFault::LostHeartbeat));
    w.cycle(&mut s, Ok(WALK_TARGETS));
    assert_safe_sit_down(
        &mut s,
        &mut w,
        Fault::Drive {
            joint: 10,
            fault: NodeFault::LostHeartbeat,
        },
    );
    w.rc = DISARMED;
    let cmd = w.run(&mut s, 1.0);
    assert!(matches!(s.mode(), Mode::Faulted { .. }));
    assert!(!cmd.clear_faults);
}

#[test]
fn imu_stale_sits_down() {
    let (mut s, mut w) = walking();
    w.imu_fresh = false;
    w.cycle(&mut s, Ok(WALK_TARGETS));
    assert_safe_sit_down(&mut s, &mut w, Fault::ImuStale);
}

#[test]
fn rc_loss_sits_down() {
    let (mut s, mut w) = walking();
    w.rc = RcState::FAILSAFE;
    w.cycle(&mut s, Ok(WALK_TARGETS));
    assert_safe_sit_down(&mut s, &mut w, Fault::RcLost);
}

#[test]
fn overrun_sits_down() {
    let (mut s, mut w) = walking();
    w.overrun = true;
    w.cycle(&mut s, Ok(WALK_TARGETS));
    w.overrun = false;
    assert_safe_sit_down(&mut s, &mut w, Fault::Overrun);
}

#[test]
fn non_finite_action_holds_the_last_targets_then_sits_down() {
    let (mut s, mut w) = walking();
    w.cycle(&mut s, Ok(WALK_TARGETS));
    let (cmd, called) = w.cycle(&mut s, Err(()));
    assert!(called);
    assert_eq!(cmd.targets_rad, WALK_TARGETS);
    assert!(cmd.targets_rad.iter().all(|t| t.is_finite()));
    assert_safe_sit_down(&mut s, &mut w, Fault::NonFinite);
}

#[test]
fn tilt_cuts_torque_at_once() {
    let (mut s, mut w) = walking();
    w.tilt_rad = 1.2;
    let (cmd, _) = w.cycle(&mut s, Ok(WALK_TARGETS));
    assert_eq!(s.mode(), Mode::Faulted { fault: Fault::Tilt });
    assert_eq!(cmd.requests, [DriveRequest::Disable; NUM_JOINTS]);
}

#[test]
fn tilt_during_a_safe_sit_down_cuts_torque() {
    let (mut s, mut w) = walking();
    w.imu_fresh = false;
    w.cycle(&mut s, Ok(WALK_TARGETS));
    w.tilt_rad = 1.2;
    let (cmd, _) = w.cycle(&mut s, Ok(WALK_TARGETS));
    assert_eq!(s.mode(), Mode::Faulted { fault: Fault::Tilt });
    assert_eq!(cmd.requests, [DriveRequest::Disable; NUM_JOINTS]);
}

#[test]
fn bus_off_holds_then_sits_when_disarmed() {
    let (mut s, mut w) = walking();
    w.cycle(&mut s, Ok(WALK_TARGETS));
    w.drive_fault = Some((2, NodeFault::BusOff));
    let cmd = w.run(&mut s, 2.0);
    assert_eq!(
        s.mode(),
        Mode::SafeHold {
            fault: Fault::BusOff { bus: 0 }
        }
    );
    assert_eq!(cmd.targets_rad, WALK_TARGETS);
    assert_eq!(cmd.requests, [DriveRequest::Enable; NUM_JOINTS]);
    w.rc = DISARMED;
    w.cycle(&mut s, Ok(WALK_TARGETS));
    assert!(matches!(s.mode(), Mode::SafeSitDown { .. }));
}

#[test]
fn recoverable_fault_clears_after_disarm_and_reset() {
    let (mut s, mut w) = walking();
    w.drive_fault = Some((4, NodeFault::DriveFault));
    w.run(&mut s, 5.7);
    assert!(matches!(s.mode(), Mode::Faulted { .. }));
    // Still armed: stays faulted, torque off.
    let cmd = w.run(&mut s, 0.5);
    assert!(!cmd.clear_faults);
    w.rc = DISARMED;
    let (cmd, _) = w.cycle(&mut s, Ok(WALK_TARGETS));
    assert!(cmd.clear_faults);
    assert_eq!(cmd.requests, [DriveRequest::FaultReset; NUM_JOINTS]);
    assert!(
        matches!(s.mode(), Mode::Faulted { .. }),
        "drive still reports the fault"
    );
    w.drive_fault = None;
    w.cycle(&mut s, Ok(WALK_TARGETS));
    assert_eq!(s.mode(), Mode::Disabled);
}

#[test]
fn drive_fault_while_disabled_latches() {
    let mut s = Supervisor::new(SupervisorConfig::default());
    let mut w = World::new();
    s.start();
    w.configuring = false;
    w.cycle(&mut s, Ok(WALK_TARGETS));
    w.drive_fault = Some((0, NodeFault::DriveFault));
    w.cycle(&mut s, Ok(WALK_TARGETS));
    assert!(matches!(s.mode(), Mode::Faulted { .. }));
}

#[test]
fn enabling_times_out() {
    let mut s = Supervisor::new(SupervisorConfig::default());
    let mut w = World::new();
    s.start();
    w.configuring = false;
    w.cycle(&mut s, Ok(WALK_TARGETS));
    w.rc = ARMED;
    w.run(&mut s, 1.1);
    assert_eq!(
        s.mode(),
        Mode::Faulted {
            fault: Fault::EnableTimeout
        }
    );
}
