//! A 3D recording of one simulated robot, step by step, for the rerun viewer: the link
//! poses and collision shapes as the simulator has them, the foot forces, the command
//! against the measured velocity and the base height. `play --rerun` and `eval --rerun`
//! fill one; [`Recording::save`] writes it as a rerun `.rrd` file in a build with the
//! `rerun` feature (`crate::cli::rerun_writer`).

use hexapod_core::robot::NUM_LEGS;
use host_sim::robot::{ContactState, LinkShape, RobotWorld};
use host_sim::terrain::Terrain;
use std::path::Path;

/// The command that builds `hexapod` with rerun recordings.
pub const BUILD_WITH_RERUN: &str =
    "cargo run --release -p host-train --features rerun --bin hexapod --";

/// Fails with how to get a build that writes rerun recordings, unless this is one.
pub fn require_rerun(subcommand: &str) -> anyhow::Result<()> {
    anyhow::ensure!(
        cfg!(feature = "rerun"),
        "--rerun: this hexapod was built without the `rerun` feature; run `{BUILD_WITH_RERUN} {subcommand} ... --rerun`"
    );
    Ok(())
}

/// One policy step of the recorded robot.
#[derive(Clone, Debug)]
pub struct RecordedStep {
    /// Simulated time, s.
    pub t_s: f32,
    /// Position of each link frame (order of [`Recording::link_names`]), world, m.
    pub link_pos_world_m: Vec<[f32; 3]>,
    /// Orientation of each link frame, world, quaternion (x, y, z, w).
    pub link_quat_world_xyzw: Vec<[f32; 4]>,
    /// Centre of each foot sphere, world, m.
    pub foot_pos_world_m: [[f32; 3]; NUM_LEGS],
    /// Ground reaction force on each foot, world, N.
    pub foot_force_world_n: [[f32; 3]; NUM_LEGS],
    /// The command (vx m/s, vy m/s, wz rad/s).
    pub command: [f32; 3],
    /// The measured base velocity (vx m/s, vy m/s in the base frame, wz rad/s).
    pub measured: [f32; 3],
    /// Base height above the ground under it, m.
    pub base_height_m: f32,
}

/// A recording of one robot: its geometry once, then one [`RecordedStep`] per policy step.
#[derive(Clone, Debug)]
pub struct Recording {
    /// The URDF link names, in the simulator's order.
    pub link_names: Vec<String>,
    /// The simulator's collision shapes on their links.
    pub shapes: Vec<LinkShape>,
    /// The steps, in time order.
    pub steps: Vec<RecordedStep>,
    /// Labelled stretches of the timeline (eval: one per command): start time, s, and label.
    pub segments: Vec<(f32, String)>,
}

impl Recording {
    /// An empty recording of `robot`'s geometry.
    pub fn new(robot: &RobotWorld) -> Self {
        Self {
            link_names: robot
                .link_poses()
                .iter()
                .map(|p| p.name.to_string())
                .collect(),
            shapes: robot.link_shapes(),
            steps: Vec::new(),
            segments: Vec::new(),
        }
    }

    /// Records `robot` at time `t_s`, with the contacts of its last step and the command,
    /// measured velocity and base height that its observation carries.
    pub fn record(
        &mut self,
        robot: &RobotWorld,
        contacts: &ContactState,
        t_s: f32,
        command: [f32; 3],
        measured: [f32; 3],
        base_height_m: f32,
    ) {
        let poses = robot.link_poses();
        self.steps.push(RecordedStep {
            t_s,
            link_pos_world_m: poses.iter().map(|p| p.pos_world_m).collect(),
            link_quat_world_xyzw: poses.iter().map(|p| p.quat_world_xyzw).collect(),
            foot_pos_world_m: robot.foot_positions_world_m(),
            foot_force_world_n: contacts.foot_force_world_n,
            command,
            measured,
            base_height_m,
        });
    }

    /// Starts a labelled stretch of the timeline at `t_s`.
    pub fn start_segment(&mut self, t_s: f32, label: impl Into<String>) {
        self.segments.push((t_s, label.into()));
    }

    /// The planar box (x min, y min, x max, y max), m, that the base visits, widened by
    /// `margin_m`; `None` for an empty recording.
    pub fn footprint_m(&self, margin_m: f32) -> Option<[f32; 4]> {
        let mut b = [
            f32::INFINITY,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NEG_INFINITY,
        ];
        for p in self.steps.iter().filter_map(|s| s.link_pos_world_m.first()) {
            b = [
                b[0].min(p[0]),
                b[1].min(p[1]),
                b[2].max(p[0]),
                b[3].max(p[1]),
            ];
        }
        b[0].is_finite().then(|| {
            [
                b[0] - margin_m,
                b[1] - margin_m,
                b[2] + margin_m,
                b[3] + margin_m,
            ]
        })
    }

    /// Writes the recording as a rerun `.rrd` file, with the part of `terrain` around the
    /// robot's path.
    pub fn save(&self, path: &Path, terrain: &Terrain) -> anyhow::Result<()> {
        #[cfg(feature = "rerun")]
        return crate::cli::rerun_writer::write_rrd(self, terrain, path);
        #[cfg(not(feature = "rerun"))]
        {
            let _ = terrain;
            anyhow::bail!("{}: writing a rerun recording needs a build with the `rerun` feature ({BUILD_WITH_RERUN} ...)", path.display())
        }
    }
}
