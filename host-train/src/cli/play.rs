//! `hexapod play`: runs a checkpoint's policy (deterministic) and writes the trajectory
//! (CSV), plots, and an animated 3D replay (GIF) of the first robot, on the checkpoint's
//! ground or on one tile of the terrain grid (`--tile StairsUp --level 5`), with the
//! discriminator's score and style reward per step for AMP checkpoints; with `--rerun`
//! (a build with the `rerun` feature) also a rerun recording to scrub (`replay.rrd`).

use crate::checkpoint::load_for_inference;
use crate::cli::eval::{contact_mask, SETTLE_STEPS};
use crate::cli::recording::{require_rerun, Recording};
use crate::cli::replay_gif::{render_replay, ReplayFrame};
use crate::config::EnvKind;
use crate::env::make_env;
use anyhow::Context;
use clap::Args;
use hexapod_core::amp::AMP_FOOT_POS;
use hexapod_core::amp::{AMP_BASE_ANG_VEL, AMP_JOINT_POS, AMP_STATE_DIM};
use hexapod_core::obs::{
    ACTOR_COMMAND, ACTOR_OBS_DIM, COMMAND_SCALE, LIN_VEL_SCALE, PRIVILEGED_DIM, PRIV_BASE_HEIGHT,
    PRIV_LIN_VEL,
};
use hexapod_core::robot::{
    FOOT_RADIUS_M, JOINT_NAMES, LEG_NAMES, NUM_LEGS, TRIPOD_A_MASK, TRIPOD_B_MASK,
};
use hexapod_core::timing::POLICY_DT_S;
use host_sim::env::HexapodEnv;
use host_sim::frames::{quat_from_yaw, rotate};
use host_sim::plot::{write_gait, write_panels, Gait, Line, Panel, COLORS};
use host_sim::terrain::{Terrain, TerrainConfig};
use host_sim::vec_env::VecEnv;
use std::fmt::Write as _;
use std::path::PathBuf;

/// Arguments of `hexapod play`.
#[derive(Args, Debug)]
pub struct PlayArgs {
    /// Checkpoint directory (policy.safetensors + config.toml), or a run directory (its
    /// latest checkpoint).
    #[arg(long)]
    pub checkpoint: PathBuf,
    /// Policy steps to run (50 per second).
    #[arg(long, default_value_t = 500)]
    pub steps: usize,
    /// The command `vx,vy,wz` (m/s, m/s, rad/s), held for the whole run.
    #[arg(
        long,
        value_parser = crate::cli::eval::parse_command,
        allow_hyphen_values = true,
        default_value = "0.3,0,0"
    )]
    pub command: [f32; 3],
    /// Output directory (default `runs/play/<checkpoint name>`).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Environment override (`sim` or `fake`).
    #[arg(long, value_parser = ["sim", "fake"])]
    pub env: Option<String>,
    /// Skip the GIF replay.
    #[arg(long)]
    pub no_replay: bool,
    /// Walk on this tile kind of the terrain grid (Flat, SmoothSlope, RoughSlope, StairsUp,
    /// StairsDown, DiscreteObstacles); the checkpoint's grid, or the default one if it was
    /// trained on flat ground.
    #[arg(long)]
    pub tile: Option<String>,
    /// Terrain row (difficulty) of `--tile`; default the hardest.
    #[arg(long, requires = "tile")]
    pub level: Option<usize>,
    /// Also write `replay.rrd`, a rerun recording to scrub in 3D (`rerun replay.rrd`): the
    /// links, the ground, the foot forces and the velocity against the command on a
    /// `sim_time` timeline. Needs the simulator and a build with the `rerun` feature
    /// (`cargo run --release -p host-train --features rerun --bin hexapod -- play ...`).
    #[arg(long)]
    pub rerun: bool,
}

/// The environment `play` and `eval` drive: the simulator (with the robot's world pose and
/// the ground for the replays) or the trainer's stand-in.
#[allow(clippy::large_enum_variant)] // one per command run
pub(crate) enum PlayEnv {
    Sim(HexapodEnv),
    Other(Box<dyn VecEnv>),
}

impl PlayEnv {
    /// The environment of `cfg`.
    pub(crate) fn new(cfg: &crate::config::TrainConfig) -> anyhow::Result<Self> {
        Ok(match cfg.env.kind {
            EnvKind::Sim => PlayEnv::Sim(HexapodEnv::new(cfg.resolved_sim())?),
            _ => PlayEnv::Other(make_env(cfg)?),
        })
    }

