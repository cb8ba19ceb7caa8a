//! The trainer's error type.

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
    #[error("motion priors: {0}")]
    Priors(String),
    /// A loss became NaN or infinite; training stopped before applying it.
    #[error("non-finite {what} at iteration {iteration} (surrogate {surrogate}, value {value}, estimator {estimator}, discriminator {discriminator}); the weights were not updated with it")]
    NonFiniteLoss {
        /// Which loss.
        what: &'static str,
        /// Iteration.
        iteration: usize,
        /// Surrogate loss value.
        surrogate: f32,
        /// Value loss value.
        value: f32,
        /// Estimator loss value.
        estimator: f32,
        /// Discriminator loss value.
        discriminator: f32,
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
