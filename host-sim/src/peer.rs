//! The MuJoCo peer: the same URDF, dt, drive law and scripted gait run in MuJoCo by
//! `bench/mujoco_peer.py`, and the same measurements taken here in rapier, so speed and
//! fidelity are compared side by side in one run.

use crate::frames::yaw_rad;
use crate::gait::TripodGait;
use crate::robot::RobotWorld;
use crate::terrain::{Terrain, TerrainConfig, TileKind};
use crate::urdf_model::{default_urdf_path, UrdfModel};
use anyhow::{bail, Context};
use hexapod_core::robot::{
    JOINT_NAMES, NUM_JOINTS, NUM_LEGS, Q0_RAD, TORQUE_LIMIT_NM, VELOCITY_LIMIT_RAD_S,
};
use hexapod_core::timing::{CSP_KP1_PER_S, CSP_KP2_NMS_PER_RAD, PHYSICS_DT_S};
use serde::Deserialize;
use std::f32::consts::{PI, TAU};
use std::path::{Path, PathBuf};

/// Physics steps standing before measuring (10 s).
pub const STAND_STEPS: usize = 2000;
/// Physics steps walking the scripted gait (10 s).
pub const WALK_STEPS: usize = 2000;
/// Base height at spawn, m.
pub const SPAWN_HEIGHT_M: f32 = 0.35;
/// Normal force above which a foot counts as loaded when measuring foot slide, N (the
/// robot's weight is about 250 N, so a stance foot carries 40-80 N).
pub const LOADED_FOOT_N: f32 = 20.0;

/// What MuJoCo reported.
#[derive(Debug, Deserialize)]
pub struct PeerReport {
    /// Version of the `mujoco` package.
    pub mujoco_version: String,
    /// Standing base height after 10 s (noslip on), m.
    pub stand_height_m: f32,
    /// Joint torques while standing, N m.
    pub stand_torque_nm: Vec<f32>,
    /// Base displacement (x, y) after 10 s of the scripted gait, m.
    pub walk_displacement_m: Vec<f32>,
    /// Horizontal speed of feet loaded above [`LOADED_FOOT_N`] over that walk, median and
    /// 90th percentile over (foot, step) samples, m/s.
    pub walk_loaded_foot_speed_m_s: Vec<f32>,
    /// Base yaw turned (unwrapped) over 10 s of [`turning_gait`] after standing 10 s, rad.
    pub turn_yaw_rad: f32,
    /// Base displacement (x, y) after 10 s of the scripted gait on the heightfield (after
    /// standing 10 s at the tile's centre), m.
    pub terrain_walk_displacement_m: Option<Vec<f32>>,
    /// Mean base height above the tile centre's ground over that walk, m.
    pub terrain_walk_mean_height_m: Option<f32>,
    /// Mean contacts per step over that walk.
    pub terrain_walk_contacts: Option<f64>,
    /// Physics steps per second on flat ground (if measured).
    pub flat_steps_per_s: Option<f64>,
    /// Mean contacts per step on flat ground.
    pub flat_contacts: Option<f64>,
    /// Physics steps per second on the heightfield (if measured).
    pub terrain_steps_per_s: Option<f64>,
    /// Mean contacts per step on the heightfield.
    pub terrain_contacts: Option<f64>,
}

/// The same measurements in rapier.
#[derive(Debug)]
pub struct FidelityReport {
    /// Standing base height after 10 s, m.
    pub stand_height_m: f32,
    /// Joint torques while standing, N m.
    pub stand_torque_nm: [f32; NUM_JOINTS],
    /// Base displacement (x, y) after 10 s of the scripted gait, m.
    pub walk_displacement_m: [f32; 2],
    /// Horizontal speed of feet loaded above [`LOADED_FOOT_N`] over that walk, median and
    /// 90th percentile, m/s: how much stance feet slide.
    pub walk_loaded_foot_speed_m_s: [f32; 2],
    /// The (foot, step) samples those figures come from.
    pub walk_loaded_foot_samples: usize,
    /// Base yaw turned (unwrapped) over 10 s of [`turning_gait`] after standing 10 s, rad.
    pub turn_yaw_rad: f32,
}

/// The scripted gait on the heightfield, measured in rapier like the peer's.
#[derive(Debug)]
pub struct HeightfieldWalk {
    /// Base displacement (x, y) after 10 s of the scripted gait, m.
    pub displacement_m: [f32; 2],
    /// Mean base height above the tile centre's ground over the walk, m.
    pub mean_height_m: f32,
    /// Mean solver contacts per step over the walk.
    pub contacts: f64,
}

/// The gait both simulators walk.
pub fn reference_gait() -> TripodGait {
    TripodGait::default()
}

/// The turn both simulators walk: the reference gait's stride turned about the base's
/// vertical axis in place.
pub fn turning_gait() -> TripodGait {
    TripodGait {
        velocity_m_s: [0.0, 0.0],
        yaw_rate_rad_s: TURN_YAW_RATE_RAD_S,
        ..TripodGait::default()
    }
}

