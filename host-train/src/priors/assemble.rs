//! From an optimized cycle to clip frames: base poses in the world, joint angles by inverse
//! kinematics, velocities by periodic central differences, and kinematic checks.

use super::feet::FootPlan;
use super::frame::Frame;
use super::geom::{
    add, log_so3, mul_mm, mul_mtv, mul_mv, norm, quat_xyzw, rot_rpy, rot_z, scale, sub, M3, V3,
};
use super::optimize::GaitSolution;
use hexapod_core::kinematics::{foot_positions_base, leg_inverse_kinematics, IkError};
use hexapod_core::robot::{
    Leg, NUM_JOINTS, NUM_LEGS, Q_MAX_RAD, Q_MIN_RAD, SHANK_LENGTH_M, THIGH_LENGTH_M,
};

/// Why frames could not be built.
#[derive(Debug, thiserror::Error)]
pub enum AssembleError {
    /// A foot target has no joint solution.
    #[error("frame {frame}: leg {leg:?}: no inverse-kinematics solution ({reason:?})")]
    Unreachable {
        /// Frame index.
        frame: usize,
        /// Leg.
        leg: Leg,
        /// Why.
        reason: IkError,
    },
    /// A joint angle leaves its limits.
    #[error("frame {frame}: joint {joint}: {angle_rad:.3} rad outside its limits")]
    JointLimit {
        /// Frame index.
        frame: usize,
        /// Joint index.
        joint: usize,
        /// Angle.
        angle_rad: f32,
    },
}

/// Kinematic quality of the frames.
#[derive(Clone, Copy, Debug, Default)]
pub struct KinematicReport {
    /// Smallest distance of any joint to its limits, rad.
    pub min_joint_limit_margin_rad: f64,
    /// Smallest distance of any foot to the edge of its leg's reach (thigh + shank fully
    /// stretched), m.
    pub min_reach_margin_m: f64,
    /// Largest speed of a stance foot in the world (slip), from consecutive frames whose foot
    /// paths are on the ground (a swing lead lifts the path in the last stance frames), m/s.
    pub max_stance_foot_speed_m_s: f64,
    /// Smallest swing-foot clearance at mid-swing above the stance height, m.
    pub min_swing_apex_m: f64,
    /// Mean base velocity over the cycle in the base frame (vx, vy) and yaw rate.
    pub mean_velocity: [f64; 3],
}

/// The world pose of the base at frame `k` (any integer; the cycle repeats).
fn base_pose(plan: &FootPlan, sol: &GaitSolution, k: i64) -> (V3, M3) {
    let n = sol.base.len() as i64;
    let x = sol.base[k.rem_euclid(n) as usize];
    let t = k as f64 * plan.schedule().frame_dt_s();
    let cmd = plan.command();
    let frame_rot = rot_z(cmd.yaw_rad(t));
    let pos_c = [x[0], x[1], sol.base_height_m + x[2]];
    let pos = add(cmd.displacement_m(t), mul_mv(&frame_rot, pos_c));
    (pos, mul_mm(&frame_rot, &rot_rpy(x[3], x[4], x[5])))
}

