//! The supervisor: the robot's operating modes and its reactions to faults.
//!
//! ```text
//! Boot -> Configuring -> Disabled -(arm switch on)-> Enabling -> StandingUp -> Walking
//!                           ^                                                   |
//!                           +------------- SittingDown <-(arm switch off)-------+
//! ```
//! Stand-up and sit-down interpolate the joint targets smoothly (cosine profile) from where
//! they are to the nominal pose `Q0_RAD` or the sitting pose `Q_SIT_RAD`, drives enabled.
//!
//! Fault reactions, so that a fault never lets the robot drop:
//!
//! | fault | detected by | reaction while the robot stands or walks |
//! |---|---|---|
//! | drive EMCY / drive fault | master (EMCY, statusword) | `SafeSitDown`: the other drives lower the body slowly to `Q_SIT_RAD`, then torque off |
//! | lost drive: heartbeat (5 x 100 ms), feedback (10 cycles), NMT state | master | the drive: target frozen from the third cycle in a row without its feedback (one or two misses are frame loss), then controlword quick stop each cycle (it holds its joint, 0x605A = 6), once seated disable voltage (3 cycles) and NMT stop ([`crate::canopen::master::LostReaction`]); the robot: `SafeSitDown` on the others |
//! | bus-off | CAN driver | `SafeHold`: the other bus's drives hold their targets (its legs keep the body up; the lost bus's drives hold by themselves, quick stop on the master's heartbeat); the CAN controller recovers after 128 x 11 recessive bits (ISO 11898-1), the master then probes, reconfigures and adopts that bus's drives, and the robot sits down on all legs; sit down on the other bus once the arm switch goes off if it does not recover |
//! | IMU stale | IMU timestamps | `SafeSitDown` (joint-space sit-down needs no IMU) |
//! | RC lost (failsafe) | CRSF receiver | `SafeSitDown` |
//! | tilt beyond the limit | attitude filter | `Faulted` with torque off at once: the robot is falling over and stiff legs only make it worse |
//! | NaN / inf in observation or action | control step | `SafeSitDown` from the last finite targets |
//! | deadline overrun | controller timing | `SafeSitDown` |
//! | controller restart (IWDG, fault reset) with drives holding the body | master: statusword and position read by SDO (and the first TPDO1) before any controlword | drives in Operation enabled or Quick stop active adopted where they hold (a drive in Operation enabled keeps its target: pre-operational and reconfigured without a reset of communication; quick stop left deliberately: target = actual position, then enable operation), then `SafeSitDown` from there (`Fault::Restarted`); the reset cause is kept ([`crate::hal::BootInfo`]) |
//!
//! `SafeSitDown` ends in `Faulted` (drives disabled). Faults while `Disabled` latch
//! `Faulted` directly. Leaving `Faulted` needs the arm switch off, the cause gone and a
//! recoverable fault (drive faults are cleared by a CiA 402 fault reset, bus-off by the
//! bus's recovery; lost heartbeat and configuration faults need a restart). Drives whose
//! own link to the master is lost hold position by themselves (quick stop on heartbeat
//! loss, see [`crate::canopen::drive_config`]).

use crate::canopen::cia402::DriveRequest;
use crate::canopen::master::NodeFault;
use crate::rc::receiver::RcState;
use crate::robot::{can_bus, NUM_JOINTS, Q0_RAD, Q_SIT_RAD};

/// Timing and limits of the supervisor.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SupervisorConfig {
    /// Stand-up duration, s.
    pub stand_up_s: f32,
    /// Sit-down duration, s.
    pub sit_down_s: f32,
    /// Sit-down duration after a fault, s (slower).
    pub safe_sit_down_s: f32,
    /// Tilt beyond which torque is cut, rad.
    pub tilt_limit_rad: f32,
    /// Time the sitting pose is held with torque on before torque goes off, s.
    pub settle_s: f32,
    /// Time allowed for all drives to reach Operation enabled, microseconds.
    pub enable_timeout_us: u64,
}

impl Default for SupervisorConfig {
    fn default() -> Self {
        Self {
            stand_up_s: 3.0,
            sit_down_s: 3.0,
            safe_sit_down_s: 5.0,
            settle_s: 0.5,
            tilt_limit_rad: 1.0,
            enable_timeout_us: 1_000_000,
        }
    }
}

