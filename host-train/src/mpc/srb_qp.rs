//! The convex MPC: single-rigid-body dynamics over a short horizon with the stance feet's
//! ground forces as inputs, friction cones as second-order cones, solved by clarabel through
//! the priors' QP builder ([`crate::priors::qp`]).
//!
//! The model is the one of Di Carlo et al. (2018), "Dynamic locomotion in the MIT Cheetah 3
//! through convex model-predictive control": state `x = (roll, pitch, yaw, p, w, v)` (12),
//! in the heading frame H of the current instant (world axes turned by the current yaw,
//! origin on the ground under the base; yaw measured from the current heading), linearized
//! for small roll and pitch:
//!
//! - `Theta' = Rz(yaw)^T w`, `p' = v`,
//! - `I_w w' = sum r_i x f_i` with `I_w = Rz(yaw) I_body Rz(yaw)^T` and the lever arms `r_i`
//!   (foot minus centre of mass) taken from the plan,
//! - `m v' = sum f_i + m g`,
//!
//! discretized by semi-implicit Euler (positions from the new velocities). Swing feet carry no
//! force. Constraints: `|f_xy| <= mu f_z`, `f_z <= f_max`. Cost: weighted squared deviation
//! from the reference states plus a small force weight.

use super::params::MpcParams;
use crate::priors::body::{RigidBody, GRAVITY_M_S2};
use crate::priors::qp::{Affine, QpBuilder, QpError, QpSolution};
use hexapod_core::robot::NUM_LEGS;

/// State dimension.
pub const NX: usize = 12;

/// One horizon's problem.
#[derive(Clone, Debug)]
pub struct SrbProblem {
    /// Current state (roll, pitch, yaw, p, w, v), H frame.
    pub x0: [f64; NX],
    /// Reference states at steps 1..=N.
    pub x_ref: Vec<[f64; NX]>,
    /// Lever arm (foot minus centre of mass, H frame) of every stance foot at steps 0..N-1;
    /// `None` for a foot in the air.
    pub lever_arms_m: Vec<[Option<[f64; 3]>; NUM_LEGS]>,
    /// Step of the horizon, s.
    pub dt_s: f64,
}

/// The solved horizon.
#[derive(Clone, Debug)]
pub struct SrbSolution {
    /// Ground force on each foot at step 0 (None in the air), H frame, N.
    pub forces_n: [Option<[f64; 3]>; NUM_LEGS],
    /// Predicted states at steps 1..=N.
    pub predicted: Vec<[f64; NX]>,
    /// The QP's solution (status, iterations, constraint violations).
    pub qp: QpSolution,
}

/// Why the horizon could not be solved.
#[derive(Debug, thiserror::Error)]
pub enum SrbError {
    /// The QP could not be set up.
    #[error(transparent)]
    Qp(#[from] QpError),
    /// The solver stopped without an optimum.
    #[error("MPC QP not solved: {0}")]
    NotSolved(String),
    /// The problem's arrays disagree in length.
    #[error("MPC horizon: {refs} reference states but {arms} contact steps")]
    Shape {
        /// Reference states given.
        refs: usize,
        /// Contact steps given.
        arms: usize,
    },
}

fn rz(yaw: f64) -> [[f64; 3]; 3] {
    let (s, c) = yaw.sin_cos();
    [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
}

/// `Rz I^-1 Rz^T` for a diagonal body inertia.
fn world_inverse_inertia(body: &RigidBody, yaw: f64) -> [[f64; 3]; 3] {
    let r = rz(yaw);
    let mut out = [[0.0; 3]; 3];
    for (i, row) in out.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = (0..3)
                .map(|k| r[i][k] * r[j][k] / body.inertia_kg_m2[k])
                .sum();
        }
    }
    out
}

/// `[r]x`: the matrix of `f -> r x f`.
fn skew(r: [f64; 3]) -> [[f64; 3]; 3] {
    [[0.0, -r[2], r[1]], [r[2], 0.0, -r[0]], [-r[1], r[0], 0.0]]
}

