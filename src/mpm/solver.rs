//! The explicit GIMP step (chapter 3 §"Solution scheme"), as named phases:
//!
//! `reset_grid` → `p2g` → `grid_update` → `g2p` → [`remap` (MUSL only)] → `update_stress` →
//! `relocate`
//!
//! - `p2g`: mass, momentum, internal force −Σ V_p σ_p ∇φ_ip and gravity onto the 3 × 3 GIMP
//!   stencil of every point.
//! - `grid_update`: v* = v + Δt f/m (plus Cundall local damping in the geostatic stage), wall
//!   constraints (boundary.rs), Δv = v* − v.
//! - `g2p`: FLIP/PIC velocity update, displacement Δx = Δt Σ φ v*, and (USL) the velocity
//!   gradient L = Σ v* ⊗ ∇φ.
//! - `remap` (MUSL): momenta of the updated points mapped back to the grid, constrained, and
//!   L taken from those velocities.
//! - `update_stress`: J ← J det(I + ΔtL), V = V_0 J, Jaumann elastic trial, return mapping.
//! - `relocate`: x ← x + Δx, watchdog checks (finite, J > 0, inside the grid), stencil base
//!   of every point, runs of equal stencil band (per chunk of points) sorted by band for the
//!   next p2g.
//!
//! All shape functions within a step are evaluated at the positions of the start of the step.
//! g2p, update_stress and the move of relocate are per-point and run fused chunk by chunk in
//! one parallel pass (`Solver::step`); their timers are apportioned from per-chunk timings.
//!
//! Mohr–Coulomb and μ(I) points are updated a block of 64 at a time in lanes, several per
//! vector instruction (`stress_block`): the lanes call the per-point `material` functions,
//! whose return mapping has no branch on the point's data, so the results are those of one
//! `material::mohr_coulomb` call per point.
//!
//! Energy of the wall constraints: booked in `boundary` (friction and normal parts).
//! Nothing allocates inside a step: the grid, the sort buffers and the per-column work
//! buffer are allocated once (`Solver::new`) or grow once to the number of points.
//!
//! Determinism. The grid is cut into bands of 2 node columns; a point belongs to the band of
//! its first stencil column, so it writes only to that band and the next. Every node receives
//! its even band's points before its odd band's; inside a band the points are visited in
//! index order (stable counting sort of the runs of equal band key). The threads share the
//! bands as contiguous ranges in one parallel region (`Solver::p2g`: boundary bands deferred
//! to whichever neighbour finishes second), which keeps exactly that order. Every nodal sum
//! is therefore accumulated in the same order whatever the number of threads: results are
//! bit-identical for 1, 2, … threads, with no floating-point atomics and no per-thread grids.
//!
//! The transfers themselves (scatter, gather) are in `transfer.rs`: scalar, and AVX2 within a
//! point with the same arithmetic (runtime detection).

use super::boundary::{self, WallWork};
use super::error::MpmError;
use super::grid::Grid;
use super::material::{self, Elastic, McSurface};
use super::params::{MpmParams, Scheme, StepRule, Wall};
use super::particles::Point;
use super::shape::first_node;
use super::state::{Ledger, State};
use super::stress_block;
use super::transfer::{Geom, simd_available};
use crate::math::{Mat2, Real, Vec2};
use crate::shared::SharedMut;
use rayon::prelude::*;
use std::sync::atomic::{AtomicU32, Ordering};
use std::time::{Duration, Instant};

/// Node columns per band of the parallel scatter.
const BAND: usize = 2;

/// Accumulated wall-clock time of each phase.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PhaseTimes {
    /// reset_grid.
    pub reset_grid: Duration,
    /// p2g (and the MUSL re-map scatter).
    pub p2g: Duration,
    /// grid_update.
    pub grid_update: Duration,
    /// g2p.
    pub g2p: Duration,
    /// update_stress (including the MUSL gradient gather).
    pub update_stress: Duration,
    /// relocate (move, checks, sort).
    pub relocate: Duration,
}

