//! The speed benchmark: rapier physics steps/s (1 robot, 1 thread) and environment steps/s
//! (N robots, several threads) on flat ground and on a rough heightfield, with MuJoCo
//! stepping the same robot from the same URDF in the same run, and the ratios.
//!
//! Single-robot rates are per second of the stepping thread's CPU time (both simulators),
//! so they hold on a machine whose cores are shared; environment rates are wall-clock.

use crate::config::EnvConfig;
use crate::env::HexapodEnv;
use crate::peer::{bench_terrain, reference_gait, run_mujoco, SPAWN_HEIGHT_M};
use crate::robot::RobotWorld;
use crate::terrain::{Terrain, TerrainConfig};
use crate::urdf_model::{default_urdf_path, UrdfModel};
use crate::vec_env::VecEnv;
use hexapod_core::robot::{NUM_JOINTS, Q0_RAD};
use hexapod_core::timing::{DECIMATION, PHYSICS_DT_S};
use std::time::Instant;

/// Benchmark settings.
#[derive(clap::Args, Debug, Clone)]
pub struct BenchArgs {
    /// Physics steps timed per single-robot case (10,000 = 50 s of walking, which stays
    /// on the 24 m benchmark heightfield).
    #[arg(long, default_value_t = 10_000)]
    pub steps: usize,
    /// Robots in the environment case.
    #[arg(long, default_value_t = 64)]
    pub envs: usize,
    /// Threads in the environment case.
    #[arg(long, default_value_t = 2)]
    pub threads: usize,
    /// Policy steps timed in the environment case.
    #[arg(long, default_value_t = 200)]
    pub env_steps: usize,
    /// Rapier solver iterations.
    #[arg(long, default_value_t = 1)]
    pub solver_iterations: usize,
    /// Skip the MuJoCo peer.
    #[arg(long)]
    pub no_mujoco: bool,
    /// Solve friction only in the unbiased solver pass (rapier's default, the simulator's
    /// before its feet held: `EnvConfig::friction_in_bias_pass`), to time the difference.
    #[arg(long)]
    pub friction_unbiased_pass_only: bool,
}

/// CPU time of the calling thread, s: unlike wall time, it does not count the time other
/// processes hold the core, so rates stay comparable on a shared machine.
fn thread_cpu_s() -> f64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid, writable timespec; the clock id is a constant Linux supports.
    unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
    ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9
}

struct SingleResult {
    steps_per_s: f64,
    contacts: f64,
    upright: bool,
}

fn time_single(
    ground: rapier3d::prelude::Collider,
    spawn_z: f32,
    steps: usize,
    iterations: usize,
    friction_in_bias_pass: bool,
) -> anyhow::Result<SingleResult> {
    let model = UrdfModel::load(&default_urdf_path())?;
    let mut robot = RobotWorld::new(&model, ground, iterations)?;
    robot.set_friction_in_bias_pass(friction_in_bias_pass);
    robot.reset([0.0, 0.0, spawn_z], [0.0, 0.0, 0.0, 1.0], &Q0_RAD);
    for _ in 0..400 {
        robot.step(&Q0_RAD);
    }
    let gait = reference_gait();
    let mut contacts = 0usize;
    let start_cpu_s = thread_cpu_s();
    for k in 0..steps {
        robot.step(&gait.joint_targets(k as f32 * PHYSICS_DT_S));
        contacts += robot.num_contact_points();
    }
    let elapsed = thread_cpu_s() - start_cpu_s;
    let s = robot.state();
    let upright = s.base_quat_xyzw[0].abs() < 0.2
        && s.base_quat_xyzw[1].abs() < 0.2
        && s.base_pos_world_m[2] - spawn_z > -0.15;
    Ok(SingleResult {
        steps_per_s: steps as f64 / elapsed,
        contacts: contacts as f64 / steps as f64,
        upright,
    })
}