    /// The environment as a vectorized one.
    pub(crate) fn env(&mut self) -> &mut dyn VecEnv {
        match self {
            PlayEnv::Sim(env) => env,
            PlayEnv::Other(env) => env.as_mut(),
        }
    }
}

/// Height of each foot's sole above the ground straight under it, m, from the AMP state's
/// foot positions (base frame) and the base's world pose.
fn foot_clearance_m(
    foot_pos_base_m: &[f32],
    base_pos_world_m: [f32; 3],
    base_quat_xyzw: [f32; 4],
    terrain: &Terrain,
) -> [f32; NUM_LEGS] {
    let mut clearance = [0.0; NUM_LEGS];
    for (leg, c) in clearance.iter_mut().enumerate() {
        let p = &foot_pos_base_m[3 * leg..3 * leg + 3];
        let r = rotate(base_quat_xyzw, [p[0], p[1], p[2]]);
        let world = [
            base_pos_world_m[0] + r[0],
            base_pos_world_m[1] + r[1],
            base_pos_world_m[2] + r[2],
        ];
        *c = world[2] - FOOT_RADIUS_M - terrain.height_at_m(world[0], world[1]);
    }
    clearance
}

/// Puts robot 0 on the named tile (kind matched case-insensitively) at `level`.
fn place_on_tile(env: &mut HexapodEnv, tile: &str, level: Option<usize>) -> anyhow::Result<()> {
    let terrain = &env.config().terrain;
    // `StairsUp`, `stairsup` and the configs' `stairs_up` all name the same kind.
    let key = |name: &str| name.replace('_', "").to_ascii_lowercase();
    let column = terrain
        .columns
        .iter()
        .position(|k| key(&format!("{k:?}")) == key(tile))
        .ok_or_else(|| {
            let kinds: Vec<String> = terrain.columns.iter().map(|k| format!("{k:?}")).collect();
            anyhow::anyhow!(
                "--tile {tile}: not a tile kind of this grid ({})",
                kinds.join(", ")
            )
        })?;
    let rows = terrain.rows;
    let level = level.unwrap_or(rows - 1);
    anyhow::ensure!(
        level < rows,
        "--level {level}: the grid has rows 0 to {}",
        rows - 1
    );
    env.set_terrain_tile(0, level, column);
    Ok(())
}

