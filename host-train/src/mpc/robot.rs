//! One robot's controller step: gait clock, footholds and swings, the horizon QP, and the drive
//! targets, from the simulator's true state (no state estimation: base pose and velocity,
//! joint angles; the controller is blind and takes the ground as flat at the height of its
//! stance feet).

use super::footholds::{displacement_m, foothold_xy_m, rotate_xy, swing_point_m, FootholdInput};
use super::gait::{GaitClock, LegPhase};
use super::joints::{drive_target_rad, inverse_kinematics, joint_velocity_rad_s, stance_torque_nm};
use super::params::MpcParams;
use super::srb_qp::{solve, SrbProblem, NX};
use crate::priors::body::{nominal_feet_m, RigidBody, GRAVITY_M_S2};
use hexapod_core::kinematics::foot_position_base;
use hexapod_core::robot::{Leg, FOOT_RADIUS_M, JOINTS_PER_LEG, NUM_JOINTS, NUM_LEGS};
use hexapod_core::timing::POLICY_DT_S;
use host_sim::robot::RobotState;

/// Below this speed (m/s) and yaw rate (rad/s) the command means "stand".
pub const STAND_COMMAND: f64 = 0.02;
/// Low-pass factor per control step of the ground-height estimate.
const GROUND_FILTER: f64 = 0.3;
/// A swing aims this far below the estimated ground, so that it lands rather than hovers, m.
const LANDING_DEPTH_M: f64 = 0.005;

/// Rotation matrix (world from base) of a quaternion (x, y, z, w).
fn rotation(q: [f32; 4]) -> [[f64; 3]; 3] {
    let [x, y, z, w] = q.map(f64::from);
    [
        [
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y - w * z),
            2.0 * (x * z + w * y),
        ],
        [
            2.0 * (x * y + w * z),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z - w * x),
        ],
        [
            2.0 * (x * z - w * y),
            2.0 * (y * z + w * x),
            1.0 - 2.0 * (x * x + y * y),
        ],
    ]
}

fn mul(r: &[[f64; 3]; 3], v: [f64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|i| r[i][0] * v[0] + r[i][1] * v[1] + r[i][2] * v[2])
}

fn mul_t(r: &[[f64; 3]; 3], v: [f64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|i| r[0][i] * v[0] + r[1][i] * v[1] + r[2][i] * v[2])
}

