//! The motion priors as an expert to imitate: joint targets for any command of the box, by
//! trilinear interpolation between the clips of the generator's command grid at the same
//! gait phase. `hexapod pretrain --expert priors` clones it, so a warm-started policy walks
//! the priors' own gait (their duty factor, footholds and swings), the one the
//! discriminator rewards, rather than a different scripted one.
//!
//! Every clip is one gait cycle of the same tripod schedule (the same frame count and frame
//! duration, the same tripod lifting at the same frame), so frame `k` of two clips is the same gait phase
//! and their joint angles can be blended. Clips off the full grid (the extra forward 0.1
//! and 0.3 m/s) are left out of the interpolation.

use super::clip::MotionClip;
use hexapod_core::robot::NUM_JOINTS;
use hexapod_core::timing::POLICY_DT_S;

/// Two commands name the same grid point when every component is this close.
const SAME_COMMAND: f32 = 1e-4;

/// Joint targets from the priors for any command.
#[derive(Clone, Debug)]
pub struct PriorExpert {
    /// Grid values of vx (m/s), vy (m/s) and wz (rad/s), ascending.
    axes: [Vec<f32>; 3],
    /// Joint angles per grid point (vx-major, then vy, then wz) and frame, rad.
    joint_pos_rad: Vec<Vec<[f32; NUM_JOINTS]>>,
    /// Frames per gait cycle.
    frames: usize,
}

/// Why the clips cannot make an expert.
#[derive(Debug, thiserror::Error)]
#[error("the motion priors cannot be imitated: {0}")]
pub struct ExpertError(String);

impl PriorExpert {
    /// The expert of `clips`: all one gait cycle at the policy period, on a full grid of
    /// commands (at least two values per axis).
    pub fn new(clips: &[MotionClip]) -> Result<Self, ExpertError> {
        let first = clips
            .first()
            .ok_or_else(|| ExpertError("no clips".into()))?;
        let frames = first.frames.len();
        for clip in clips {
            if clip.frames.len() != frames {
                return Err(ExpertError(format!(
                    "`{}` has {} frames, `{}` {frames}: the clips must share one gait cycle",
                    clip.name,
                    clip.frames.len(),
                    first.name
                )));
            }
            if (clip.frame_duration_s - POLICY_DT_S).abs() > 1e-4 {
                return Err(ExpertError(format!(
                    "`{}`: frame duration {} s, the policy period is {POLICY_DT_S} s",
                    clip.name, clip.frame_duration_s
                )));
            }
        }
        let find = |c: [f32; 3]| {
            clips
                .iter()
                .position(|clip| (0..3).all(|k| (clip.command[k] - c[k]).abs() < SAME_COMMAND))
        };
        let axes = grid_axes(clips, find);
        if let Some(k) = (0..3).find(|&k| axes[k].len() < 2) {
            return Err(ExpertError(format!(
                "command axis {k} has fewer than two values on a full grid: {:?}",
                axes[k]
            )));
        }
        let mut joint_pos_rad = Vec::new();
        for &vx in &axes[0] {
            for &vy in &axes[1] {
                for &wz in &axes[2] {
                    let i = find([vx, vy, wz])
                        .ok_or_else(|| ExpertError(format!("no clip at ({vx}, {vy}, {wz})")))?;
                    joint_pos_rad.push(clips[i].frames.iter().map(|f| f.joint_pos_rad).collect());
                }
            }
        }
        Ok(Self {
            axes,
            joint_pos_rad,
            frames,
        })
    }

    /// Frames per gait cycle (policy steps).
    pub fn cycle_steps(&self) -> usize {
        self.frames
    }

    /// The grid's command range per axis, (min, max).
    pub fn command_range(&self) -> [(f32, f32); 3] {
        std::array::from_fn(|k| (self.axes[k][0], *self.axes[k].last().unwrap_or(&0.0)))
    }

    /// The priors' joint angles at gait frame `frame` (wrapping) for `command`, clamped to
    /// the grid, rad.
    pub fn joint_targets(&self, command: [f32; 3], frame: usize) -> [f32; NUM_JOINTS] {
        let frame = frame % self.frames;
        let brackets: [(usize, f32); 3] =
            std::array::from_fn(|k| bracket(&self.axes[k], command[k]));
        let (ny, nz) = (self.axes[1].len(), self.axes[2].len());
        let mut q = [0.0f32; NUM_JOINTS];
        for corner in 0..8 {
            let mut weight = 1.0f32;
            let mut index = [0usize; 3];
            for k in 0..3 {
                let upper = corner >> k & 1 == 1;
                let (i, u) = brackets[k];
                index[k] = i + upper as usize;
                weight *= if upper { u } else { 1.0 - u };
            }
            if weight == 0.0 {
                continue;
            }
            let clip = &self.joint_pos_rad[(index[0] * ny + index[1]) * nz + index[2]];
            for (qj, cj) in q.iter_mut().zip(&clip[frame]) {
                *qj += weight * cj;
            }
        }
        q
    }
}

