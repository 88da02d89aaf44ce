//! CD verification suite: one test binary (one link) for every tests/cd_*.rs file.
#[path = "cd_determinism_threads.rs"]
mod cd_determinism_threads;
#[path = "cd_energy_balance.rs"]
mod cd_energy_balance;
#[path = "cd_shear.rs"]
mod cd_shear;
#[path = "cd_stability_preflight.rs"]
mod cd_stability_preflight;
#[path = "cd_verification.rs"]
mod cd_verification;
