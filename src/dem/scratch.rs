//! The step's scratch, shared by the world's phases and the chunk kernels: the chunk sizes
//! (fixed, so every reduction's order is independent of the thread count), the per-chunk
//! partial results and done flags, the compacted rolling-dashpot lists, and the helpers that
//! share chunks out on the thread team and collect their results in chunk order.

use crate::dem::contact_law::RollDashpot;
use crate::dem::energy::Ledger;
use crate::math::{Real, Vec2};
use crate::shared::SharedMut;
use std::sync::atomic::AtomicU64;

/// Pairs per parallel work unit (fixed: the reduction order must not depend on threads).
pub const PAIR_CHUNK: usize = 512;
// a pair chunk's live bits are whole words (`World::plive`)
const _: () = assert!(PAIR_CHUNK.is_multiple_of(64) && PAIR_CHUNK <= 1 << 16);
/// Grains per parallel work unit.
pub const GRAIN_CHUNK: usize = 256;
/// Most walls a scene can have.
pub const MAX_WALLS: usize = 8;

/// Per-chunk partial results, summed in chunk order.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Partial {
    pub ledger: Ledger,
    pub max_overlap: Real,
    pub max_i: u32,
    pub max_j: u32,
    pub wall_force: [Vec2; MAX_WALLS],
    pub moved: bool,
    /// Rolling dashpots this chunk listed (pair pass), per wall (wall pass).
    pub n_roll: [u32; MAX_WALLS],
    /// CPU seconds of the chunk (pair pass in `World::staged_forces`, with timers on).
    pub secs: f64,
}

/// Done flags of a phase's chunks: a chunk stores the phase's stamp into its flag when its
/// output is written (release), and a chunk that reads it waits for the stamp (acquire).
/// Stamps grow phase by phase, so the flags are never reset.
#[derive(Debug, Default)]
pub(crate) struct Flags(pub(crate) Vec<AtomicU64>);
impl Clone for Flags {
    /// Fresh flags (a copied world's phases start over: stamps of 0 are never waited for).
    fn clone(&self) -> Self {
        Flags::default()
    }
}
impl Flags {
    pub(crate) fn ensure(&mut self, n: usize) {
        if self.0.len() < n {
            self.0.resize_with(n, || AtomicU64::new(0));
        }
    }
}

/// One implicit rolling dashpot for the integrator's sweep: grains `i`, `j` (`j =
/// u32::MAX`: a wall) and the dashpot.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct RollItem {
    pub i: u32,
    pub j: u32,
    pub d: RollDashpot,
}

/// The dashpots of the last force evaluation, compacted in sweep order: chunk `c` of the
/// pair pass wrote its dashpots to `items[c * PAIR_CHUNK..][..count[c]]` in pair order;
/// the grain chunk `c` of wall `wi` to `witems[wi * n + c * GRAIN_CHUNK..][..wcount[wi * nc + c]]`.
/// The sweep reads them in that order — pairs by (i, j), then walls by (wall, grain), as
/// before — without scanning the separated pairs and empty wall slots.
#[derive(Debug, Clone, Default)]
pub(crate) struct RollLists {
    pub items: Vec<RollItem>,
    pub count: Vec<u32>,
    pub witems: Vec<RollItem>,
    pub wcount: Vec<u32>,
}

impl Partial {
    pub(crate) fn merge(&mut self, o: &Partial) {
        self.ledger += o.ledger;
        if o.max_overlap > self.max_overlap {
            self.max_overlap = o.max_overlap;
            self.max_i = o.max_i;
            self.max_j = o.max_j;
        }
        for w in 0..MAX_WALLS {
            self.wall_force[w] += o.wall_force[w];
        }
        self.moved |= o.moved;
    }
}

/// What one chunk of the fused grain pass returns: the wall pass's partial, the kick's
/// partial (merged apart, in chunk order, exactly as the separate passes did) and the CPU
/// seconds of its three parts (gather, walls, kick), by which the pass's wall time is
/// apportioned to the phase timers.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct GrainChunk {
    pub walls: Partial,
    pub kick: Partial,
    pub secs: [f64; 3],
}

/// Below this many grains a world steps on its calling thread (the team's threshold,
/// [`crate::dem::team::TEAM_MIN_GRAINS`]; the name the stage drivers refer to).
pub const PAR_MIN_ITEMS: usize = crate::dem::team::TEAM_MIN_GRAINS;

/// `f(lo, hi)` for each chunk of `chunk` items of `0..n`, results in chunk order in `out`:
/// shared out on the world's thread team inside a [`World::run`] that has one (see
/// [`crate::dem::team`]), else in order on this thread. The chunking — and so every
/// sum's order — is the same either way, so results do not depend on the thread count.
pub(crate) fn chunked<T: Send>(n: usize, chunk: usize, out: &mut Vec<T>, f: impl Fn(usize, usize) -> T + Sync + Send) {
    let nc = n.div_ceil(chunk);
    let dst = slots(out, nc);
    crate::dem::team::for_chunks(nc, &|c| {
        let v = f(c * chunk, ((c + 1) * chunk).min(n));
        // SAFETY: each chunk index is run exactly once, into reserved capacity
        unsafe { dst.write(c, v) };
    });
    // SAFETY: every slot 0..nc was written above (for_chunks returns when all are done)
    unsafe { out.set_len(nc) };
}

/// `out` emptied with room for `n` per-chunk results, written through the returned pointer
/// by the chunks (slot `c` by chunk `c` only); once all are written, `out.set_len(n)`.
pub(crate) fn slots<T>(out: &mut Vec<T>, n: usize) -> SharedMut<T> {
    out.clear();
    out.reserve(n);
    SharedMut::spare(out)
}
