//! Motion clips: the JSON motion files (in the spirit of AMP_for_hardware) and their loader.
//!
//! A file holds one periodic gait cycle:
//!
//! ```json
//! { "LoopMode": "Wrap", "FrameDuration": 0.02, "MotionWeight": 1.0,
//!   "Command": [vx, vy, wz], "Frames": [[73 numbers], ...], "Metadata": { ... } }
//! ```
//!
//! Frames follow the layout of [`super::frame`]. `FrameDuration` must be the policy period
//! so frames align with policy steps. The loader refuses malformed files with an error that
//! names the file, the frame and the field: wrong lengths, non-finite numbers, non-unit
//! quaternions, contact flags other than 0/1, joints outside their limits, foot positions
//! that disagree with the joints' forward kinematics, and `Wrap` loops whose last frame does
//! not lead back to the first.

use super::frame::{field_name, Frame, FRAME_BASE_QUAT, FRAME_CONTACT, FRAME_DIM, FRAME_JOINT_POS};
use hexapod_core::amp::AMP_STATE_DIM;
use hexapod_core::kinematics::foot_positions_base;
use hexapod_core::robot::{NUM_JOINTS, Q_MAX_RAD, Q_MIN_RAD};
use hexapod_core::timing::POLICY_DT_S;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Tolerance on joint limits, rad (float round-off of the generator).
const JOINT_LIMIT_TOL_RAD: f32 = 1e-3;
/// Tolerance between stored foot positions and forward kinematics, m.
const FOOT_FK_TOL_M: f32 = 2e-3;
/// Tolerance of the position step between consecutive frames against the trapezoidal
/// integral of the stored velocities, rad.
const STEP_TOL_RAD: f32 = 0.05;
/// Largest base-height change between consecutive frames, m (0.5 m/s at 50 Hz).
const HEIGHT_STEP_TOL_M: f32 = 0.01;

/// How a clip continues after its last frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum LoopMode {
    /// The last frame is followed by the first (a periodic cycle).
    Wrap,
    /// The clip ends at its last frame.
    Clamp,
}

fn is_zero(x: &f64) -> bool {
    *x == 0.0
}

/// Solver and kinematic figures of a generated clip, stored for traceability.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ClipMetadata {
    /// What made the clip.
    pub generator: String,
    /// Gait period, s.
    pub period_s: f64,
    /// Duty factor of every leg.
    pub duty_factor: f64,
    /// Swing apex above the ground, m.
    pub swing_clearance_m: f64,
    /// Vertical speed of a swing foot at lift-off and touch-down, m/s (0 when absent: the
    /// clips made before it existed).
    #[serde(default)]
    pub swing_contact_speed_m_s: f64,
    /// How far the feet's paths lead the scheduled lift-off and trail the touch-down, s (0
    /// when absent).
    #[serde(default)]
    pub swing_lead_s: f64,
    /// Height of the base above the nominal stance's, m (0 when absent, and not written
    /// when 0).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub base_lift_m: f64,
    /// Clarabel's final status.
    pub solver_status: String,
    /// QP objective.
    pub objective: f64,
    /// Worst QP constraint violation.
    pub max_qp_violation: f64,
    /// Worst rigid-body moment residual, N m.
    pub max_moment_residual_nm: f64,
    /// Worst friction-cone violation, N.
    pub max_friction_violation_n: f64,
    /// Smallest joint-limit margin, rad.
    pub min_joint_limit_margin_rad: f64,
    /// Smallest leg-reach margin, m.
    pub min_reach_margin_m: f64,
    /// Largest stance-foot slip speed, m/s.
    pub max_stance_foot_speed_m_s: f64,
}

/// The JSON form of a clip.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct ClipFile {
    #[serde(rename = "LoopMode")]
    loop_mode: LoopMode,
    #[serde(rename = "FrameDuration")]
    frame_duration_s: f64,
    #[serde(rename = "MotionWeight")]
    motion_weight: f64,
    #[serde(rename = "Command")]
    command: [f64; 3],
    #[serde(rename = "Frames")]
    frames: Vec<Vec<f64>>,
    #[serde(rename = "Metadata", default, skip_serializing_if = "Option::is_none")]
    metadata: Option<ClipMetadata>,
}

/// A validated motion clip.
#[derive(Clone, Debug)]
pub struct MotionClip {
    /// Name (file stem).
    pub name: String,
    /// Loop mode.
    pub loop_mode: LoopMode,
    /// Frame duration, s (the policy period).
    pub frame_duration_s: f32,
    /// Sampling weight relative to other clips.
    pub motion_weight: f32,
    /// Commanded (vx, vy, wz) the clip realizes.
    pub command: [f32; 3],
    /// The frames.
    pub frames: Vec<Frame>,
    /// Generator figures.
    pub metadata: Option<ClipMetadata>,
}

