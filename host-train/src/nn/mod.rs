//! Network building blocks: ELU MLPs, empirical normalization, the asymmetric actor-critic.

pub mod actor_critic;
pub mod bias;
pub mod elu;
pub mod mlp;
pub mod normalizer;
pub(crate) mod simd;