impl PhaseTimes {
    /// Total.
    pub fn total(&self) -> Duration {
        self.reset_grid + self.p2g + self.grid_update + self.g2p + self.update_stress + self.relocate
    }
    /// (name, seconds) pairs, in phase order.
    pub fn as_list(&self) -> [(&'static str, f64); 6] {
        [
            ("reset_grid", self.reset_grid.as_secs_f64()),
            ("p2g", self.p2g.as_secs_f64()),
            ("grid_update", self.grid_update.as_secs_f64()),
            ("g2p", self.g2p.as_secs_f64()),
            ("update_stress", self.update_stress.as_secs_f64()),
            ("relocate", self.relocate.as_secs_f64()),
        ]
    }
}

/// Explicit GIMP solver: owns the grid and scratch only; the state comes in by `&mut`.
#[derive(Debug, Clone)]
pub struct Solver {
    /// Background grid.
    pub grid: Grid,
    /// Active walls (the geostatic stage adds a gate).
    pub walls: Vec<Wall>,
    /// Cundall local damping coefficient (0 during flow).
    pub damping: Real,
    /// FLIP fraction in use (from the parameters; the geostatic stage uses 0 = PIC, which
    /// also removes the velocity modes FLIP keeps invisible to the grid).
    pub flip: Real,
    /// Per-phase timers.
    pub times: PhaseTimes,
    /// Height below which a gate (a wall with the material on its minus side) is open [m]:
    /// −∞ (closed) unless the gate is being lifted (`column::CollapseOptions::gate_lift_speed`).
    pub gate_open_below: Real,
    params: MpmParams,
    elastic: Elastic,
    surface: McSurface,
    lp: Real,
    // Scratch (allocated once).
    band_start: Vec<u32>,
    key: Vec<u32>,
    cursor: Vec<u32>,
    /// Runs of equal band key: chunk c (points c·CHUNK…) has its runs at
    /// runs[c·CHUNK..c·CHUNK + run_count[c]]; `run_order` holds them sorted by band (stable),
    /// band b's at run_order[run_start[b]..run_start[b + 1]].
    runs: Vec<Run>,
    run_count: Vec<u32>,
    run_order: Vec<Run>,
    run_start: Vec<u32>,
    col_work: Vec<(WallWork, Real)>,
    /// P2G: first band of every thread's range, and arrival counts at the range boundaries.
    cuts: Vec<usize>,
    arrivals: Arrivals,
    sorted_len: usize,
    /// Whether the transfers use AVX2 (`transfer::simd_available`; same results).
    simd: bool,
    /// Whether m, p, f of every node are zero (the previous step cleared them on its last
    /// pass over the grid, so `reset_grid` has nothing to do).
    grid_clean: bool,
}

impl Solver {
    /// A solver on `grid` with `walls`. Fails on invalid parameters.
    pub fn new(params: &MpmParams, grid: Grid, walls: Vec<Wall>) -> Result<Self, MpmError> {
        let issues = params.validate();
        if !issues.is_empty() {
            return Err(MpmError::InvalidParams(issues));
        }
        let m = &params.material;
        let nb = grid.nx.div_ceil(BAND);
        let nx = grid.nx;
        Ok(Self {
            grid,
            walls,
            damping: 0.0,
            flip: params.flip,
            times: PhaseTimes::default(),
            gate_open_below: Real::NEG_INFINITY,
            params: params.clone(),
            elastic: Elastic::new(m.young_pa, m.poisson),
            surface: material::surface_of(m),
            lp: params.shape_half_width(),
            band_start: vec![0; nb + 1],
            key: Vec::new(),
            cursor: Vec::with_capacity(nb),
            runs: Vec::new(),
            run_count: Vec::new(),
            run_order: Vec::new(),
            run_start: vec![0; nb + 1],
            col_work: vec![(WallWork::default(), 0.0); nx],
            cuts: Vec::with_capacity(nb + 1),
            arrivals: Arrivals((0..=nb).map(|_| AtomicU32::new(0)).collect()),
            sorted_len: usize::MAX,
            simd: simd_available(),
            grid_clean: false,
        })
    }

