//! Data-driven scenarios (`tests/scenarios/*.toml`): a seed and a list of steps (operator
//! inputs, injected faults, time, expectations) run on a [`Sil`] rig.
//!
//! ```toml
//! description = "bus-off while standing: hold on the other bus"
//! seed = 81
//! [[step]]
//! do = "stand_up"
//! [[step]]
//! do = "bus_off"
//! bus = 0
//! [[step]]
//! do = "run"
//! seconds = 1.0
//! [[step]]
//! do = "expect"
//! mode = "SafeHold { fault: BusOff { bus: 0 } }"
//! min_height_m = 0.25
//! ```
//!
//! A `[ground]` table puts the robot at the start of a lane of host-sim's evaluation course
//! instead of on flat ground (`kind` and its size as in `host_sim::course::Feature`, e.g.
//! `kind = "stairs_up"`, `step_height_m = 0.13`, or `kind = "slope_down"`, `slope_deg = 20`):
//! level ground, then the feature 1 m ahead of the base, the robot facing it.

use std::path::Path;

use hexapod_core::controller::ZeroPolicy;
use hexapod_core::supervisor::Mode;
use host_sim::course::Feature;
use serde::Deserialize;

use crate::gait_policy::GaitPolicy;
use crate::sil::{generated_policy, GeneratedPolicy, Sil};
use crate::sim_plant::PlantError;

fn one() -> f32 {
    1.0
}

/// One scenario file.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    /// What the scenario checks.
    pub description: String,
    /// Seed of every random source of the rig.
    pub seed: u64,
    /// The ground: a feature of the evaluation course (absent: flat ground).
    #[serde(default)]
    pub ground: Option<Feature>,
    /// The steps, in order.
    pub step: Vec<Step>,
}

/// Which policy runs while `Walking`.
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum PolicyKind {
    /// Zero action: stand at the nominal pose.
    #[default]
    Zero,
    /// The generated fixed-point policy (`firmware/policy`).
    Generated,
    /// The scripted tripod gait at the commanded velocity.
    Gait,
}

/// One step of a scenario.
#[derive(Clone, Debug, Deserialize)]
#[serde(tag = "do", rename_all = "snake_case", deny_unknown_fields)]
pub enum Step {
    /// Boot, arm and stand up until `Walking`.
    StandUp,
    /// Run control cycles.
    Run {
        /// Simulated time, s.
        seconds: f32,
        /// The policy.
        #[serde(default)]
        policy: PolicyKind,
    },
    /// Run control cycles until the mode's debug form starts with `mode`.
    RunUntil {
        /// The mode to reach.
        mode: String,
        /// Fail after this much simulated time, s.
        max_seconds: f32,
        /// The policy.
        #[serde(default)]
        policy: PolicyKind,
    },
    /// RC sticks, fractions of full travel.
    Sticks {
        /// Forward.
        forward: f32,
        /// Left.
        left: f32,
        /// Turn left.
        turn_left: f32,
    },
    /// The arm switch.
    Arm {
        /// On.
        on: bool,
    },
    /// RC link lost (failsafe) or back.
    RcLost {
        /// Lost.
        lost: bool,
    },
    /// The IMU stops (or resumes) delivering samples.
    ImuStale {
        /// Stale.
        stale: bool,
    },
    /// Bus-off of the controller's CAN peripheral on `bus`.
    BusOff {
        /// Bus index.
        bus: usize,
    },
    /// Frame loss probability on both buses.
    FrameLoss {
        /// Probability in [0, 1].
        probability: f32,
        /// Mean length of a loss burst, frames (1: independent).
        #[serde(default = "one")]
        burst_frames: f32,
        /// Probability of a bit error per transmission (error frame, retransmission).
        #[serde(default)]
        error_probability: f32,
    },
    /// The disturbance that held `bus` bus-off ends (the peripheral then recovers).
    BusOn {
        /// Bus index.
        bus: usize,
    },
    /// A drive fault with its EMCY.
    DriveFault {
        /// Joint index.
        joint: usize,
        /// EMCY error code.
        error_code: u16,
    },
    /// A drive falls silent (no heartbeat, no PDOs).
    MuteDrive {
        /// Joint index.
        joint: usize,
    },
    /// A push of the base, world frame, m/s.
    Push {
        /// Velocity change.
        dv_world_m_s: [f32; 3],
    },
    /// Checks of the state now and of the run so far.
    Expect {
        /// The supervisor mode's debug form starts with this.
        #[serde(default)]
        mode: Option<String>,
        /// Base height above the ground under it at least this now, m.
        #[serde(default)]
        min_height_m: Option<f32>,
        /// Base height above the ground under it at most this now, m.
        #[serde(default)]
        max_height_m: Option<f32>,
        /// The base has come at least this far along +x (the start's heading) since the
        /// start, m.
        #[serde(default)]
        min_progress_m: Option<f32>,
        /// Joints with torque now.
        #[serde(default)]
        powered_joints: Option<usize>,
        /// The trunk has not touched the ground while any drive had torque.
        #[serde(default)]
        trunk_clear: bool,
        /// The base never sank faster than this since the robot stopped walking after standing
        /// up (since it stood up, when it did not), m/s.
        #[serde(default)]
        max_sink_speed_m_s: Option<f32>,
        /// The base never tilted more than this since it stood up, rad.
        #[serde(default)]
        max_tilt_rad: Option<f32>,
    },
}