/// Runs `hexapod play`.
pub fn run(args: PlayArgs) -> anyhow::Result<()> {
    if args.rerun {
        require_rerun("play")?;
    }
    let checkpoint = crate::checkpoint::resolve_dir(&args.checkpoint)?;
    let (mut cfg, mut ppo) = load_for_inference(&checkpoint)?;
    cfg.env.num_envs = 1;
    if let Some(kind) = &args.env {
        cfg.env.kind = if kind == "fake" {
            EnvKind::Fake
        } else {
            EnvKind::Sim
        };
    }
    let out = args.out.clone().unwrap_or_else(|| {
        PathBuf::from("runs/play").join(crate::checkpoint::display_name(&checkpoint))
    });
    std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
    let mut play_env = match cfg.env.kind {
        EnvKind::Sim => {
            let mut sim = cfg.resolved_sim();
            if args.tile.is_some() {
                if !sim.terrain.tiles {
                    sim.terrain = TerrainConfig {
                        tiles: true,
                        ..TerrainConfig::default()
                    };
                }
                sim.curriculum = false;
            }
            let mut env = HexapodEnv::new(sim)?;
            if let Some(tile) = &args.tile {
                place_on_tile(&mut env, tile, args.level)?;
            }
            PlayEnv::Sim(env)
        }
        _ => {
            anyhow::ensure!(
                args.tile.is_none(),
                "--tile needs the simulator (env.kind = \"sim\")"
            );
            PlayEnv::Other(make_env(&cfg)?)
        }
    };
    let mut recording = match (&play_env, args.rerun) {
        (PlayEnv::Sim(env), true) => Some(Recording::new(env.robot_world(0))),
        (PlayEnv::Other(_), true) => anyhow::bail!(
            "--rerun records the simulator's robot, not the stand-in (env.kind = \"fake\")"
        ),
        (_, false) => None,
    };
    let command = args.command;
    play_env.env().set_command(0, command);
    let mut obs = play_env.env().reset();
    let [vx, vy, wz] = command;
    eprintln!(
        "play {}: command vx {vx} m/s, vy {vy} m/s, wz {wz} rad/s for {:.1} s -> {}",
        checkpoint.display(),
        args.steps as f32 * POLICY_DT_S,
        out.display()
    );
    let mut csv = String::from(
        "t_s,cmd_vx,cmd_vy,cmd_wz,vx_m_s,vy_m_s,wz_rad_s,est_vx_m_s,est_vy_m_s,base_height_m,done",
    );
    for name in JOINT_NAMES {
        write!(csv, ",q_{name}").ok();
    }
    for name in JOINT_NAMES {
        write!(csv, ",a_{name}").ok();
    }
    for name in LEG_NAMES {
        write!(csv, ",clearance_m_{name}").ok();
    }
    // The ground's normal force on each foot, split into its horizontal and vertical parts.
    for name in LEG_NAMES {
        write!(csv, ",foot_force_xy_n_{name},foot_force_z_n_{name}").ok();
    }
    let with_style = ppo.disc.is_some();
    if with_style {
        csv.push_str(",d_score,style_reward");
    }
    csv.push('\n');
    let mut frames = Vec::with_capacity(args.steps);
    // The stand-in has no world pose: integrate its planar velocity and yaw rate.
    let (mut x, mut y, mut yaw) = (0.0f32, 0.0f32, 0.0f32);
    let (mut vel, mut cmd_series, mut q_series) = (
        vec![Vec::new(); 3],
        vec![Vec::new(); 3],
        vec![Vec::new(); 6],
    );
    let mut clearance_series = vec![Vec::new(); NUM_LEGS];
    let (mut time_s, mut stance_masks) = (
        Vec::with_capacity(args.steps),
        Vec::with_capacity(args.steps),
    );
    let mut summary = Summary::default();
    for step in 0..args.steps {
        let act = ppo.act(&obs, true)?;
        let t = step as f32 * POLICY_DT_S;
        let a = &obs.actor[..ACTOR_OBS_DIM];
        let p = &obs.privileged[..PRIVILEGED_DIM];
        let amp = &obs.amp[..AMP_STATE_DIM];
        let cmd: Vec<f32> = (0..3)
            .map(|k| a[ACTOR_COMMAND.start + k] / COMMAND_SCALE[k])
            .collect();
        let v = [
            p[PRIV_LIN_VEL.start] / LIN_VEL_SCALE,
            p[PRIV_LIN_VEL.start + 1] / LIN_VEL_SCALE,
            amp[AMP_BASE_ANG_VEL.start + 2],
        ];
        let est = if act.estimate.is_empty() {
            [f32::NAN; 2]
        } else {
            [
                act.estimate[0] / LIN_VEL_SCALE,
                act.estimate[1] / LIN_VEL_SCALE,
            ]
        };
        let (base_pos_world_m, base_quat_xyzw) = match &play_env {
            PlayEnv::Sim(env) => {
                let s = env.robot_state(0);
                (s.base_pos_world_m, s.base_quat_xyzw)
            }
            PlayEnv::Other(_) => {
                let (c, s) = (yaw.cos(), yaw.sin());
                x += (c * v[0] - s * v[1]) * POLICY_DT_S;
                y += (s * v[0] + c * v[1]) * POLICY_DT_S;
                yaw += v[2] * POLICY_DT_S;
                ([x, y, p[PRIV_BASE_HEIGHT]], quat_from_yaw(yaw))
            }
        };
        if let (Some(rec), PlayEnv::Sim(env)) = (&mut recording, &play_env) {
            rec.record(
                env.robot_world(0),
                &env.contacts(0),
                t,
                [cmd[0], cmd[1], cmd[2]],
                v,
                p[PRIV_BASE_HEIGHT],
            );
        }
        let res = play_env.env().step(&act.actions);
        // The discriminator's score and the unweighted style reward of this step's transition
        // (s_t, s_t+1), s_t+1 taken before any reset, as the trainer takes it.
        let style = match &ppo.disc {
            Some(disc) => {
                let (r, d) = disc.style_reward(amp, &res.amp_next[..AMP_STATE_DIM])?;
                Some((d[0], r[0]))
            }
            None => None,
        };
        time_s.push(t);
        stance_masks.push(contact_mask(p));
        if step >= SETTLE_STEPS {
            for k in 0..3 {
                summary.sum_v[k] += v[k] as f64;
            }
            let mask = contact_mask(p);
            summary.tripod += usize::from(mask == TRIPOD_A_MASK || mask == TRIPOD_B_MASK);
            summary.samples += 1;
            if let Some((_, r)) = style {
                summary.sum_style += f64::from(r);
            }
        }
        summary.falls += usize::from(res.dones[0] && !res.time_outs[0]);
        write!(
            csv,
            "{t},{},{},{},{},{},{},{},{},{},{}",
            cmd[0],
            cmd[1],
            cmd[2],
            v[0],
            v[1],
            v[2],
            est[0],
            est[1],
            p[PRIV_BASE_HEIGHT],
            res.dones[0] as u8
        )
        .ok();
        for q in &amp[AMP_JOINT_POS] {
            write!(csv, ",{q}").ok();
        }
        for x in &act.actions[..18] {
            write!(csv, ",{x}").ok();
        }
        for k in 0..3 {
            vel[k].push((t as f64, v[k] as f64));
            cmd_series[k].push((t as f64, cmd[k] as f64));
        }
        for (j, s) in q_series.iter_mut().enumerate() {
            s.push((t as f64, amp[AMP_JOINT_POS.start + j] as f64));
        }
        let mut q = [0.0f32; 18];
        q.copy_from_slice(&amp[AMP_JOINT_POS]);
        let (clearance_m, foot_force_n) = match &play_env {
            PlayEnv::Sim(env) => (
                foot_clearance_m(
                    &amp[AMP_FOOT_POS],
                    base_pos_world_m,
                    base_quat_xyzw,
                    env.terrain(),
                ),
                env.contacts(0).foot_force_world_n,
            ),
            PlayEnv::Other(_) => ([f32::NAN; NUM_LEGS], [[f32::NAN; 3]; NUM_LEGS]),
        };
        for (leg, c) in clearance_m.iter().enumerate() {
            write!(csv, ",{c}").ok();
            clearance_series[leg].push((t as f64, *c as f64));
        }
        for f in foot_force_n {
            write!(csv, ",{},{}", f[0].hypot(f[1]), f[2]).ok();
        }
        if let Some((d, r)) = style {
            write!(csv, ",{d},{r}").ok();
        }
        csv.push('\n');
        frames.push(ReplayFrame {
            q_rad: q,
            base_pos_world_m,
            base_quat_xyzw,
        });
        obs = res.obs;
    }
    std::fs::write(out.join("trajectory.csv"), csv)?;
    write_plots(
        &out,
        &time_s,
        &vel,
        &cmd_series,
        q_series,
        &stance_masks,
        matches!(play_env, PlayEnv::Sim(_)).then_some(clearance_series),
    )?;
    if !args.no_replay {
        let ground = |x: f32, y: f32| match &play_env {
            PlayEnv::Sim(env) => env.terrain().height_at_m(x, y),
            PlayEnv::Other(_) => 0.0,
        };
        render_replay(&out.join("replay.gif"), &frames, &ground).map_err(anyhow::Error::msg)?;
    }
    if let (Some(rec), PlayEnv::Sim(env)) = (&recording, &play_env) {
        rec.save(&out.join("replay.rrd"), env.terrain())?;
    }
    eprintln!(
        "wrote {} (trajectory.csv, plots{}{})",
        out.display(),
        if args.no_replay { "" } else { ", replay.gif" },
        if recording.is_some() {
            ", replay.rrd"
        } else {
            ""
        }
    );
    if summary.samples > 0 {
        let n = summary.samples as f64;
        let mean = summary.sum_v.map(|x| x / n);
        println!(
            "after the first {:.0} s: mean (vx, vy, wz) ({:+.2} m/s, {:+.2} m/s, {:+.2} rad/s) for the command ({:+.2}, {:+.2}, {:+.2}); tripod score {:.2} (share of steps with exactly one tripod down); falls {}",
            SETTLE_STEPS as f32 * POLICY_DT_S,
            mean[0],
            mean[1],
            mean[2],
            command[0],
            command[1],
            command[2],
            summary.tripod as f64 / n,
            summary.falls
        );
        if with_style {
            println!(
                "style reward (unweighted, max(0, 1 - 0.25 (d - 1)^2), of at most 1): mean {:.3} over the same steps",
                summary.sum_style / n
            );
        }
    }
    Ok(())
}

