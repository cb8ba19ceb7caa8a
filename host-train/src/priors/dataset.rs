//! The motion-prior dataset: all clips of a directory as reference motions, transition
//! sampling for the discriminator at a random phase with interpolation, the reference
//! states for reference state initialization, and the command-coverage check.
//!
//! Two kinds of reference states ([`PriorStates`]): the clips' own frames (the trajectory
//! optimization's states, which the simulated robot cannot quite reach: under the drives it
//! walks about 2.5 cm lower with 0.05-0.08 rad RMS joint differences), or the states of the
//! simulator tracking each clip (`sim_tracking::replay_clip`), which lie on the robot's reachable
//! manifold by construction.

use super::clip::{ClipError, LoopMode, MotionClip};
use super::sim_tracking::{replay_clip, ReplayConfig};
use hexapod_core::amp::AMP_STATE_DIM;
use host_sim::reference::{ReferenceStart, ReferenceState};
use rand::Rng;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// One AMP state.
pub type AmpState = [f32; AMP_STATE_DIM];

/// Which states of the clips the discriminator and the reference state initialization use.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PriorStates {
    /// The simulator tracking each clip with its drives (after one warm-up cycle, four
    /// cycles recorded): states the simulated robot reaches.
    #[default]
    Tracked,
    /// The clips' frames as the trajectory optimization made them.
    Optimized,
}

/// A reference motion: states one policy step apart.
#[derive(Clone, Debug)]
pub struct ReferenceMotion {
    /// The clip's name.
    pub name: String,
    /// The velocity the motion realizes (vx, vy, wz): the clip's command for its own
    /// frames, the measured mean for a tracked clip.
    pub command: [f32; 3],
    /// Relative probability of drawing this motion.
    pub weight: f32,
    /// The last state is followed by the first (one periodic cycle).
    pub wrap: bool,
    /// The states, one policy step (0.02 s) apart.
    pub states: Vec<ReferenceState>,
}

impl ReferenceMotion {
    /// The clip's frames as a motion.
    pub fn from_clip(clip: &MotionClip) -> Self {
        let states = clip
            .frames
            .iter()
            .map(|f| ReferenceState {
                q_rad: f.joint_pos_rad,
                qdot_rad_s: f.joint_vel_rad_s,
                lin_vel_base_m_s: f.lin_vel_base_m_s,
                ang_vel_base_rad_s: f.ang_vel_base_rad_s,
                up_base: f.up_base(),
                base_height_m: f.base_height_m(),
            })
            .collect();
        Self {
            name: clip.name.clone(),
            command: clip.command,
            weight: clip.motion_weight,
            wrap: clip.loop_mode == LoopMode::Wrap,
            states,
        }
    }

    /// The length of the time range a transition can start in, in policy steps: the whole
    /// cycle when it wraps, else up to two steps before the end.
    pub fn start_range_steps(&self) -> f32 {
        let n = self.states.len() as f32;
        if self.wrap {
            n
        } else {
            (n - 2.0).max(0.0)
        }
    }

    /// The state at time `t_steps` (policy steps from the first state), linearly
    /// interpolated between the two states around it.
    pub fn state_at(&self, t_steps: f32) -> ReferenceState {
        let n = self.states.len();
        let k = (t_steps.floor().max(0.0) as usize).min(n - 1);
        let u = (t_steps - k as f32).clamp(0.0, 1.0);
        let next = if self.wrap {
            (k + 1) % n
        } else {
            (k + 1).min(n - 1)
        };
        self.states[k].lerp(&self.states[next], u)
    }
}

/// Validated clips with their reference motions.
#[derive(Clone, Debug)]
pub struct MotionDataset {
    dir: PathBuf,
    clips: Vec<MotionClip>,
    motions: Vec<ReferenceMotion>,
    cumulative_weight: Vec<f32>,
}

/// Why a dataset could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum DatasetError {
    /// A clip was refused.
    #[error(transparent)]
    Clip(#[from] ClipError),
    /// The directory could not be listed.
    #[error("{dir}: {source}")]
    Dir {
        /// Directory.
        dir: PathBuf,
        /// Cause.
        source: std::io::Error,
    },
    /// No clip was found.
    #[error("{0}: no motion files (*.json)")]
    Empty(PathBuf),
    /// The simulator could not be built to track the clips.
    #[error("{dir}: tracking the clips in the simulator: {message}")]
    Tracking {
        /// Directory.
        dir: PathBuf,
        /// Cause.
        message: String,
    },
    /// A clip the simulator cannot perform (it tilts over or sinks).
    #[error("{file}: the simulator tracking this clip does not perform it: {summary}")]
    Untrackable {
        /// The clip's file.
        file: PathBuf,
        /// The replay's figures.
        summary: String,
    },
    /// Part of the configured command range has no clip near it.
    #[error("{dir}: no clip within {tolerance} of the command (vx {:.2} m/s, vy {:.2} m/s, wz {:.2} rad/s) of the configured range; the nearest is `{nearest}` ({:.2}, {:.2}, {:.2}). Add clips there (`hexapod priors`) or narrow [sim.commands]", command[0], command[1], command[2], nearest_command[0], nearest_command[1], nearest_command[2])]
    Coverage {
        /// Directory.
        dir: PathBuf,
        /// The uncovered command.
        command: [f32; 3],
        /// The nearest clip.
        nearest: String,
        /// Its command.
        nearest_command: [f32; 3],
        /// The tolerance, in words.
        tolerance: String,
    },
}

