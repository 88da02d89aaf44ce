//! Sample preparation (chapter 3 "Particle assembling methods", docs/definitions.md SC-COL):
//! ballistic deposition into a box with a constant drop height between layers, settling
//! to E_k/E_p < 1e-6, trimming to L_0 × H_0; monodisperse hexagonal-lattice columns;
//! packing-fraction measurement; loose/dense control through the deposition friction.
//!
//! Density control (L79 / D83, UNSPEC in the chapter): the chapter prepares dense samples
//! "with an initial friction angle of zero"; we deposit with `prep_friction` (μ during
//! deposition: 0 → densest, 0.53 or more with rolling resistance → loosest), settle, then
//! restore the run parameters and settle again. The achieved φ is reported, never assumed.

use crate::dem::error::DemError;
use crate::dem::params::DemParams;
use crate::dem::state::State;
use crate::dem::walls::Wall;
use crate::dem::world::{SavedHistories, World};
use crate::math::{PI, Real};
use serde::{Deserialize, Serialize};

use crate::sample::rng::SplitMix64;

/// Local inverse-CDF sampler of diameters uniform by area (volume) fraction on
/// [d_min, d_max] (number pdf ∝ d⁻², docs/definitions.md SC-PSD): d = 1/(1/d_min − U(1/d_min −
/// 1/d_max)). For tests and benches only; the pipeline passes the PSD stage's radii.
pub fn diameters_uniform_by_area(n: usize, d_min: Real, d_max: Real, seed: u64) -> Vec<Real> {
    let mut rng = SplitMix64(seed);
    (0..n)
        .map(|_| 1.0 / (1.0 / d_min - rng.next_f64() * (1.0 / d_min - 1.0 / d_max)))
        .collect()
}

/// Outcome of a settling run.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SettleReport {
    /// Simulated time spent [s].
    pub time: Real,
    /// Final E_k/E_p (translational + rotational kinetic over potential).
    pub ke_over_ep: Real,
    /// Whether the target ratio was reached before the time cap.
    pub converged: bool,
}

/// Run at least `min_time`, then until (E_k + E_rot)/E_p < `ratio` (checked every 1e-3 s
/// of simulated time) or `max_time` has elapsed.
pub fn settle(world: &mut World, ratio: Real, min_time: Real, max_time: Real) -> Result<SettleReport, DemError> {
    let t0 = world.t;
    let check = 1e-3;
    world.run_until(t0 + min_time)?;
    loop {
        let e = world.energies();
        let r = (e.ek() + e.erot) / e.ep.max(1e-300);
        if r < ratio || world.t - t0 >= max_time {
            return Ok(SettleReport {
                time: world.t - t0,
                ke_over_ep: r,
                converged: r < ratio,
            });
        }
        world.run_until(world.t + check)?;
    }
}

/// Kinetic damping (dynamic relaxation): step, and whenever the total kinetic energy
/// passes a maximum set every velocity to zero; stop when (E_k + E_rot)/E_p < `ratio` or
/// after `max_steps`. Used after switching from the soft preparation stiffness to the run
/// stiffness, so that the stored overlap energy is drained instead of popping the packing.
pub fn quench(world: &mut World, ratio: Real, max_steps: u64) -> Result<SettleReport, DemError> {
    let t0 = world.t;
    let ke = |w: &World| -> Real {
        let s = &w.state;
        (0..s.len())
            .map(|i| s.m[i] * (s.vx[i] * s.vx[i] + s.vy[i] * s.vy[i]) + s.inertia[i] * s.w[i] * s.w[i])
            .sum::<Real>()
            * 0.5
    };
    let mut prev = ke(world);
    let mut r = Real::INFINITY;
    for k in 0..max_steps {
        world.step()?;
        let e = ke(world);
        if e < prev {
            world.state.stop();
            prev = 0.0;
        } else {
            prev = e;
        }
        if k % 100 == 99 {
            let ep = world.energies().ep.max(1e-300);
            r = e / ep;
            if r < ratio && k > 1000 {
                break;
            }
        }
    }
    Ok(SettleReport {
        time: world.t - t0,
        ke_over_ep: r,
        converged: r < ratio,
    })
}

