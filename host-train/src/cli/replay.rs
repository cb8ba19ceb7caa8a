//! An animated 3D replay (GIF) of one robot: trunk box, legs as hip-coxa-thigh-shank stick
//! figures from the joint angles, the base pose integrated from its planar velocity and yaw
//! rate, and a ground grid that moves under the robot.

use hexapod_core::kinematics::foot_position_base;
use hexapod_core::robot::{Leg, COXA_LENGTH_M, HIP_POS_BASE_M, MOUNT_YAW_RAD, NUM_JOINTS, THIGH_LENGTH_M, TRUNK_SIZE_M};
use hexapod_core::timing::POLICY_DT_S;
use plotters::prelude::*;
use std::path::Path;

/// One frame of the replay.
#[derive(Clone, Debug)]
pub struct ReplayFrame {
    /// Joint angles (absolute), joint order.
    pub q_rad: [f32; NUM_JOINTS],
    /// Base planar velocity (base frame).
    pub lin_vel_base_m_s: [f32; 2],
    /// Yaw rate.
    pub yaw_rate_rad_s: f32,
    /// Base height above the terrain.
    pub base_height_m: f32,
}

/// Points of one leg in the base frame: hip, coxa end (thigh axis), knee, foot.
pub fn leg_points_base(leg: Leg, q: [f32; 3]) -> [[f32; 3]; 4] {
    let i = leg.index();
    let hip = HIP_POS_BASE_M[i];
    let yaw = MOUNT_YAW_RAD[i] + q[0];
    let (c, s) = (yaw.cos(), yaw.sin());
    let coxa = [hip[0] + COXA_LENGTH_M[i] * c, hip[1] + COXA_LENGTH_M[i] * s, hip[2]];
    let r = THIGH_LENGTH_M * q[1].cos();
    let knee = [coxa[0] + r * c, coxa[1] + r * s, coxa[2] - THIGH_LENGTH_M * q[1].sin()];
    [hip, coxa, knee, foot_position_base(leg, q)]
}

/// Renders the frames (every `stride`-th, real-time playback) into an animated GIF.
pub fn render_replay(path: &Path, frames: &[ReplayFrame]) -> Result<(), String> {
    let stride = 2usize; // 25 frames per second
    let delay_ms = (1000.0 * POLICY_DT_S * stride as f32) as u32;
    let root = BitMapBackend::gif(path, (640, 480), delay_ms).map_err(|e| e.to_string())?.into_drawing_area();
    let (mut x, mut y, mut yaw) = (0.0f32, 0.0f32, 0.0f32);
    for (k, f) in frames.iter().enumerate() {
        let (c, s) = (yaw.cos(), yaw.sin());
        x += (c * f.lin_vel_base_m_s[0] - s * f.lin_vel_base_m_s[1]) * POLICY_DT_S;
        y += (s * f.lin_vel_base_m_s[0] + c * f.lin_vel_base_m_s[1]) * POLICY_DT_S;
        yaw += f.yaw_rate_rad_s * POLICY_DT_S;
        if k % stride != 0 {
            continue;
        }
        let z0 = f.base_height_m;
        let to_world = |p: [f32; 3]| -> (f64, f64, f64) {
            ((x + c * p[0] - s * p[1]) as f64, (p[2] + z0) as f64, (y + s * p[0] + c * p[1]) as f64)
        };
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let half = 0.8f64;
        let (cx, cy) = (x as f64, y as f64);
        let mut chart = ChartBuilder::on(&root)
            .caption(format!("t = {:.2} s", k as f32 * POLICY_DT_S), ("sans-serif", 18))
            .margin(8)
            .build_cartesian_3d(cx - half..cx + half, 0.0..0.6f64, cy - half..cy + half)
            .map_err(|e| e.to_string())?;
        chart.with_projection(|mut pb| {
            pb.yaw = 0.6;
            pb.pitch = 0.35;
            pb.scale = 0.9;
            pb.into_matrix()
        });
        // Ground grid, 0.2 m, anchored in the world so it slides under a walking robot.
        let step = 0.2f64;
        let start = |v: f64| ((v - half) / step).ceil() * step;
        let mut g = start(cx);
        while g <= cx + half {
            chart
                .draw_series(LineSeries::new([(g, 0.0, cy - half), (g, 0.0, cy + half)], RGBColor(200, 200, 200)))
                .map_err(|e| e.to_string())?;
            g += step;
        }
        let mut g = start(cy);
        while g <= cy + half {
            chart
                .draw_series(LineSeries::new([(cx - half, 0.0, g), (cx + half, 0.0, g)], RGBColor(200, 200, 200)))
                .map_err(|e| e.to_string())?;
            g += step;
        }
        let (hx, hy) = (TRUNK_SIZE_M[0] / 2.0, TRUNK_SIZE_M[1] / 2.0);
        let trunk = [[hx, hy, 0.0], [hx, -hy, 0.0], [-hx, -hy, 0.0], [-hx, hy, 0.0], [hx, hy, 0.0]];
        chart
            .draw_series(LineSeries::new(trunk.iter().map(|&p| to_world(p)), BLACK.stroke_width(3)))
            .map_err(|e| e.to_string())?;
        for leg in Leg::ALL {
            let j = 3 * leg.index();
            let pts = leg_points_base(leg, [f.q_rad[j], f.q_rad[j + 1], f.q_rad[j + 2]]);
            let color = if leg.tripod() == hexapod_core::robot::Tripod::A { RED } else { BLUE };
            chart
                .draw_series(LineSeries::new(pts.iter().map(|&p| to_world(p)), color.stroke_width(3)))
                .map_err(|e| e.to_string())?;
        }
        root.present().map_err(|e| e.to_string())?;
    }
    Ok(())
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
            let d: f32 = (0..3).map(|k| (pts[3][k] - pts[2][k]).powi(2)).sum::<f32>().sqrt();
            assert!((d - hexapod_core::robot::SHANK_LENGTH_M).abs() < 1e-5, "{d}");
        }
    }
}
