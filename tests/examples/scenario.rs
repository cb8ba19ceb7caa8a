//! Runs one scenario file and writes what happened: the CAN traffic as a candump log and
//! the robot's trace as CSV.
//!
//! `cargo run -p sil-tests --example scenario -- tests/scenarios/bus_off_while_standing.toml [OUT_DIR]`
//! (default `target/sil-scenario`); read the log with can-utils (`canplayer -I`, `log2asc`),
//! python-can or SavvyCAN.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result};
use sil_tests::scenario::Scenario;

fn main() -> Result<()> {
    let mut args = std::env::args().skip(1);
    let path = PathBuf::from(args.next().context("usage: scenario FILE.toml [OUT_DIR]")?);
    let out = PathBuf::from(args.next().unwrap_or_else(|| "target/sil-scenario".into()));
    let scenario = Scenario::load(&path)?;
    let mut sil = scenario.rig()?;
    sil.h.rig.record();
    let wall = Instant::now();
    let result = scenario.run_on(sil);
    let elapsed_s = wall.elapsed().as_secs_f64();
    let sil = match result {
        Ok(sil) => sil,
        Err(e) => anyhow::bail!("{}: {e}", path.display()),
    };
    std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
    let stem = path
        .file_stem()
        .map_or("scenario".into(), |s| s.to_string_lossy());
    let log_path = out.join(format!("{stem}.log"));
    let csv_path = out.join(format!("{stem}.csv"));
    std::fs::write(&log_path, sil.h.rig.candump())?;
    std::fs::write(&csv_path, sil.plant().trace.to_csv())?;
    let sim_s = sil.time_s() as f64;
    println!("{}: {}", path.display(), scenario.description);
    println!(
        "ok: {sim_s:.1} s simulated in {elapsed_s:.2} s ({:.0}x real time), final mode {:?}",
        sim_s / elapsed_s,
        sil.mode()
    );
    let p = sil.plant();
    let [x, y, _] = p.state().base_pos_world_m;
    println!(
        "the base came {:.2} m along +x; the ground under it went from {:.2} m to {:.2} m",
        p.progress_m(),
        p.ground.height_at_m(p.start_pos_m[0], p.start_pos_m[1]),
        p.ground.height_at_m(x, y)
    );
    println!("-> {} and {}", log_path.display(), csv_path.display());
    Ok(())
}