/// Why a motion file was refused.
#[derive(Debug, thiserror::Error)]
pub enum ClipError {
    /// The file could not be read or written.
    #[error("{file}: {source}")]
    Io {
        /// File.
        file: PathBuf,
        /// Cause.
        source: std::io::Error,
    },
    /// Not JSON of the expected shape.
    #[error("{file}: not a motion file: {source}")]
    Json {
        /// File.
        file: PathBuf,
        /// Cause.
        source: serde_json::Error,
    },
    /// A header field is wrong.
    #[error("{file}: {field}: {reason}")]
    Header {
        /// File.
        file: PathBuf,
        /// Field name as in the file.
        field: &'static str,
        /// What is wrong.
        reason: String,
    },
    /// A frame has the wrong number of values.
    #[error("{file}: frame {frame}: has {got} values, expected {FRAME_DIM}")]
    FrameLength {
        /// File.
        file: PathBuf,
        /// Frame index.
        frame: usize,
        /// Values found.
        got: usize,
    },
    /// A frame field is invalid.
    #[error("{file}: frame {frame}: {field}: {reason}")]
    Field {
        /// File.
        file: PathBuf,
        /// Frame index.
        frame: usize,
        /// Field name, e.g. `joint_pos[4]`.
        field: String,
        /// What is wrong.
        reason: String,
    },
}

impl MotionClip {
    /// Loads and validates a motion file.
    pub fn load(path: &Path) -> Result<Self, ClipError> {
        let text = std::fs::read_to_string(path).map_err(|source| ClipError::Io {
            file: path.to_path_buf(),
            source,
        })?;
        Self::parse(path, &text)
    }

    /// Parses and validates the text of a motion file; `path` names it in errors.
    pub fn parse(path: &Path, text: &str) -> Result<Self, ClipError> {
        let file = path.to_path_buf();
        let raw: ClipFile = serde_json::from_str(text).map_err(|source| ClipError::Json {
            file: file.clone(),
            source,
        })?;
        let header = |field: &'static str, reason: String| ClipError::Header {
            file: file.clone(),
            field,
            reason,
        };
        if !raw.frame_duration_s.is_finite()
            || (raw.frame_duration_s - POLICY_DT_S as f64).abs() > 1e-6
        {
            return Err(header(
                "FrameDuration",
                format!(
                    "{} s, expected the policy period {POLICY_DT_S} s",
                    raw.frame_duration_s
                ),
            ));
        }
        if !(raw.motion_weight.is_finite() && raw.motion_weight > 0.0) {
            return Err(header(
                "MotionWeight",
                format!("{} is not positive", raw.motion_weight),
            ));
        }
        if raw.command.iter().any(|c| !c.is_finite()) {
            return Err(header(
                "Command",
                format!("{:?} is not finite", raw.command),
            ));
        }
        if raw.frames.len() < 2 {
            return Err(header(
                "Frames",
                format!("{} frames, need at least 2", raw.frames.len()),
            ));
        }
        let mut frames = Vec::with_capacity(raw.frames.len());
        for (k, values) in raw.frames.iter().enumerate() {
            let row: [f32; FRAME_DIM] = values
                .iter()
                .map(|&v| v as f32)
                .collect::<Vec<_>>()
                .try_into()
                .map_err(|_| ClipError::FrameLength {
                    file: file.clone(),
                    frame: k,
                    got: values.len(),
                })?;
            check_frame(&file, k, &row)?;
            frames.push(Frame::from_row(&row));
        }
        let clip = Self {
            name: path
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default(),
            loop_mode: raw.loop_mode,
            frame_duration_s: raw.frame_duration_s as f32,
            motion_weight: raw.motion_weight as f32,
            command: raw.command.map(|c| c as f32),
            frames,
            metadata: raw.metadata,
        };
        clip.check_continuity(&file)?;
        Ok(clip)
    }

    /// The JSON text of the clip.
    pub fn to_json(&self) -> String {
        let raw = ClipFile {
            loop_mode: self.loop_mode,
            frame_duration_s: self.frame_duration_s as f64,
            motion_weight: self.motion_weight as f64,
            command: self.command.map(|c| c as f64),
            frames: self
                .frames
                .iter()
                .map(|f| f.to_row().iter().map(|&v| round6(v)).collect())
                .collect(),
            metadata: self.metadata.clone(),
        };
        serde_json::to_string(&raw).expect("plain data serializes")
    }

    /// Writes the clip to `path`.
    pub fn save(&self, path: &Path) -> Result<(), ClipError> {
        std::fs::write(path, self.to_json() + "\n").map_err(|source| ClipError::Io {
            file: path.to_path_buf(),
            source,
        })
    }

    /// Duration of the clip, s.
    pub fn duration_s(&self) -> f32 {
        self.frames.len() as f32 * self.frame_duration_s
    }

    /// The AMP state of every frame, by `hexapod_core::amp::amp_state`.
    pub fn amp_states(&self) -> Vec<[f32; AMP_STATE_DIM]> {
        self.frames.iter().map(Frame::amp_state).collect()
    }

    /// Index of the frame after `k`, if any.
    pub fn next_frame(&self, k: usize) -> Option<usize> {
        match self.loop_mode {
            LoopMode::Wrap => Some((k + 1) % self.frames.len()),
            LoopMode::Clamp => (k + 1 < self.frames.len()).then_some(k + 1),
        }
    }

    /// Consecutive frames (and, for `Wrap`, last to first) must agree with the stored
    /// velocities: the position step is the trapezoidal integral of the joint velocities.
    fn check_continuity(&self, file: &Path) -> Result<(), ClipError> {
        let dt = self.frame_duration_s;
        for k in 0..self.frames.len() {
            let Some(next) = self.next_frame(k) else {
                continue;
            };
            let (a, b) = (&self.frames[k], &self.frames[next]);
            let field_err = |field: String, reason: String| ClipError::Field {
                file: file.to_path_buf(),
                frame: next,
                field,
                reason: if next == 0 {
                    format!("{reason} (loop wrap from the last frame)")
                } else {
                    reason
                },
            };
            for j in 0..NUM_JOINTS {
                let step = b.joint_pos_rad[j] - a.joint_pos_rad[j];
                let integral = 0.5 * dt * (a.joint_vel_rad_s[j] + b.joint_vel_rad_s[j]);
                if (step - integral).abs() > STEP_TOL_RAD {
                    return Err(field_err(
                        field_name(FRAME_JOINT_POS.start + j),
                        format!(
                            "jumps {step:.4} rad from frame {k}, its velocities integrate to {integral:.4} rad"
                        ),
                    ));
                }
            }
            let dz = b.base_height_m() - a.base_height_m();
            if dz.abs() > HEIGHT_STEP_TOL_M {
                return Err(field_err(
                    "base_pos[2]".into(),
                    format!("height jumps {dz:.4} m from frame {k}"),
                ));
            }
        }
        Ok(())
    }
}

