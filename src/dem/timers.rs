//! Per-phase wall-clock counters (rapier `stages_counters.rs`), kept when a world asks for
//! them (`World::timing`: `bench dem` does; pipeline runs do not, so their steps make no
//! clock calls — the vDSO `clock_gettime` of ~10 reads per step was ≈ 2 % of a
//! few-hundred-grain step, e.g. the calibration's shear test).

use serde::{Deserialize, Serialize};
use std::time::Instant;

/// Seconds spent in each phase of [`World::step`](crate::dem::World::step).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct PhaseTimers {
    /// `refresh_neighbors` (displacement check + rebuilds).
    pub neighbors: f64,
    /// `compute_contacts`, pair pass (forces per listed pair).
    pub contacts: f64,
    /// Per-grain gather of pair forces in fixed order (+ gravity), the first part of `grain_pass`.
    pub gather: f64,
    /// Grain–wall contacts (the wall part of `grain_pass`).
    pub walls: f64,
    /// `integrate` (both half kicks, the second one inside `grain_pass`, and the drift).
    pub integrate: f64,
    /// Implicit rolling dashpot sweeps (both half kicks).
    #[serde(default)]
    pub rolling: f64,
    /// `ledger` (reduction of dissipation partials).
    pub ledger: f64,
    /// `watchdog`.
    pub watchdog: f64,
}

impl PhaseTimers {
    /// Sum of all phases [s].
    pub fn total(&self) -> f64 {
        self.neighbors
            + self.contacts
            + self.gather
            + self.walls
            + self.integrate
            + self.rolling
            + self.ledger
            + self.watchdog
    }
}

/// A phase timer a phase's wall time is apportioned to (`World::apportion`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Phase {
    Contacts,
    Gather,
    Walls,
    Integrate,
    Rolling,
}

/// A phase clock reading: the time when the world keeps phase timers, else nothing.
#[derive(Debug, Clone, Copy)]
pub struct Clock(Option<Instant>);

impl Clock {
    /// Read the clock if `on`.
    #[inline(always)]
    pub fn now(on: bool) -> Self {
        Clock(if on { Some(Instant::now()) } else { None })
    }
    /// Seconds from `self` to `later` (0 when either was not read).
    #[inline(always)]
    pub fn to(self, later: Clock) -> f64 {
        match (self.0, later.0) {
            (Some(a), Some(b)) => (b - a).as_secs_f64(),
            _ => 0.0,
        }
    }
    /// Seconds since `self` (0 when it was not read).
    #[inline(always)]
    pub fn elapsed(self) -> f64 {
        self.0.map_or(0.0, |t| t.elapsed().as_secs_f64())
    }
}

/// Run `f`, add its duration to `*slot`.
#[inline(always)]
pub fn timed<T>(slot: &mut f64, f: impl FnOnce() -> T) -> T {
    let t0 = Instant::now();
    let r = f();
    *slot += t0.elapsed().as_secs_f64();
    r
}

/// How often each optional physics path ran (leave-out proof, issue 12): a scene that does
/// not enable a term must leave its counter at 0.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct PathCounts {
    /// Force passes that evaluated rolling resistance (contact law with `ROLLING`).
    pub rolling_forces: u64,
    /// Implicit rolling-dashpot sweeps (`integrate::rolling_dashpot`).
    pub rolling_dashpot: u64,
    /// Force passes that booked the energy ledger.
    pub ledger: u64,
}
