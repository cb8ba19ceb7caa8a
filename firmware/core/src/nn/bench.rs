//! A fixed, deterministic policy input for cross-target comparisons (the QEMU benchmark
//! and its host check run the policy on exactly these values).
//!
//! Values come from a 32-bit LCG mapped to multiples of 2^-12 (exact in f32), in ranges
//! typical of each observation entry, so no float function can differ between targets.

use crate::obs::{
    ACTOR_COMMAND, ACTOR_OBS_DIM, ACTOR_PREV_ACTION, ACTOR_PROPRIO, HISTORY_DIM, HISTORY_LEN,
    PROPRIO_DIM, PROPRIO_GRAVITY,
};

/// Uniform value in `[-amplitude, amplitude)`, a multiple of `amplitude * 2^-12`.
fn next(state: &mut u32, amplitude: f32) -> f32 {
    *state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
    let q = (*state >> 19) as i32 - 4096; // 13 bits: -4096..4095
    q as f32 * (amplitude / 4096.0)
}

fn proprio_amplitude(i: usize) -> f32 {
    if PROPRIO_GRAVITY.contains(&i) {
        0.3
    } else {
        0.8
    }
}

/// The benchmark input: (actor observation, flattened history), newest frame last and
/// equal to the actor observation's o^p.
pub fn bench_input(seed: u32) -> ([f32; ACTOR_OBS_DIM], [f32; HISTORY_DIM]) {
    let mut state = seed;
    let mut history = [0.0; HISTORY_DIM];
    for (i, h) in history.iter_mut().enumerate() {
        let k = i % PROPRIO_DIM;
        *h = next(&mut state, proprio_amplitude(k));
        if k == PROPRIO_GRAVITY.start + 2 {
            *h -= 1.0; // gravity points down
        }
    }
    let mut obs = [0.0; ACTOR_OBS_DIM];
    for i in ACTOR_COMMAND {
        obs[i] = next(&mut state, 1.0);
    }
    for i in ACTOR_PREV_ACTION {
        obs[i] = next(&mut state, 1.5);
    }
    let newest = (HISTORY_LEN - 1) * PROPRIO_DIM;
    obs[ACTOR_PROPRIO].copy_from_slice(&history[newest..]);
    (obs, history)
}
