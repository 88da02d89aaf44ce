//! Team scheduling of [`World::run`]: the steps of one call run on a thread team while the
//! team is clearly faster than the world alone (timed probes, blocks, rests), consecutive
//! steps joined ([`World::steps_with`]). Results are the same with or without the team.

use std::time::Instant;

use super::data::World;
use crate::dem::error::DemError;

/// [`World::run`] steps a world with a thread team while the team is clearly faster than
/// the world alone: it times [`TEAM_PROBE`] steps alone (the reference, taken again after
/// [`TEAM_REFRESH`] steps), then the team in blocks of [`TEAM_BLOCK`] steps; a team
/// slower than 0.9 × the reference rests for [`TEAM_REST`] steps (doubling with every
/// further loss, up to 4 × TEAM_REST) and is tried again. Results are the same either way.
pub const TEAM_PROBE: u64 = 128;
/// See [`TEAM_PROBE`].
pub const TEAM_BLOCK: u64 = 1024;
/// See [`TEAM_PROBE`].
pub const TEAM_REFRESH: u64 = 32768;
/// See [`TEAM_PROBE`].
pub const TEAM_REST: u64 = 256;

impl World {
    pub(super) fn run_with<const R: bool, const IMP: bool, const L: bool>(&mut self, n: u64) -> Result<(), DemError> {
        // The hot loops index the grain arrays with the list's indices unchecked
        // (`crate::shared`):
        // a state edited without `resize_scratch` (or resized without a rebuild) gets its
        // scratch and list brought up to date first. The library's own callers never
        // reach these branches (they resize and rebuild themselves), so no result moves.
        let ng = self.state.len();
        if self.fx.len() != ng || self.wall_cn.len() != ng {
            self.resize_scratch();
        }
        if self.nl.x0.len() != ng {
            self.rebuild();
        }
        if self.walls != self.walls_seen {
            // a wall was edited between runs (gate removed, wall shifted): the stored forces
            // are stale for the first half kick
            self.forces_valid = false;
        }
        if !self.forces_valid && self.nl.needs_rebuild(&self.state) {
            // grains moved by hand since the last build (`invalidate_forces`): the pair
            // and near-wall lists assume no grain is more than skin/2 from its build
            // position
            self.rebuild();
        }
        if !self.forces_valid {
            self.compute_forces::<R, IMP, L, false>(0.0);
            self.forces_valid = true;
        }
        let team = ng >= self.team_min_grains && rayon::current_num_threads() > 1;
        let mut res = Ok(());
        let mut left = n;
        while left > 0 && res.is_ok() {
            if !(team && self.team_probe) {
                res = crate::dem::team::with_team(team, || self.steps_with::<R, IMP, L>(left));
                break;
            }
            let fresh = self.solo_ref.is_some_and(|(_, at)| self.steps < at + TEAM_REFRESH);
            if !fresh && left >= 2 * TEAM_PROBE {
                // the reference: TEAM_PROBE steps alone, then try the team
                let t0 = Instant::now();
                res = self.steps_with::<R, IMP, L>(TEAM_PROBE);
                self.solo_ref = Some((t0.elapsed().as_secs_f64() / TEAM_PROBE as f64, self.steps));
                left -= TEAM_PROBE;
            } else if self.solo_ref.is_some() && self.steps >= self.team_until {
                // with the team, in timed blocks, while it stays clearly faster than alone
                let mut ran = 0;
                res = crate::dem::team::with_team(true, || self.team_blocks::<R, IMP, L>(left, &mut ran));
                left -= ran;
            } else {
                // alone until the team's next try (timed: the reference for it; steps alone
                // are measured whenever they run)
                let k = if self.solo_ref.is_some() {
                    left.min(self.team_until - self.steps)
                } else {
                    left
                };
                let t0 = Instant::now();
                res = self.steps_with::<R, IMP, L>(k);
                if k >= TEAM_PROBE {
                    self.solo_ref = Some((t0.elapsed().as_secs_f64() / k as f64, self.steps));
                }
                left -= k;
            }
        }
        self.walls_seen.clone_from(&self.walls);
        res
    }

    /// Up to `left` steps with the team (`World::run_with`), in blocks timed against the
    /// reference alone (`solo_ref`): the first after TEAM_PROBE / 4 steps that wake the
    /// helpers and fill their caches, then TEAM_BLOCK steps each. Stops when a block is
    /// not clearly faster than the reference (the other core got busy, or the team does
    /// not pay on this scene: the team rests, and is tried again after TEAM_REST steps,
    /// doubling with every further loss up to 4 × TEAM_REST) or when the reference is
    /// older than TEAM_REFRESH steps. `ran`: steps done.
    fn team_blocks<const R: bool, const IMP: bool, const L: bool>(
        &mut self,
        left: u64,
        ran: &mut u64,
    ) -> Result<(), DemError> {
        let warm = (TEAM_PROBE / 4).min(left);
        self.steps_with::<R, IMP, L>(warm)?;
        *ran = warm;
        let mut block = TEAM_PROBE - warm;
        while *ran < left {
            let k = block.min(left - *ran);
            let t0 = Instant::now();
            self.steps_with::<R, IMP, L>(k)?;
            *ran += k;
            let (solo, at) = self.solo_ref.unwrap_or((f64::INFINITY, self.steps));
            // a short block is noisy: the team must be clearly faster
            if k >= TEAM_PROBE / 2 && !(t0.elapsed().as_secs_f64() / (k as f64) < 0.9 * solo) {
                self.team_lost = (self.team_lost + 1).min(3);
                self.team_until = self.steps + (TEAM_REST << (self.team_lost - 1));
                crate::dem::team::dismiss();
                return Ok(());
            }
            self.team_lost = 0;
            if self.steps >= at + TEAM_REFRESH {
                break;
            }
            block = TEAM_BLOCK;
        }
        Ok(())
    }

    /// `n` steps. On a thread team, two steps of this call are *joined* (except where the
    /// watchdog looks at the state between them): the grain pass of the first does the
    /// second's translational kick and drift on the grains it has just kicked (in cache,
    /// on the thread that computed their forces), and the spin work between them — this
    /// step's second dashpot sweep, the next one's spin kick and first sweep, serial —
    /// runs at the next step's start on one thread while the others filter its pairs
    /// (`World::staged_forces`). Every grain's arithmetic and every sum is that of the
    /// separate passes (`integrate_second_half`, `integrate_first_half`, `compute_contacts`),
    /// so results are bit-identical to them; on one thread the separate passes are as
    /// fast.
    fn steps_with<const R: bool, const IMP: bool, const L: bool>(&mut self, n: u64) -> Result<(), DemError> {
        let boundary = n >= 2 && crate::dem::team::active() && self.join_ok::<IMP>();
        let wd = self.params.watchdog.every;
        let mut first = None;
        for k in 0..n {
            let join = boundary && k + 1 < n && !(wd > 0 && (self.steps + 1).is_multiple_of(wd));
            first = self.step_with::<R, IMP, L>(first, join)?;
        }
        Ok(())
    }
}