/// Ballistic deposition settings (SC-COL proposal: layers of ~5 d̄ rained from 5 d̄ above
/// the current surface).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DepositionParams {
    /// Box width [m] (left wall at 0, right wall at `width`).
    pub width: Real,
    /// Drop height of each layer's lowest row above the current surface, in mean diameters.
    pub drop_height: Real,
    /// Lattice rows per layer.
    pub rows_per_layer: usize,
    /// Lattice spacing as a multiple of d_max (grains placed without contact).
    pub spacing: Real,
    /// Friction coefficient during deposition (grain–grain and wall); `None` = run value.
    pub prep_friction: Option<Real>,
    /// Stiffness softening for the raining phase (1 = run stiffness); Δt scales with √.
    /// 0.01 is ample: the deposit is re-settled with the run stiffness afterwards.
    pub softening: Real,
    /// Settling criterion (E_k + E_rot)/E_p.
    pub settle_ratio: Real,
    /// Cap on each settling phase [s].
    pub max_settle_time: Real,
    /// Seed of the random placement.
    pub seed: u64,
}

impl Default for DepositionParams {
    fn default() -> Self {
        Self {
            width: 0.0624,
            drop_height: 5.0,
            rows_per_layer: 5,
            spacing: 1.05,
            prep_friction: None,
            softening: 0.01,
            settle_ratio: 1e-6,
            max_settle_time: 0.3,
            seed: 1,
        }
    }
}

/// A prepared, settled granular column.
#[derive(Debug, Clone)]
pub struct Column {
    /// Settled grains (x ∈ [0, L_0], y ≥ 0).
    pub state: State,
    /// Width L_0 [m] (gate position).
    pub l0: Real,
    /// Height H_0 [m] (top of the highest grain).
    pub h0: Real,
    /// Packing fraction Σπr²/(L_0 H_0) [-] (global; the rough top lowers it).
    pub packing_fraction: Real,
    /// Packing fraction of the core window [2d̄, L_0−2d̄] × [2d̄, H_0−2d̄] (centres inside),
    /// free of wall and surface layers (D09 "local" value; the L79/D83 targets).
    pub packing_fraction_core: Real,
    /// Final settling report.
    pub settle: SettleReport,
    /// Contact histories of the settled state (walls indexed as in [`box_walls`]), so a
    /// restart keeps its tangential and rolling springs.
    pub histories: SavedHistories,
}

impl Column {
    /// A world of this column inside `walls` (indexed as [`box_walls`] for the first
    /// three), with the settled contact histories restored.
    pub fn world(&self, params: &DemParams, walls: Vec<Wall>) -> Result<World, DemError> {
        let mut w = World::new(params.clone(), self.state.clone(), walls, None)?;
        w.restore_histories(&self.histories);
        w.reset_ledger();
        Ok(w)
    }
}

/// Packing fraction of the grains whose centres lie in the rectangle, Σπr²/area.
pub fn packing_fraction(s: &State, x0: Real, x1: Real, y0: Real, y1: Real) -> Real {
    packing_fraction_window(s, x0, x1, y0, y1)
}

fn packing_fraction_window(s: &State, x0: Real, x1: Real, y0: Real, y1: Real) -> Real {
    if !(x1 > x0 && y1 > y0) {
        return 0.0;
    }
    let mut a = 0.0;
    for i in 0..s.len() {
        if s.x[i] >= x0 && s.x[i] < x1 && s.y[i] >= y0 && s.y[i] < y1 {
            a += PI * s.r[i] * s.r[i];
        }
    }
    a / ((x1 - x0) * (y1 - y0))
}

/// Box walls of width `w`: floor, left, right ("gate").
pub fn box_walls(w: Real) -> Vec<Wall> {
    vec![Wall::floor(0.0), Wall::left(0.0), Wall::right("gate", w)]
}

