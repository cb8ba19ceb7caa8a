//! Adversarial motion priors: the discriminator with its explicit gradient penalty, the
//! buffer of policy transitions, and the source of prior transitions.

pub mod discriminator;
pub mod prior_source;
pub mod transition_buffer;
