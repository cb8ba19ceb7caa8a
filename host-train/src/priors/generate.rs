//! The generator: one command in, one validated periodic clip and its report out.

use super::assemble::{assemble, AssembleError, KinematicReport};
use super::clip::{ClipMetadata, LoopMode, MotionClip};
use super::command::GaitCommand;
use super::feet::FootPlan;
use super::optimize::{optimize_gait, GaitQpConfig, GaitQpError, GaitSolution};
use super::schedule::{ScheduleError, TripodSchedule};

/// Settings of the dataset generator.
#[derive(Clone, Debug)]
pub struct GeneratorConfig {
    /// Frames per gait cycle (period = frames x 0.02 s).
    pub frames_per_cycle: usize,
    /// Swing frames of each leg per cycle.
    pub swing_frames: usize,
    /// Swing apex above the ground, m.
    pub swing_clearance_m: f64,
    /// Vertical speed of a swing foot at lift-off and touch-down, m/s.
    pub swing_contact_speed_m_s: f64,
    /// How long before the scheduled lift-off a foot's path leaves the ground, and after the
    /// scheduled touch-down it meets it, s.
    pub swing_lead_s: f64,
    /// The QP's weights and limits.
    pub qp: GaitQpConfig,
}

impl Default for GeneratorConfig {
    fn default() -> Self {
        // 0.6 s cycle, 0.26 s swing: duty factor 0.57 with short six-foot support phases.
        Self {
            frames_per_cycle: 30,
            swing_frames: 13,
            swing_clearance_m: 0.08,
            swing_contact_speed_m_s: 0.0,
            swing_lead_s: 0.0,
            qp: GaitQpConfig::default(),
        }
    }
}

/// What the generator reports per clip.
#[derive(Clone, Debug)]
pub struct ClipReport {
    /// Clip name.
    pub name: String,
    /// Commanded (vx, vy, wz).
    pub command: [f64; 3],
    /// Clarabel status of the last QP.
    pub solver_status: String,
    /// Interior-point iterations of the last QP.
    pub iterations: u32,
    /// QP objective.
    pub objective: f64,
    /// Worst QP constraint violation (equalities, bounds, cones).
    pub max_qp_violation: f64,
    /// Worst translational dynamics residual, N.
    pub max_force_residual_n: f64,
    /// Worst rotational dynamics residual with exact lever arms, N m.
    pub max_moment_residual_nm: f64,
    /// Worst friction-cone violation, N.
    pub max_friction_violation_n: f64,
    /// Kinematic checks of the frames.
    pub kinematics: KinematicReport,
    /// Wall time of the optimization, s.
    pub solve_time_s: f64,
}

impl ClipReport {
    /// One line for the console.
    pub fn summary(&self) -> String {
        let k = &self.kinematics;
        format!(
            "{:<28} cmd ({:+.2}, {:+.2}, {:+.2})  {} in {} it  obj {:.3}  viol qp {:.1e} force {:.1e} N moment {:.1e} N m cone {:.1e} N  IK margin {:.3} rad / {:.3} m  slip {:.1e} m/s  v ({:+.3}, {:+.3}, {:+.3})  {:.0} ms",
            self.name,
            self.command[0],
            self.command[1],
            self.command[2],
            self.solver_status,
            self.iterations,
            self.objective,
            self.max_qp_violation,
            self.max_force_residual_n,
            self.max_moment_residual_nm,
            self.max_friction_violation_n,
            k.min_joint_limit_margin_rad,
            k.min_reach_margin_m,
            k.max_stance_foot_speed_m_s,
            k.mean_velocity[0],
            k.mean_velocity[1],
            k.mean_velocity[2],
            self.solve_time_s * 1e3,
        )
    }
}

/// Why a clip could not be generated.
#[derive(Debug, thiserror::Error)]
pub enum GenerateError {
    /// Bad schedule settings.
    #[error(transparent)]
    Schedule(#[from] ScheduleError),
    /// The QP failed.
    #[error("{clip}: {source}")]
    Optimize {
        /// Clip name.
        clip: String,
        /// Cause.
        source: GaitQpError,
    },
    /// The frames failed the kinematic checks.
    #[error("{clip}: {source}")]
    Assemble {
        /// Clip name.
        clip: String,
        /// Cause.
        source: AssembleError,
    },
}

/// Optimizes and assembles the clip of one command.
pub fn generate_clip(
    command: &GaitCommand,
    cfg: &GeneratorConfig,
) -> Result<(MotionClip, ClipReport, GaitSolution), GenerateError> {
    let schedule = TripodSchedule::new(cfg.frames_per_cycle, cfg.swing_frames)?;
    let plan = FootPlan::new(command.clone(), schedule, cfg.swing_clearance_m)
        .with_contact_speed_m_s(cfg.swing_contact_speed_m_s)
        .with_swing_lead_s(cfg.swing_lead_s);
    let start = std::time::Instant::now();
    let sol = optimize_gait(&plan, &cfg.qp).map_err(|source| GenerateError::Optimize {
        clip: command.name.clone(),
        source,
    })?;
    let solve_time_s = start.elapsed().as_secs_f64();
    let (frames, kinematics) = assemble(&plan, &sol).map_err(|source| GenerateError::Assemble {
        clip: command.name.clone(),
        source,
    })?;
    let report = ClipReport {
        name: command.name.clone(),
        command: command.as_array(),
        solver_status: format!("{:?}", sol.qp.status),
        iterations: sol.qp.iterations,
        objective: sol.qp.objective,
        max_qp_violation: sol.qp.max_violation(),
        max_force_residual_n: sol.max_force_residual_n,
        max_moment_residual_nm: sol.max_moment_residual_nm,
        max_friction_violation_n: sol.max_friction_violation_n,
        kinematics,
        solve_time_s,
    };
    let metadata = ClipMetadata {
        generator: "hexapod priors: tripod schedule, single-rigid-body QP (clarabel), leg IK"
            .into(),
        period_s: schedule.period_s(),
        duty_factor: schedule.duty_factor(),
        swing_clearance_m: cfg.swing_clearance_m,
        swing_contact_speed_m_s: cfg.swing_contact_speed_m_s,
        swing_lead_s: cfg.swing_lead_s,
        base_lift_m: cfg.qp.base_lift_m,
        solver_status: report.solver_status.clone(),
        objective: report.objective,
        max_qp_violation: report.max_qp_violation,
        max_moment_residual_nm: report.max_moment_residual_nm,
        max_friction_violation_n: report.max_friction_violation_n,
        min_joint_limit_margin_rad: kinematics.min_joint_limit_margin_rad,
        min_reach_margin_m: kinematics.min_reach_margin_m,
        max_stance_foot_speed_m_s: kinematics.max_stance_foot_speed_m_s,
    };
    let clip = MotionClip {
        name: command.name.clone(),
        loop_mode: LoopMode::Wrap,
        frame_duration_s: schedule.frame_dt_s() as f32,
        motion_weight: 1.0,
        command: command.as_array().map(|c| c as f32),
        frames,
        metadata: Some(metadata),
    };
    Ok((clip, report, sol))
}