/// Rain `radii` into a box of `dep.width` in layers from a constant height above the
/// surface, then settle with the run parameters. Grains keep the order of `radii`.
pub fn ballistic_deposition(
    radii: &[Real],
    run: &DemParams,
    dep: &DepositionParams,
) -> Result<(State, SettleReport), DemError> {
    if radii.is_empty() || !(dep.width > 0.0) {
        return Err(DemError::Setup("deposition needs radii and a positive width".into()));
    }
    let r_max = radii.iter().cloned().fold(0.0, Real::max);
    let d_mean = 2.0 * radii.iter().sum::<Real>() / radii.len() as Real;
    let pitch = 2.0 * r_max * dep.spacing;
    let per_row = ((dep.width - 2.0 * r_max) / pitch).floor() as usize + 1;
    if per_row == 0 || 2.0 * r_max > dep.width {
        return Err(DemError::Setup(format!(
            "box width {} m narrower than a grain",
            dep.width
        )));
    }
    let mut prep = run.softened(dep.softening);
    if let Some(mu) = dep.prep_friction {
        prep.grain.friction = mu;
        prep.wall.friction = mu;
    }
    prep.ledger = false;
    let mut world = World::new(prep, State::with_capacity(radii.len()), box_walls(dep.width), None)?;
    let mut rng = SplitMix64(dep.seed);
    let g = world.params.gravity.max(1e-9);
    let mut next = 0usize;
    while next < radii.len() {
        let surface = (0..world.state.len())
            .map(|i| world.state.y[i] + world.state.r[i])
            .fold(0.0, Real::max);
        let y_base = surface + dep.drop_height * d_mean + r_max;
        'rows: for row in 0..dep.rows_per_layer {
            let offset = if row % 2 == 1 { 0.5 * pitch } else { 0.0 };
            let slots = if offset > 0.0 {
                ((dep.width - 2.0 * r_max - offset) / pitch).floor() as usize + 1
            } else {
                per_row
            };
            for k in 0..slots {
                if next >= radii.len() {
                    break 'rows;
                }
                // random lateral jitter within the free space of the slot
                let jitter = (rng.next_f64() - 0.5) * (pitch - 2.0 * r_max);
                let x = (r_max + offset + k as Real * pitch + jitter).clamp(radii[next], dep.width - radii[next]);
                let y = y_base + row as Real * pitch;
                world.state.insert(x, y, radii[next], world.params.density);
                next += 1;
            }
        }
        world.resize_scratch();
        world.rebuild();
        world.e0 = world.energies().total();
        let fall = dep.drop_height * d_mean + dep.rows_per_layer as Real * pitch;
        let t_fall = (2.0 * fall / g).sqrt();
        world.run_until(world.t + 1.3 * t_fall)?;
    }
    settle(&mut world, dep.settle_ratio * 10.0, 0.01, dep.max_settle_time)?;
    // back to the run parameters, then settle for real
    let mut state = world.state_by_id();
    state.stop();
    let mut w2 = World::new(run.clone(), state, box_walls(dep.width), None)?;
    quench(&mut w2, dep.settle_ratio, 20_000)?;
    let rep = settle(&mut w2, dep.settle_ratio, 0.0, dep.max_settle_time)?;
    Ok((w2.state_by_id(), rep))
}

/// Remove grains reaching above `h0` (top edge) or right of `l0`, keep the rest.
pub fn trim(s: &State, l0: Real, h0: Real) -> State {
    s.retain(|i| s.y[i] + s.r[i] <= h0 && s.x[i] + s.r[i] <= l0)
}

/// Deposit `radii` in a box of width L_0, trim to H_0, settle again with the gate in place.
pub fn deposited_column(
    radii: &[Real],
    l0: Real,
    h0: Real,
    run: &DemParams,
    dep: &DepositionParams,
) -> Result<Column, DemError> {
    let dep = DepositionParams {
        width: l0,
        ..dep.clone()
    };
    let (s, _) = ballistic_deposition(radii, run, &dep)?;
    let top = (0..s.len()).map(|i| s.y[i] + s.r[i]).fold(0.0, Real::max);
    if top < h0 {
        return Err(DemError::Setup(format!(
            "deposit reaches only {top:.4} m < H_0 = {h0:.4} m: pass more grains"
        )));
    }
    let s = trim(&s, l0, h0);
    finish_column(s, l0, run, dep.settle_ratio, dep.max_settle_time)
}

fn finish_column(s: State, l0: Real, run: &DemParams, ratio: Real, max_time: Real) -> Result<Column, DemError> {
    let w = World::new(run.clone(), s, box_walls(l0), None)?;
    settled_column(w, l0, ratio, max_time)
}