/// Why a scenario failed.
#[derive(Debug, thiserror::Error)]
pub enum ScenarioError {
    /// The file could not be read.
    #[error("{path}: {source}")]
    Read {
        /// The file.
        path: String,
        /// The error.
        source: std::io::Error,
    },
    /// The file is not a scenario.
    #[error("{path}: {source}")]
    Parse {
        /// The file.
        path: String,
        /// The error.
        source: toml::de::Error,
    },
    /// The rig could not be built.
    #[error(transparent)]
    Plant(#[from] PlantError),
    /// A step failed.
    #[error("step {index} ({step:?}) at {t_s:.2} s: {message}")]
    Step {
        /// Step index.
        index: usize,
        /// The step.
        step: Box<Step>,
        /// Simulated time, s.
        t_s: f32,
        /// What went wrong.
        message: String,
    },
}

impl Scenario {
    /// Reads a scenario file.
    pub fn load(path: &Path) -> Result<Self, ScenarioError> {
        let name = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| ScenarioError::Read {
            path: name.clone(),
            source,
        })?;
        toml::from_str(&text).map_err(|source| ScenarioError::Parse { path: name, source })
    }

    /// Runs the scenario on a new rig; the rig is returned for further checks.
    pub fn run(&self) -> Result<Sil, ScenarioError> {
        self.run_on(self.rig()?)
    }

    /// A new rig for the scenario: its ground, its seed.
    pub fn rig(&self) -> Result<Sil, PlantError> {
        match self.ground {
            None => Sil::new(self.seed),
            Some(feature) => Sil::before(feature, self.seed),
        }
    }

    /// Runs the scenario on `sil` (built with [`Scenario::seed`], e.g. recording traffic).
    pub fn run_on(&self, mut sil: Sil) -> Result<Sil, ScenarioError> {
        let mut policies = Policies {
            generated: generated_policy(),
            gait: GaitPolicy::default(),
        };
        for (index, step) in self.step.iter().enumerate() {
            apply(&mut sil, &mut policies, step).map_err(|message| ScenarioError::Step {
                index,
                step: Box::new(step.clone()),
                t_s: sil.time_s(),
                message,
            })?;
        }
        Ok(sil)
    }
}

/// The policies of a run, kept across steps (the gait's phase, the policy's state).
struct Policies {
    generated: Option<GeneratedPolicy>,
    gait: GaitPolicy,
}

