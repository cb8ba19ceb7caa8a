//! The demo: one robot on flat ground stands, then walks the scripted tripod gait.

use crate::gait::TripodGait;
use crate::robot::RobotWorld;
use crate::terrain::{Terrain, TerrainConfig};
use crate::trajectory::{Sample, Trajectory};
use crate::urdf_model::{default_urdf_path, UrdfModel};
use anyhow::Context;
use hexapod_core::robot::Q0_RAD;
use hexapod_core::timing::{DECIMATION, PHYSICS_DT_S, POLICY_DT_S};
use std::path::Path;

/// Runs the demo and writes its outputs into `out`.
pub fn run(out: &Path, stand_s: f32, walk_s: f32, speed_m_s: f32) -> anyhow::Result<()> {
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let model = UrdfModel::load(&default_urdf_path())?;
    let mut robot = RobotWorld::new(
        &model,
        Terrain::generate(&TerrainConfig::default()).collider(),
        1,
    )?;
    let gait = TripodGait {
        velocity_m_s: [speed_m_s, 0.0],
        ..Default::default()
    };
    let mut traj = Trajectory::default();
    let steps = ((stand_s + walk_s) / POLICY_DT_S).round() as usize;
    let stand_steps = (stand_s / POLICY_DT_S).round() as usize;
    let started = std::time::Instant::now();
    for k in 0..steps {
        let walking = k >= stand_steps;
        for sub in 0..DECIMATION {
            let t = ((k - stand_steps.min(k)) * DECIMATION + sub) as f32 * PHYSICS_DT_S;
            let target = if walking {
                gait.joint_targets(t)
            } else {
                Q0_RAD
            };
            robot.step(&target);
        }
        let state = robot.state();
        let contacts = robot.contacts();
        let mask = crate::rewards::stance_mask(&contacts.foot_force_world_n);
        traj.push(Sample {
            time_s: (k + 1) as f32 * POLICY_DT_S,
            state,
            command: if walking {
                [speed_m_s, 0.0, 0.0]
            } else {
                [0.0; 3]
            },
            contact_mask: mask,
            height_m: state.base_pos_world_m[2],
        });
        if (k + 1) % 50 == 0 {
            eprint!(
                "\r[demo] {:5.1} s simulated / {:.1} s",
                (k + 1) as f32 * POLICY_DT_S,
                stand_s + walk_s
            );
        }
    }
    eprintln!();
    traj.write_csv(&out.join("trajectory.csv"))?;
    traj.write_plots(out)?;
    let last = traj.samples.last().map(|s| s.state).unwrap_or_default();
    let walked_m = last.base_pos_world_m[0];
    println!(
        "stood {stand_s} s, walked {walk_s} s at {speed_m_s} m/s commanded: base moved {walked_m:.2} m ({:.3} m/s), final height {:.3} m; simulated in {:.2} s",
        walked_m / walk_s.max(1e-3),
        last.base_pos_world_m[2],
        started.elapsed().as_secs_f32()
    );
    println!(
        "wrote {}/trajectory.csv, motion.png, gait.png",
        out.display()
    );
    Ok(())
}