/// What play measures after the settle time.
#[derive(Default)]
struct Summary {
    sum_v: [f64; 3],
    tripod: usize,
    samples: usize,
    falls: usize,
    /// Sum of the unweighted style reward (AMP checkpoints).
    sum_style: f64,
}

/// `play`'s plots: velocity against the command (linear in m/s, yaw rate in rad/s, one
/// panel each), RF and RM joint angles, the gait diagram (feet in stance: contact force
/// above [`host_sim::rewards::STANCE_FORCE_N`]) and, on the simulator, each foot's
/// clearance (one small panel per leg, laid out as on the robot seen from above).
fn write_plots(
    out: &std::path::Path,
    time_s: &[f32],
    vel: &[Vec<(f64, f64)>],
    cmd: &[Vec<(f64, f64)>],
    q_series: Vec<Vec<(f64, f64)>>,
    stance_masks: &[u8],
    clearance_m: Option<Vec<Vec<(f64, f64)>>>,
) -> anyhow::Result<()> {
    let (vx, vy, wz) = (COLORS[0], COLORS[1], COLORS[2]);
    let velocity = [
        Panel::new(
            "linear velocity (base frame): measured, command dashed",
            "time (s)",
            "velocity (m/s)",
        )
        .line(Line::new("vx", vel[0].clone(), vx))
        .line(Line::new("vx command", cmd[0].clone(), vx).dashed())
        .line(Line::new("vy", vel[1].clone(), vy))
        .line(Line::new("vy command", cmd[1].clone(), vy).dashed()),
        Panel::new(
            "yaw rate: measured, command dashed",
            "time (s)",
            "yaw rate (rad/s)",
        )
        .line(Line::new("wz", vel[2].clone(), wz))
        .line(Line::new("wz command", cmd[2].clone(), wz).dashed()),
    ];
    write_panels(
        &out.join("velocity_tracking.png"),
        None,
        1,
        (1000, 340),
        &velocity,
    )?;
    let mut q = q_series.into_iter();
    let joints: Vec<Panel> = ["RF", "RM"]
        .iter()
        .enumerate()
        .map(|(leg, name)| {
            (0..3).fold(
                Panel::new(
                    format!("{name} joint angles"),
                    "time (s)",
                    "joint angle (rad)",
                ),
                |p, k| {
                    p.line(Line::nth(
                        k,
                        JOINT_NAMES[3 * leg + k],
                        q.next().unwrap_or_default(),
                    ))
                },
            )
        })
        .collect();
    write_panels(&out.join("joints_rf_rm.png"), None, 1, (1000, 320), &joints)?;
    let dt_s = if time_s.len() > 1 {
        time_s[1] - time_s[0]
    } else {
        POLICY_DT_S
    };
    let title = format!(
        "gait diagram: feet in stance (contact force > {} N)",
        host_sim::rewards::STANCE_FORCE_N
    );
    write_gait(
        &out.join("gait.png"),
        &Gait {
            title: &title,
            time_s,
            stance_masks,
            dt_s,
        },
    )?;
    if let Some(clearance_m) = clearance_m {
        // Robot seen from above: left legs in the left column, front at the top; one y range
        // for all so the panels compare.
        let cm = |leg: usize| -> Vec<(f64, f64)> {
            clearance_m[leg]
                .iter()
                .map(|(t, c)| (*t, 100.0 * c))
                .collect()
        };
        let (lo, hi) = (0..NUM_LEGS)
            .flat_map(&cm)
            .filter(|p| p.1.is_finite())
            .fold((0.0f64, 1.0f64), |(lo, hi), p| (lo.min(p.1), hi.max(p.1)));
        let pad = 0.05 * (hi - lo);
        let panels: Vec<Panel> = [3usize, 0, 4, 1, 5, 2]
            .iter()
            .map(|&leg| {
                let color = if TRIPOD_A_MASK & (1 << leg) != 0 {
                    host_sim::plot::TRIPOD_A_COLOR
                } else {
                    host_sim::plot::TRIPOD_B_COLOR
                };
                Panel::new(LEG_NAMES[leg].to_uppercase(), "time (s)", "clearance (cm)")
                    .y_range(lo - pad, hi + pad)
                    .line(Line::new(LEG_NAMES[leg], cm(leg), color))
            })
            .collect();
        write_panels(
            &out.join("foot_clearance.png"),
            Some("foot clearance above the ground under it"),
            2,
            (560, 230),
            &panels,
        )?;
    }
    Ok(())
}