    /// Parameters in use.
    pub fn params(&self) -> &MpmParams {
        &self.params
    }
    /// Elastic constants.
    pub fn elastic(&self) -> &Elastic {
        &self.elastic
    }
    /// GIMP half-width l_p [m].
    pub fn half_width(&self) -> Real {
        self.lp
    }
    /// Name of the update scheme.
    pub fn scheme(&self) -> &'static str {
        self.params.scheme.name()
    }

    /// Time step for the next step: fixed, or CFL Δt = C h/(c_p + max|v|).
    pub fn dt(&self, state: &State) -> Real {
        match self.params.step {
            StepRule::Fixed { dt } => dt,
            StepRule::Cfl { courant, dt_max } => self.cfl_dt(state, courant).min(dt_max),
        }
    }

    /// Δt = C h/(c_p + max|v_p|) [s]. c_p does not depend on the point's dilation because
    /// the elastic moduli scale with the current density (see `update_stress`).
    pub fn cfl_dt(&self, state: &State, courant: Real) -> Real {
        let vmax = state.points.par_iter().map(|p| p.v.norm()).reduce(|| 0.0, Real::max);
        courant * self.grid.h / (self.params.material.p_wave_speed() + vmax)
    }

    /// Diagnostic: scatter the points onto a fresh grid (phase p2g only) and return the total
    /// nodal mass [kg/m], which must equal the total point mass (partition of unity).
    pub fn grid_mass(&mut self, state: &mut State) -> Result<Real, MpmError> {
        if self.sorted_len != state.points.len() {
            self.sort(&mut state.points, state.step, state.t)?;
        }
        self.reset_grid();
        self.p2g::<true>(&state.points);
        self.grid_clean = false;
        Ok(self.grid.nodes.iter().map(|n| n.m).sum())
    }

    /// Forget the cached sort/stencil bases: call after moving points (or swapping the state)
    /// outside [`Solver::step`]. A state with a different number of points is detected
    /// automatically.
    pub fn invalidate(&mut self) {
        self.sorted_len = usize::MAX;
    }

    /// Advance by one step of size `dt`.
    ///
    /// The point-side phases (g2p → update_stress → the move of relocate) run fused, chunk
    /// by chunk, in one parallel pass (one fork-join instead of three, and each chunk of
    /// points stays in cache); each chunk times its phases and the pass's wall time is
    /// apportioned to them in proportion. Under MUSL the velocity update (g2p) runs first as
    /// its own pass, then the re-map, then the fused gradient + stress + move pass.
    pub fn step(&mut self, state: &mut State, dt: Real) -> Result<(), MpmError> {
        if self.sorted_len != state.points.len() {
            self.sort(&mut state.points, state.step, state.t)?;
        }
        let t0 = Instant::now();
        if !self.grid_clean {
            self.reset_grid();
        }
        self.grid_clean = false;
        let t1 = Instant::now();
        self.p2g::<true>(&state.points);
        let t2 = Instant::now();
        let musl = self.params.scheme == Scheme::Musl;
        self.grid_update(dt, &mut state.ledger, !musl);
        let t3 = Instant::now();
        self.times.reset_grid += t1 - t0;
        self.times.p2g += t2 - t1;
        self.times.grid_update += t3 - t2;
        state.t += dt;
        state.step += 1;
        state.last_dt = dt;
        self.grid_clean = true; // grid_update (USL) or remap (MUSL) leaves m, p, f zero
        let gather = if musl {
            let t4 = Instant::now();
            self.g2p(&mut state.points, dt);
            let t5 = Instant::now();
            self.remap(&state.points);
            let t6 = Instant::now();
            self.times.g2p += t5 - t4;
            self.times.p2g += t6 - t5;
            Gather::GradientOnly
        } else {
            Gather::Full
        };
        self.point_pass(state, dt, gather)
    }

    fn reset_grid(&mut self) {
        self.grid
            .nodes
            .par_chunks_mut(4096)
            .for_each(|c| c.fill(Default::default()));
    }

