//! `hexapod priors`: generate the motion-prior dataset by trajectory optimization, check a
//! dataset's files, and replay clips in the simulator.

use crate::priors::clip::MotionClip;
use crate::priors::command::default_commands;
use crate::priors::dataset::MotionDataset;
use crate::priors::generate::{generate_clip, ClipReport, GeneratorConfig};
use crate::priors::optimize::GaitQpConfig;
use crate::priors::plot::plot_clip;
use crate::priors::schedule::TripodSchedule;
use crate::priors::sim_tracking::{replay_clip, ReplayConfig, ReplayReport};
use anyhow::{bail, Context};
use hexapod_core::robot::NUM_LEGS;
use host_sim::robot::RobotWorld;
use host_sim::terrain::{Terrain, TerrainConfig};
use host_sim::urdf_model::{default_urdf_path, UrdfModel};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Highest swing apex above the ground from the nominal stance, m (the legs' reach).
const MAX_SWING_CLEARANCE_M: f64 = 0.2;
/// Highest base lift above the nominal stance, m.
const MAX_BASE_LIFT_M: f64 = 0.08;

/// Arguments of `hexapod priors`.
#[derive(clap::Args, Debug)]
pub struct PriorsArgs {
    /// Directory to write the clips (*.json), plots (plots/*.png) and report.md into.
    #[arg(long, default_value = "assets/priors")]
    pub out: PathBuf,
    /// Only validate the clips of this directory (no generation).
    #[arg(long, value_name = "DIR")]
    pub check: Option<PathBuf>,
    /// Replay every clip in the simulator (drives tracking the joint trajectories) and
    /// require it upright and within 25 % of the commanded velocity.
    #[arg(long)]
    pub validate: bool,
    /// Skip the plots.
    #[arg(long)]
    pub no_plots: bool,
    /// Swing apex above the ground, m: 0.08 for the flat-ground priors, higher for a
    /// climbing gait (`assets/priors-climb` is made with 0.14).
    #[arg(long, default_value_t = GeneratorConfig::default().swing_clearance_m)]
    pub swing_clearance_m: f64,
    /// Swing frames of each leg per 30-frame (0.6 s) cycle: 13 gives a duty factor of 0.57
    /// with two short six-foot support phases per cycle, 15 a duty factor of 0.5 in which
    /// one tripod touches down as the other lifts off.
    #[arg(long, default_value_t = GeneratorConfig::default().swing_frames)]
    pub swing_frames: usize,
    /// Vertical speed of a swing foot at lift-off and touch-down, m/s (0: min-jerk height,
    /// the foot settles onto the ground). With some speed the three feet of a tripod land
    /// and lift off in the same policy step under the drives (assets/priors/README.md).
    #[arg(long, default_value_t = GeneratorConfig::default().swing_contact_speed_m_s)]
    pub swing_contact_speed_m_s: f64,
    /// How long before the scheduled lift-off a foot's path leaves the ground and after the
    /// scheduled touch-down it meets it, s (the contact flags keep the schedule): a loaded
    /// leg stays on the ground until it has unloaded, and a swinging foot meets the sagging
    /// body's ground early (assets/priors/README.md).
    #[arg(long, default_value_t = GeneratorConfig::default().swing_lead_s)]
    pub swing_lead_s: f64,
    /// Height of the base above the nominal stance's (0.31 m), m: a high stance for climbing,
    /// whose legs stand straighter, so a swing apex reaches higher above the ground before
    /// the thigh meets its limit.
    #[arg(long, default_value_t = GeneratorConfig::default().qp.base_lift_m)]
    pub base_lift_m: f64,
    /// With --validate: passes of iterative learning control on the replay's joint targets
    /// before the recorded replay (0: the clip's trajectories as they are, as the trainer's
    /// tracked prior states are made). A diagnostic: how the clips play when the drives'
    /// sag is corrected (assets/priors/README.md).
    #[arg(long, default_value_t = 0, requires = "validate")]
    pub learning_passes: usize,
}

/// Runs the subcommand.
pub fn run(args: PriorsArgs) -> anyhow::Result<()> {
    let started = Instant::now();
    let (clips, dir, gen_reports) = match &args.check {
        Some(dir) => (check(dir)?, dir.clone(), None),
        None => {
            if !(0.0..=MAX_BASE_LIFT_M).contains(&args.base_lift_m) {
                bail!(
                    "--base-lift-m {} is outside 0..={MAX_BASE_LIFT_M} m",
                    args.base_lift_m
                );
            }
            let max_clearance_m = MAX_SWING_CLEARANCE_M + args.base_lift_m;
            if !(0.02..=max_clearance_m).contains(&args.swing_clearance_m) {
                bail!(
                    "--swing-clearance-m {} is outside 0.02..={max_clearance_m} m (the legs reach about \
                     {MAX_SWING_CLEARANCE_M} m above the ground from the nominal stance, more by the base's lift)",
                    args.swing_clearance_m
                );
            }
            if !(0.0..=1.0).contains(&args.swing_contact_speed_m_s) {
                bail!(
                    "--swing-contact-speed-m-s {} is outside 0..=1 m/s",
                    args.swing_contact_speed_m_s
                );
            }
            if !(0.0..=0.1).contains(&args.swing_lead_s) {
                bail!("--swing-lead-s {} is outside 0..=0.1 s", args.swing_lead_s);
            }
            let cfg = GeneratorConfig {
                swing_clearance_m: args.swing_clearance_m,
                swing_frames: args.swing_frames,
                swing_contact_speed_m_s: args.swing_contact_speed_m_s,
                swing_lead_s: args.swing_lead_s,
                qp: GaitQpConfig {
                    base_lift_m: args.base_lift_m,
                    ..GaitQpConfig::default()
                },
                ..GeneratorConfig::default()
            };
            // Refused before anything is written.
            TripodSchedule::new(cfg.frames_per_cycle, cfg.swing_frames)
                .context("--swing-frames")?;
            let (clips, reports) = generate(&args.out, &cfg, !args.no_plots)?;
            (clips, args.out.clone(), Some(reports))
        }
    };
    let replays = if args.validate {
        Some(validate(&clips, args.learning_passes)?)
    } else {
        None
    };
    if let Some(reports) = &gen_reports {
        let path = dir.join("report.md");
        std::fs::write(
            &path,
            report_markdown(&regenerate_command(&args), reports, replays.as_deref()),
        )
        .with_context(|| format!("writing {}", path.display()))?;
        println!("wrote {}", path.display());
    }
    println!("done in {:.1} s", started.elapsed().as_secs_f32());
    if let Some(replays) = &replays {
        let failed: Vec<&str> = replays
            .iter()
            .filter(|r| !r.passed)
            .map(|r| r.name.as_str())
            .collect();
        if !failed.is_empty() {
            bail!("replay failed for {}", failed.join(", "));
        }
    }
    Ok(())
}

fn generate(
    out: &Path,
    cfg: &GeneratorConfig,
    plots: bool,
) -> anyhow::Result<(Vec<MotionClip>, Vec<ClipReport>)> {
    let plot_dir = out.join("plots");
    std::fs::create_dir_all(&plot_dir)
        .with_context(|| format!("creating {}", plot_dir.display()))?;
    let commands = default_commands();
    println!(
        "[priors] {} commands, cycle {} frames x 0.02 s, swing {} frames, clearance {} m, contact speed {} m/s, lead {} s",
        commands.len(),
        cfg.frames_per_cycle,
        cfg.swing_frames,
        cfg.swing_clearance_m,
        cfg.swing_contact_speed_m_s,
        cfg.swing_lead_s
    );
    let mut clips = Vec::new();
    let mut reports = Vec::new();
    for (i, command) in commands.iter().enumerate() {
        let (clip, report, _) = generate_clip(command, cfg)?;
        println!(
            "[priors {:>2}/{}] {}",
            i + 1,
            commands.len(),
            report.summary()
        );
        let path = out.join(format!("{}.json", clip.name));
        clip.save(&path)?;
        // What was written must pass the loader.
        let loaded = MotionClip::load(&path)?;
        if plots {
            plot_clip(&loaded, &plot_dir.join(format!("{}.png", clip.name)))?;
        }
        clips.push(loaded);
        reports.push(report);
    }
    let total_s: f32 = clips.iter().map(MotionClip::duration_s).sum();
    println!(
        "[priors] wrote {} clips, {total_s:.2} s of motion, into {}",
        clips.len(),
        out.display()
    );
    let names: Vec<String> = clips.iter().map(|c| format!("{}.json", c.name)).collect();
    for entry in std::fs::read_dir(out)?.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        if name.ends_with(".json") && !names.contains(&name) {
            println!("[priors] warning: {name} was not generated by this run (stale?)");
        }
    }
    Ok((clips, reports))
}