/// A fault the supervisor reacts to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Fault {
    /// A drive failed (EMCY, fault state, lost heartbeat or feedback, configuration).
    Drive {
        /// Joint index.
        joint: u8,
        /// What the master saw.
        fault: NodeFault,
    },
    /// A CAN bus went bus-off.
    BusOff {
        /// Bus index.
        bus: u8,
    },
    /// No fresh IMU sample.
    ImuStale,
    /// RC link lost (failsafe).
    RcLost,
    /// Tilt beyond the limit.
    Tilt,
    /// NaN or infinity in the observation or the action.
    NonFinite,
    /// The control cycle missed its deadline.
    Overrun,
    /// The drives did not all reach Operation enabled in time.
    EnableTimeout,
    /// The controller (re)started while drives held the body (a watchdog or fault reset
    /// of the MCU): they were adopted at their positions and the robot sits down.
    Restarted,
}

/// What the supervisor does about a fault while the robot is up.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Reaction {
    /// Lower slowly to the sitting pose with the remaining drives, then torque off.
    SitDown,
    /// Hold the targets with the remaining drives.
    Hold,
    /// Torque off now.
    TorqueOff,
}

impl Fault {
    /// The fault of a drive as the master reports it (bus-off names the bus).
    pub fn from_drive((joint, fault): (usize, NodeFault)) -> Self {
        match fault {
            NodeFault::BusOff => Fault::BusOff {
                bus: can_bus(joint) as u8,
            },
            fault => Fault::Drive {
                joint: joint as u8,
                fault,
            },
        }
    }

    /// The reaction table of the module docs.
    pub fn reaction(self) -> Reaction {
        match self {
            Fault::Tilt | Fault::EnableTimeout => Reaction::TorqueOff,
            Fault::BusOff { .. } => Reaction::Hold,
            _ => Reaction::SitDown,
        }
    }

    /// True when the fault can be cleared without a restart.
    pub fn recoverable(self) -> bool {
        match self {
            Fault::Drive { fault, .. } => fault.link_alive(),
            // The bus recovers by itself; its drives are re-synchronized (the fault clears).
            Fault::BusOff { .. } => true,
            _ => true,
        }
    }
}

/// Operating mode.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Mode {
    /// Before the drives are started.
    Boot,
    /// Drives booting and being configured.
    Configuring,
    /// Drives configured, torque off, waiting for the arm switch.
    Disabled,
    /// Bringing the drives to Operation enabled.
    Enabling {
        /// Start time.
        since_us: u64,
    },
    /// Interpolating to the nominal pose.
    StandingUp {
        /// Start time.
        since_us: u64,
    },
    /// The policy walks.
    Walking,
    /// Interpolating to the sitting pose.
    SittingDown {
        /// Start time.
        since_us: u64,
    },
    /// Sitting down after a fault.
    SafeSitDown {
        /// Start time.
        since_us: u64,
        /// The cause.
        fault: Fault,
    },
    /// Holding after a fault that leaves the sit-down unsafe.
    SafeHold {
        /// The cause.
        fault: Fault,
    },
    /// Torque off after a fault.
    Faulted {
        /// The cause.
        fault: Fault,
    },
}

/// What the supervisor needs to know each cycle.
#[derive(Clone, Copy, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Inputs<'a> {
    /// Now, microseconds.
    pub now_us: u64,
    /// Some drive is still booting or being configured.
    pub configuring: bool,
    /// Every drive is in Operation enabled.
    pub drives_enabled: bool,
    /// Some drive had torque on when the controller started (it holds the body).
    pub drives_adopted: bool,
    /// Where the adopted drives hold their joints (the measured position of the others).
    pub adopted_rad: &'a [f32; NUM_JOINTS],
    /// The first latched drive fault.
    pub drive_fault: Option<(usize, NodeFault)>,
    /// Measured joint positions, rad.
    pub q_rad: &'a [f32; NUM_JOINTS],
    /// The IMU delivered a sample recently.
    pub imu_fresh: bool,
    /// Tilt from the attitude filter, rad.
    pub tilt_rad: f32,
    /// The operator.
    pub rc: RcState,
    /// The last control cycle missed its deadline.
    pub overrun: bool,
}

/// What to send to the drives this cycle.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Command {
    /// Per-drive request.
    pub requests: [DriveRequest; NUM_JOINTS],
    /// Joint targets, rad.
    pub targets_rad: [f32; NUM_JOINTS],
    /// The controller should clear recoverable drive faults (after a fault reset).
    pub clear_faults: bool,
}

/// The supervisor state.
#[derive(Clone, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Supervisor {
    config: SupervisorConfig,
    mode: Mode,
    from_rad: [f32; NUM_JOINTS],
    targets_rad: [f32; NUM_JOINTS],
    arm_previous: bool,
}

/// Cosine ease from 0 to 1 over `s` in [0, 1].
fn ease(s: f32) -> f32 {
    let s = s.clamp(0.0, 1.0);
    0.5 - 0.5 * libm::cosf(core::f32::consts::PI * s)
}