/// Yaw rate the turning gait's strides are planned for, rad/s.
pub const TURN_YAW_RATE_RAD_S: f32 = 0.4;

/// One period of `gait`'s joint targets at the physics rate.
fn period_targets(gait: &TripodGait) -> Vec<Vec<f32>> {
    let period_steps = (gait.period_s / PHYSICS_DT_S).round() as usize;
    (0..period_steps)
        .map(|k| gait.joint_targets(k as f32 * PHYSICS_DT_S).to_vec())
        .collect()
}

/// The rough heightfield both simulators are timed on: one 24 m tile of +-3 cm noise
/// (0.2 m lattice), large enough that the timed walk stays on it.
pub fn bench_terrain() -> Terrain {
    Terrain::generate(&TerrainConfig {
        tiles: true,
        rows: 1,
        columns: vec![TileKind::RoughSlope],
        max_slope_deg: 0.0,
        rough_noise_m: 0.03,
        tile_size_m: 24.0,
        border_m: 1.0,
        ..Default::default()
    })
}

/// Runs the fidelity procedure in rapier.
pub fn rapier_fidelity() -> anyhow::Result<FidelityReport> {
    let model = UrdfModel::load(&default_urdf_path())?;
    let mut robot = RobotWorld::new(
        &model,
        Terrain::generate(&TerrainConfig::default()).collider(),
        1,
    )?;
    stand(&mut robot);
    let s = robot.state();
    let stand_height_m = s.base_pos_world_m[2];
    let stand_torque_nm = robot.torque_nm;
    let gait = reference_gait();
    let mut feet_before = robot.foot_positions_world_m();
    let mut slide_m_s = Vec::with_capacity(WALK_STEPS * NUM_LEGS);
    for k in 0..WALK_STEPS {
        robot.step(&gait.joint_targets(k as f32 * PHYSICS_DT_S));
        let feet = robot.foot_positions_world_m();
        let force_n = robot.foot_forces_world_n();
        for leg in 0..NUM_LEGS {
            if force_n[leg][2] > LOADED_FOOT_N {
                let moved_m =
                    (feet[leg][0] - feet_before[leg][0]).hypot(feet[leg][1] - feet_before[leg][1]);
                slide_m_s.push(moved_m / PHYSICS_DT_S);
            }
        }
        feet_before = feet;
    }
    let e = robot.state().base_pos_world_m;
    slide_m_s.sort_by(f32::total_cmp);
    stand(&mut robot);
    let turn = turning_gait();
    let mut heading_rad = yaw_rad(robot.state().base_quat_xyzw);
    let mut turn_yaw_rad = 0.0;
    for k in 0..WALK_STEPS {
        robot.step(&turn.joint_targets(k as f32 * PHYSICS_DT_S));
        let h = yaw_rad(robot.state().base_quat_xyzw);
        // The heading's change in (-pi, pi]: it wraps at +-pi as the robot turns round.
        turn_yaw_rad += (h - heading_rad + PI).rem_euclid(TAU) - PI;
        heading_rad = h;
    }
    Ok(FidelityReport {
        stand_height_m,
        stand_torque_nm,
        walk_displacement_m: [e[0] - s.base_pos_world_m[0], e[1] - s.base_pos_world_m[1]],
        walk_loaded_foot_samples: slide_m_s.len(),
        walk_loaded_foot_speed_m_s: [quantile(&slide_m_s, 0.5), quantile(&slide_m_s, 0.9)],
        turn_yaw_rad,
    })
}

/// Spawns the robot at the origin and lets it stand [`STAND_STEPS`] at the nominal pose.
fn stand(robot: &mut RobotWorld) {
    robot.reset([0.0, 0.0, SPAWN_HEIGHT_M], [0.0, 0.0, 0.0, 1.0], &Q0_RAD);
    for _ in 0..STAND_STEPS {
        robot.step(&Q0_RAD);
    }
}

/// The `q` quantile (nearest rank below) of ascending `sorted`; 0 for none.
fn quantile(sorted: &[f32], q: f32) -> f32 {
    if sorted.is_empty() {
        return 0.0;
    }
    sorted[((sorted.len() - 1) as f32 * q) as usize]
}

/// The peer script shipped with the project.
pub fn peer_script() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../bench/mujoco_peer.py")
}

/// Whether `python3 -c "import mujoco"` works here.
pub fn mujoco_available() -> bool {
    std::process::Command::new("python3")
        .args(["-c", "import mujoco"])
        .output()
        .map(|o| o.status.success())
        .unwrap_or(false)
}

