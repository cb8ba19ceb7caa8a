//! Thread tuning for candle on the CPU: element-wise ops on one thread, matrix products
//! (gemm, over rayon) and the simulator (rayon) on all.
//!
//! candle 0.11 runs element-wise ops on its own barrier pool whose threads spin while they
//! wait for each other. On a 2-core machine shared with the simulator (or anything else),
//! a descheduled worker keeps the others spinning: a PPO minibatch step of 768 samples took
//! 0.19 s with the pool on 2 threads against 0.076 s on 1 (`benches/learner.rs`, under load).
//! The big element-wise passes that matter (ELU forward and backward) are parallel through
//! rayon in `nn::elu` anyway.

/// Sets `CANDLE_NUM_THREADS=1` unless the user chose a value. Call before any tensor op
/// (candle reads it once, when its pool starts).
pub fn single_threaded_elementwise() {
    if std::env::var_os("CANDLE_NUM_THREADS").is_none() {
        std::env::set_var("CANDLE_NUM_THREADS", "1");
    }
}
