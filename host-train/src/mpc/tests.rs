//! The MPC in host-sim: it walks, it stands, its forces are physical. Nominal robots (no
//! randomization, no pushes) on flat ground; a few seconds of simulated time each.

use super::*;
use crate::cli::suite::batch::{heading_velocity_m_s, tilt_rad};
use crate::config::TrainConfig;
use crate::priors::body::GRAVITY_M_S2;
use host_sim::env::{HexapodEnv, SpawnPose};
use host_sim::vec_env::VecEnv;

/// How a run went, per robot.
#[derive(Clone, Debug, Default)]
struct RunStats {
    fell: bool,
    /// Mean heading-frame velocity (vx, vy) and yaw rate after the settling time.
    mean_velocity: [f64; 3],
    /// Largest tilt after the settling time, deg.
    max_tilt_deg: f64,
    /// Mean base height above the ground after the settling time, m.
    mean_height_m: f64,
    /// Largest horizontal drift from the start, m.
    max_drift_m: f64,
}

/// Runs `n` robots at `command` for `duration_s`, measuring after `settle_s`: nominal robots,
/// or with the suite's randomization when `randomized`.
fn run_robots(
    params: &MpcParams,
    command: [f32; 3],
    duration_s: f32,
    settle_s: f32,
    n: usize,
    randomized: bool,
) -> (Vec<RunStats>, MpcController) {
    let mut sim = TrainConfig::default().resolved_sim();
    sim.num_envs = n;
    sim.seed = 3;
    sim.randomization.enabled = randomized;
    sim.randomization.friction = crate::cli::suite::batch::SUITE_FRICTION;
    sim.push.enabled = false;
    sim.observation_noise = false;
    sim.terrain = host_sim::terrain::TerrainConfig::default();
    sim.curriculum = false;
    sim.reference_init_probability = 0.0;
    sim.episode_length_s = duration_s + 1.0;
    let mut env = HexapodEnv::new(sim).unwrap();
    for i in 0..n {
        env.set_spawn_pose(
            i,
            Some(SpawnPose {
                position_m: [0.0, 3.0 * i as f32],
                yaw_rad: 0.0,
            }),
        );
    }
    env.reset();
    let mut mpc = MpcController::new(params.clone()).unwrap();
    mpc.reset(n);
    let steps = (duration_s / 0.02).round() as usize;
    let settle = (settle_s / 0.02).round() as usize;
    let mut stats = vec![RunStats::default(); n];
    let start: Vec<[f32; 3]> = (0..n)
        .map(|i| env.robot_state(i).base_pos_world_m)
        .collect();
    for step in 0..steps {
        let states: Vec<_> = (0..n).map(|i| env.robot_state(i)).collect();
        for i in 0..n {
            env.set_command(i, command);
        }
        let actions = mpc.actions(&states, &vec![command; n]);
        let res = env.step(&actions);
        for i in 0..n {
            let st = &mut stats[i];
            if st.fell {
                continue;
            }
            if res.dones[i] {
                st.fell = true;
                continue;
            }
            let s = env.robot_state(i);
            let d = [0, 1].map(|k| (s.base_pos_world_m[k] - start[i][k]) as f64);
            if command == [0.0; 3] {
                st.max_drift_m = st.max_drift_m.max(d[0].hypot(d[1]));
            }
            if step >= settle {
                let v = heading_velocity_m_s(&s);
                let m = (steps - settle) as f64;
                st.mean_velocity[0] += v[0] as f64 / m;
                st.mean_velocity[1] += v[1] as f64 / m;
                st.mean_velocity[2] += s.base_ang_vel_world_rad_s[2] as f64 / m;
                st.mean_height_m += s.base_pos_world_m[2] as f64 / m;
                st.max_tilt_deg = st.max_tilt_deg.max(tilt_rad(&s).to_degrees() as f64);
            }
        }
    }
    (stats, mpc)
}

/// [`run_robots`] with `n` nominal robots.
fn run(
    params: &MpcParams,
    command: [f32; 3],
    duration_s: f32,
    settle_s: f32,
    n: usize,
) -> (Vec<RunStats>, MpcController) {
    run_robots(params, command, duration_s, settle_s, n, false)
}

