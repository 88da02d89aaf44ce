//! MPM verification suite: one test binary (one link) for every tests/mpm_*.rs file.
#[path = "mpm_column.rs"]
mod mpm_column;
#[path = "mpm_determinism.rs"]
mod mpm_determinism;
#[path = "mpm_geostatic.rs"]
mod mpm_geostatic;
#[path = "mpm_material.rs"]
mod mpm_material;
#[path = "mpm_preflight.rs"]
mod mpm_preflight;
#[path = "mpm_shape.rs"]
mod mpm_shape;
#[path = "mpm_sliding.rs"]
mod mpm_sliding;
#[path = "mpm_transfer.rs"]
mod mpm_transfer;
#[path = "mpm_watchdog.rs"]
mod mpm_watchdog;
#[path = "mpm_wave.rs"]
mod mpm_wave;