fn check(dir: &Path) -> anyhow::Result<Vec<MotionClip>> {
    let dataset = MotionDataset::load_dir(dir)?;
    for (i, clip) in dataset.clips().iter().enumerate() {
        let states = dataset.amp_states(i);
        let n = clip.frames.len() as f32;
        let mean_v = [0, 1].map(|k| {
            clip.frames
                .iter()
                .map(|f| f.lin_vel_base_m_s[k])
                .sum::<f32>()
                / n
        });
        let mean_w = clip
            .frames
            .iter()
            .map(|f| f.ang_vel_base_rad_s[2])
            .sum::<f32>()
            / n;
        println!(
            "[check] {:<28} ok: {} frames ({:.2} s, {:?}), weight {}, command ({:+.2}, {:+.2}, {:+.2}), mean velocity ({:+.3}, {:+.3}, {:+.3}), {} AMP states",
            clip.name,
            clip.frames.len(),
            clip.duration_s(),
            clip.loop_mode,
            clip.motion_weight,
            clip.command[0],
            clip.command[1],
            clip.command[2],
            mean_v[0],
            mean_v[1],
            mean_w,
            states.len()
        );
    }
    println!(
        "[check] {} clips, {:.2} s of motion: all valid",
        dataset.clips().len(),
        dataset.duration_s()
    );
    Ok(dataset.clips().to_vec())
}