    /// Scatter onto the grid in the deterministic band order. `full`: mass, momentum and
    /// forces (`FULL`); otherwise momentum only (MUSL re-map, mass already there).
    ///
    /// One parallel region: the bands that hold points are cut into two contiguous ranges per
    /// thread, balanced by point count, every range but the first starting at an odd band.
    /// A range scatters its last (even) band first, then its other even bands, then its odd
    /// bands; its first (odd) band `s` is deferred and scattered by whichever of the two
    /// neighbouring ranges arrives second at boundary `s` — the left one after its band
    /// s − 1, the right one after all its other bands (an atomic arrival count; nobody waits).
    /// So every node still receives its even band's points before its odd band's, each band
    /// in index order: the same sums, in the same order, as scattering all even bands and
    /// then all odd bands, whatever the number of threads.
    fn p2g<const FULL: bool>(&mut self, points: &[Point]) {
        let ny = self.grid.ny;
        let geo = self.geom();
        let g = self.params.gravity;
        let (runs, run_start) = (&self.run_order, &self.run_start);
        let start = &self.band_start;
        let nb = start.len() - 1;
        let Some(b_lo) = (0..nb).find(|&b| start[b + 1] > start[b]) else {
            return;
        };
        let b_hi = (0..nb).rev().find(|&b| start[b + 1] > start[b]).unwrap_or(b_lo);
        // Range boundaries: cuts[0] = b_lo < cuts[1] < … (odd, ≥ 2 apart) < cuts[R] = b_hi + 1.
        let cuts = &mut self.cuts;
        cuts.clear();
        cuts.push(b_lo);
        // Two ranges per thread: a thread that starts late (shared cores) leaves whole ranges
        // to the others instead of holding up the region.
        let ranges = 2 * rayon::current_num_threads().max(1);
        let (p0, p1) = (start[b_lo] as usize, start[b_hi + 1] as usize);
        for r in 1..ranges {
            let target = p0 + (p1 - p0) * r / ranges;
            let prev = *cuts.last().unwrap_or(&b_lo);
            // the odd band nearest the target point, after the previous cut (odd cuts ≥ 2 apart)
            let min = if r == 1 { (prev + 1) | 1 } else { prev + 2 };
            let c = start.partition_point(|&s| (s as usize) <= target).saturating_sub(1) | 1;
            let dist = |m: usize| (start[m.min(nb)] as usize).abs_diff(target);
            let m = if c >= min + 2 && dist(c - 2) < dist(c) {
                c - 2
            } else {
                c.max(min)
            };
            if m > b_hi {
                break;
            }
            cuts.push(m);
        }
        cuts.push(b_hi + 1);
        let cuts = &self.cuts;
        let arrivals = &self.arrivals.0;
        for a in arrivals.iter().take(cuts.len()) {
            a.store(0, Ordering::Relaxed);
        }
        let len = self.grid.nodes.len();
        // the grid's nodes, shared by the P2G ranges (below: why their writes never overlap
        // in time)
        let nodes = SharedMut::of(&mut self.grid.nodes);
        let band = |b: usize| {
            let first = (b * BAND * ny).min(len);
            let last = ((b + 2) * BAND * ny).min(len);
            // SAFETY: band b writes node columns [b·BAND, (b + 2)·BAND) only. Two bands run at
            // the same time only if they are ≥ 2 apart (disjoint columns): inside a range the
            // bands run one after another, and a boundary band s runs only after both of its
            // neighbours s − 1 and s + 1 are done (arrival count, Acquire/Release) while the
            // range that runs it goes on with bands ≤ s − 2 or ≥ s + 2.
            let chunk = unsafe { nodes.slice_mut(first, last - first) };
            let band_runs = &runs[run_start[b] as usize..run_start[b + 1] as usize];
            let idx = band_runs
                .iter()
                .flat_map(|r| r.start as usize..(r.start + r.len) as usize);
            geo.scatter::<FULL>(chunk, b * BAND, points, idx, g);
        };
        let arrive = |s: usize| arrivals[s].fetch_add(1, Ordering::AcqRel) == 1;
        let nr = cuts.len() - 1;
        (0..nr).into_par_iter().with_min_len(1).for_each(|r| {
            let (lo, hi) = (cuts[r], cuts[r + 1]);
            let (left, right) = (r > 0, r + 1 < nr);
            if right {
                band(hi - 1);
                if arrive(r + 1) {
                    band(hi);
                }
            }
            for b in (lo..hi).filter(|b| b % 2 == 0 && !(right && *b == hi - 1)) {
                band(b);
            }
            for b in (lo..hi).filter(|b| b % 2 == 1 && !(left && *b == lo)) {
                band(b);
            }
            if left && arrive(r) {
                band(lo);
            }
        });
    }

