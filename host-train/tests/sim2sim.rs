//! `hexapod sim2sim`'s MuJoCo side: the shipped policy walks in MuJoCo, and a MuJoCo robot
//! observes its spawn as the simulator's does. Needs python3 with mujoco and numpy
//! (`python3 -m pip install mujoco numpy`; `.ci/run` installs them).

use host_train::checkpoint::load_for_inference;
use host_train::cli::eval::{track_command, EstimatorError};
use host_train::cli::sim2sim::{mujoco_env, nominal_sim, python_interpreter, rapier_env};
use std::path::Path;

fn shipped_policy() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/policies/terrain-averaged")
}

fn mujoco(sim: &host_sim::config::EnvConfig) -> host_sim::mujoco_env::MujocoEnv {
    mujoco_env(sim, &python_interpreter(None))
        .unwrap_or_else(|e| panic!("MuJoCo is needed here: {e}"))
}

#[test]
fn the_shipped_policy_walks_in_mujoco() {
    let (cfg, mut ppo) = load_for_inference(&shipped_policy()).unwrap();
    let sim = nominal_sim(cfg.resolved_sim());
    let mut env = mujoco(&sim);
    // 2 s at 0.3 m/s: the first second settles, the second is measured.
    let r = track_command(
        &mut env,
        &mut ppo,
        [0.3, 0.0, 0.0],
        false,
        100,
        &mut EstimatorError::default(),
        None,
    )
    .unwrap();
    eprintln!("MuJoCo {}: {r:?}", env.mujoco_version());
    assert_eq!(r.fall_rate, 0.0, "the robot fell in MuJoCo");
    assert!(
        r.mean_velocity[0] > 0.1,
        "mean vx {:.3} m/s at a 0.3 m/s command",
        r.mean_velocity[0]
    );
}

#[test]
fn mujoco_and_rapier_observe_the_same_spawn() {
    let (cfg, _) = load_for_inference(&shipped_policy()).unwrap();
    let sim = nominal_sim(cfg.resolved_sim());
    let mut a = rapier_env(&sim).unwrap().reset();
    let mut b = mujoco(&sim).reset().unwrap();
    // The simulator draws a random command at a reset; the caller sets it, as eval does.
    a.set_command(0, [0.3, 0.0, 0.0]);
    b.set_command(0, [0.3, 0.0, 0.0]);
    for (name, x, y) in [
        ("actor", &a.actor, &b.actor),
        ("history", &a.history, &b.history),
        ("amp", &a.amp, &b.amp),
    ] {
        assert_eq!(x.len(), y.len(), "{name}");
        for (k, (p, q)) in x.iter().zip(y).enumerate() {
            assert!((p - q).abs() < 1e-4, "{name}[{k}]: rapier {p}, MuJoCo {q}");
        }
    }
}