fn yaw_rotation(yaw: f64) -> [[f64; 3]; 3] {
    let (s, c) = yaw.sin_cos();
    [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
}

/// What one step decided (for tests and diagnostics).
#[derive(Clone, Copy, Debug, Default)]
pub struct StepInfo {
    /// Ground force the MPC wants on each stance foot, world axes, N.
    pub forces_world_n: [Option<[f64; 3]>; NUM_LEGS],
    /// Largest friction-cone violation of the QP's solution, N.
    pub max_cone_violation_n: f64,
    /// The QP was solved (otherwise the weight was split evenly over the stance feet).
    pub solved: bool,
    /// Estimated ground height, m.
    pub ground_z_m: f64,
}

/// The controller state of one robot.
#[derive(Clone, Debug)]
pub struct RobotMpc {
    clock: GaitClock,
    started: bool,
    in_stance: [bool; NUM_LEGS],
    lift_off_world_m: [[f64; 3]; NUM_LEGS],
    ground_z_m: f64,
    /// Steps whose QP was not solved.
    pub qp_failures: usize,
    /// The last step.
    pub last: StepInfo,
}

impl RobotMpc {
    /// A controller at rest (a fresh episode).
    pub fn new(p: &MpcParams) -> Self {
        Self {
            clock: GaitClock::new(p.gait_period_s, p.swing_fraction),
            started: false,
            in_stance: [true; NUM_LEGS],
            lift_off_world_m: [[0.0; 3]; NUM_LEGS],
            ground_z_m: 0.0,
            qp_failures: 0,
            last: StepInfo::default(),
        }
    }

    /// Joint position targets for the next control period (50 Hz) at `command`
    /// (vx m/s, vy m/s, wz rad/s in the heading frame).
    pub fn step(
        &mut self,
        p: &MpcParams,
        body: &RigidBody,
        s: &RobotState,
        command: [f32; 3],
    ) -> [f32; NUM_JOINTS] {
        let dt_c = POLICY_DT_S as f64;
        let cmd = command.map(f64::from);
        let moving = cmd[0].hypot(cmd[1]) > STAND_COMMAND || cmd[2].abs() > STAND_COMMAND;
        if self.started {
            self.clock.advance(dt_c, moving);
        }
        let base = s.base_pos_world_m.map(f64::from);
        let r_wb = rotation(s.base_quat_xyzw);
        let yaw = r_wb[1][0].atan2(r_wb[0][0]);
        let q: [f64; NUM_JOINTS] = s.q_rad.map(f64::from);
        let q_leg = |leg: Leg| -> [f64; 3] {
            let j = JOINTS_PER_LEG * leg.index();
            [q[j], q[j + 1], q[j + 2]]
        };
        let feet_w: [[f64; 3]; NUM_LEGS] = Leg::ALL.map(|leg| {
            let f = foot_position_base(leg, q_leg(leg).map(|v| v as f32)).map(f64::from);
            let r = mul(&r_wb, f);
            [base[0] + r[0], base[1] + r[1], base[2] + r[2]]
        });
        let phases = Leg::ALL.map(|leg| self.clock.leg_phase(leg));
        let stance_now = phases.map(|ph| ph == LegPhase::Stance);
        for leg in 0..NUM_LEGS {
            if self.in_stance[leg] && !stance_now[leg] {
                self.lift_off_world_m[leg] = feet_w[leg];
            }
        }
        // Ground: the stance feet that were already down, low-passed.
        let settled: Vec<f64> = (0..NUM_LEGS)
            .filter(|&l| stance_now[l] && self.in_stance[l])
            .map(|l| feet_w[l][2] - FOOT_RADIUS_M as f64)
            .collect();
        if !settled.is_empty() {
            let z = settled.iter().sum::<f64>() / settled.len() as f64;
            self.ground_z_m = if self.started {
                self.ground_z_m + GROUND_FILTER * (z - self.ground_z_m)
            } else {
                z
            };
        }
        self.in_stance = stance_now;
        self.started = true;
        let ground = self.ground_z_m;

        // Heading frame H: world axes turned by the yaw, origin on the ground under the base.
        let to_h = |w: [f64; 3]| -> [f64; 3] {
            let d = rotate_xy(-yaw, [w[0] - base[0], w[1] - base[1]]);
            [d[0], d[1], w[2] - ground]
        };
        let roll = r_wb[2][1].atan2(r_wb[2][2]);
        let pitch = (-r_wb[2][0]).clamp(-1.0, 1.0).asin();
        let w_h = {
            let w = s.base_ang_vel_world_rad_s.map(f64::from);
            let xy = rotate_xy(-yaw, [w[0], w[1]]);
            [xy[0], xy[1], w[2]]
        };
        let v_w = s.base_lin_vel_world_m_s.map(f64::from);
        let v_h = {
            let xy = rotate_xy(-yaw, [v_w[0], v_w[1]]);
            [xy[0], xy[1], v_w[2]]
        };
        let mut x0 = [0.0; NX];
        x0[0..3].copy_from_slice(&[roll, pitch, 0.0]);
        x0[3..6].copy_from_slice(&[0.0, 0.0, base[2] - ground]);
        x0[6..9].copy_from_slice(&w_h);
        x0[9..12].copy_from_slice(&v_h);
        let (n, dt_h) = (p.horizon_steps, p.horizon_dt_s);
        let v_cmd = [cmd[0], cmd[1]];
        let reference = |t: f64| -> [f64; NX] {
            let yaw_t = cmd[2] * t;
            let d = displacement_m(0.0, v_cmd, cmd[2], t);
            let v = rotate_xy(yaw_t, v_cmd);
            [
                0.0,
                0.0,
                yaw_t,
                d[0],
                d[1],
                p.body_height_m,
                0.0,
                0.0,
                cmd[2],
                v[0],
                v[1],
                0.0,
            ]
        };
        let x_ref: Vec<[f64; NX]> = (1..=n).map(|k| reference(k as f64 * dt_h)).collect();

        // Footholds, world xy, as a function of the time to touch-down.
        let fh_input = FootholdInput {
            base_xy_m: [base[0], base[1]],
            yaw_rad: yaw,
            command: cmd,
            velocity_xy_m_s: [v_w[0], v_w[1]],
            stance_s: p.stance_s(),
            raibert_gain_s: p.raibert_gain_s,
        };
        let nominal = nominal_feet_m();
        let foothold_w = |leg: usize, t_td: f64| -> [f64; 3] {
            let xy = foothold_xy_m(&fh_input, [nominal[leg][0], nominal[leg][1]], t_td);
            [xy[0], xy[1], ground + FOOT_RADIUS_M as f64]
        };

        // Contact plan over the horizon: lever arms from the reference centre of mass.
        let mut swung = [false; NUM_LEGS];
        let mut planned: [Option<[f64; 3]>; NUM_LEGS] = [None; NUM_LEGS];
        let mut lever_arms_m = Vec::with_capacity(n);
        for k in 0..n {
            let t = k as f64 * dt_h;
            let phase = self.clock.phase_after(t, moving);
            let com = if k == 0 {
                [x0[3], x0[4], x0[5]]
            } else {
                let r = &x_ref[k - 1];
                [r[3], r[4], r[5]]
            };
            let arms = std::array::from_fn(|leg| {
                if self.clock.leg_phase_at(Leg::ALL[leg], phase) != LegPhase::Stance {
                    swung[leg] = true;
                    return None;
                }
                let foot_h = if stance_now[leg] && !swung[leg] {
                    to_h(feet_w[leg])
                } else {
                    *planned[leg].get_or_insert_with(|| to_h(foothold_w(leg, t)))
                };
                Some([foot_h[0] - com[0], foot_h[1] - com[1], foot_h[2] - com[2]])
            });
            lever_arms_m.push(arms);
        }
        let problem = SrbProblem {
            x0,
            x_ref,
            lever_arms_m,
            dt_s: dt_h,
        };
        let stance_count = stance_now.iter().filter(|&&b| b).count().max(1);
        let (forces_h, solved, cone) = match solve(&problem, body, p) {
            Ok(sol) => (sol.forces_n, true, sol.qp.max_cone_violation),
            Err(_) => {
                self.qp_failures += 1;
                let fz = body.mass_kg * GRAVITY_M_S2 / stance_count as f64;
                let f = std::array::from_fn(|l| stance_now[l].then_some([0.0, 0.0, fz]));
                (f, false, 0.0)
            }
        };
        let forces_w = forces_h.map(|f| {
            f.map(|f| {
                let xy = rotate_xy(yaw, [f[0], f[1]]);
                [xy[0], xy[1], f[2]]
            })
        });
        self.last = StepInfo {
            forces_world_n: forces_w,
            max_cone_violation_n: cone,
            solved,
            ground_z_m: ground,
        };

        // Desired base pose one control period ahead, for the stance legs' kinematics.
        let d = displacement_m(yaw, v_cmd, cmd[2], dt_c);
        let base_des = [base[0] + d[0], base[1] + d[1], ground + p.body_height_m];
        let r_des = yaw_rotation(yaw + cmd[2] * dt_c);
        let mut targets = [0.0f32; NUM_JOINTS];
        for leg in Leg::ALL {
            let l = leg.index();
            let ql = q_leg(leg);
            let (q_ref, gain, tau, qdot_ref) = match (phases[l], forces_w[l]) {
                (LegPhase::Stance, force) => {
                    let rel = [0, 1, 2].map(|a| feet_w[l][a] - base_des[a]);
                    let foot_des = mul_t(&r_des, rel);
                    let q_ref = inverse_kinematics(leg, foot_des).unwrap_or(ql);
                    let tau = force
                        .map(|f| stance_torque_nm(leg, ql, mul_t(&r_wb, f)))
                        .unwrap_or([0.0; 3]);
                    // The foot's velocity relative to a base moving as commanded.
                    let v_foot = [
                        -cmd[0] + cmd[2] * foot_des[1],
                        -cmd[1] - cmd[2] * foot_des[0],
                        0.0,
                    ];
                    let qdot = joint_velocity_rad_s(leg, ql, v_foot).unwrap_or([0.0; 3]);
                    (q_ref, p.stance_position_gain, tau, qdot)
                }
                (LegPhase::Swing(u), _) => {
                    let t_td = self.clock.time_to_touch_down_s(leg);
                    let hold = foothold_w(l, t_td);
                    let u_lead = (u + p.swing_lead_s / p.swing_s()).min(1.0);
                    let target = swing_point_m(
                        self.lift_off_world_m[l],
                        [hold[0], hold[1]],
                        hold[2] - LANDING_DEPTH_M,
                        p.lift_height_m,
                        u_lead,
                    );
                    let rel = [0, 1, 2].map(|a| target[a] - base[a]);
                    let q_ref = inverse_kinematics(leg, mul_t(&r_wb, rel)).unwrap_or(ql);
                    (q_ref, 1.0, [0.0; 3], [0.0; 3])
                }
            };
            for k in 0..JOINTS_PER_LEG {
                targets[JOINTS_PER_LEG * l + k] =
                    drive_target_rad(ql[k], q_ref[k], gain, tau[k], qdot_ref[k]) as f32;
            }
        }
        targets
    }
}
