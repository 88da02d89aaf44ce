//! Soft-contact DEM for 2D disks (chapter 3 "Discrete Element Method", chapter 4 §4.2.1):
//! linear spring-dashpot contacts with Coulomb friction and Iwashita & Oda rolling
//! resistance, frictional walls, x-periodic cells, velocity Verlet, deterministic rayon
//! parallelism, energy ledger, pre-flight stability audit and watchdog; plus sample
//! preparation and the calibration / collapse / benchmark drivers.
//!
//! Step phases: see [`world`]. Solvers never touch files: drivers return typed results.
//!
//! Files: `params` (table 4.2 + UNSPEC choices), `state` (SoA grains, ids, contact keys),
//! `contact_law` (the one law), `neighbors` (linked cells + Verlet list + history merge),
//! `walls`, `energy` (ledger), `error`, `timers`, `preflight` (stability audit), `world`
//! (the step as phases), `integrate` (velocity Verlet + implicit rolling dashpot),
//! `watchdog`; drivers: `prep` (deposition, hex, settle), `column` (collapse +
//! work-precision), `shear` (C1, the calibration grid's short protocol), `critical_state` (C1 by the critical-state protocol, fig4-03), `compress` (C2), `pile` (P5), `bench`.

pub mod bench;
pub mod column;
pub mod compress;
pub mod contact_law;
pub mod critical_state;
pub mod energy;
pub mod error;
pub mod integrate;
pub mod neighbors;
pub mod order;
pub mod params;
pub(crate) mod passes;
pub mod pile;
pub mod pour;
pub mod preflight;
pub mod prep;
pub mod scratch;
pub mod shear;
pub mod state;
pub mod team;
pub mod time_scale;
pub mod timers;
pub mod walls;
pub mod watchdog;
pub mod world;

pub use contact_law::{Law, LawCoeffs, PairIn, PairOut};
pub use energy::{Balance, Energies, Ledger};
pub use error::DemError;
pub use params::{ContactParams, DampingModel, DemParams, RollingDamping, RollingModel, RollingParams, WatchdogParams};
pub use preflight::{Preflight, SizeClasses, preflight, time_scales};
pub use state::{ContactKey, ContactState, GrainId, Motion, State};
pub use time_scale::TimeScale;
pub use timers::PhaseTimers;
pub use walls::Wall;
pub use world::{SavedHistories, StepInfo, World};
