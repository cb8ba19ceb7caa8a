//! Observation sets for calibration and accuracy: synthetic (deterministic, plausible
//! ranges; the simulator's closed loop adds the rest, [`crate::calibration_set`]), and a
//! file format for recordings (`sim-compare --record`).
//!
//! File format: little-endian f32 rows of 273 values, the simulator's observation buffers
//! side by side: actor observation (63) then flattened history (210, oldest first).

use hexapod_core::obs::{
    actor_obs, proprio_obs, ProprioHistory, ACTOR_OBS_DIM, HISTORY_DIM, HISTORY_LEN,
};
use hexapod_core::robot::{Q0_RAD, Q_MAX_RAD, Q_MIN_RAD};
use hexapod_core::NUM_JOINTS;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use std::path::Path;

/// Values per record in a file.
pub const RECORD_LEN: usize = ACTOR_OBS_DIM + HISTORY_DIM;

/// One policy input: what the simulator's `Observations` hold for one robot.
#[derive(Clone, Debug, PartialEq)]
pub struct ObsRecord {
    /// Actor observation (command scaled, previous action, o^p).
    pub actor_obs: [f32; ACTOR_OBS_DIM],
    /// Flattened history, oldest first; its newest frame is the o^p of `actor_obs`.
    pub history: [f32; HISTORY_DIM],
}

/// `n` synthetic inputs: a random walking-like state per record (command up to 1 m/s and
/// 1 rad/s, tilt up to ~0.3 rad, joints within limits around q0 with 0.25 rad spread,
/// joint velocities 3 rad/s rms, body rates 0.5 rad/s rms, previous action 1 rms), with
/// a history that drifts from frame to frame.
pub fn synthetic(n: usize, seed: u64) -> Vec<ObsRecord> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let unit = Normal::new(0.0f32, 1.0).expect("unit normal");
    (0..n)
        .map(|_| {
            let command = [
                rng.gen_range(-1.0..1.0),
                rng.gen_range(-0.5..0.5),
                rng.gen_range(-1.0..1.0),
            ];
            let mut q: [f32; NUM_JOINTS] =
                core::array::from_fn(|j| Q0_RAD[j] + 0.25 * unit.sample(&mut rng));
            let mut qdot: [f32; NUM_JOINTS] = core::array::from_fn(|_| 3.0 * unit.sample(&mut rng));
            let mut ang_vel: [f32; 3] = core::array::from_fn(|_| 0.5 * unit.sample(&mut rng));
            let (roll, pitch) = (0.15 * unit.sample(&mut rng), 0.15 * unit.sample(&mut rng));
            let mut history: Option<ProprioHistory> = None;
            let mut last = [0.0; 42];
            for _ in 0..HISTORY_LEN {
                for j in 0..NUM_JOINTS {
                    qdot[j] += 0.5 * unit.sample(&mut rng);
                    q[j] = (q[j] + 0.02 * qdot[j]).clamp(Q_MIN_RAD[j], Q_MAX_RAD[j]);
                }
                ang_vel
                    .iter_mut()
                    .for_each(|w| *w += 0.1 * unit.sample(&mut rng));
                let gravity = [
                    pitch.sin(),
                    -roll.sin() * pitch.cos(),
                    -roll.cos() * pitch.cos(),
                ];
                last = proprio_obs(ang_vel, gravity, &q, &qdot);
                match &mut history {
                    Some(h) => h.push(&last),
                    None => history = Some(ProprioHistory::filled_with(&last)),
                }
            }
            let prev_action: [f32; NUM_JOINTS] = core::array::from_fn(|_| unit.sample(&mut rng));
            ObsRecord {
                actor_obs: actor_obs(command, &prev_action, &last),
                history: history.map(|h| h.flatten()).unwrap_or([0.0; HISTORY_DIM]),
            }
        })
        .collect()
}

/// Reads a recording (see the module doc).
pub fn load(path: &Path) -> anyhow::Result<Vec<ObsRecord>> {
    let bytes = std::fs::read(path)?;
    anyhow::ensure!(
        bytes.len() % (4 * RECORD_LEN) == 0,
        "{}: size {} is not a multiple of {} f32",
        path.display(),
        bytes.len(),
        RECORD_LEN
    );
    let values: Vec<f32> = bytes
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect();
    Ok(values
        .chunks_exact(RECORD_LEN)
        .map(|row| {
            let mut r = ObsRecord {
                actor_obs: [0.0; ACTOR_OBS_DIM],
                history: [0.0; HISTORY_DIM],
            };
            r.actor_obs.copy_from_slice(&row[..ACTOR_OBS_DIM]);
            r.history.copy_from_slice(&row[ACTOR_OBS_DIM..]);
            r
        })
        .collect())
}

/// Writes a recording.
pub fn save(path: &Path, records: &[ObsRecord]) -> std::io::Result<()> {
    let bytes: Vec<u8> = records
        .iter()
        .flat_map(|r| r.actor_obs.iter().chain(r.history.iter()))
        .flat_map(|v| v.to_le_bytes())
        .collect();
    std::fs::write(path, bytes)
}