fn lerp(a: &[f32; NUM_JOINTS], b: &[f32; NUM_JOINTS], s: f32) -> [f32; NUM_JOINTS] {
    let mut out = [0.0; NUM_JOINTS];
    for j in 0..NUM_JOINTS {
        out[j] = a[j] + s * (b[j] - a[j]);
    }
    out
}

fn elapsed_s(now_us: u64, since_us: u64) -> f32 {
    now_us.saturating_sub(since_us) as f32 * 1e-6
}

impl Supervisor {
    /// A supervisor in `Boot`.
    pub const fn new(config: SupervisorConfig) -> Self {
        Self {
            config,
            mode: Mode::Boot,
            from_rad: Q_SIT_RAD,
            targets_rad: Q_SIT_RAD,
            arm_previous: true,
        }
    }

    /// The current mode.
    pub fn mode(&self) -> Mode {
        self.mode
    }

    /// The last targets commanded.
    pub fn targets_rad(&self) -> &[f32; NUM_JOINTS] {
        &self.targets_rad
    }

    /// Boot -> Configuring (the controller has started the CANopen master).
    pub fn start(&mut self) {
        self.mode = Mode::Configuring;
    }

    /// The fault the inputs show while the robot is up, highest priority first.
    fn active_fault(&self, i: &Inputs) -> Option<Fault> {
        if i.tilt_rad.is_nan() || i.tilt_rad > self.config.tilt_limit_rad {
            return Some(Fault::Tilt);
        }
        if let Some(drive_fault) = i.drive_fault {
            return Some(Fault::from_drive(drive_fault));
        }
        if !i.imu_fresh {
            return Some(Fault::ImuStale);
        }
        if !i.rc.link_ok {
            return Some(Fault::RcLost);
        }
        if i.overrun {
            return Some(Fault::Overrun);
        }
        None
    }

    fn react(&mut self, fault: Fault, now_us: u64) {
        self.mode = match fault.reaction() {
            Reaction::TorqueOff => Mode::Faulted { fault },
            Reaction::Hold => Mode::SafeHold { fault },
            Reaction::SitDown => {
                self.from_rad = self.targets_rad;
                Mode::SafeSitDown {
                    since_us: now_us,
                    fault,
                }
            }
        };
    }

    /// Reports that the control step produced no usable targets this cycle.
    pub fn report_non_finite(&mut self, now_us: u64) {
        if matches!(self.mode, Mode::Walking | Mode::StandingUp { .. }) {
            self.react(Fault::NonFinite, now_us);
        }
    }

