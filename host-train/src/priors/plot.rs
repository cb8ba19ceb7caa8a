//! Plots of a clip (PNG): gait diagram, joint trajectories, base velocity against the
//! command, over two cycles.

use super::clip::MotionClip;
use hexapod_core::robot::{Leg, Tripod, JOINT_NAMES, LEG_NAMES, NUM_LEGS};
use plotters::prelude::*;
use std::path::Path;

/// Why a plot could not be drawn.
#[derive(Debug, thiserror::Error)]
#[error("plot {file}: {message}")]
pub struct PlotError {
    file: String,
    message: String,
}

/// A curve of the velocity panel: name, colour, value per frame, commanded value.
type Series<'a> = (&'static str, RGBColor, Box<dyn Fn(usize) -> f32 + 'a>, f32);

/// Cycles shown.
const CYCLES: usize = 2;

/// Draws the three panels of `clip` into `path`.
pub fn plot_clip(clip: &MotionClip, path: &Path) -> Result<(), PlotError> {
    draw(clip, path).map_err(|message| PlotError {
        file: path.display().to_string(),
        message,
    })
}

fn draw(clip: &MotionClip, path: &Path) -> Result<(), String> {
    let e = |err: &dyn std::fmt::Display| err.to_string();
    let root = BitMapBackend::new(path, (1000, 1100)).into_drawing_area();
    root.fill(&WHITE).map_err(|x| e(&x))?;
    let title = format!(
        "{}: command vx {:+.2} m/s, vy {:+.2} m/s, wz {:+.2} rad/s",
        clip.name, clip.command[0], clip.command[1], clip.command[2]
    );
    let root = root.titled(&title, ("sans-serif", 22)).map_err(|x| e(&x))?;
    let (top, rest) = root.split_vertically(260);
    let (middle, bottom) = rest.split_vertically(440);
    let dt = clip.frame_duration_s;
    let n = clip.frames.len();
    let total = CYCLES * n;
    let t_end = total as f32 * dt;
    let frame = |i: usize| &clip.frames[i % n];

    // Gait diagram: a bar where a foot is on the ground.
    let mut chart = ChartBuilder::on(&top)
        .caption(
            "gait diagram: feet on the ground (blue tripod A, red tripod B)",
            ("sans-serif", 18),
        )
        .margin(10)
        .x_label_area_size(30)
        .y_label_area_size(50)
        .build_cartesian_2d(0f32..t_end, -0.5f32..NUM_LEGS as f32 - 0.5)
        .map_err(|x| e(&x))?;
    chart
        .configure_mesh()
        .light_line_style(WHITE)
        .x_desc("time [s]")
        .y_labels(NUM_LEGS + 1)
        .y_label_formatter(&|y| {
            let row = y.round();
            if (y - row).abs() < 0.01 && (0.0..NUM_LEGS as f32).contains(&row) {
                LEG_NAMES[NUM_LEGS - 1 - row as usize].to_uppercase()
            } else {
                String::new()
            }
        })
        .disable_y_mesh()
        .draw()
        .map_err(|x| e(&x))?;
    for leg in Leg::ALL {
        let color = match leg.tripod() {
            Tripod::A => BLUE,
            Tripod::B => RED,
        };
        let row = (NUM_LEGS - 1 - leg.index()) as f32;
        let bars = (0..total)
            .filter(|&i| frame(i).contacts[leg.index()])
            .map(|i| {
                let t = i as f32 * dt;
                Rectangle::new(
                    [(t - 0.5 * dt, row - 0.35), (t + 0.5 * dt, row + 0.35)],
                    color.mix(0.7).filled(),
                )
            });
        chart.draw_series(bars).map_err(|x| e(&x))?;
    }

    // Joint trajectories of one leg of each tripod (RF in A, LF in B).
    let joints = [0usize, 1, 2, 9, 10, 11];
    let (lo, hi) = joints.iter().fold((f32::MAX, f32::MIN), |(lo, hi), &j| {
        clip.frames.iter().fold((lo, hi), |(lo, hi), f| {
            (lo.min(f.joint_pos_rad[j]), hi.max(f.joint_pos_rad[j]))
        })
    });
    let mut chart = ChartBuilder::on(&middle)
        .caption(
            "joint positions (RF: tripod A, LF: tripod B)",
            ("sans-serif", 18),
        )
        .margin(10)
        .x_label_area_size(30)
        .y_label_area_size(50)
        .build_cartesian_2d(0f32..t_end, (lo - 0.1)..(hi + 0.1))
        .map_err(|x| e(&x))?;
    chart
        .configure_mesh()
        .light_line_style(WHITE)
        .x_desc("time [s]")
        .y_desc("rad")
        .draw()
        .map_err(|x| e(&x))?;
    let palette = [BLUE, GREEN, MAGENTA, RED, CYAN, BLACK];
    for (c, &j) in joints.iter().enumerate() {
        let color = palette[c];
        chart
            .draw_series(LineSeries::new(
                (0..total).map(|i| (i as f32 * dt, frame(i).joint_pos_rad[j])),
                color.stroke_width(2),
            ))
            .map_err(|x| e(&x))?
            .label(JOINT_NAMES[j])
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
            });
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(|x| e(&x))?;

    // Base velocity (base frame) against the command.
    let series: [Series; 3] = [
        (
            "vx [m/s]",
            BLUE,
            Box::new(|i| frame(i).lin_vel_base_m_s[0]),
            clip.command[0],
        ),
        (
            "vy [m/s]",
            GREEN,
            Box::new(|i| frame(i).lin_vel_base_m_s[1]),
            clip.command[1],
        ),
        (
            "wz [rad/s]",
            RED,
            Box::new(|i| frame(i).ang_vel_base_rad_s[2]),
            clip.command[2],
        ),
    ];
    let (lo, hi) = series
        .iter()
        .fold((-0.1f32, 0.1f32), |(lo, hi), (_, _, f, c)| {
            (0..n).fold((lo.min(*c), hi.max(*c)), |(lo, hi), i| {
                (lo.min(f(i)), hi.max(f(i)))
            })
        });
    let mut chart = ChartBuilder::on(&bottom)
        .caption(
            "base velocity (solid) and command (dashed)",
            ("sans-serif", 18),
        )
        .margin(10)
        .x_label_area_size(30)
        .y_label_area_size(50)
        .build_cartesian_2d(0f32..t_end, (lo - 0.05)..(hi + 0.05))
        .map_err(|x| e(&x))?;
    chart
        .configure_mesh()
        .light_line_style(WHITE)
        .x_desc("time [s]")
        .draw()
        .map_err(|x| e(&x))?;
    for (name, color, f, command) in series {
        chart
            .draw_series(LineSeries::new(
                (0..total).map(|i| (i as f32 * dt, f(i))),
                color.stroke_width(2),
            ))
            .map_err(|x| e(&x))?
            .label(name)
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
            });
        chart
            .draw_series(DashedLineSeries::new(
                [(0.0, command), (t_end, command)],
                8,
                6,
                color.stroke_width(1),
            ))
            .map_err(|x| e(&x))?;
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(|x| e(&x))?;
    root.present().map_err(|x| e(&x))?;
    Ok(())
}