    fn geom(&self) -> Geom {
        let (ox, oy, h, ny) = (self.grid.origin.x, self.grid.origin.y, self.grid.h, self.grid.ny);
        Geom {
            ox,
            oy,
            h,
            lp: self.lp,
            ny,
            simd: self.simd,
        }
    }

    /// Nodal velocity update with damping and wall constraints; books wall work. Clears p and
    /// f of every node, and m too if `clear_mass` (USL: nothing else reads them this step;
    /// MUSL's re-map still needs m and clears it itself), so the next step skips reset_grid.
    fn grid_update(&mut self, dt: Real, ledger: &mut Ledger, clear_mass: bool) {
        let ny = self.grid.ny;
        let (origin, h) = (self.grid.origin, self.grid.h);
        let walls = &self.walls;
        let open = self.gate_open_below;
        let alpha = self.damping;
        let mmin = self.mass_floor();
        self.grid
            .nodes
            .par_chunks_mut(ny)
            .zip(self.col_work.par_iter_mut())
            .enumerate()
            .for_each(|(i, (col, work))| {
                let mut ww = WallWork::default();
                let mut wd = 0.0;
                for (j, n) in col.iter_mut().enumerate() {
                    let (m, p, f0) = (n.m, n.p, n.f);
                    n.p = Vec2::zeros();
                    n.f = Vec2::zeros();
                    if clear_mass {
                        n.m = 0.0;
                    }
                    if m <= mmin {
                        n.v = Vec2::zeros();
                        n.dv = Vec2::zeros();
                        continue;
                    }
                    let v0 = p / m;
                    let mut f = f0;
                    if alpha > 0.0 {
                        // Cundall local damping: f_k ← f_k − α |f_k| sign(v_k).
                        for k in 0..2 {
                            let d = alpha * f[k].abs() * sgn(v0[k]);
                            f[k] -= d;
                            wd += d * v0[k] * dt;
                        }
                    }
                    let mut v = v0 + f * (dt / m);
                    if !walls.is_empty() {
                        let x = Vec2::new(origin.x + i as Real * h, origin.y + j as Real * h);
                        ww.add(boundary::constrain(walls, x, m, v0, &mut v, 1e-6 * h, open));
                    }
                    n.dv = v - v0;
                    n.v = v;
                }
                *work = (ww, wd);
            });
        for (w, d) in &self.col_work {
            ledger.wall_friction += w.friction;
            ledger.wall_normal += w.normal;
            ledger.damping += d;
        }
    }

    fn mass_floor(&self) -> Real {
        // Nodes lighter than 1e-9 of a point's mass carry no meaningful velocity.
        1e-9 * self.params.material.density * self.params.spacing().powi(2)
    }

    /// MUSL phase g2p on its own: velocity update and step displacement.
    fn g2p(&mut self, points: &mut [Point], dt: Real) {
        let (geo, flip) = (self.geom(), self.flip);
        let nodes = &self.grid.nodes;
        points
            .par_chunks_mut(1024)
            .for_each(|chunk| geo.gather::<true, false>(chunk, nodes, flip, dt));
    }