    /// One supervisor cycle. `policy` is called only while walking; an `Err` from it is
    /// a non-finite fault and the last finite targets are held this cycle.
    pub fn step<F>(&mut self, i: &Inputs, policy: F) -> Command
    where
        F: FnOnce() -> Result<[f32; NUM_JOINTS], ()>,
    {
        let now = i.now_us;
        let arm_edge = i.rc.arm && !self.arm_previous;
        self.arm_previous = i.rc.arm;
        let fault = self.active_fault(i);
        let mut clear_faults = false;
        let up = matches!(
            self.mode,
            Mode::StandingUp { .. } | Mode::Walking | Mode::SittingDown { .. }
        );
        if up {
            if let Some(f) = fault {
                self.react(f, now);
            }
        }
        match self.mode {
            Mode::Boot => {}
            Mode::Configuring => {
                if i.drives_adopted && !i.configuring {
                    // Drives hold the body after a restart: never disable them under load;
                    // sit down slowly from where the joints are (on the drives that work).
                    self.from_rad = *i.adopted_rad;
                    self.targets_rad = *i.adopted_rad;
                    self.mode = Mode::SafeSitDown {
                        since_us: now,
                        fault: Fault::Restarted,
                    };
                } else if i.drives_adopted {
                    // Wait for every drive's state before acting, even on a drive fault.
                } else if let Some(drive_fault) = i.drive_fault {
                    self.mode = Mode::Faulted {
                        fault: Fault::from_drive(drive_fault),
                    };
                } else if !i.configuring {
                    self.mode = Mode::Disabled;
                }
            }
            Mode::Disabled => {
                if let Some(drive_fault) = i.drive_fault {
                    self.mode = Mode::Faulted {
                        fault: Fault::from_drive(drive_fault),
                    };
                } else if arm_edge && fault.is_none() {
                    self.mode = Mode::Enabling { since_us: now };
                }
            }
            Mode::Enabling { since_us } => {
                if let Some(f) = fault {
                    self.mode = Mode::Faulted { fault: f };
                } else if !i.rc.arm {
                    self.mode = Mode::Disabled;
                } else if i.drives_enabled {
                    self.from_rad = *i.q_rad;
                    self.mode = Mode::StandingUp { since_us: now };
                } else if now.saturating_sub(since_us) > self.config.enable_timeout_us {
                    self.mode = Mode::Faulted {
                        fault: Fault::EnableTimeout,
                    };
                }
            }
            Mode::StandingUp { since_us } => {
                let s = elapsed_s(now, since_us) / self.config.stand_up_s;
                self.targets_rad = lerp(&self.from_rad, &Q0_RAD, ease(s));
                if !i.rc.arm {
                    self.from_rad = self.targets_rad;
                    self.mode = Mode::SittingDown { since_us: now };
                } else if s >= 1.0 {
                    self.targets_rad = Q0_RAD;
                    self.mode = Mode::Walking;
                }
            }
            Mode::Walking => {
                if !i.rc.arm {
                    self.from_rad = self.targets_rad;
                    self.mode = Mode::SittingDown { since_us: now };
                } else {
                    match policy() {
                        Ok(t) => self.targets_rad = t,
                        Err(()) => self.react(Fault::NonFinite, now),
                    }
                }
            }
            Mode::SittingDown { since_us } => {
                let t_s = elapsed_s(now, since_us);
                self.targets_rad = self.sit_targets(t_s / self.config.sit_down_s);
                if t_s >= self.config.sit_down_s + self.config.settle_s {
                    self.mode = Mode::Disabled;
                }
            }
            Mode::SafeSitDown {
                since_us,
                fault: cause,
            } => {
                if fault == Some(Fault::Tilt) {
                    self.mode = Mode::Faulted { fault: Fault::Tilt };
                } else {
                    let t_s = elapsed_s(now, since_us);
                    self.targets_rad = self.sit_targets(t_s / self.config.safe_sit_down_s);
                    if t_s >= self.config.safe_sit_down_s + self.config.settle_s {
                        self.mode = Mode::Faulted { fault: cause };
                    }
                }
            }
            Mode::SafeHold { fault: cause } => {
                let bus_back = i.drive_fault.is_none() && !i.configuring;
                if fault == Some(Fault::Tilt) {
                    self.mode = Mode::Faulted { fault: Fault::Tilt };
                } else if bus_back || (i.rc.link_ok && !i.rc.arm) {
                    // The bus recovered and its drives are adopted again (or the operator
                    // switched off): sit down, on all legs when the bus is back.
                    self.from_rad = self.targets_rad;
                    self.mode = Mode::SafeSitDown {
                        since_us: now,
                        fault: cause,
                    };
                }
            }
            Mode::Faulted { fault: cause } => {
                let operator_reset = i.rc.link_ok && !i.rc.arm;
                if operator_reset && cause.recoverable() {
                    clear_faults = true;
                    let drive_ok = i.drive_fault.is_none();
                    let conditions_ok = i.imu_fresh && i.tilt_rad <= self.config.tilt_limit_rad;
                    if drive_ok && conditions_ok {
                        self.mode = Mode::Disabled;
                    }
                }
            }
        }
        self.command(i, clear_faults)
    }

    /// Sit-down targets at progress `s` (exactly the sitting pose once `s >= 1`).
    fn sit_targets(&self, s: f32) -> [f32; NUM_JOINTS] {
        if s >= 1.0 {
            Q_SIT_RAD
        } else {
            lerp(&self.from_rad, &Q_SIT_RAD, ease(s))
        }
    }

    fn command(&mut self, i: &Inputs, clear_faults: bool) -> Command {
        let (request, targets) = match self.mode {
            // Drives that hold the body after a restart keep holding where they are
            // commanded until every drive's state is known; nothing is disabled under load.
            Mode::Configuring if i.drives_adopted => (DriveRequest::Enable, *i.adopted_rad),
            Mode::Boot | Mode::Configuring | Mode::Disabled => (DriveRequest::Disable, *i.q_rad),
            Mode::Faulted { .. } if clear_faults => (DriveRequest::FaultReset, *i.q_rad),
            Mode::Faulted { .. } => (DriveRequest::Disable, *i.q_rad),
            Mode::Enabling { .. } => (DriveRequest::Enable, *i.q_rad),
            _ => (DriveRequest::Enable, self.targets_rad),
        };
        if !matches!(
            self.mode,
            Mode::StandingUp { .. }
                | Mode::Walking
                | Mode::SittingDown { .. }
                | Mode::SafeSitDown { .. }
                | Mode::SafeHold { .. }
        ) {
            self.targets_rad = *i.q_rad;
        }
        Command {
            requests: [request; NUM_JOINTS],
            targets_rad: targets,
            clear_faults,
        }
    }
}

#[cfg(test)]
#[path = "supervisor_tests.rs"]
mod tests;
