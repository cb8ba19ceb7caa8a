//! Plots of a clip (PNG): gait diagram, joint trajectories, base velocity against the
//! command, over two cycles.

use super::clip::MotionClip;
use hexapod_core::robot::{JOINT_NAMES, NUM_LEGS};
use host_sim::plot::{
    draw_gait, draw_panel, gait_legend_width, legend_width, Gait, Line, Panel, COLORS, FONT,
};
use plotters::prelude::*;
use std::path::Path;

/// Why a plot could not be drawn.
#[derive(Debug, thiserror::Error)]
#[error("plot {file}: {message}")]
pub struct PlotError {
    file: String,
    message: String,
}

/// Cycles shown.
const CYCLES: usize = 2;

/// Draws the panels of `clip` (gait, joints, linear velocity, yaw rate) into `path`.
pub fn plot_clip(clip: &MotionClip, path: &Path) -> Result<(), PlotError> {
    draw(clip, path).map_err(|message| PlotError {
        file: path.display().to_string(),
        message,
    })
}

fn draw(clip: &MotionClip, path: &Path) -> Result<(), String> {
    let e = |err: &dyn std::fmt::Display| err.to_string();
    let root = BitMapBackend::new(path, (1000, 1240)).into_drawing_area();
    root.fill(&WHITE).map_err(|x| e(&x))?;
    let title = format!(
        "{}: command vx {:+.2} m/s, vy {:+.2} m/s, wz {:+.2} rad/s",
        clip.name, clip.command[0], clip.command[1], clip.command[2]
    );
    let root = root.titled(&title, (FONT, 20)).map_err(|x| e(&x))?;
    let (gait_area, rest) = root.split_vertically(260);
    let (joint_area, rest) = rest.split_vertically(380);
    let (lin_area, yaw_area) = rest.split_vertically(280);
    let dt = clip.frame_duration_s;
    let n = clip.frames.len();
    let total = CYCLES * n;
    let frame = |i: usize| &clip.frames[i % n];
    let time_s: Vec<f32> = (0..total).map(|i| i as f32 * dt).collect();
    let trace = |f: &dyn Fn(usize) -> f32| -> Vec<(f64, f64)> {
        (0..total)
            .map(|i| (time_s[i] as f64, f(i) as f64))
            .collect()
    };

    // Joint trajectories of one leg of each tripod (RF in A, LF in B).
    let joints = [0usize, 1, 2, 9, 10, 11];
    let joint_panel = joints.iter().enumerate().fold(
        Panel::new(
            "joint positions (RF: tripod A, LF: tripod B)",
            "time (s)",
            "joint angle (rad)",
        ),
        |p, (c, &j)| {
            p.line(Line::nth(
                c,
                JOINT_NAMES[j],
                trace(&|i| frame(i).joint_pos_rad[j]),
            ))
        },
    );
    // Base velocity (base frame) against the command: m/s and rad/s on separate axes.
    let flat =
        |v: f32| -> Vec<(f64, f64)> { vec![(0.0, v as f64), (total as f64 * dt as f64, v as f64)] };
    let (vx, vy, wz) = (COLORS[0], COLORS[1], COLORS[2]);
    let lin_panel = Panel::new(
        "linear velocity (base frame): clip, command dashed",
        "time (s)",
        "velocity (m/s)",
    )
    .line(Line::new(
        "vx",
        trace(&|i| frame(i).lin_vel_base_m_s[0]),
        vx,
    ))
    .line(Line::new("vx command", flat(clip.command[0]), vx).dashed())
    .line(Line::new(
        "vy",
        trace(&|i| frame(i).lin_vel_base_m_s[1]),
        vy,
    ))
    .line(Line::new("vy command", flat(clip.command[1]), vy).dashed());
    let yaw_panel = Panel::new(
        "yaw rate (base frame): clip, command dashed",
        "time (s)",
        "yaw rate (rad/s)",
    )
    .line(Line::new(
        "wz",
        trace(&|i| frame(i).ang_vel_base_rad_s[2]),
        wz,
    ))
    .line(Line::new("wz command", flat(clip.command[2]), wz).dashed());

    let legend_px =
        legend_width(&root, &[&joint_panel, &lin_panel, &yaw_panel]).max(gait_legend_width(&root));
    let masks: Vec<u8> = (0..total)
        .map(|i| {
            (0..NUM_LEGS)
                .filter(|&l| frame(i).contacts[l])
                .fold(0u8, |m, l| m | (1 << l))
        })
        .collect();
    let gait = Gait {
        title: "gait diagram: feet on the ground",
        time_s: &time_s,
        stance_masks: &masks,
        dt_s: dt,
    };
    draw_gait(&gait_area, &gait, legend_px).map_err(|x| e(&x))?;
    draw_panel(&joint_area, &joint_panel, legend_px).map_err(|x| e(&x))?;
    draw_panel(&lin_area, &lin_panel, legend_px).map_err(|x| e(&x))?;
    draw_panel(&yaw_area, &yaw_panel, legend_px).map_err(|x| e(&x))?;
    root.present().map_err(|x| e(&x))?;
    Ok(())
}
