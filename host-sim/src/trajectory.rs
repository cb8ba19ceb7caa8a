//! Recording a robot's motion at the policy rate: CSV output and the standard plots
//! (base height, base velocity and yaw rate against the command, roll and pitch, gait
//! diagram).

use crate::frames::rotate_inverse;
use crate::plot::{trace, write_gait, write_panels, Gait, Line, Panel, COLORS};
use crate::robot::RobotState;
use hexapod_core::robot::NUM_JOINTS;
use std::io::Write;
use std::path::Path;

/// One recorded instant.
#[derive(Clone, Debug)]
pub struct Sample {
    /// Time, s.
    pub time_s: f32,
    /// Robot state.
    pub state: RobotState,
    /// Command (vx, vy, wz).
    pub command: [f32; 3],
    /// Feet in contact (bit i = leg i).
    pub contact_mask: u8,
    /// Base height above the terrain, m.
    pub height_m: f32,
}

/// A recorded trajectory.
#[derive(Clone, Debug, Default)]
pub struct Trajectory {
    /// Samples in time order.
    pub samples: Vec<Sample>,
}

fn roll_pitch_rad(q: [f32; 4]) -> (f32, f32) {
    let [x, y, z, w] = q;
    let roll = (2.0 * (w * x + y * z)).atan2(1.0 - 2.0 * (x * x + y * y));
    let pitch = (2.0 * (w * y - z * x)).clamp(-1.0, 1.0).asin();
    (roll, pitch)
}

impl Trajectory {
    /// Appends a sample.
    pub fn push(&mut self, sample: Sample) {
        self.samples.push(sample);
    }

    /// Base velocity in the base frame of every sample.
    pub fn lin_vel_base(&self) -> Vec<[f32; 3]> {
        self.samples
            .iter()
            .map(|s| rotate_inverse(s.state.base_quat_xyzw, s.state.base_lin_vel_world_m_s))
            .collect()
    }

    /// Writes one row per sample.
    pub fn write_csv(&self, path: &Path) -> anyhow::Result<()> {
        let mut f = std::io::BufWriter::new(std::fs::File::create(path)?);
        write!(f, "time_s,x_m,y_m,z_m,qx,qy,qz,qw,vx_base_m_s,vy_base_m_s,vz_base_m_s,wx_rad_s,wy_rad_s,wz_rad_s,cmd_vx,cmd_vy,cmd_wz,height_m,contact_mask")?;
        for j in 0..NUM_JOINTS {
            write!(f, ",q{j}_rad")?;
        }
        writeln!(f)?;
        for (s, v) in self.samples.iter().zip(self.lin_vel_base()) {
            let st = &s.state;
            let w = rotate_inverse(st.base_quat_xyzw, st.base_ang_vel_world_rad_s);
            write!(
                f,
                "{:.4},{:.5},{:.5},{:.5}",
                s.time_s, st.base_pos_world_m[0], st.base_pos_world_m[1], st.base_pos_world_m[2]
            )?;
            for q in st.base_quat_xyzw {
                write!(f, ",{q:.5}")?;
            }
            for x in v.iter().chain(w.iter()).chain(s.command.iter()) {
                write!(f, ",{x:.5}")?;
            }
            write!(f, ",{:.5},{}", s.height_m, s.contact_mask)?;
            for q in st.q_rad {
                write!(f, ",{q:.5}")?;
            }
            writeln!(f)?;
        }
        Ok(())
    }

    /// Writes `motion.png` (height, planar velocity and yaw rate against the command,
    /// attitude) and `gait.png` into `dir`.
    pub fn write_plots(&self, dir: &Path) -> anyhow::Result<()> {
        let t: Vec<f32> = self.samples.iter().map(|s| s.time_s).collect();
        let v = self.lin_vel_base();
        let wz = self
            .samples
            .iter()
            .map(|s| rotate_inverse(s.state.base_quat_xyzw, s.state.base_ang_vel_world_rad_s)[2]);
        let cmd = |k: usize| trace(&t, self.samples.iter().map(move |s| s.command[k]));
        let (roll, pitch): (Vec<f32>, Vec<f32>) = self
            .samples
            .iter()
            .map(|s| {
                let (r, p) = roll_pitch_rad(s.state.base_quat_xyzw);
                (r.to_degrees(), p.to_degrees())
            })
            .unzip();
        let (vx_color, vy_color) = (COLORS[0], COLORS[1]);
        let panels = [
            Panel::new(
                "base height above the terrain",
                "time (s)",
                "base height (m)",
            )
            .line(Line::nth(
                0,
                "height",
                trace(&t, self.samples.iter().map(|s| s.height_m)),
            )),
            Panel::new(
                "base velocity (base frame): measured, command dashed",
                "time (s)",
                "velocity (m/s)",
            )
            .line(Line::new("vx", trace(&t, v.iter().map(|v| v[0])), vx_color))
            .line(Line::new("vx command", cmd(0), vx_color).dashed())
            .line(Line::new("vy", trace(&t, v.iter().map(|v| v[1])), vy_color))
            .line(Line::new("vy command", cmd(1), vy_color).dashed()),
            Panel::new(
                "yaw rate (base frame): measured, command dashed",
                "time (s)",
                "yaw rate (rad/s)",
            )
            .line(Line::new("wz", trace(&t, wz), COLORS[2]))
            .line(Line::new("wz command", cmd(2), COLORS[2]).dashed()),
            Panel::new("attitude", "time (s)", "angle (deg)")
                .line(Line::nth(0, "roll", trace(&t, roll)))
                .line(Line::nth(1, "pitch", trace(&t, pitch))),
        ];
        write_panels(&dir.join("motion.png"), None, 1, (1000, 270), &panels)?;
        let masks: Vec<u8> = self.samples.iter().map(|s| s.contact_mask).collect();
        let dt_s = if t.len() > 1 {
            t[1] - t[0]
        } else {
            hexapod_core::timing::POLICY_DT_S
        };
        write_gait(
            &dir.join("gait.png"),
            &Gait {
                title: "gait diagram: feet in stance",
                time_s: &t,
                stance_masks: &masks,
                dt_s,
            },
        )?;
        Ok(())
    }
}
