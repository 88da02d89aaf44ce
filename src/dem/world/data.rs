//! The DEM world as data: the scene (parameters, grains, walls) with its solver scratch,
//! the saved contact histories and the last step's diagnostics. The step itself is
//! `impl World` in [`super`] (the phases), `crate::dem::integrate` and `crate::dem::passes`
//! (the chunk kernels), which all read this one definition.

use crate::dem::energy::Ledger;
use crate::dem::neighbors::NeighborList;
use crate::dem::params::DemParams;
use crate::dem::scratch::{Flags, GrainChunk, MAX_WALLS, Partial, RollLists};
use crate::dem::state::{ContactState, State};
use crate::dem::timers::PhaseTimers;
use crate::dem::walls::{NearWalls, Wall};
use crate::math::{Real, Vec2};
use serde::{Deserialize, Serialize};

/// Contact histories of a settled state (see [`World::saved_histories`]).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct SavedHistories {
    /// Grain pairs (i < j) and their history.
    pub pairs: Vec<(u32, u32, ContactState)>,
    /// Grain–wall contacts: (wall index, grain, history).
    pub walls: Vec<(u32, u32, ContactState)>,
}

/// Diagnostics of the last step.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StepInfo {
    /// Largest overlap / smaller diameter of the pair (or the grain at a wall).
    pub max_overlap_fraction: Real,
    /// Grains of that contact (j = u32::MAX for a wall).
    pub max_pair: (u32, u32),
    /// Force exerted by the grains on each wall [N/m] (index as in `walls`).
    pub wall_force: [Vec2; MAX_WALLS],
}

/// A DEM scene with its solver scratch.
#[derive(Debug, Clone)]
pub struct World {
    /// Parameters (read each step; change between `run` calls only).
    pub params: DemParams,
    /// Grain state.
    pub state: State,
    /// Walls (at most [`MAX_WALLS`]).
    pub walls: Vec<Wall>,
    /// Period along x [m], if the cell is periodic in x.
    pub periodic_x: Option<Real>,
    /// Simulated time [s].
    pub t: Real,
    /// Steps done.
    pub steps: u64,
    /// Cumulative dissipation (filled when `params.ledger`).
    pub ledger: Ledger,
    /// Total energy when the ledger was (re)started [J/m].
    pub e0: Real,
    /// Whether the watchdog's energy-rise check applies (off for driven scenes without ledger).
    pub energy_check: bool,
    /// Original index of each grain (the index it had when the world was made, or when it
    /// was appended): a sort ([`DemParams::sort_every`]) renames grains, this keeps who is
    /// who. The identity until the first sort.
    pub grain_ids: Vec<u32>,
    /// Phase timers.
    pub timers: PhaseTimers,
    /// Optional physics paths taken (leave-out counters).
    pub paths: crate::dem::timers::PathCounts,
    /// Last step's diagnostics.
    pub info: StepInfo,
    /// Below this many grains the world steps on its calling thread even in a
    /// multi-thread pool (default [`crate::dem::team::TEAM_MIN_GRAINS`]; results are the
    /// same either way — `bench dem-crossover` sets it to measure the crossover).
    pub team_min_grains: usize,
    /// Below this many grains the world is never sorted (default
    /// [`crate::dem::order::SORT_MIN_GRAINS`]; the tests set 0).
    pub sort_min_grains: usize,
    /// Whether `run` times steps alone against steps with the team and keeps the faster
    /// (default true; `bench dem-crossover` turns it off to time the team itself).
    pub team_probe: bool,
    /// Keep the phase timers (`timers`; default false: no clock calls in the steps).
    pub timing: bool,
    /// Seconds per step alone, and the step when timed (see [`TEAM_PROBE`]).
    pub(crate) solo_ref: Option<(f64, u64)>,
    /// A team that lost rests until this step.
    pub(crate) team_until: u64,
    /// Tries lost by the team in a row.
    pub(crate) team_lost: u32,
    pub(crate) nl: NeighborList,
    pub(crate) wall_hist: Vec<ContactState>,
    pub(crate) wall_cn: Vec<Real>,
    pub(crate) fx: Vec<Real>,
    pub(crate) fy: Vec<Real>,
    pub(crate) tq: Vec<Real>,
    /// Per-pair output [f_x, f_y, torque_i, torque_j] (one cache line per two pairs).
    pub(crate) pout: Vec<[Real; 4]>,
    /// Implicit rolling dashpots of the last force evaluation, in sweep order.
    pub(crate) roll: RollLists,
    /// Per listed pair, one bit (pair k: bit k % 64 of word k / 64): 0 when its last
    /// evaluation found it separated, so that its history and output are zero and stay
    /// so while it stays separated (the pair pass then does nothing for it). Set for
    /// every pair by a rebuild or a history restore ([`World::all_pairs_live`]). A live
    /// pair is evaluated whether or not it touches: the filter checks only the others.
    pub(crate) plive: Vec<u64>,
    /// The same per grain–wall slot (`wall * n + grain`), one byte each.
    pub(crate) wlive: Vec<u8>,
    /// Per wall, the grains near it (the grain–wall pass visits only those).
    pub(crate) near: NearWalls,
    pub(crate) partials: Vec<Partial>,
    /// Per-chunk results of the fused grain pass (gather + walls + second half kick).
    pub(crate) gpartials: Vec<GrainChunk>,
    /// The pair filter's output (pass 1 of the pair pass, [`crate::dem::passes::PairFilter`]): pair chunk `c`'s
    /// pairs with work, as offsets from the chunk's first pair, at `todo[c * PAIR_CHUNK..]`.
    pub(crate) todo: Vec<u16>,
    /// Results of the first stage of `World::staged_forces`: slot `1 + c` pair chunk `c`'s
    /// count of pairs with work and the filter's seconds (slot 0: the spin job's).
    pub(crate) filtered: Vec<(u32, f64)>,
    /// Per grain chunk, the pair chunks `first..last` holding a pair of its grains (made
    /// with the list): what its gather waits for in `World::staged_forces`.
    pub(crate) gdeps: Vec<(u32, u32)>,
    /// Number of `staged_forces` phases so far: the stamp of their done flags.
    pub(crate) phase_id: u64,
    /// Done stamps of the first stage's chunks (spin job, filters) and of the pair chunks.
    pub(crate) fdone: Flags,
    pub(crate) pdone: Flags,
    pub(crate) forces_valid: bool,
    /// Step at or after which the next neighbour rebuild sorts the grains first.
    pub(crate) next_sort: u64,
    /// Number of sorts so far.
    pub(crate) sorts: u64,
    /// Inactive walls whose contact histories have been released.
    pub(crate) wall_cleared: [bool; MAX_WALLS],
    /// Walls as they were at the end of the last `run` (edits in between invalidate forces).
    pub(crate) walls_seen: Vec<Wall>,
}