fn time_env(args: &BenchArgs, terrain: bool) -> anyhow::Result<f64> {
    let mut config = EnvConfig {
        num_envs: args.envs,
        solver_iterations: args.solver_iterations,
        friction_in_bias_pass: !args.friction_unbiased_pass_only,
        ..Default::default()
    };
    if terrain {
        config.terrain.tiles = true;
        config.terrain.rows = 5;
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(args.threads)
        .build()?;
    let mut env = HexapodEnv::new(config)?;
    env.reset();
    let gait = reference_gait();
    let start = pool.install(|| -> anyhow::Result<Instant> {
        for _ in 0..10 {
            env.step(&vec![0.0; args.envs * NUM_JOINTS]);
        }
        let start = Instant::now();
        for k in 0..args.env_steps {
            let q = gait.joint_targets((k * DECIMATION) as f32 * PHYSICS_DT_S);
            let a: Vec<f32> = (0..args.envs)
                .flat_map(|_| {
                    (0..NUM_JOINTS)
                        .map(|j| (q[j] - Q0_RAD[j]) / hexapod_core::timing::ACTION_SCALE_RAD)
                })
                .collect();
            env.step(&a);
        }
        Ok(start)
    })?;
    Ok((args.env_steps * args.envs) as f64 / start.elapsed().as_secs_f64())
}

/// Runs the benchmark and prints the table.
pub fn run(args: &BenchArgs) -> anyhow::Result<()> {
    for (name, value) in [
        ("--steps", args.steps),
        ("--envs", args.envs),
        ("--threads", args.threads),
        ("--env-steps", args.env_steps),
        ("--solver-iterations", args.solver_iterations),
    ] {
        if value == 0 {
            anyhow::bail!("{name} must be at least 1");
        }
    }
    let flat_ground = Terrain::generate(&TerrainConfig::default()).collider();
    let rough = bench_terrain();
    let [cx, cy] = rough.tile_center_m(0, 0);
    let mut rough_ground = rough.collider();
    // Centre the tile at the origin, where the robot stands.
    rough_ground
        .set_translation(rough_ground.translation() - rapier3d::prelude::Vector::new(cx, cy, 0.0));
    let z_rough = SPAWN_HEIGHT_M + rough.height_at_m(cx, cy);
    eprintln!(
        "[bench] rapier, 1 robot, 1 thread, {} physics steps per case ...",
        args.steps
    );
    let friction_in_bias_pass = !args.friction_unbiased_pass_only;
    let flat = time_single(
        flat_ground,
        SPAWN_HEIGHT_M,
        args.steps,
        args.solver_iterations,
        friction_in_bias_pass,
    )?;
    let terr = time_single(
        rough_ground,
        z_rough,
        args.steps,
        args.solver_iterations,
        friction_in_bias_pass,
    )?;
    eprintln!(
        "[bench] rapier env, {} robots, {} threads ...",
        args.envs, args.threads
    );
    let env_flat = time_env(args, false)?;
    let env_terrain = time_env(args, true)?;
    let peer = if args.no_mujoco {
        None
    } else {
        eprintln!("[bench] MuJoCo, same URDF, dt and gait ...");
        Some(run_mujoco(args.steps, 400)?)
    };
    println!("| case | rapier (host-sim) | MuJoCo | ratio rapier/MuJoCo |");
    println!("|---|---|---|---|");
    let row = |name: &str, ours: &SingleResult, theirs: Option<(f64, f64)>| {
        match theirs {
        Some((sps, contacts)) => println!(
            "| {name} | {:.0} steps/s ({:.1} contacts, upright: {}) | {:.0} steps/s ({:.1} contacts) | {:.2}x |",
            ours.steps_per_s, ours.contacts, ours.upright, sps, contacts, ours.steps_per_s / sps
        ),
        None => println!("| {name} | {:.0} steps/s ({:.1} contacts, upright: {}) | - | - |", ours.steps_per_s, ours.contacts, ours.upright),
    }
    };
    let p = peer.as_ref();
    row(
        "physics, flat, 1 robot, 1 thread",
        &flat,
        p.and_then(|p| Some((p.flat_steps_per_s?, p.flat_contacts?))),
    );
    row(
        "physics, rough heightfield, 1 robot, 1 thread",
        &terr,
        p.and_then(|p| Some((p.terrain_steps_per_s?, p.terrain_contacts?))),
    );
    println!(
        "| env, flat, {} robots, {} threads | {:.0} env steps/s ({:.0} physics steps/s) | | |",
        args.envs,
        args.threads,
        env_flat,
        env_flat * DECIMATION as f64
    );
    println!("| env, tile terrain, {} robots, {} threads | {:.0} env steps/s ({:.0} physics steps/s) | | |", args.envs, args.threads, env_terrain, env_terrain * DECIMATION as f64);
    if let Some(p) = p {
        println!(
            "\nMuJoCo {} ; rapier solver iterations {} ; dt {} s",
            p.mujoco_version, args.solver_iterations, PHYSICS_DT_S
        );
    }
    Ok(())
}