/// Rounds to 6 significant decimals so files stay small and diffs readable.
fn round6(v: f32) -> f64 {
    (v as f64 * 1e6).round() / 1e6
}

/// Checks the values of one frame.
fn check_frame(file: &Path, k: usize, row: &[f32; FRAME_DIM]) -> Result<(), ClipError> {
    let err = |i: usize, reason: String| ClipError::Field {
        file: file.to_path_buf(),
        frame: k,
        field: field_name(i),
        reason,
    };
    if let Some(i) = row.iter().position(|v| !v.is_finite()) {
        return Err(err(i, format!("{} is not finite", row[i])));
    }
    let quat = &row[FRAME_BASE_QUAT];
    let quat_norm = quat.iter().map(|v| v * v).sum::<f32>().sqrt();
    if (quat_norm - 1.0).abs() > 1e-3 {
        return Err(err(
            FRAME_BASE_QUAT.start,
            format!("quaternion norm {quat_norm:.5}, expected 1"),
        ));
    }
    for i in FRAME_CONTACT {
        if row[i] != 0.0 && row[i] != 1.0 {
            return Err(err(
                i,
                format!("contact flag {} is neither 0 nor 1", row[i]),
            ));
        }
    }
    if row[2] <= 0.0 {
        return Err(err(
            2,
            format!("base height {} m is not above the ground", row[2]),
        ));
    }
    let frame = Frame::from_row(row);
    for j in 0..NUM_JOINTS {
        let q = frame.joint_pos_rad[j];
        if q < Q_MIN_RAD[j] - JOINT_LIMIT_TOL_RAD || q > Q_MAX_RAD[j] + JOINT_LIMIT_TOL_RAD {
            return Err(err(
                FRAME_JOINT_POS.start + j,
                format!("{q:.4} rad outside [{}, {}]", Q_MIN_RAD[j], Q_MAX_RAD[j]),
            ));
        }
    }
    let fk = foot_positions_base(&frame.joint_pos_rad);
    for (leg, (stored, kin)) in frame.foot_pos_base_m.iter().zip(fk.iter()).enumerate() {
        for c in 0..3 {
            if (stored[c] - kin[c]).abs() > FOOT_FK_TOL_M {
                return Err(err(
                    super::frame::FRAME_FOOT_POS.start + 3 * leg + c,
                    format!(
                        "{:.4} m disagrees with forward kinematics of the joints ({:.4} m)",
                        stored[c], kin[c]
                    ),
                ));
            }
        }
    }
    Ok(())
}
