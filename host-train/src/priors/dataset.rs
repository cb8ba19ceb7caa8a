//! The motion-prior dataset: all clips of a directory, their AMP states, and transition
//! sampling for the discriminator.

use super::clip::{ClipError, MotionClip};
use hexapod_core::amp::AMP_STATE_DIM;
use rand::Rng;
use std::path::{Path, PathBuf};

/// One AMP state.
pub type AmpState = [f32; AMP_STATE_DIM];

/// Validated clips with their precomputed AMP states.
#[derive(Clone, Debug)]
pub struct MotionDataset {
    clips: Vec<MotionClip>,
    states: Vec<Vec<AmpState>>,
    cumulative_weight: Vec<f32>,
}

/// Why a dataset could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum DatasetError {
    /// A clip was refused.
    #[error(transparent)]
    Clip(#[from] ClipError),
    /// The directory could not be listed.
    #[error("{dir}: {source}")]
    Dir {
        /// Directory.
        dir: PathBuf,
        /// Cause.
        source: std::io::Error,
    },
    /// No clip was found.
    #[error("{0}: no motion files (*.json)")]
    Empty(PathBuf),
}

impl MotionDataset {
    /// A dataset of the given clips (at least one).
    pub fn new(clips: Vec<MotionClip>) -> Self {
        let states = clips.iter().map(MotionClip::amp_states).collect();
        let mut total = 0.0;
        let cumulative_weight = clips
            .iter()
            .map(|c| {
                total += c.motion_weight;
                total
            })
            .collect();
        Self {
            clips,
            states,
            cumulative_weight,
        }
    }

    /// Loads every `*.json` file of `dir` (sorted by name), refusing the first bad one.
    pub fn load_dir(dir: &Path) -> Result<Self, DatasetError> {
        let mut paths: Vec<PathBuf> = std::fs::read_dir(dir)
            .map_err(|source| DatasetError::Dir {
                dir: dir.to_path_buf(),
                source,
            })?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|e| e == "json"))
            .collect();
        paths.sort();
        if paths.is_empty() {
            return Err(DatasetError::Empty(dir.to_path_buf()));
        }
        let clips = paths
            .iter()
            .map(|p| MotionClip::load(p))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Self::new(clips))
    }

    /// The clips.
    pub fn clips(&self) -> &[MotionClip] {
        &self.clips
    }

    /// AMP states of clip `i`, one per frame.
    pub fn amp_states(&self, i: usize) -> &[AmpState] {
        &self.states[i]
    }

    /// Total duration, s.
    pub fn duration_s(&self) -> f32 {
        self.clips.iter().map(MotionClip::duration_s).sum()
    }

    /// `n` transitions `(s_t, s_t+1)` one policy step apart: a clip drawn with probability
    /// proportional to its `MotionWeight`, then a frame uniformly (AMP_for_hardware's
    /// scheme).
    pub fn sample_transitions<R: Rng + ?Sized>(
        &self,
        rng: &mut R,
        n: usize,
    ) -> Vec<(AmpState, AmpState)> {
        let total = *self.cumulative_weight.last().unwrap_or(&0.0);
        (0..n)
            .map(|_| {
                let u = rng.gen_range(0.0..total);
                let c = self
                    .cumulative_weight
                    .partition_point(|&w| w <= u)
                    .min(self.clips.len() - 1);
                let clip = &self.clips[c];
                let last = match clip.loop_mode {
                    super::clip::LoopMode::Wrap => clip.frames.len(),
                    super::clip::LoopMode::Clamp => clip.frames.len() - 1,
                };
                let k = rng.gen_range(0..last);
                let next = clip.next_frame(k).expect("k has a successor");
                (self.states[c][k], self.states[c][next])
            })
            .collect()
    }
}