fn matmul(a: [[f64; 3]; 3], b: [[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let mut out = [[0.0; 3]; 3];
    for (i, row) in out.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    out
}

/// Solves the horizon for the robot's rigid body.
pub fn solve(
    problem: &SrbProblem,
    body: &RigidBody,
    p: &MpcParams,
) -> Result<SrbSolution, SrbError> {
    let n = problem.x_ref.len();
    if problem.lever_arms_m.len() != n || n == 0 {
        return Err(SrbError::Shape {
            refs: n,
            arms: problem.lever_arms_m.len(),
        });
    }
    let dt = problem.dt_s;
    let mut qp = QpBuilder::new();
    let xs = qp.add_vars(NX * n);
    // State j at step k as an affine expression (step 0 is the measured state).
    let state = |k: usize, j: usize, coef: f64| -> Affine {
        if k == 0 {
            Affine {
                lin: Vec::new(),
                constant: coef * problem.x0[j],
            }
        } else {
            Affine::var(xs + NX * (k - 1) + j, coef)
        }
    };
    let mut force_vars: Vec<[Option<usize>; NUM_LEGS]> = Vec::with_capacity(n);
    for arms in &problem.lever_arms_m {
        let mut vars = [None; NUM_LEGS];
        for (leg, arm) in arms.iter().enumerate() {
            if arm.is_some() {
                let f = qp.add_vars(3);
                qp.add_cone([
                    Affine::var(f + 2, p.friction_mu),
                    Affine::var(f, 1.0),
                    Affine::var(f + 1, 1.0),
                ]);
                qp.add_inequality(vec![(f + 2, 1.0)], p.max_normal_force_n);
                for a in 0..3 {
                    qp.add_square(p.w_force, Affine::var(f + a, 1.0));
                }
                vars[leg] = Some(f);
            }
        }
        force_vars.push(vars);
    }
    let mut equal_zero = |terms: Vec<Affine>| {
        let mut lin = Vec::new();
        let mut constant = 0.0;
        for t in terms {
            lin.extend(t.lin);
            constant += t.constant;
        }
        qp.add_equality(lin, -constant);
    };
    let gravity = [0.0, 0.0, -GRAVITY_M_S2];
    for k in 0..n {
        let yaw_k = if k == 0 {
            problem.x0[2]
        } else {
            problem.x_ref[k - 1][2]
        };
        let forces: Vec<(usize, [f64; 3])> = force_vars[k]
            .iter()
            .zip(&problem.lever_arms_m[k])
            .filter_map(|(v, r)| Some(((*v)?, (*r)?)))
            .collect();
        // v_{k+1} = v_k + dt (sum f / m + g).
        for a in 0..3 {
            let mut t = vec![
                state(k + 1, 9 + a, 1.0),
                state(k, 9 + a, -1.0),
                Affine {
                    lin: Vec::new(),
                    constant: -dt * gravity[a],
                },
            ];
            for &(f, _) in &forces {
                t.push(Affine::var(f + a, -dt / body.mass_kg));
            }
            equal_zero(t);
        }
        // p_{k+1} = p_k + dt v_{k+1}.
        for a in 0..3 {
            equal_zero(vec![
                state(k + 1, 3 + a, 1.0),
                state(k, 3 + a, -1.0),
                state(k + 1, 9 + a, -dt),
            ]);
        }
        // w_{k+1} = w_k + dt I_w^-1 sum r x f.
        let inv_i = world_inverse_inertia(body, yaw_k);
        let maps: Vec<(usize, [[f64; 3]; 3])> = forces
            .iter()
            .map(|&(f, r)| (f, matmul(inv_i, skew(r))))
            .collect();
        for a in 0..3 {
            let mut t = vec![state(k + 1, 6 + a, 1.0), state(k, 6 + a, -1.0)];
            for (f, m) in &maps {
                t.push(Affine {
                    lin: (0..3).map(|b| (f + b, -dt * m[a][b])).collect(),
                    constant: 0.0,
                });
            }
            equal_zero(t);
        }
        // Theta_{k+1} = Theta_k + dt Rz(yaw)^T w_{k+1}.
        let r = rz(yaw_k);
        for a in 0..3 {
            let mut t = vec![state(k + 1, a, 1.0), state(k, a, -1.0)];
            for b in 0..3 {
                // (Rz^T)[a][b] = Rz[b][a].
                t.push(state(k + 1, 6 + b, -dt * r[b][a]));
            }
            equal_zero(t);
        }
    }
    let weights: [f64; NX] = {
        let mut w = [0.0; NX];
        w[0..3].copy_from_slice(&p.w_attitude);
        w[3..6].copy_from_slice(&p.w_position);
        w[6..9].copy_from_slice(&p.w_angular_velocity);
        w[9..12].copy_from_slice(&p.w_linear_velocity);
        w
    };
    for (k, x_ref) in problem.x_ref.iter().enumerate() {
        for j in 0..NX {
            qp.add_square(
                weights[j],
                Affine {
                    lin: vec![(xs + NX * k + j, 1.0)],
                    constant: -x_ref[j],
                },
            );
        }
    }
    let sol = qp.solve()?;
    if !sol.is_solved() {
        return Err(SrbError::NotSolved(format!("{:?}", sol.status)));
    }
    let forces_n = force_vars[0].map(|v| v.map(|f| [sol.x[f], sol.x[f + 1], sol.x[f + 2]]));
    let predicted = (0..n)
        .map(|k| {
            let mut x = [0.0; NX];
            x.copy_from_slice(&sol.x[xs + NX * k..xs + NX * (k + 1)]);
            x
        })
        .collect();
    Ok(SrbSolution {
        forces_n,
        predicted,
        qp: sol,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::priors::body::{nominal_base_height_m, nominal_feet_m};

    fn standing(height_m: f64) -> SrbProblem {
        let mut x0 = [0.0; NX];
        x0[5] = height_m;
        let feet = nominal_feet_m();
        let arms: [Option<[f64; 3]>; NUM_LEGS] =
            std::array::from_fn(|i| Some([feet[i][0], feet[i][1], feet[i][2] - height_m]));
        SrbProblem {
            x0,
            x_ref: vec![x0; 8],
            lever_arms_m: vec![arms; 8],
            dt_s: 0.04,
        }
    }

    #[test]
    fn standing_forces_carry_the_weight_inside_the_cones() {
        let p = MpcParams::default();
        let body = RigidBody::hexapod();
        let s = solve(&standing(nominal_base_height_m()), &body, &p).unwrap();
        let forces: Vec<[f64; 3]> = s.forces_n.iter().map(|f| f.unwrap()).collect();
        let fz: f64 = forces.iter().map(|f| f[2]).sum();
        let weight = body.mass_kg * GRAVITY_M_S2;
        assert!((fz - weight).abs() < 0.01 * weight, "{fz} vs {weight}");
        for f in &forces {
            assert!(f[2] > 0.0 && f[0].hypot(f[1]) <= p.friction_mu * f[2] + 1e-6);
            // Six feet share the weight, none carries more than half of it.
            assert!(f[2] < 0.5 * weight, "{f:?}");
        }
        assert!(s.qp.max_cone_violation < 1e-6);
        // At rest on the reference it stays there.
        let last = s.predicted.last().unwrap();
        assert!(
            (last[5] - nominal_base_height_m()).abs() < 2e-3,
            "{} vs {}",
            last[5],
            nominal_base_height_m()
        );
    }

    #[test]
    fn a_sagging_body_is_lifted_and_a_tilted_one_righted() {
        let p = MpcParams::default();
        let body = RigidBody::hexapod();
        let h = nominal_base_height_m();
        let mut prob = standing(h);
        prob.x0[5] = h - 0.03;
        let s = solve(&prob, &body, &p).unwrap();
        let fz: f64 = s.forces_n.iter().map(|f| f.unwrap()[2]).sum();
        assert!(fz > body.mass_kg * GRAVITY_M_S2 * 1.05, "{fz}");
        // Rolled right (positive roll): the right feet (negative y) push harder.
        let mut prob = standing(h);
        prob.x0[0] = 0.1;
        let s = solve(&prob, &body, &p).unwrap();
        let f: Vec<f64> = s.forces_n.iter().map(|f| f.unwrap()[2]).collect();
        // Legs 0..3 are the right legs.
        assert!(f[0] + f[1] + f[2] > f[3] + f[4] + f[5], "{f:?}");
    }

    #[test]
    fn shapes_are_checked() {
        let mut prob = standing(0.3);
        prob.lever_arms_m.pop();
        let e = solve(&prob, &RigidBody::hexapod(), &MpcParams::default()).unwrap_err();
        assert_eq!(
            e.to_string(),
            "MPC horizon: 8 reference states but 7 contact steps"
        );
    }
}
