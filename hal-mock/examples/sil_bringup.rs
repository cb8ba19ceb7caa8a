//! Runs the controller core against the emulated drives through boot, stand-up, 5 s of
//! standing with the zero policy and sit-down, and writes the CAN traffic as a candump log.
//!
//! `cargo run -p hal-mock --example sil_bringup -- [LOG]` (default `target/sil_bringup.log`);
//! replay or inspect the log with can-utils (`canplayer -I LOG`), python-can or SavvyCAN.

use std::time::Instant;

use hal_mock::harness::Harness;
use hal_mock::plant::JointModel;
use hexapod_core::controller::{ControllerConfig, ZeroPolicy};
use hexapod_core::robot::Q_SIT_RAD;

fn main() -> std::io::Result<()> {
    let path = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "target/sil_bringup.log".into());
    let mut physics = |p: &mut JointModel, dt: f32| p.step(dt);
    let mut h = Harness::new(JointModel::at(&Q_SIT_RAD), ControllerConfig::default(), 1);
    h.rig.record();
    let wall = Instant::now();
    h.start(&mut physics);
    h.run(1.0, &mut ZeroPolicy, &mut physics);
    println!(
        "{:>6.2} s  {:?}",
        h.now_us as f64 * 1e-6,
        h.controller.mode()
    );
    h.rc.set_arm(true);
    for _ in 0..9 {
        h.run(1.0, &mut ZeroPolicy, &mut physics);
        println!(
            "{:>6.2} s  {:?}",
            h.now_us as f64 * 1e-6,
            h.controller.mode()
        );
    }
    h.rc.set_arm(false);
    h.run(4.0, &mut ZeroPolicy, &mut physics);
    println!(
        "{:>6.2} s  {:?}",
        h.now_us as f64 * 1e-6,
        h.controller.mode()
    );
    let elapsed = wall.elapsed();
    let log = h.rig.candump();
    std::fs::write(&path, &log)?;
    let stats = h.controller.stats;
    println!(
        "{} frames -> {path}; {} cycles, worst SYNC-to-RPDO {} us, {} overruns, {} incomplete",
        log.lines().count(),
        stats.cycles,
        stats.worst_cycle_us,
        stats.overruns,
        stats.incomplete_feedback
    );
    println!(
        "simulated {:.1} s in {:.2} s of wall time ({:.0}x real time)",
        h.now_us as f64 * 1e-6,
        elapsed.as_secs_f64(),
        h.now_us as f64 * 1e-6 / elapsed.as_secs_f64()
    );
    Ok(())
}