impl Column {
    /// Member `k` of an ensemble of starts: member 0 is this column, member k > 0 has every
    /// grain moved by a uniform random offset of at most `amplitude` m in x and y (seeded
    /// by `seed` and k). A run-out is chaotic: ensembles give its mean and spread.
    pub fn perturbed(&self, k: usize, amplitude: Real, seed: u64) -> Column {
        let mut c = self.clone();
        if k > 0 {
            let mut rng = SplitMix64(seed.wrapping_mul(0x9E37_79B9).wrapping_add(k as u64));
            for i in 0..c.state.len() {
                c.state.x[i] += amplitude * (2.0 * rng.next_f64() - 1.0);
                c.state.y[i] += amplitude * (2.0 * rng.next_f64() - 1.0);
            }
        }
        c
    }

    /// This column re-settled behind its gate with other solver parameters (another
    /// contact stiffness or step): the overlap energy the change releases is drained by
    /// kinetic damping, then the column settles to (E_k + E_rot)/E_p < `ratio`. Contact
    /// histories start afresh (springs stored at another stiffness mean other forces).
    pub fn resettled(&self, run: &DemParams, ratio: Real, max_time: Real) -> Result<Column, DemError> {
        let mut s = self.state.clone();
        s.stop();
        let mut w = World::new(run.clone(), s, box_walls(self.l0), None)?;
        quench(&mut w, ratio, 40_000)?;
        settled_column(w, self.l0, ratio, max_time)
    }
}

fn settled_column(mut w: World, l0: Real, ratio: Real, max_time: Real) -> Result<Column, DemError> {
    let settle = settle(&mut w, ratio, 0.005, max_time)?;
    let histories = w.saved_histories();
    let s = w.state;
    let h0 = (0..s.len()).map(|i| s.y[i] + s.r[i]).fold(0.0, Real::max);
    let packing_fraction = s.solid_area() / (l0 * h0);
    let d = 2.0 * s.radius_stats().1;
    let packing_fraction_core = packing_fraction_window(&s, 2.0 * d, l0 - 2.0 * d, 2.0 * d, h0 - 2.0 * d);
    Ok(Column {
        state: s,
        l0,
        h0,
        packing_fraction,
        packing_fraction_core,
        settle,
        histories,
    })
}

/// Monodisperse hexagonal lattice of diameter `d` filling L_0 × H_0 (touching grains,
/// rows alternately offset by d/2), settled under gravity (docs/definitions.md SC-PSD,
/// HEX: d = 1.15 mm).
pub fn hex_column(l0: Real, h0: Real, d: Real, run: &DemParams, max_settle_time: Real) -> Result<Column, DemError> {
    let s = hex_lattice(l0, h0, d, run.density);
    finish_column(s, l0, run, 1e-6, max_settle_time)
}

/// The unsettled hexagonal lattice of [`hex_column`].
pub fn hex_lattice(l0: Real, h0: Real, d: Real, density: Real) -> State {
    let r = 0.5 * d;
    let dy = d * (3.0 as Real).sqrt() / 2.0;
    let mut s = State::new();
    let mut row = 0;
    loop {
        let y = r + row as Real * dy;
        if y + r > h0 {
            break;
        }
        let x0 = if row % 2 == 1 { d } else { r };
        let mut x = x0;
        while x + r <= l0 {
            s.insert(x, y, r, density);
            x += d;
        }
        row += 1;
    }
    s
}

/// Column of `radii` placed on a loose lattice of pitch d_max (no settling; LAMMPS bench
/// scene `bench/lammps/column.lmp`: hex lattice of spacing 1.38 mm inside L_0).
pub fn lattice_column(radii: &[Real], l0: Real, pitch: Real, density: Real) -> State {
    let r_max = radii.iter().cloned().fold(0.0, Real::max);
    let dy = pitch * (3.0 as Real).sqrt() / 2.0;
    let mut s = State::with_capacity(radii.len());
    let mut row = 0;
    let mut k = 0;
    while k < radii.len() {
        let y = r_max + row as Real * dy;
        let mut x = if row % 2 == 1 { r_max + 0.5 * pitch } else { r_max };
        while x + r_max <= l0 && k < radii.len() {
            s.insert(x, y, radii[k], density);
            k += 1;
            x += pitch;
        }
        row += 1;
    }
    s
}