fn validate(clips: &[MotionClip], learning_passes: usize) -> anyhow::Result<Vec<ReplayReport>> {
    let model = UrdfModel::load(&default_urdf_path())?;
    let ground = Terrain::generate(&TerrainConfig::default()).collider();
    let cfg = ReplayConfig {
        learning_passes,
        ..ReplayConfig::default()
    };
    let mut reports = Vec::new();
    for clip in clips {
        let mut robot = RobotWorld::new(&model, ground.clone(), 1)?;
        let report = replay_clip(&mut robot, clip, &cfg);
        println!("[replay] {}", report.summary());
        if learning_passes > 0 {
            let per_pass: Vec<String> = report
                .joint_rms_per_pass_rad
                .iter()
                .map(|r| format!("{r:.3}"))
                .collect();
            let feet_down: Vec<String> = report
                .feet_down_fraction
                .iter()
                .map(|f| format!("{f:.2}"))
                .collect();
            println!(
                "[replay]   joint rms per pass, rad: {}; feet down 0..6: {}",
                per_pass.join(" "),
                feet_down.join(" ")
            );
        }
        reports.push(report);
    }
    let passed = reports.iter().filter(|r| r.passed).count();
    println!(
        "[replay] {passed}/{} clips upright and within 25 % of the command",
        reports.len()
    );
    let n = reports.len().max(1) as f32;
    let mean_feet_down: Vec<String> = (0..7)
        .map(|k| {
            let f = reports.iter().map(|r| r.feet_down_fraction[k]).sum::<f32>() / n;
            format!("{f:.2}")
        })
        .collect();
    let (min, max) = reports
        .iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), r| {
            (lo.min(r.tripod_score), hi.max(r.tripod_score))
        });
    println!(
        "[replay] tripod score mean {:.2} ({min:.2}-{max:.2}); feet down 0..6, mean share: {}",
        reports.iter().map(|r| r.tripod_score).sum::<f32>() / n,
        mean_feet_down.join(" ")
    );
    Ok(reports)
}

