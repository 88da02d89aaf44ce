//! The excited pile (§4.4), as every method reports it to the `pile-run` kind.
//!
//! Contract: [`PileEngine::excite`] runs the method's solver on the settled DEM deposit
//! ([`PileScene`], the same grains for every method), once per input energy in the order
//! given, publishes what only that method has (its own scalars, checks and notes), and
//! returns one [`Excited`] per energy: the method-agnostic summary (D01, D10–D16) and time
//! series from which the kind computes, once for every method, the tables, the snapshot
//! metrics and the chart. The snapshot rules that depend on how a method represents matter
//! (when a body touches the wall, which bodies are one mass) are the engine's answers to
//! [`PileEngine::wall_contact`] and [`PileEngine::cavity_link`].

use crate::analysis::pile::{PileRun, Summary};
use crate::dem::State;
use crate::pipeline::context::{InputRef, Output, StageCtx};

use super::preflight::Preflight;

/// The settled deposit every method starts from.
pub struct PileScene {
    /// The grains, with the method's grain density.
    pub state: State,
    /// Surface profile (x, top) of the deposit [m].
    pub profile: Vec<(f64, f64)>,
    /// L_0 [m].
    pub l0: f64,
    /// Packing fraction of the deposit.
    pub packing: f64,
}

/// One energy's run.
pub struct Excited {
    /// The per-run summary (D01, D10–D16).
    pub summary: Summary,
    /// The run's samples and frames.
    pub run: PileRun,
    /// Wall time [s].
    pub wall_s: f64,
}

/// A method that runs the excited pile.
pub trait PileEngine: Preflight {
    /// Grain density the deposit is read with [kg/m³].
    fn density(&self) -> f64;
    /// Gravity [m/s²].
    fn gravity(&self) -> f64;
    /// Refuse a deposit the method cannot continue (DEM: settled with other contacts).
    fn accept(&self, _input: &InputRef) -> anyhow::Result<()> {
        Ok(())
    }
    /// Run every energy of the stage, in its order; publish the method's own outputs.
    fn excite(&self, ctx: &StageCtx, scene: &PileScene, out: &mut Output) -> anyhow::Result<Vec<Excited>>;
    /// A body is in contact with the left wall within this gap [d̄], and what that gap is
    /// in the method's terms (for the claim's statement).
    fn wall_contact(&self) -> (f64, &'static str);
    /// Extra gap [m] across which bodies of half-size `half` are still one mass (the
    /// cavity's outline). 0: they touch.
    fn cavity_link(&self, _half: f64) -> f64 {
        0.0
    }
    /// Work of `time` simulated [√(d/g)] on a deposit of `grains` grains: (size, steps) as
    /// the cost model's named factors.
    fn work(&self, grains: f64, time: f64) -> Vec<(&'static str, f64)>;
}