/// Tracking of eval's commands by 4 randomized robots, 6 s each (2 s settling), printed.
/// `cargo test --release -p host-train --lib mpc::tests::commands -- --ignored --nocapture`.
#[test]
#[ignore]
fn commands() {
    let p = MpcParams::default();
    for c in crate::cli::eval::EVAL_COMMANDS {
        let (stats, mpc) = run_robots(&p, c, 6.0, 2.0, 4, true);
        let falls = stats.iter().filter(|s| s.fell).count();
        let mean = |k: usize| stats.iter().map(|s| s.mean_velocity[k]).sum::<f64>() / 4.0;
        println!(
            "command {c:?}: falls {falls}/4, mean vx {:.3} vy {:.3} wz {:.3}, QP failures {}",
            mean(0),
            mean(1),
            mean(2),
            mpc.qp_failures()
        );
    }
}

#[test]
fn walks_forward_for_ten_seconds_at_the_command() {
    let p = MpcParams::default();
    let (stats, mpc) = run(&p, [0.25, 0.0, 0.0], 10.0, 2.0, 1);
    let s = &stats[0];
    eprintln!("{s:?}, QP failures {}", mpc.qp_failures());
    assert!(!s.fell, "{s:?}");
    // Tracking: the mean forward velocity within 0.05 m/s of 0.25 m/s, little sideways drift
    // or turning, upright.
    assert!((s.mean_velocity[0] - 0.25).abs() < 0.05, "{s:?}");
    assert!(
        s.mean_velocity[1].abs() < 0.05 && s.mean_velocity[2].abs() < 0.1,
        "{s:?}"
    );
    assert!(s.max_tilt_deg < 10.0, "{s:?}");
    assert_eq!(mpc.qp_failures(), 0);
}

#[test]
fn stands_still_at_a_zero_command_with_physical_forces() {
    let p = MpcParams::default();
    let (stats, mpc) = run(&p, [0.0; 3], 3.0, 1.0, 1);
    let s = &stats[0];
    assert!(!s.fell, "{s:?}");
    assert!(s.max_drift_m < 0.03, "{s:?}");
    assert!(s.mean_velocity.iter().all(|v| v.abs() < 0.01), "{s:?}");
    assert!((s.mean_height_m - p.body_height_m).abs() < 0.02, "{s:?}");
    // The last QP: all six feet carry the weight, inside the friction cones.
    let last = mpc.robot(0).last;
    assert!(last.solved);
    let forces: Vec<[f64; 3]> = last.forces_world_n.iter().map(|f| f.unwrap()).collect();
    let weight = RigidBody::hexapod().mass_kg * GRAVITY_M_S2;
    let fz: f64 = forces.iter().map(|f| f[2]).sum();
    assert!((fz - weight).abs() < 0.05 * weight, "{fz} vs {weight}");
    for f in &forces {
        assert!(f[0].hypot(f[1]) <= p.friction_mu * f[2] + 1e-6, "{f:?}");
    }
    assert!(last.max_cone_violation_n < 1e-6);
}

/// The defaults' tuning on flat ground: eval's six commands, 2 randomized robots each, 5 s
/// (2 s settling), over body height, lift height and gait period; prints the mean planar
/// velocity error, the mean yaw-rate error and the falls per setting.
/// `cargo test --release -p host-train --lib mpc::tests::tune -- --ignored --nocapture`.
#[test]
#[ignore]
fn tune() {
    let base = MpcParams::default();
    for h in [0.27, 0.30, 0.33] {
        for lift in [0.05, 0.08, 0.11] {
            for period in [0.5, 0.6, 0.8] {
                let p = MpcParams {
                    body_height_m: h,
                    lift_height_m: lift,
                    gait_period_s: period,
                    ..base.clone()
                };
                let (mut lin, mut yaw, mut falls, mut runs) = (0.0, 0.0, 0, 0);
                for c in crate::cli::eval::EVAL_COMMANDS {
                    let (stats, _) = run_robots(&p, c, 5.0, 2.0, 2, true);
                    for s in &stats {
                        let v = s.mean_velocity;
                        lin += (v[0] - c[0] as f64).hypot(v[1] - c[1] as f64);
                        yaw += (v[2] - c[2] as f64).abs();
                        falls += s.fell as usize;
                        runs += 1;
                    }
                }
                println!(
                    "height {h:.2} m, lift {lift:.2} m, period {period:.1} s: planar error {:.3} m/s, yaw-rate error {:.3} rad/s, falls {falls}/{runs}",
                    lin / runs as f64,
                    yaw / runs as f64
                );
            }
        }
    }
}
