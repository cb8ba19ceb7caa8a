//! The gait QP: base motion and stance forces of one periodic tripod cycle.
//!
//! Decision variables at each of the N frames k of the cycle (periodic indices):
//! the base offset from the commanded motion in C(t_k) coordinates,
//! `x_k = (dp_x, dp_y, dp_z, roll, pitch, dyaw)` (the base sits at `(0, 0, h0) + dp`), and
//! a ground force `f` (world axes) for every foot in stance; swing feet carry no force
//! variable (zero force). Velocities and accelerations are periodic central differences,
//! so the cycle closes on itself and its mean velocity is the command by construction.
//!
//! Constraints, linear in the variables:
//! - translation, in the rotating frame C (yaw rate w, command velocity v):
//!   `m (dp'' + 2 w z x dp' - w^2 dp_xy + w z x v) = sum f + m g` (exact for a point mass);
//! - rotation, small roll/pitch: `I th'' + w z x (I th') = sum r_i x f_i` with the lever arm
//!   `r_i` from the centre of mass to the contact point taken at the previous iterate
//!   (sequential convex programming: a few QPs, each convex);
//! - friction cones `|f_xy| <= mu f_z` (second-order cones, so `f_z >= 0`), `f_z <= f_max`;
//! - bounds on the base offset (height, roll, pitch, drift) that keep the feet reachable.
//!
//! Cost: effort `|f|^2`, force rate, forces at touch-down/lift-off frames (soft contact
//! switches), base linear and angular acceleration, velocity deviation from the command,
//! height, attitude and drift deviations.

use super::body::{nominal_base_height_m, RigidBody, GRAVITY_M_S2};
use super::feet::FootPlan;
use super::geom::{cross, norm, sub, V3};
use super::qp::{Affine, Lin, QpBuilder, QpError, QpSolution};
use hexapod_core::robot::{Leg, FOOT_RADIUS_M, NUM_LEGS};

/// Weights and limits of the gait QP.
#[derive(Clone, Debug)]
pub struct GaitQpConfig {
    /// Friction coefficient of the cones (conservative: the simulator's ground is higher).
    pub friction_mu: f64,
    /// Upper bound on each normal force, N.
    pub max_normal_force_n: f64,
    /// Effort weight per N^2.
    pub w_force: f64,
    /// Force-rate weight per N^2 between consecutive frames of one stance.
    pub w_force_rate: f64,
    /// Extra force weight on the first and last frame of each stance.
    pub w_force_switch: f64,
    /// Base linear acceleration weight per (m/s^2)^2.
    pub w_lin_acc: f64,
    /// Base angular acceleration weight per (rad/s^2)^2.
    pub w_ang_acc: f64,
    /// Velocity deviation weight per (m/s)^2.
    pub w_vel: f64,
    /// Yaw-rate deviation weight per (rad/s)^2.
    pub w_yaw_rate: f64,
    /// Height deviation weight per m^2.
    pub w_height: f64,
    /// Roll/pitch weight per rad^2.
    pub w_tilt: f64,
    /// Yaw deviation weight per rad^2.
    pub w_yaw: f64,
    /// Horizontal drift weight per m^2.
    pub w_drift: f64,
    /// Bound on |dp_x|, |dp_y|.
    pub max_drift_m: f64,
    /// Bound on |dp_z|.
    pub max_height_offset_m: f64,
    /// Bound on |roll|, |pitch|, |dyaw|.
    pub max_tilt_rad: f64,
    /// Sequential convex iterations (lever-arm updates).
    pub iterations: usize,
    /// Height of the base above the nominal stance's, m: the legs stand straighter, and a
    /// swing apex of a given height above the ground folds the thigh less.
    pub base_lift_m: f64,
}

impl Default for GaitQpConfig {
    fn default() -> Self {
        Self {
            friction_mu: 0.6,
            max_normal_force_n: 300.0,
            w_force: 1e-4,
            w_force_rate: 1e-3,
            w_force_switch: 2e-3,
            w_lin_acc: 1e-2,
            w_ang_acc: 1e-3,
            w_vel: 1.0,
            w_yaw_rate: 0.3,
            w_height: 100.0,
            w_tilt: 30.0,
            w_yaw: 10.0,
            w_drift: 10.0,
            max_drift_m: 0.05,
            max_height_offset_m: 0.04,
            max_tilt_rad: 0.15,
            iterations: 3,
            base_lift_m: 0.0,
        }
    }
}

