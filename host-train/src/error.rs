//! The trainer's error type: it gathers the error types of the modules below it (each
//! module keeps its own; none of them imports this one).

/// Why training, playing or evaluating failed.
#[derive(Debug, thiserror::Error)]
pub enum TrainError {
    /// A tensor operation failed.
    #[error("tensor error: {0}")]
    Candle(#[from] candle_core::Error),
    /// The configuration is unusable.
    #[error(transparent)]
    Config(#[from] crate::config::ConfigError),
    /// A checkpoint is missing, malformed or does not fit the config.
    #[error(transparent)]
    Checkpoint(#[from] crate::checkpoint::CheckpointError),
    /// The environment could not be created.
    #[error(transparent)]
    Env(#[from] crate::env::EnvError),
    /// The motion priors are missing or malformed.
    #[error(transparent)]
    Priors(#[from] crate::amp::prior_source::PriorSourceError),
    /// The learner could not be built or updated (a non-finite loss among others).
    #[error(transparent)]
    Learner(#[from] crate::algo::ppo::PpoError),
    /// The environment panicked while stepping the robots (a bug in the simulator or in
    /// one of its libraries). The learner is still that of the last finished iteration.
    #[error("the environment panicked in iteration {iteration}'s rollout: {message}")]
    EnvPanic {
        /// The iteration whose rollout was cut short.
        iteration: usize,
        /// The panic's message.
        message: String,
    },
    /// File output failed.
    #[error("i/o error on {path}: {source}")]
    Io {
        /// File.
        path: String,
        /// Cause.
        source: std::io::Error,
    },
}
