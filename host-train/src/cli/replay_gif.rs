//! An animated 3D replay (GIF) of one robot: trunk box, legs as hip-coxa-thigh-shank stick
//! figures from the joint angles, at the base's world pose (roll and pitch included), over
//! the ground around it: a height grid that follows the terrain (steps, slopes, blocks) and
//! moves under the robot.

use hexapod_core::kinematics::foot_position_base;
use hexapod_core::robot::{
    Leg, COXA_LENGTH_M, HIP_POS_BASE_M, MOUNT_YAW_RAD, NUM_JOINTS, THIGH_LENGTH_M, TRUNK_SIZE_M,
};
use hexapod_core::timing::POLICY_DT_S;
use host_sim::frames::rotate;
use plotters::prelude::*;
use std::path::Path;

/// One frame of the replay.
#[derive(Clone, Debug)]
pub struct ReplayFrame {
    /// Joint angles (absolute), joint order.
    pub q_rad: [f32; NUM_JOINTS],
    /// Base position, world, m.
    pub base_pos_world_m: [f32; 3],
    /// Base orientation, world, quaternion (x, y, z, w).
    pub base_quat_xyzw: [f32; 4],
}

/// Half the side of the square of ground drawn around the robot, m.
const VIEW_HALF_M: f32 = 0.7;
/// Height of the drawn volume, m: as wide as it is high, so the plot's unit cube keeps the
/// robot's proportions.
const VIEW_HEIGHT_M: f32 = 2.0 * VIEW_HALF_M;
/// Spacing of the ground grid's lines, and of the samples along them, m.
const GRID_LINE_M: f32 = 0.1;
const GRID_SAMPLE_M: f32 = 0.025;

/// Points of one leg in the base frame: hip, coxa end (thigh axis), knee, foot.
pub fn leg_points_base(leg: Leg, q: [f32; 3]) -> [[f32; 3]; 4] {
    let i = leg.index();
    let hip = HIP_POS_BASE_M[i];
    let yaw = MOUNT_YAW_RAD[i] + q[0];
    let (c, s) = (yaw.cos(), yaw.sin());
    let coxa = [
        hip[0] + COXA_LENGTH_M[i] * c,
        hip[1] + COXA_LENGTH_M[i] * s,
        hip[2],
    ];
    let r = THIGH_LENGTH_M * q[1].cos();
    let knee = [
        coxa[0] + r * c,
        coxa[1] + r * s,
        coxa[2] - THIGH_LENGTH_M * q[1].sin(),
    ];
    [hip, coxa, knee, foot_position_base(leg, q)]
}

/// Renders the frames (every other one: 25 per second, real-time playback) into an animated
/// GIF. `ground_height_m(x, y)` is the terrain height under a world point.
pub fn render_replay(
    path: &Path,
    frames: &[ReplayFrame],
    ground_height_m: &dyn Fn(f32, f32) -> f32,
) -> Result<(), String> {
    let stride = 2usize;
    let delay_ms = (1000.0 * POLICY_DT_S * stride as f32) as u32;
    let root = BitMapBackend::gif(path, (640, 480), delay_ms)
        .map_err(|e| e.to_string())?
        .into_drawing_area();
    for (k, f) in frames.iter().enumerate().step_by(stride) {
        let [px, py, pz] = f.base_pos_world_m;
        // Plot axes: x = world x, y = up, z = world y.
        let to_plot = |p: [f32; 3]| -> (f64, f64, f64) { (p[0] as f64, p[2] as f64, p[1] as f64) };
        let to_world = |p: [f32; 3]| -> (f64, f64, f64) {
            let r = rotate(f.base_quat_xyzw, p);
            to_plot([px + r[0], py + r[1], pz + r[2]])
        };
        let floor_m = ground_height_m(px, py) - 0.45;
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let half = VIEW_HALF_M as f64;
        let mut chart = ChartBuilder::on(&root)
            .caption(
                format!("t = {:.2} s", k as f32 * POLICY_DT_S),
                (host_sim::plot::FONT, 18),
            )
            .margin(8)
            .build_cartesian_3d(
                px as f64 - half..px as f64 + half,
                floor_m as f64..(floor_m + VIEW_HEIGHT_M) as f64,
                py as f64 - half..py as f64 + half,
            )
            .map_err(|e| e.to_string())?;
        chart.with_projection(|mut pb| {
            pb.yaw = 0.6;
            pb.pitch = 0.45;
            pb.scale = 1.1;
            pb.into_matrix()
        });
        for line in ground_grid(px, py, ground_height_m) {
            chart
                .draw_series(LineSeries::new(
                    line.into_iter().map(to_plot),
                    RGBColor(110, 110, 110),
                ))
                .map_err(|e| e.to_string())?;
        }
        let (hx, hy) = (TRUNK_SIZE_M[0] / 2.0, TRUNK_SIZE_M[1] / 2.0);
        let trunk = [
            [hx, hy, 0.0],
            [hx, -hy, 0.0],
            [-hx, -hy, 0.0],
            [-hx, hy, 0.0],
            [hx, hy, 0.0],
        ];
        chart
            .draw_series(LineSeries::new(
                trunk.iter().map(|&p| to_world(p)),
                BLACK.stroke_width(3),
            ))
            .map_err(|e| e.to_string())?;
        for leg in Leg::ALL {
            let j = 3 * leg.index();
            let pts = leg_points_base(leg, [f.q_rad[j], f.q_rad[j + 1], f.q_rad[j + 2]]);
            let color = if leg.tripod() == hexapod_core::robot::Tripod::A {
                RED
            } else {
                BLUE
            };
            chart
                .draw_series(LineSeries::new(
                    pts.iter().map(|&p| to_world(p)),
                    color.stroke_width(3),
                ))
                .map_err(|e| e.to_string())?;
        }
        root.present().map_err(|e| e.to_string())?;
    }
    Ok(())
}