/// Coverage tolerance per command axis: vx and vy in m/s, wz in rad/s (half the spacing of
/// the generator's grid).
pub const COVERAGE_TOLERANCE: [f32; 3] = [0.1, 0.1, 0.25];

impl MotionDataset {
    /// A dataset of the given clips (at least one), with their own frames as states.
    pub fn new(clips: Vec<MotionClip>) -> Self {
        let motions = clips.iter().map(ReferenceMotion::from_clip).collect();
        Self::with_motions(PathBuf::new(), clips, motions)
    }

    fn with_motions(dir: PathBuf, clips: Vec<MotionClip>, motions: Vec<ReferenceMotion>) -> Self {
        let mut total = 0.0;
        let cumulative_weight = motions
            .iter()
            .map(|m: &ReferenceMotion| {
                total += m.weight;
                total
            })
            .collect();
        Self {
            dir,
            clips,
            motions,
            cumulative_weight,
        }
    }

    /// Loads every `*.json` file of `dir` (sorted by name), refusing the first bad one;
    /// the states are the clips' frames.
    pub fn load_dir(dir: &Path) -> Result<Self, DatasetError> {
        let clips = load_clips(dir)?;
        let mut data = Self::new(clips);
        data.dir = dir.to_path_buf();
        Ok(data)
    }

    /// Loads `dir` with the states `kind` asks for: for [`PriorStates::Tracked`] every clip
    /// is replayed in the simulator on flat ground (about 0.1 s per clip in a release
    /// build), with the training's foot friction (`friction_in_bias_pass`,
    /// `host_sim::config::EnvConfig`), and a clip the simulator cannot perform is refused.
    pub fn load(
        dir: &Path,
        kind: PriorStates,
        friction_in_bias_pass: bool,
    ) -> Result<Self, DatasetError> {
        let clips = load_clips(dir)?;
        let motions = match kind {
            PriorStates::Optimized => clips.iter().map(ReferenceMotion::from_clip).collect(),
            PriorStates::Tracked => track_clips(dir, &clips, friction_in_bias_pass)?,
        };
        Ok(Self::with_motions(dir.to_path_buf(), clips, motions))
    }

    /// The clips.
    pub fn clips(&self) -> &[MotionClip] {
        &self.clips
    }

    /// The reference motions, one per clip.
    pub fn motions(&self) -> &[ReferenceMotion] {
        &self.motions
    }

    /// AMP states of motion `i`, one per state.
    pub fn amp_states(&self, i: usize) -> Vec<AmpState> {
        self.motions[i]
            .states
            .iter()
            .map(ReferenceState::amp_state)
            .collect()
    }

    /// Every reference state of every motion (for reference state initialization).
    pub fn reference_states(&self) -> Vec<ReferenceStart> {
        self.motions
            .iter()
            .flat_map(|m| {
                m.states.iter().map(|&state| ReferenceStart {
                    state,
                    command: m.command,
                })
            })
            .collect()
    }

    /// Total duration of the clips, s.
    pub fn duration_s(&self) -> f32 {
        self.clips.iter().map(MotionClip::duration_s).sum()
    }

    /// `n` transitions `(s_t, s_t+1)` one policy step apart: a motion drawn with
    /// probability proportional to its weight, then a start time uniformly over the motion
    /// (not only frame instants), both states interpolated (AMP_for_hardware's scheme).
    pub fn sample_transitions<R: Rng + ?Sized>(
        &self,
        rng: &mut R,
        n: usize,
    ) -> Vec<(AmpState, AmpState)> {
        let total = *self.cumulative_weight.last().unwrap_or(&0.0);
        (0..n)
            .map(|_| {
                let u = rng.gen_range(0.0..total);
                let c = self
                    .cumulative_weight
                    .partition_point(|&w| w <= u)
                    .min(self.motions.len() - 1);
                let motion = &self.motions[c];
                let t = rng.gen_range(0.0..motion.start_range_steps().max(f32::MIN_POSITIVE));
                (
                    motion.state_at(t).amp_state(),
                    motion.state_at(t + 1.0).amp_state(),
                )
            })
            .collect()
    }