    /// MUSL: map the updated point momenta back to the grid and constrain them.
    /// Leaves m, p, f zero for the next step (p was cleared by grid_update).
    fn remap(&mut self, points: &[Point]) {
        self.p2g::<false>(points);
        let ny = self.grid.ny;
        let (origin, h) = (self.grid.origin, self.grid.h);
        let walls = &self.walls;
        let open = self.gate_open_below;
        let mmin = self.mass_floor();
        self.grid.nodes.par_chunks_mut(ny).enumerate().for_each(|(i, col)| {
            for (j, n) in col.iter_mut().enumerate() {
                let (m, p) = (n.m, n.p);
                n.m = 0.0;
                n.p = Vec2::zeros();
                if m <= mmin {
                    n.v = Vec2::zeros();
                    continue;
                }
                let mut v = p / m;
                if !walls.is_empty() {
                    let x = Vec2::new(origin.x + i as Real * h, origin.y + j as Real * h);
                    boundary::project(walls, x, &mut v, 1e-6 * h, open);
                }
                n.v = v;
            }
        });
    }

    fn kernel(&self, dt: Real) -> Kernel {
        let m = &self.params.material;
        Kernel {
            ox: self.grid.origin.x,
            oy: self.grid.origin.y,
            h: self.grid.h,
            lp: self.lp,
            geo: self.geom(),
            nb: self.band_start.len() - 1,
            flip: self.flip,
            dt,
            el: self.elastic,
            frictional: stress_block::Consts::new(
                dt, self.elastic, self.surface, &m.model, m.grain_diameter, m.grain_density, m.i_max,
            ),
        }
    }

    /// Fused point pass: g2p (or the MUSL gradient gather) → update_stress → move + checks +
    /// band key; then the counting sort (phase relocate).
    fn point_pass(&mut self, state: &mut State, dt: Real, gather: Gather) -> Result<(), MpmError> {
        let k = self.kernel(dt);
        let grid = &self.grid;
        let nodes = &grid.nodes;
        let n = state.points.len();
        self.key.resize(n, 0);
        self.runs.resize(n, Run::default());
        self.run_count.resize(n.div_ceil(CHUNK), 0);
        let clock = Instant::now();
        let (cpu, bad) = state
            .points
            .par_chunks_mut(CHUNK)
            .zip(self.key.par_chunks_mut(CHUNK))
            .zip(self.runs.par_chunks_mut(CHUNK))
            .zip(self.run_count.par_iter_mut())
            .enumerate()
            .map(|(c, (((pc, kc), rc), count))| {
                let t0 = Instant::now();
                match gather {
                    Gather::Full => k.geo.gather::<true, true>(pc, nodes, k.flip, k.dt),
                    Gather::GradientOnly => k.geo.gather::<false, true>(pc, nodes, k.flip, k.dt),
                }
                let t1 = Instant::now();
                k.update_stress(pc);
                let t2 = Instant::now();
                let bad = k.relocate(pc, kc, grid);
                *count = key_runs(kc, c * CHUNK, rc);
                let t3 = Instant::now();
                ([t1 - t0, t2 - t1, t3 - t2], bad)
            })
            .reduce(
                || ([Duration::ZERO; 3], false),
                |a, b| ([a.0[0] + b.0[0], a.0[1] + b.0[1], a.0[2] + b.0[2]], a.1 | b.1),
            );
        let wall = clock.elapsed();
        let tot = (cpu[0] + cpu[1] + cpu[2]).as_secs_f64().max(1e-12);
        let share = |d: Duration| wall.mul_f64(d.as_secs_f64() / tot);
        match gather {
            Gather::Full => self.times.g2p += share(cpu[0]),
            Gather::GradientOnly => self.times.update_stress += share(cpu[0]),
        }
        self.times.update_stress += share(cpu[1]);
        let t = Instant::now();
        if bad {
            super::watchdog::check_points(&state.points, &self.grid, self.lp, state.step, state.t)?;
        }
        self.sort_runs();
        self.times.relocate += share(cpu[2]) + t.elapsed();
        Ok(())
    }