/// The lower grid index of `x`'s cell and its fraction towards the upper one (x clamped to
/// the axis).
fn bracket(axis: &[f32], x: f32) -> (usize, f32) {
    let last = axis.len() - 1;
    let x = x.clamp(axis[0], axis[last]);
    let i = axis[..last].iter().rposition(|&a| a <= x).unwrap_or(0);
    let u = (x - axis[i]) / (axis[i + 1] - axis[i]);
    (i, u.clamp(0.0, 1.0))
}

/// The values of each command axis that, with every value kept on the other axes, have a
/// clip: the largest full grid the clips span (found axis by axis, vx first).
fn grid_axes(clips: &[MotionClip], find: impl Fn([f32; 3]) -> Option<usize>) -> [Vec<f32>; 3] {
    let mut axes: [Vec<f32>; 3] = std::array::from_fn(|k| {
        let mut values: Vec<f32> = clips.iter().map(|c| c.command[k]).collect();
        values.sort_by(f32::total_cmp);
        values.dedup_by(|a, b| (*a - *b).abs() < SAME_COMMAND);
        values
    });
    for k in 0..3 {
        let (a, b) = ((k + 1) % 3, (k + 2) % 3);
        let kept: Vec<f32> = axes[k]
            .iter()
            .copied()
            .filter(|&v| {
                axes[a].iter().all(|&va| {
                    axes[b].iter().all(|&vb| {
                        let mut c = [0.0; 3];
                        (c[k], c[a], c[b]) = (v, va, vb);
                        find(c).is_some()
                    })
                })
            })
            .collect();
        axes[k] = kept;
    }
    axes
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::priors::dataset::MotionDataset;
    use std::path::Path;

    fn committed() -> (Vec<MotionClip>, PriorExpert) {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/priors");
        let clips = MotionDataset::load_dir(&dir).unwrap().clips().to_vec();
        let expert = PriorExpert::new(&clips).unwrap();
        (clips, expert)
    }

    #[test]
    fn committed_priors_make_a_full_grid_over_the_command_box() {
        let (_, expert) = committed();
        assert_eq!(expert.axes[0], vec![-0.4, -0.2, 0.0, 0.2, 0.4, 0.5]);
        assert_eq!(expert.axes[1], vec![-0.2, 0.0, 0.2]);
        assert_eq!(expert.axes[2], vec![-0.5, 0.0, 0.5]);
        assert_eq!(expert.cycle_steps(), 30);
    }

    #[test]
    fn on_a_grid_point_the_expert_is_that_clip() {
        let (clips, expert) = committed();
        for clip in clips
            .iter()
            .filter(|c| c.name.starts_with("backward_0.2_left"))
        {
            for (k, frame) in clip.frames.iter().enumerate() {
                let q = expert.joint_targets(clip.command, k + clip.frames.len());
                for j in 0..NUM_JOINTS {
                    assert!(
                        (q[j] - frame.joint_pos_rad[j]).abs() < 1e-5,
                        "{} frame {k}",
                        clip.name
                    );
                }
            }
        }
    }

    #[test]
    fn between_grid_points_the_expert_blends_linearly() {
        let (clips, expert) = committed();
        let at = |cmd: [f32; 3]| {
            clips
                .iter()
                .find(|c| (0..3).all(|k| (c.command[k] - cmd[k]).abs() < 1e-4))
                .unwrap()
        };
        let (a, b) = (at([0.2, 0.0, 0.0]), at([0.4, 0.0, 0.0]));
        let q = expert.joint_targets([0.35, 0.0, 0.0], 7);
        for j in 0..NUM_JOINTS {
            let want = 0.25 * a.frames[7].joint_pos_rad[j] + 0.75 * b.frames[7].joint_pos_rad[j];
            assert!((q[j] - want).abs() < 1e-5);
        }
        // Beyond the grid the command is clamped to it.
        let top = at([0.5, 0.2, 0.5]);
        assert_eq!(
            expert.joint_targets([0.9, 0.3, 2.0], 3),
            top.frames[3].joint_pos_rad
        );
    }

    #[test]
    fn clips_of_different_cycles_are_refused() {
        let (mut clips, _) = committed();
        clips[3].frames.pop();
        let err = PriorExpert::new(&clips).unwrap_err().to_string();
        assert!(err.contains("gait cycle"), "{err}");
        assert!(PriorExpert::new(&[]).is_err());
    }
}
