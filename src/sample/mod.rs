//! Sample generation: particle size distributions.
pub mod psd;