    /// Check the points, set their stencil bases and band keys, then the counting sort.
    fn sort(&mut self, points: &mut [Point], step: u64, t: Real) -> Result<(), MpmError> {
        super::watchdog::check_points(points, &self.grid, self.lp, step, t)?;
        let (ox, oy, h, lp) = (self.grid.origin.x, self.grid.origin.y, self.grid.h, self.lp);
        let nb = self.band_start.len() - 1;
        let n = points.len();
        self.key.resize(n, 0);
        self.runs.resize(n, Run::default());
        self.run_count.resize(n.div_ceil(CHUNK), 0);
        self.key
            .par_chunks_mut(CHUNK)
            .zip(points.par_chunks_mut(CHUNK))
            .zip(self.runs.par_chunks_mut(CHUNK))
            .zip(self.run_count.par_iter_mut())
            .enumerate()
            .for_each(|(c, (((kc, pc), rc), count))| {
                for (k, p) in kc.iter_mut().zip(pc) {
                    *k = set_base(p, ox, oy, h, lp, nb);
                }
                *count = key_runs(kc, c * CHUNK, rc);
            });
        self.sort_runs();
        Ok(())
    }

    /// Stable counting sort of the runs of equal band key (a few per chunk of points: the
    /// points are stored roughly band by band) into `run_order`; points per band into
    /// `band_start`. Band b's points in index order are then its runs' points, run by run.
    fn sort_runs(&mut self) {
        let nb = self.band_start.len() - 1;
        let (start, rstart) = (&mut self.band_start, &mut self.run_start);
        start.fill(0);
        rstart.fill(0);
        let chunk_runs = |c: usize, count: u32| &self.runs[c * CHUNK..c * CHUNK + count as usize];
        for (c, &count) in self.run_count.iter().enumerate() {
            for r in chunk_runs(c, count) {
                start[r.key as usize + 1] += r.len;
                rstart[r.key as usize + 1] += 1;
            }
        }
        for b in 0..nb {
            start[b + 1] += start[b];
            rstart[b + 1] += rstart[b];
        }
        let fill = &mut self.cursor;
        fill.clear();
        fill.extend_from_slice(&rstart[..nb]);
        self.run_order.resize(rstart[nb] as usize, Run::default());
        for (c, &count) in self.run_count.iter().enumerate() {
            for r in chunk_runs(c, count) {
                self.run_order[fill[r.key as usize] as usize] = *r;
                fill[r.key as usize] += 1;
            }
        }
        self.sorted_len = self.key.len();
    }
}

/// P2G arrival counts (scratch; a clone starts from zero).
#[derive(Debug)]
struct Arrivals(Vec<AtomicU32>);
impl Clone for Arrivals {
    fn clone(&self) -> Self {
        Self(self.0.iter().map(|_| AtomicU32::new(0)).collect())
    }
}

/// A run of consecutive points with the same band key.
#[derive(Debug, Clone, Copy, Default)]
struct Run {
    start: u32,
    len: u32,
    key: u32,
}

/// Write the runs of equal key of `keys` (points `first`, `first` + 1, …) to `out`; returns
/// their number.
fn key_runs(keys: &[u32], first: usize, out: &mut [Run]) -> u32 {
    let mut n = 0usize;
    let mut i = 0usize;
    while i < keys.len() {
        let k = keys[i];
        let mut e = i + 1;
        while e < keys.len() && keys[e] == k {
            e += 1;
        }
        out[n] = Run {
            start: (first + i) as u32,
            len: (e - i) as u32,
            key: k,
        };
        n += 1;
        i = e;
    }
    n as u32
}

/// Points per chunk of the fused point pass (≈ 50 kB of points: stays in L1/L2). Smaller
/// than needed for cache reasons so that two threads on shared cores balance well (160
/// chunks for the 40,000-point bench; 1024 gave ~15 % less at 2 threads, no gain at 1).
const CHUNK: usize = 256;

/// What the fused point pass gathers from the grid.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Gather {
    /// USL: velocity update, displacement and velocity gradient.
    Full,
    /// MUSL: velocity gradient only (velocities were updated before the re-map).
    GradientOnly,
}