/// The optimized cycle.
#[derive(Clone, Debug)]
pub struct GaitSolution {
    /// Base offset `(dp_x, dp_y, dp_z, roll, pitch, dyaw)` per frame, C coordinates.
    pub base: Vec<[f64; 6]>,
    /// Ground force per frame and leg (None in swing), world axes.
    pub forces_n: Vec<[Option<V3>; NUM_LEGS]>,
    /// Foot sphere centres per frame and leg, C coordinates.
    pub feet_m: Vec<[V3; NUM_LEGS]>,
    /// Contact flags per frame and leg.
    pub contacts: Vec<[bool; NUM_LEGS]>,
    /// Base height the cycle moves about (the nominal stance's plus the lift), m.
    pub base_height_m: f64,
    /// The last QP's solution.
    pub qp: QpSolution,
    /// Worst residual of the rotational dynamics with the lever arms of the final base
    /// motion (the linearization error), N m.
    pub max_moment_residual_nm: f64,
    /// Worst residual of the translational dynamics, N.
    pub max_force_residual_n: f64,
    /// Worst friction-cone violation `max(0, |f_xy| - mu f_z)`, N.
    pub max_friction_violation_n: f64,
}

/// Why a gait could not be optimized.
#[derive(Debug, thiserror::Error)]
pub enum GaitQpError {
    /// The QP could not be set up.
    #[error(transparent)]
    Qp(#[from] QpError),
    /// The solver did not find an optimum.
    #[error("solver stopped with status {status} after {iterations} iterations")]
    NotSolved {
        /// Clarabel's status.
        status: String,
        /// Interior-point iterations.
        iterations: u32,
    },
}

const NX: usize = 6;

/// Optimizes one periodic cycle of `plan`.
pub fn optimize_gait(plan: &FootPlan, cfg: &GaitQpConfig) -> Result<GaitSolution, GaitQpError> {
    let sched = plan.schedule();
    let n = sched.frames_per_cycle();
    let dt = sched.frame_dt_s();
    let body = RigidBody::hexapod();
    let h0 = nominal_base_height_m() + cfg.base_lift_m;
    let mut feet_m = Vec::with_capacity(n);
    let mut contacts = Vec::with_capacity(n);
    for k in 0..n {
        let t = k as f64 * dt;
        let mut f = [[0.0; 3]; NUM_LEGS];
        let mut c = [false; NUM_LEGS];
        for leg in Leg::ALL {
            (f[leg.index()], c[leg.index()]) = plan.foot_m(leg, t);
        }
        feet_m.push(f);
        contacts.push(c);
    }
    let mut com_offset = vec![[0.0; 3]; n];
    let mut last = None;
    for _ in 0..cfg.iterations.max(1) {
        let (qp, force_index) = build(plan, cfg, &body, h0, &feet_m, &contacts, &com_offset);
        let sol = qp.solve()?;
        if !sol.is_solved() {
            return Err(GaitQpError::NotSolved {
                status: format!("{:?}", sol.status),
                iterations: sol.iterations,
            });
        }
        for (k, off) in com_offset.iter_mut().enumerate() {
            *off = [0, 1, 2].map(|j| sol.x[NX * k + j]);
        }
        last = Some((sol, force_index));
    }
    let (qp, force_index) = last.expect("at least one iteration");
    let base: Vec<[f64; 6]> = (0..n)
        .map(|k| [0, 1, 2, 3, 4, 5].map(|j| qp.x[NX * k + j]))
        .collect();
    let forces_n: Vec<[Option<V3>; NUM_LEGS]> = force_index
        .iter()
        .map(|row| row.map(|idx| idx.map(|i| [qp.x[i], qp.x[i + 1], qp.x[i + 2]])))
        .collect();
    let (max_force_residual_n, max_moment_residual_nm) =
        dynamics_residuals(plan, &body, h0, &base, &forces_n, &feet_m);
    let max_friction_violation_n = forces_n
        .iter()
        .flatten()
        .flatten()
        .map(|f| (f[0].hypot(f[1]) - cfg.friction_mu * f[2]).max(0.0))
        .fold(0.0, f64::max);
    Ok(GaitSolution {
        base,
        forces_n,
        feet_m,
        contacts,
        base_height_m: h0,
        qp,
        max_moment_residual_nm,
        max_force_residual_n,
        max_friction_violation_n,
    })
}

/// Indices of the central differences at frame k: (prev, k, next).
fn neighbours(k: usize, n: usize) -> (usize, usize) {
    ((k + n - 1) % n, (k + 1) % n)
}

fn var(k: usize, j: usize) -> usize {
    NX * k + j
}

/// `d/dt x_j` at k: (x_next - x_prev) / 2dt.
fn d1(k: usize, j: usize, n: usize, dt: f64, coef: f64) -> Lin {
    let (p, q) = neighbours(k, n);
    vec![
        (var(q, j), coef / (2.0 * dt)),
        (var(p, j), -coef / (2.0 * dt)),
    ]
}

/// `d2/dt2 x_j` at k: (x_next - 2 x_k + x_prev) / dt^2.
fn d2(k: usize, j: usize, n: usize, dt: f64, coef: f64) -> Lin {
    let (p, q) = neighbours(k, n);
    let s = coef / (dt * dt);
    vec![(var(q, j), s), (var(k, j), -2.0 * s), (var(p, j), s)]
}

/// Contact point (ground) of a foot sphere centre.
fn contact_point(foot: V3) -> V3 {
    [foot[0], foot[1], foot[2] - FOOT_RADIUS_M as f64]
}

type ForceIndex = Vec<[Option<usize>; NUM_LEGS]>;

#[allow(clippy::too_many_arguments)]
fn build(
    plan: &FootPlan,
    cfg: &GaitQpConfig,
    body: &RigidBody,
    h0: f64,
    feet_m: &[[V3; NUM_LEGS]],
    contacts: &[[bool; NUM_LEGS]],
    com_offset: &[V3],
) -> (QpBuilder, ForceIndex) {
    let n = feet_m.len();
    let dt = plan.schedule().frame_dt_s();
    let cmd = plan.command();
    let (vx, vy, w) = (cmd.vx_m_s, cmd.vy_m_s, cmd.wz_rad_s);
    let m = body.mass_kg;
    let [ixx, iyy, izz] = body.inertia_kg_m2;
    let mut qp = QpBuilder::new();
    qp.add_vars(NX * n);
    let mut force_index: ForceIndex = vec![[None; NUM_LEGS]; n];
    for k in 0..n {
        for leg in 0..NUM_LEGS {
            if contacts[k][leg] {
                force_index[k][leg] = Some(qp.add_vars(3));
            }
        }
    }

    for k in 0..n {
        // Translation: m (dp'' + 2 w z x dp' - w^2 dp_xy) - sum f = -m w z x v + m g.
        let mut rows: [Lin; 3] = [
            [
                d2(k, 0, n, dt, m),
                d1(k, 1, n, dt, -2.0 * m * w),
                vec![(var(k, 0), -m * w * w)],
            ]
            .concat(),
            [
                d2(k, 1, n, dt, m),
                d1(k, 0, n, dt, 2.0 * m * w),
                vec![(var(k, 1), -m * w * w)],
            ]
            .concat(),
            d2(k, 2, n, dt, m),
        ];
        let rhs = [m * w * vy, -m * w * vx, -m * GRAVITY_M_S2];
        // Rotation: I th'' + w z x (I th') - sum r x f = 0.
        let mut rot: [Lin; 3] = [
            [d2(k, 3, n, dt, ixx), d1(k, 4, n, dt, -w * iyy)].concat(),
            [d2(k, 4, n, dt, iyy), d1(k, 3, n, dt, w * ixx)].concat(),
            d2(k, 5, n, dt, izz),
        ];
        let com = [com_offset[k][0], com_offset[k][1], h0 + com_offset[k][2]];
        for leg in 0..NUM_LEGS {
            let Some(fi) = force_index[k][leg] else {
                continue;
            };
            for (j, row) in rows.iter_mut().enumerate() {
                row.push((fi + j, -1.0));
            }
            let r = sub(contact_point(feet_m[k][leg]), com);
            // (r x f)_x = r_y f_z - r_z f_y, (r x f)_y = r_z f_x - r_x f_z,
            // (r x f)_z = r_x f_y - r_y f_x; subtracted.
            rot[0].extend([(fi + 2, -r[1]), (fi + 1, r[2])]);
            rot[1].extend([(fi, -r[2]), (fi + 2, r[0])]);
            rot[2].extend([(fi + 1, -r[0]), (fi, r[1])]);
        }
        for (row, b) in rows.into_iter().zip(rhs) {
            qp.add_equality(row, b);
        }
        for row in rot {
            qp.add_equality(row, 0.0);
        }

        // Costs on the base.
        for j in 0..3 {
            qp.add_square(
                cfg.w_lin_acc,
                Affine {
                    lin: d2(k, j, n, dt, 1.0),
                    constant: 0.0,
                },
            );
            qp.add_square(
                cfg.w_ang_acc,
                Affine {
                    lin: d2(k, 3 + j, n, dt, 1.0),
                    constant: 0.0,
                },
            );
            qp.add_square(
                cfg.w_vel,
                Affine {
                    lin: d1(k, j, n, dt, 1.0),
                    constant: 0.0,
                },
            );
        }
        qp.add_square(
            cfg.w_yaw_rate,
            Affine {
                lin: d1(k, 5, n, dt, 1.0),
                constant: 0.0,
            },
        );
        qp.add_square(cfg.w_drift, Affine::var(var(k, 0), 1.0));
        qp.add_square(cfg.w_drift, Affine::var(var(k, 1), 1.0));
        qp.add_square(cfg.w_height, Affine::var(var(k, 2), 1.0));
        qp.add_square(cfg.w_tilt, Affine::var(var(k, 3), 1.0));
        qp.add_square(cfg.w_tilt, Affine::var(var(k, 4), 1.0));
        qp.add_square(cfg.w_yaw, Affine::var(var(k, 5), 1.0));
        qp.add_bounds(var(k, 0), -cfg.max_drift_m, cfg.max_drift_m);
        qp.add_bounds(var(k, 1), -cfg.max_drift_m, cfg.max_drift_m);
        qp.add_bounds(var(k, 2), -cfg.max_height_offset_m, cfg.max_height_offset_m);
        for j in 3..6 {
            qp.add_bounds(var(k, j), -cfg.max_tilt_rad, cfg.max_tilt_rad);
        }

        // Forces: cones, bounds, effort, rate, soft switches.
        for (leg, slot) in force_index[k].iter().enumerate() {
            let Some(fi) = *slot else {
                continue;
            };
            qp.add_cone([
                Affine::var(fi + 2, cfg.friction_mu),
                Affine::var(fi, 1.0),
                Affine::var(fi + 1, 1.0),
            ]);
            qp.add_inequality(vec![(fi + 2, 1.0)], cfg.max_normal_force_n);
            let (prev, next) = neighbours(k, n);
            let switching = force_index[prev][leg].is_none() || force_index[next][leg].is_none();
            let w_f = cfg.w_force + if switching { cfg.w_force_switch } else { 0.0 };
            for j in 0..3 {
                qp.add_square(w_f, Affine::var(fi + j, 1.0));
                if let Some(fp) = force_index[prev][leg] {
                    qp.add_square(
                        cfg.w_force_rate,
                        Affine {
                            lin: vec![(fi + j, 1.0), (fp + j, -1.0)],
                            constant: 0.0,
                        },
                    );
                }
            }
        }
    }
    (qp, force_index)
}

/// Residuals of the rigid-body equations with lever arms from the final base motion.
fn dynamics_residuals(
    plan: &FootPlan,
    body: &RigidBody,
    h0: f64,
    base: &[[f64; 6]],
    forces_n: &[[Option<V3>; NUM_LEGS]],
    feet_m: &[[V3; NUM_LEGS]],
) -> (f64, f64) {
    let n = base.len();
    let dt = plan.schedule().frame_dt_s();
    let cmd = plan.command();
    let w = cmd.wz_rad_s;
    let m = body.mass_kg;
    let i = body.inertia_kg_m2;
    let (mut worst_f, mut worst_m) = (0.0f64, 0.0f64);
    for k in 0..n {
        let (p, q) = neighbours(k, n);
        let vel = |j: usize| (base[q][j] - base[p][j]) / (2.0 * dt);
        let acc = |j: usize| (base[q][j] - 2.0 * base[k][j] + base[p][j]) / (dt * dt);
        let mut sum_f = [0.0; 3];
        let mut sum_m = [0.0; 3];
        let com = [base[k][0], base[k][1], h0 + base[k][2]];
        for leg in 0..NUM_LEGS {
            if let Some(f) = forces_n[k][leg] {
                let r = sub(contact_point(feet_m[k][leg]), com);
                let rf = cross(r, f);
                for j in 0..3 {
                    sum_f[j] += f[j];
                    sum_m[j] += rf[j];
                }
            }
        }
        let lin = [
            m * (acc(0) - 2.0 * w * vel(1) - w * w * base[k][0] - w * cmd.vy_m_s) - sum_f[0],
            m * (acc(1) + 2.0 * w * vel(0) - w * w * base[k][1] + w * cmd.vx_m_s) - sum_f[1],
            m * (acc(2) + GRAVITY_M_S2) - sum_f[2],
        ];
        let ang = [
            i[0] * acc(3) - w * i[1] * vel(4) - sum_m[0],
            i[1] * acc(4) + w * i[0] * vel(3) - sum_m[1],
            i[2] * acc(5) - sum_m[2],
        ];
        worst_f = worst_f.max(norm(lin));
        worst_m = worst_m.max(norm(ang));
    }
    (worst_f, worst_m)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::priors::command::GaitCommand;
    use crate::priors::schedule::TripodSchedule;

    fn solve(vx: f64, vy: f64, wz: f64) -> GaitSolution {
        let plan = FootPlan::new(
            GaitCommand::new("t", vx, vy, wz),
            TripodSchedule::new(30, 13).unwrap(),
            0.08,
        );
        optimize_gait(&plan, &GaitQpConfig::default()).unwrap()
    }

    #[test]
    fn forces_carry_the_weight_and_respect_the_cones() {
        let sol = solve(0.3, 0.0, 0.0);
        let body = RigidBody::hexapod();
        let n = sol.base.len() as f64;
        // Averaged over a periodic cycle, accelerations vanish: mean vertical force = m g.
        let mean_fz: f64 = sol
            .forces_n
            .iter()
            .flatten()
            .flatten()
            .map(|f| f[2])
            .sum::<f64>()
            / n;
        assert!(
            (mean_fz - body.mass_kg * GRAVITY_M_S2).abs() < 1e-3,
            "{mean_fz}"
        );
        assert!(sol.qp.max_violation() < 1e-6, "{}", sol.qp.max_violation());
        assert!(sol.max_friction_violation_n < 1e-4);
        assert!(sol.max_force_residual_n < 1e-4);
        // Sequential iterations make the linearization error small against m g.
        assert!(
            sol.max_moment_residual_nm < 0.5,
            "{}",
            sol.max_moment_residual_nm
        );
        // Swing feet carry no force.
        for (row, contacts) in sol.forces_n.iter().zip(&sol.contacts) {
            for (force, in_contact) in row.iter().zip(contacts) {
                assert_eq!(force.is_some(), *in_contact);
            }
        }
    }

    #[test]
    fn standing_in_place_needs_no_base_motion_beyond_sway() {
        // Zero command: the base stays near nominal and the forces are symmetric enough.
        let sol = solve(0.0, 0.0, 0.0);
        for x in &sol.base {
            assert!(
                x[2].abs() < 0.02 && x[3].abs() < 0.05 && x[4].abs() < 0.05,
                "{x:?}"
            );
        }
    }

    #[test]
    fn turning_balances_the_centripetal_force() {
        // Walking an arc: the mean horizontal force points to the centre, m v w.
        let sol = solve(0.3, 0.0, 0.5);
        let n = sol.base.len() as f64;
        let mean_fy: f64 = sol
            .forces_n
            .iter()
            .flatten()
            .flatten()
            .map(|f| f[1])
            .sum::<f64>()
            / n;
        let expect = RigidBody::hexapod().mass_kg * 0.3 * 0.5;
        assert!(
            (mean_fy - expect).abs() < 0.1 * expect,
            "{mean_fy} vs {expect}"
        );
    }
}
