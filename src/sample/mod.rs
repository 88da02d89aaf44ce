//! Sample generation: particle size distributions, and the one random generator.
pub mod psd;
pub mod rng;