fn apply(sil: &mut Sil, policies: &mut Policies, step: &Step) -> Result<(), String> {
    match *step {
        Step::StandUp => sil.stand_up().map_err(|m| format!("stuck in {m:?}"))?,
        Step::Run { seconds, policy } => {
            run_until(sil, policies, policy, seconds, |_| false)?;
        }
        Step::RunUntil {
            ref mode,
            max_seconds,
            policy,
        } => {
            let reached = run_until(sil, policies, policy, max_seconds, |m| {
                format!("{m:?}").starts_with(mode.as_str())
            })?;
            if !reached {
                return Err(format!("still {:?}", sil.mode()));
            }
        }
        Step::Sticks {
            forward,
            left,
            turn_left,
        } => sil.h.rc.set_sticks(forward, left, turn_left),
        Step::Arm { on } => sil.h.rc.set_arm(on),
        Step::RcLost { lost } => sil.h.rc.set_lost(lost),
        Step::ImuStale { stale } => sil.h.imu.set_stale(stale),
        Step::BusOff { bus } => {
            sil.h
                .rig
                .buses
                .get_mut(bus)
                .ok_or("no such bus")?
                .faults
                .bus_off = true;
        }
        Step::FrameLoss {
            probability,
            burst_frames,
            error_probability,
        } => {
            for bus in &mut sil.h.rig.buses {
                bus.faults.loss_probability = probability;
                bus.faults.loss_burst_frames = burst_frames;
                bus.faults.error_probability = error_probability;
            }
        }
        Step::BusOn { bus } => {
            sil.h
                .rig
                .buses
                .get_mut(bus)
                .ok_or("no such bus")?
                .faults
                .bus_off = false;
        }
        Step::DriveFault { joint, error_code } => sil.h.rig.inject_drive_fault(joint, error_code),
        Step::MuteDrive { joint } => sil.h.rig.set_drive_mute(joint, true),
        Step::Push { dv_world_m_s } => sil.h.plant.push(dv_world_m_s),
        Step::Expect {
            ref mode,
            min_height_m,
            max_height_m,
            min_progress_m,
            powered_joints,
            trunk_clear,
            max_sink_speed_m_s,
            max_tilt_rad,
        } => expect(
            sil,
            mode.as_deref(),
            [min_height_m, max_height_m, min_progress_m],
            powered_joints,
            trunk_clear,
            [max_sink_speed_m_s, max_tilt_rad],
        )?,
    }
    Ok(())
}

/// Runs `policy` until `done` or `max_s`; true when `done`.
fn run_until(
    sil: &mut Sil,
    policies: &mut Policies,
    policy: PolicyKind,
    max_s: f32,
    done: impl Fn(Mode) -> bool,
) -> Result<bool, String> {
    Ok(match policy {
        PolicyKind::Zero => sil.run_until(max_s, &mut ZeroPolicy, done),
        PolicyKind::Generated => {
            let p = policies
                .generated
                .as_mut()
                .ok_or("the generated policy does not validate")?;
            sil.run_until(max_s, p, done)
        }
        PolicyKind::Gait => sil.run_until(max_s, &mut policies.gait, done),
    })
}

fn expect(
    sil: &Sil,
    mode: Option<&str>,
    [min_height_m, max_height_m, min_progress_m]: [Option<f32>; 3],
    powered_joints: Option<usize>,
    trunk_clear: bool,
    [max_sink_speed_m_s, max_tilt_rad]: [Option<f32>; 2],
) -> Result<(), String> {
    let actual = format!("{:?}", sil.mode());
    if let Some(m) = mode {
        if !actual.starts_with(m) {
            return Err(format!("mode {actual}, expected {m}"));
        }
    }
    let z = sil.plant().height_above_ground_m();
    if min_height_m.is_some_and(|min| z < min) || max_height_m.is_some_and(|max| z > max) {
        return Err(format!("base height {z} m above the ground"));
    }
    let progress = sil.plant().progress_m();
    if min_progress_m.is_some_and(|min| progress < min) {
        return Err(format!("came {progress:.2} m along the course"));
    }
    let powered = sil.plant().powered_joints();
    if powered_joints.is_some_and(|n| n != powered) {
        return Err(format!("{powered} joints with torque"));
    }
    let trace = &sil.plant().trace;
    if trunk_clear {
        if let Some(c) = trace
            .first_trunk_contact(0.0)
            .filter(|c| c.powered_joints > 0)
        {
            return Err(format!("trunk touched at {:.2} s with torque on", c.t_s));
        }
    }
    if max_sink_speed_m_s.is_some() || max_tilt_rad.is_some() {
        let since_s = sil.stood_up_at_s.ok_or("the robot never stood up")?;
        // A walking trunk bobs at up to about 0.2 m/s: the sink limit holds from the moment
        // the robot stops walking (a fault's hold and sit-down), or from standing up while it
        // has not.
        let sink_since_s = sil.left_walking_at_s.unwrap_or(since_s).max(since_s);
        let sink = trace.max_sink_speed_m_s(sink_since_s, f32::INFINITY);
        if max_sink_speed_m_s.is_some_and(|max| sink > max) {
            return Err(format!("sank at {sink} m/s"));
        }
        let tilt = trace
            .since(since_s)
            .iter()
            .map(|s| s.tilt_rad)
            .fold(0.0, f32::max);
        if max_tilt_rad.is_some_and(|max| tilt > max) {
            return Err(format!("tilted {tilt} rad"));
        }
    }
    Ok(())
}