/// Builds the frames of one cycle and checks them.
pub fn assemble(
    plan: &FootPlan,
    sol: &GaitSolution,
) -> Result<(Vec<Frame>, KinematicReport), AssembleError> {
    let n = sol.base.len();
    let dt = plan.schedule().frame_dt_s();
    let mut q_all = Vec::with_capacity(n);
    let mut margin_limit = f64::INFINITY;
    let mut margin_reach = f64::INFINITY;
    for k in 0..n {
        let x = sol.base[k];
        let rot_c = rot_rpy(x[3], x[4], x[5]);
        let pos_c = [x[0], x[1], sol.base_height_m + x[2]];
        let mut q = [0.0f32; NUM_JOINTS];
        for leg in Leg::ALL {
            let foot_base = mul_mtv(&rot_c, sub(sol.feet_m[k][leg.index()], pos_c));
            let q_leg =
                leg_inverse_kinematics(leg, foot_base.map(|v| v as f32)).map_err(|reason| {
                    AssembleError::Unreachable {
                        frame: k,
                        leg,
                        reason,
                    }
                })?;
            q[3 * leg.index()..3 * leg.index() + 3].copy_from_slice(&q_leg);
            let (lt, ls) = (THIGH_LENGTH_M as f64, SHANK_LENGTH_M as f64);
            let reach = (lt * lt + ls * ls + 2.0 * lt * ls * (q_leg[2] as f64).cos()).sqrt();
            margin_reach = margin_reach.min(lt + ls - reach);
        }
        for (joint, &angle) in q.iter().enumerate() {
            let m = (angle - Q_MIN_RAD[joint]).min(Q_MAX_RAD[joint] - angle) as f64;
            if m < 0.0 {
                return Err(AssembleError::JointLimit {
                    frame: k,
                    joint,
                    angle_rad: angle,
                });
            }
            margin_limit = margin_limit.min(m);
        }
        q_all.push(q);
    }

    let mut frames = Vec::with_capacity(n);
    for k in 0..n {
        let (pos, rot) = base_pose(plan, sol, k as i64);
        let (pos_prev, rot_prev) = base_pose(plan, sol, k as i64 - 1);
        let (pos_next, rot_next) = base_pose(plan, sol, k as i64 + 1);
        let lin_vel = mul_mtv(&rot, scale(0.5 / dt, sub(pos_next, pos_prev)));
        let ang_vel = scale(
            0.5 / dt,
            log_so3(&mul_mm(&super::geom::transpose(&rot_prev), &rot_next)),
        );
        let (qp, qn) = (&q_all[(k + n - 1) % n], &q_all[(k + 1) % n]);
        let q = q_all[k];
        let quat = quat_xyzw(&rot);
        frames.push(Frame {
            base_pos_world_m: pos.map(|v| v as f32),
            base_quat_xyzw: quat.map(|v| v as f32),
            joint_pos_rad: q,
            foot_pos_base_m: foot_positions_base(&q),
            lin_vel_base_m_s: lin_vel.map(|v| v as f32),
            ang_vel_base_rad_s: ang_vel.map(|v| v as f32),
            joint_vel_rad_s: std::array::from_fn(|j| (qn[j] - qp[j]) / (2.0 * dt as f32)),
            contacts: sol.contacts[k],
        });
    }
    let report = KinematicReport {
        min_joint_limit_margin_rad: margin_limit,
        min_reach_margin_m: margin_reach,
        max_stance_foot_speed_m_s: stance_foot_speed(plan, sol, &q_all),
        min_swing_apex_m: swing_apex(sol),
        mean_velocity: mean_velocity(&frames),
    };
    Ok((frames, report))
}

/// World positions of the feet at frame `k` from the base pose and forward kinematics.
fn feet_world(
    plan: &FootPlan,
    sol: &GaitSolution,
    q_all: &[[f32; NUM_JOINTS]],
    k: i64,
) -> [V3; NUM_LEGS] {
    let n = q_all.len() as i64;
    let (pos, rot) = base_pose(plan, sol, k);
    foot_positions_base(&q_all[k.rem_euclid(n) as usize])
        .map(|f| add(pos, mul_mv(&rot, f.map(|v| v as f64))))
}

fn stance_foot_speed(plan: &FootPlan, sol: &GaitSolution, q_all: &[[f32; NUM_JOINTS]]) -> f64 {
    let n = q_all.len();
    let dt = plan.schedule().frame_dt_s();
    let ground_z = ground_z_m(sol);
    let mut worst = 0.0f64;
    for k in 0..n {
        let a = feet_world(plan, sol, q_all, k as i64);
        let b = feet_world(plan, sol, q_all, k as i64 + 1);
        for leg in 0..NUM_LEGS {
            let on_ground = |frame: usize| sol.feet_m[frame][leg][2] <= ground_z + 1e-9;
            if sol.contacts[k][leg]
                && sol.contacts[(k + 1) % n][leg]
                && on_ground(k)
                && on_ground((k + 1) % n)
            {
                worst = worst.max(norm(sub(b[leg], a[leg])) / dt);
            }
        }
    }
    worst
}

/// Height of the foot centres on the ground: the lowest any foot path goes, m.
fn ground_z_m(sol: &GaitSolution) -> f64 {
    sol.feet_m
        .iter()
        .flatten()
        .map(|f| f[2])
        .fold(f64::INFINITY, f64::min)
}

fn swing_apex(sol: &GaitSolution) -> f64 {
    let stance_z = ground_z_m(sol);
    let mut apex = [f64::NEG_INFINITY; NUM_LEGS];
    for feet in &sol.feet_m {
        for leg in 0..NUM_LEGS {
            apex[leg] = apex[leg].max(feet[leg][2] - stance_z);
        }
    }
    apex.into_iter().fold(f64::INFINITY, f64::min)
}

fn mean_velocity(frames: &[Frame]) -> [f64; 3] {
    let n = frames.len() as f64;
    let sum = |f: &dyn Fn(&Frame) -> f32| frames.iter().map(|fr| f(fr) as f64).sum::<f64>() / n;
    [
        sum(&|f| f.lin_vel_base_m_s[0]),
        sum(&|f| f.lin_vel_base_m_s[1]),
        sum(&|f| f.ang_vel_base_rad_s[2]),
    ]
}
