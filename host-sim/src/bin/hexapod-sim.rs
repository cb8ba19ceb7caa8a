//! `hexapod-sim`: the simulator's command line: a demo (stand, then walk a scripted tripod
//! gait, with a CSV trajectory and plots), the speed benchmark against MuJoCo, and the URDF
//! generated from hexapod-core.

use clap::{Parser, Subcommand};
use std::path::PathBuf;

#[derive(Parser)]
#[command(
    name = "hexapod-sim",
    version,
    about = "Hexapod simulator: demo and benchmarks"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Stand, then walk an open-loop tripod gait; write trajectory.csv, motion.png, gait.png.
    Demo {
        /// Output directory.
        #[arg(long, default_value = "runs/demo")]
        out: PathBuf,
        /// Seconds standing before walking.
        #[arg(long, default_value_t = 3.0)]
        stand_s: f32,
        /// Seconds walking.
        #[arg(long, default_value_t = 10.0)]
        walk_s: f32,
        /// Forward speed of the scripted gait, m/s.
        #[arg(long, default_value_t = 0.2)]
        speed_m_s: f32,
    },
    /// Physics and environment steps per second, side by side with MuJoCo on the same URDF.
    Bench(host_sim::bench::BenchArgs),
    /// Writes the robot's URDF from hexapod-core's robot definition (or checks it is fresh).
    Urdf {
        /// The URDF file.
        #[arg(long, default_value = "assets/hexapod.urdf")]
        out: PathBuf,
        /// Only check that the file is up to date (exit 1 when stale).
        #[arg(long)]
        check: bool,
    },
}

fn main() -> anyhow::Result<()> {
    match Cli::parse().command {
        Command::Demo {
            out,
            stand_s,
            walk_s,
            speed_m_s,
        } => host_sim::demo::run(&out, stand_s, walk_s, speed_m_s),
        Command::Bench(args) => host_sim::bench::run(&args),
        Command::Urdf { out, check } => host_sim::urdf_gen::write_or_check(&out, check),
    }
}