/// The ground around (`cx`, `cy`) as polylines in the world frame: lines every
/// [`GRID_LINE_M`] along x and along y, anchored in the world (so they slide under a walking
/// robot), sampled finely enough to draw a stair's riser as a step.
fn ground_grid(cx: f32, cy: f32, ground_height_m: &dyn Fn(f32, f32) -> f32) -> Vec<Vec<[f32; 3]>> {
    // Grid lines at whole multiples of GRID_LINE_M within the view (by index: no drift).
    let line_indices = |c: f32| {
        let lo = ((c - VIEW_HALF_M) / GRID_LINE_M - 1e-3).ceil() as i64;
        let hi = ((c + VIEW_HALF_M) / GRID_LINE_M + 1e-3).floor() as i64;
        (lo..=hi).map(|k| k as f32 * GRID_LINE_M)
    };
    let samples = (2.0 * VIEW_HALF_M / GRID_SAMPLE_M).round() as usize + 1;
    let along = |c: f32, i: usize| c - VIEW_HALF_M + i as f32 * GRID_SAMPLE_M;
    let mut lines: Vec<Vec<[f32; 3]>> = line_indices(cx)
        .map(|x| {
            (0..samples)
                .map(|i| {
                    let y = along(cy, i);
                    [x, y, ground_height_m(x, y)]
                })
                .collect()
        })
        .collect();
    lines.extend(line_indices(cy).map(|y| {
        (0..samples)
            .map(|i| {
                let x = along(cx, i);
                [x, y, ground_height_m(x, y)]
            })
            .collect()
    }));
    lines
}

#[cfg(test)]
mod tests {
    use super::*;
    use hexapod_core::robot::Q0_RAD;

    #[test]
    fn stick_figure_ends_at_the_foot() {
        for leg in Leg::ALL {
            let j = 3 * leg.index();
            let q = [Q0_RAD[j], Q0_RAD[j + 1], Q0_RAD[j + 2]];
            let pts = leg_points_base(leg, q);
            // The shank segment (knee -> foot) has the shank's length.
            let d: f32 = (0..3)
                .map(|k| (pts[3][k] - pts[2][k]).powi(2))
                .sum::<f32>()
                .sqrt();
            assert!(
                (d - hexapod_core::robot::SHANK_LENGTH_M).abs() < 1e-5,
                "{d}"
            );
        }
    }

    #[test]
    fn ground_grid_follows_the_terrain() {
        // A 10 cm step at x = 0.3: the lines across it carry both heights.
        let step = |x: f32, _y: f32| if x > 0.3 { 0.1 } else { 0.0 };
        let lines = ground_grid(0.0, 0.0, &step);
        assert_eq!(lines.len(), 2 * 15);
        let across = lines.iter().find(|l| l[0][1] == l[l.len() - 1][1]).unwrap();
        assert!(across.iter().any(|p| p[2] == 0.1) && across.iter().any(|p| p[2] == 0.0));
        for line in &lines {
            for p in line {
                assert!(p[0].abs() <= VIEW_HALF_M + 2e-3 && p[1].abs() <= VIEW_HALF_M + 2e-3);
                assert_eq!(p[2], step(p[0], p[1]));
            }
        }
    }
}
