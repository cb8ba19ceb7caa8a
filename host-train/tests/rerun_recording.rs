//! Rerun recordings (`--features rerun`): `hexapod play --rerun` with the shipped policy
//! writes `replay.rrd`, and a recording on a stairs tile carries the terrain around the
//! robot; both are RRD files (rerun's magic bytes first).
#![cfg(feature = "rerun")]

use hexapod_core::robot::NUM_LEGS;
use hexapod_core::timing::POLICY_DT_S;
use host_sim::config::EnvConfig;
use host_sim::env::HexapodEnv;
use host_sim::terrain::{TerrainConfig, TileKind};
use host_sim::vec_env::VecEnv;
use host_train::cli::play::{run, PlayArgs};
use host_train::cli::recording::Recording;
use rerun::external::re_log_encoding::RRD_FOURCC;
use std::path::{Path, PathBuf};

fn out_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("hexapod-rerun-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

/// The file's size after checking that it starts with rerun's RRD magic bytes.
fn rrd_size(path: &Path) -> usize {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    assert!(
        bytes.len() > RRD_FOURCC.len(),
        "{}: {} bytes",
        path.display(),
        bytes.len()
    );
    assert_eq!(
        bytes[..4],
        RRD_FOURCC,
        "{}: not an RRD file",
        path.display()
    );
    bytes.len()
}

#[test]
fn play_writes_a_rerun_recording() {
    let out = out_dir("play");
    let checkpoint = Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/policies/flat-tripod");
    run(PlayArgs {
        checkpoint,
        steps: 20,
        command: [0.3, 0.0, 0.0],
        out: Some(out.clone()),
        env: None,
        no_replay: true,
        tile: None,
        level: None,
        rerun: true,
    })
    .unwrap();
    let size = rrd_size(&out.join("replay.rrd"));
    // 20 steps of 19 link transforms, contacts and 7 scalars, the shapes and the ground.
    assert!(size > 20_000, "{size} bytes");
    assert!(out.join("trajectory.csv").exists());
    std::fs::remove_dir_all(&out).ok();
}

#[test]
fn recording_on_stairs_carries_the_terrain() {
    let terrain = TerrainConfig {
        tiles: true,
        rows: 2,
        columns: vec![TileKind::Flat, TileKind::StairsUp],
        ..Default::default()
    };
    let config = EnvConfig {
        num_envs: 1,
        terrain,
        curriculum: false,
        ..Default::default()
    };
    let mut env = HexapodEnv::new(config).unwrap();
    env.set_terrain_tile(0, 1, 1);
    env.reset();
    let mut recording = Recording::new(env.robot_world(0));
    assert_eq!(recording.link_names.len(), 1 + 3 * NUM_LEGS);
    assert_eq!(recording.shapes.len(), 1 + 3 * NUM_LEGS);
    let actions = vec![0.0; 18];
    for step in 0..20 {
        let t_s = step as f32 * POLICY_DT_S;
        let s = env.robot_state(0);
        recording.record(
            env.robot_world(0),
            &env.contacts(0),
            t_s,
            [0.0; 3],
            [0.0; 3],
            s.base_pos_world_m[2],
        );
        env.step(&actions);
    }
    // Standing on the tile: the feet carry its weight.
    let last = recording.steps.last().unwrap();
    let stance = last
        .foot_force_world_n
        .iter()
        .filter(|f| f[2] > host_sim::rewards::STANCE_FORCE_N)
        .count();
    assert!(stance >= 3, "{stance} feet down");
    let out = out_dir("stairs");
    std::fs::create_dir_all(&out).unwrap();
    let path = out.join("stairs.rrd");
    recording.save(&path, env.terrain()).unwrap();
    // The ground around the robot: 3 m x 3 m or more of a 5 cm grid (some 3600 points).
    assert!(rrd_size(&path) > 60_000);
    std::fs::remove_dir_all(&out).ok();
}