/// The command line that regenerates a directory, for its report.
fn regenerate_command(args: &PriorsArgs) -> String {
    let mut command = format!("hexapod priors --out {}", args.out.display());
    if args.swing_clearance_m != GeneratorConfig::default().swing_clearance_m {
        command += &format!(" --swing-clearance-m {}", args.swing_clearance_m);
    }
    if args.swing_frames != GeneratorConfig::default().swing_frames {
        command += &format!(" --swing-frames {}", args.swing_frames);
    }
    if args.swing_contact_speed_m_s != GeneratorConfig::default().swing_contact_speed_m_s {
        command += &format!(
            " --swing-contact-speed-m-s {}",
            args.swing_contact_speed_m_s
        );
    }
    if args.swing_lead_s != GeneratorConfig::default().swing_lead_s {
        command += &format!(" --swing-lead-s {}", args.swing_lead_s);
    }
    if args.base_lift_m != GeneratorConfig::default().qp.base_lift_m {
        command += &format!(" --base-lift-m {}", args.base_lift_m);
    }
    command + " --validate"
}

fn report_markdown(
    command: &str,
    reports: &[ClipReport],
    replays: Option<&[ReplayReport]>,
) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# Motion-prior generation report\n");
    let _ = writeln!(
        s,
        "Generated by `{command}`; see README.md for the method.\n"
    );
    let _ = writeln!(s, "| clip | command (vx, vy, wz) | status | iters | objective | max QP violation | force residual N | moment residual N m | cone violation N | joint-limit margin rad | reach margin m | stance slip m/s | swing apex m |");
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    for r in reports {
        let k = &r.kinematics;
        let _ = writeln!(
            s,
            "| {} | ({:+.2}, {:+.2}, {:+.2}) | {} | {} | {:.3} | {:.1e} | {:.1e} | {:.1e} | {:.1e} | {:.3} | {:.3} | {:.1e} | {:.3} |",
            r.name, r.command[0], r.command[1], r.command[2], r.solver_status, r.iterations, r.objective,
            r.max_qp_violation, r.max_force_residual_n, r.max_moment_residual_nm, r.max_friction_violation_n,
            k.min_joint_limit_margin_rad, k.min_reach_margin_m, k.max_stance_foot_speed_m_s, k.min_swing_apex_m
        );
    }
    if let Some(replays) = replays {
        let _ = writeln!(
            s,
            "\n## Replay in host-sim (drives tracking the joint trajectories)\n"
        );
        let _ = writeln!(s, "| clip | result | command (vx, vy, wz) | simulated mean (vx, vy, wz) | planar error / tolerance m/s | yaw-rate error / tolerance rad/s | max tilt rad | min height m | joint RMS vs clip rad | tripod score (clip's contact flags) | all feet down |");
        let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|---|---|");
        for r in replays {
            let _ = writeln!(
                s,
                "| {} | {} | ({:+.2}, {:+.2}, {:+.2}) | ({:+.3}, {:+.3}, {:+.3}) | {:.3} / {:.3} | {:.3} / {:.3} | {:.3} | {:.3} | {:.3} | {:.2} ({:.2}) | {:.2} |",
                r.name, if r.passed { "pass" } else { "FAIL" }, r.command[0], r.command[1], r.command[2],
                r.mean_velocity[0], r.mean_velocity[1], r.mean_velocity[2], r.lin_error_m_s, r.lin_tolerance_m_s,
                r.yaw_error_rad_s, r.yaw_tolerance_rad_s, r.max_tilt_rad, r.min_height_m, r.joint_rms_rad,
                r.tripod_score, r.clip_tripod_score, r.feet_down_fraction[NUM_LEGS]
            );
        }
    }
    s
}
