//! DEM verification suite: one test binary (one link) for every tests/dem_*.rs file.
#[path = "dem_column.rs"]
mod dem_column;
#[path = "dem_compression.rs"]
mod dem_compression;
#[path = "dem_determinism_threads.rs"]
mod dem_determinism_threads;
#[path = "dem_energy_balance.rs"]
mod dem_energy_balance;
#[path = "dem_prep.rs"]
mod dem_prep;
#[path = "dem_rolling_dashpot.rs"]
mod dem_rolling_dashpot;
#[path = "dem_shear.rs"]
mod dem_shear;
#[path = "dem_stability_preflight.rs"]
mod dem_stability_preflight;
#[path = "dem_verification.rs"]
mod dem_verification;