/// Runs MuJoCo on the same job; `speed_steps` > 0 also times flat and heightfield stepping.
pub fn run_mujoco(speed_steps: usize, settle_steps: usize) -> anyhow::Result<PeerReport> {
    let targets = period_targets(&reference_gait());
    let turn_targets = period_targets(&turning_gait());
    let model = UrdfModel::load(&default_urdf_path())?;
    let terrain = bench_terrain();
    // MuJoCo's heightfield rows run along y, columns along x.
    let mut heights = Vec::with_capacity(terrain.nx * terrain.ny);
    for iy in 0..terrain.ny {
        for ix in 0..terrain.nx {
            heights.push(terrain.heights_m[ix * terrain.ny + iy]);
        }
    }
    let cell = terrain.config.cell_size_m;
    let [cx, cy] = terrain.tile_center_m(0, 0);
    let job = serde_json::json!({
        "urdf": default_urdf_path().canonicalize()?,
        "dt_s": PHYSICS_DT_S,
        "armature_kg_m2": model.armature_kg_m2,
        "joint_names": JOINT_NAMES,
        "q0_rad": Q0_RAD,
        "gait_targets_rad": targets,
        "turn_targets_rad": turn_targets,
        "kp1_per_s": CSP_KP1_PER_S,
        "kp2_nms_per_rad": CSP_KP2_NMS_PER_RAD,
        "velocity_limit_rad_s": VELOCITY_LIMIT_RAD_S,
        "torque_limit_nm": TORQUE_LIMIT_NM,
        "spawn_height_m": SPAWN_HEIGHT_M,
        "stand_steps": STAND_STEPS,
        "walk_steps": WALK_STEPS,
        "settle_steps": settle_steps,
        "speed_steps": speed_steps,
        "hfield": {
            "nrow": terrain.ny, "ncol": terrain.nx,
            "half_x_m": (terrain.nx - 1) as f32 * cell / 2.0,
            "half_y_m": (terrain.ny - 1) as f32 * cell / 2.0,
            "heights_m": heights,
            "center_height_m": terrain.height_at_m(cx, cy),
        },
    });
    let dir = std::env::temp_dir().join(format!("hexapod-peer-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let job_path = dir.join("job.json");
    std::fs::write(&job_path, serde_json::to_vec(&job)?)?;
    let output = std::process::Command::new("python3")
        .arg(peer_script())
        .arg(&job_path)
        .output()
        .context("running python3 bench/mujoco_peer.py (pip install mujoco numpy)")?;
    let _ = std::fs::remove_dir_all(&dir);
    if !output.status.success() {
        bail!(
            "MuJoCo peer failed: {}",
            String::from_utf8_lossy(&output.stderr)
        );
    }
    let stdout = String::from_utf8_lossy(&output.stdout);
    serde_json::from_str(stdout.trim())
        .with_context(|| format!("parsing MuJoCo peer output: {stdout}"))
}

/// Stands 10 s at the centre of [`bench_terrain`], then walks the scripted gait 10 s, with
/// one contact per foot (the simulator's default) or every triangle's contact.
pub fn rapier_heightfield_walk(one_contact_per_foot: bool) -> anyhow::Result<HeightfieldWalk> {
    let model = UrdfModel::load(&default_urdf_path())?;
    let rough = bench_terrain();
    let [cx, cy] = rough.tile_center_m(0, 0);
    let z0 = rough.height_at_m(cx, cy);
    let mut robot = RobotWorld::new(&model, rough.collider(), 1)?;
    robot.set_one_contact_per_foot(one_contact_per_foot);
    robot.reset([cx, cy, SPAWN_HEIGHT_M + z0], [0.0, 0.0, 0.0, 1.0], &Q0_RAD);
    for _ in 0..STAND_STEPS {
        robot.step(&Q0_RAD);
    }
    let start = robot.state().base_pos_world_m;
    let gait = reference_gait();
    let (mut height_sum_m, mut contacts) = (0.0f64, 0usize);
    for k in 0..WALK_STEPS {
        robot.step(&gait.joint_targets(k as f32 * PHYSICS_DT_S));
        height_sum_m += f64::from(robot.state().base_pos_world_m[2] - z0);
        contacts += robot.num_contact_points();
    }
    let end = robot.state().base_pos_world_m;
    Ok(HeightfieldWalk {
        displacement_m: [end[0] - start[0], end[1] - start[1]],
        mean_height_m: (height_sum_m / WALK_STEPS as f64) as f32,
        contacts: contacts as f64 / WALK_STEPS as f64,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn feet_report_forces_on_the_heightfield() {
        let rough = bench_terrain();
        let [cx, cy] = rough.tile_center_m(0, 0);
        let model = UrdfModel::load(&default_urdf_path()).unwrap();
        let mut robot = RobotWorld::new(&model, rough.collider(), 1).unwrap();
        robot.reset(
            [cx, cy, SPAWN_HEIGHT_M + rough.height_at_m(cx, cy)],
            [0.0, 0.0, 0.0, 1.0],
            &Q0_RAD,
        );
        for _ in 0..400 {
            robot.step(&Q0_RAD);
        }
        let c = robot.contacts();
        let fz: f32 = c.foot_force_world_n.iter().map(|f| f[2]).sum();
        eprintln!(
            "fz {fz} contacts {} z {}",
            robot.num_contact_points(),
            robot.state().base_pos_world_m[2]
        );
        assert!((fz - 25.5 * 9.81).abs() < 30.0, "fz {fz}");
    }
}