    /// Refuses a dataset that leaves part of the command box without a clip near it (by the
    /// clips' commands; a tracked clip realizes its command within the replay's 25 %): every
    /// command of a grid over the box (the axes' ends, zero and steps of at most half the
    /// tolerance) must have a clip within [`COVERAGE_TOLERANCE`] on every axis; with
    /// `zero_probability > 0` the zero command must be covered too.
    pub fn check_command_coverage(
        &self,
        ranges: [[f32; 2]; 3],
        zero_probability: f32,
    ) -> Result<(), DatasetError> {
        let axis = |[lo, hi]: [f32; 2], tol: f32| -> Vec<f32> {
            let steps = (((hi - lo) / (0.5 * tol)).ceil() as usize).max(1);
            let mut v: Vec<f32> = (0..=steps)
                .map(|i| lo + (hi - lo) * i as f32 / steps as f32)
                .collect();
            if lo < 0.0 && hi > 0.0 {
                v.push(0.0);
            }
            v
        };
        let mut commands = Vec::new();
        for vx in axis(ranges[0], COVERAGE_TOLERANCE[0]) {
            for vy in axis(ranges[1], COVERAGE_TOLERANCE[1]) {
                for wz in axis(ranges[2], COVERAGE_TOLERANCE[2]) {
                    commands.push([vx, vy, wz]);
                }
            }
        }
        if zero_probability > 0.0 {
            commands.push([0.0; 3]);
        }
        for command in commands {
            let distance = |c: &[f32; 3]| {
                (0..3)
                    .map(|k| (c[k] - command[k]).abs() / COVERAGE_TOLERANCE[k])
                    .fold(0.0f32, f32::max)
            };
            let nearest = self
                .clips
                .iter()
                .min_by(|a, b| distance(&a.command).total_cmp(&distance(&b.command)))
                .expect("a dataset has at least one clip");
            if distance(&nearest.command) > 1.0 + 1e-4 {
                return Err(DatasetError::Coverage {
                    dir: self.dir.clone(),
                    command,
                    nearest: nearest.name.clone(),
                    nearest_command: nearest.command,
                    tolerance: format!(
                        "{} m/s, {} m/s, {} rad/s",
                        COVERAGE_TOLERANCE[0], COVERAGE_TOLERANCE[1], COVERAGE_TOLERANCE[2]
                    ),
                });
            }
        }
        Ok(())
    }
}

/// The validated clips of `dir`, sorted by file name.
fn load_clips(dir: &Path) -> Result<Vec<MotionClip>, DatasetError> {
    let mut paths: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|source| DatasetError::Dir {
            dir: dir.to_path_buf(),
            source,
        })?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "json"))
        .collect();
    paths.sort();
    if paths.is_empty() {
        return Err(DatasetError::Empty(dir.to_path_buf()));
    }
    Ok(paths
        .iter()
        .map(|p| MotionClip::load(p))
        .collect::<Result<Vec<_>, _>>()?)
}

/// Each clip as the simulator performs it: its replay's states after the warm-up.
fn track_clips(
    dir: &Path,
    clips: &[MotionClip],
    friction_in_bias_pass: bool,
) -> Result<Vec<ReferenceMotion>, DatasetError> {
    use host_sim::robot::RobotWorld;
    use host_sim::terrain::{Terrain, TerrainConfig};
    use host_sim::urdf_model::{default_urdf_path, UrdfModel};
    use rayon::prelude::*;
    let tracking = |message: String| DatasetError::Tracking {
        dir: dir.to_path_buf(),
        message,
    };
    let model = UrdfModel::load(&default_urdf_path()).map_err(|e| tracking(e.to_string()))?;
    let ground = Terrain::generate(&TerrainConfig::default()).collider();
    let cfg = ReplayConfig::default();
    clips
        .par_iter()
        .map(|clip| {
            let mut robot =
                RobotWorld::new(&model, ground.clone(), 1).map_err(|e| tracking(e.to_string()))?;
            robot.set_friction_in_bias_pass(friction_in_bias_pass);
            let report = replay_clip(&mut robot, clip, &cfg);
            // A fall is refused; a velocity off the clip's command is what the robot does,
            // so the motion is labelled with the velocity it realizes.
            if report.max_tilt_rad > cfg.max_tilt_rad || report.min_height_m < cfg.min_height_m {
                return Err(DatasetError::Untrackable {
                    file: dir.join(format!("{}.json", clip.name)),
                    summary: report.summary(),
                });
            }
            Ok(ReferenceMotion {
                name: clip.name.clone(),
                command: report.mean_velocity,
                weight: clip.motion_weight,
                wrap: false,
                states: report.states,
            })
        })
        .collect()
}