/// Everything the per-point phases need, copied once per step.
#[derive(Debug, Clone, Copy)]
struct Kernel {
    ox: Real,
    oy: Real,
    h: Real,
    lp: Real,
    geo: Geom,
    nb: usize,
    flip: Real,
    dt: Real,
    el: Elastic,
    /// Constants of the block update of a frictional model (None: elastic model).
    frictional: Option<stress_block::Consts>,
}

impl Kernel {
    /// Kinematics (J, volume) and the constitutive update of a chunk of points.
    ///
    /// Density-scaled moduli: a point uses E V_0/V (ν unchanged), so its P-wave speed
    /// √(M/ρ) is that of the undeformed material whatever its dilation. In the bulk
    /// J = V/V_0 stays within a few per mil of 1 (ψ = 0, stiff compared with ρgH) and nothing
    /// changes; at a thinning front, points dilate several-fold (J ≈ 8 seen at the a = 0.4
    /// toe) and with constant moduli their wave speed √J c_p would break the CFL limit,
    /// ejecting points. UNSPEC in the chapter; documented here as our choice.
    ///
    /// Mohr–Coulomb and μ(I) points are updated a block at a time, several per vector
    /// instruction (`stress_block`, which calls the per-point `material` functions lane by
    /// lane).
    #[inline(always)]
    fn update_stress(&self, points: &mut [Point]) {
        if let Some(c) = &self.frictional {
            stress_block::update(points, c);
            return;
        }
        let (el0, dt) = (self.el, self.dt);
        for p in points {
            let j = p.j * (Mat2::identity() + p.grad_v * dt).determinant();
            p.j = j;
            p.vol = p.vol0 * j;
            let el = el0.scaled_by_jacobian(j);
            p.stress = material::elastic_trial(&p.stress, &p.grad_v, dt, &el);
        }
    }

    /// Move a chunk of points, flag anything the watchdog would reject, set stencil bases and
    /// band keys. Returns whether a point is bad.
    #[inline(always)]
    fn relocate(&self, points: &mut [Point], keys: &mut [u32], grid: &Grid) -> bool {
        // Same arithmetic as `Grid::contains` and `set_base`, with the scaled coordinates
        // computed once (two divisions per point instead of six).
        let l = self.lp / self.h;
        let (ux_max, uy_max) = ((grid.nx - 2) as Real, (grid.ny - 2) as Real);
        let mut bad = false;
        for (p, k) in points.iter_mut().zip(keys.iter_mut()) {
            p.x += p.dx;
            let sum = p.v.x + p.v.y + p.stress.xx + p.stress.yy + p.stress.xy + p.stress.zz;
            let ux = (p.x.x - self.ox) / self.h;
            let uy = (p.x.y - self.oy) / self.h;
            let inside = ux - l >= 0.0 && uy - l >= 0.0 && ux + l < ux_max && uy + l < uy_max;
            let ok = p.x.x.is_finite() && p.x.y.is_finite() && sum.is_finite() && p.vol > 0.0 && inside;
            if !ok {
                bad = true;
                *k = 0;
                continue;
            }
            let i0 = first_node(ux, l).max(0) as usize;
            let j0 = first_node(uy, l).max(0) as usize;
            p.base = [i0 as u32, j0 as u32];
            *k = ((i0 / BAND).min(self.nb - 1)) as u32;
        }
        bad
    }
}

/// Store the stencil base of a point (valid position assumed) and return its band.
#[inline(always)]
fn set_base(p: &mut Point, ox: Real, oy: Real, h: Real, lp: Real, nb: usize) -> u32 {
    let i0 = first_node((p.x.x - ox) / h, lp / h).max(0) as usize;
    let j0 = first_node((p.x.y - oy) / h, lp / h).max(0) as usize;
    p.base = [i0 as u32, j0 as u32];
    ((i0 / BAND).min(nb - 1)) as u32
}

#[inline(always)]
fn sgn(x: Real) -> Real {
    if x > 0.0 {
        1.0
    } else if x < 0.0 {
        -1.0
    } else {
        0.0
    }
}
