//! Pile preparation (docs/definitions.md SC-PILE, stage P5) and the DEM pile run under a
//! horizontal excitation (R7/R8). Preparation follows the chapter: grains are poured into a
//! box of given width, the right-hand wall is shifted far to the right, and the pile
//! relaxes until every grain is at rest (stopping criterion: (E_k + E_rot)/E_p
//! < `settle_ratio` and the fastest grain slower than `settle_speed` √(g d̄), checked every
//! 1 ms of simulated time).

use crate::analysis::front::{Body, Link, front};
use crate::analysis::pile::{
    Frame, FrameTimes, PileRun, Profile, Sampled, StopRule, excitation, grain_sample, kinetic, sample_run,
};
use crate::dem::error::DemError;
use crate::dem::params::DemParams;
use crate::dem::prep::{DepositionParams, ballistic_deposition, box_walls, quench};
use crate::dem::state::State;
use crate::dem::walls::Wall;
use crate::dem::world::World;
use crate::math::Real;
use serde::{Deserialize, Serialize};

/// Pile settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PileParams {
    /// Deposition into the initial box (its `width` is the box width).
    pub deposition: DepositionParams,
    /// New right-wall position as a multiple of the box width.
    pub shift_to: Real,
    /// Rest criterion after the shift: (E_k + E_rot)/E_p below this …
    pub settle_ratio: Real,
    /// … and every grain slower than this many √(g d̄).
    pub settle_speed: Real,
    /// Shortest relaxation after the shift [s].
    pub min_time: Real,
    /// Cap on the relaxation time [s]; a pile not at rest by then is reported unsettled
    /// (and refused by the excitation stages).
    pub max_time: Real,
}

impl Default for PileParams {
    fn default() -> Self {
        Self {
            deposition: DepositionParams::default(),
            shift_to: 20.0,
            settle_ratio: 1e-6,
            settle_speed: 1e-3,
            min_time: 0.3,
            max_time: 5.0,
        }
    }
}

/// A prepared pile.
#[derive(Debug, Clone)]
pub struct Pile {
    /// Grains at rest (main mass and any grain that rolled away).
    pub state: State,
    /// L_0: right edge of the main mass [m].
    pub l0: Real,
    /// H_0: top of the main mass [m].
    pub h0: Real,
    /// Whether the rest criterion was met.
    pub settled: bool,
    /// Relaxation time after the shift [s].
    pub relax_time: Real,
    /// Final (E_k + E_rot)/E_p.
    pub ke_over_ep: Real,
    /// Final largest grain speed [m/s].
    pub v_max: Real,
}

fn v_max(s: &State) -> Real {
    (0..s.len())
        .map(|i| (s.vx[i] * s.vx[i] + s.vy[i] * s.vy[i]).sqrt())
        .fold(0.0, Real::max)
}

/// Pour `radii` into the box, shift the right wall, relax to rest.
pub fn prepare_pile(radii: &[Real], params: &DemParams, pp: &PileParams) -> Result<Pile, DemError> {
    let (s, _) = ballistic_deposition(radii, params, &pp.deposition)?;
    let width = pp.deposition.width;
    let mut walls = box_walls(width);
    walls[2].origin.x = pp.shift_to * width;
    let mut w = World::new(params.clone(), s, walls, None)?;
    let dbar = 2.0 * w.state.radius_stats().1;
    let v_rest = pp.settle_speed * (params.gravity * dbar).sqrt();
    w.run_until(pp.min_time)?;
    let (mut r, mut vm);
    loop {
        let e = w.energies();
        r = (e.ek() + e.erot) / e.ep.max(1e-300);
        vm = v_max(&w.state);
        if (r < pp.settle_ratio && vm < v_rest) || w.t >= pp.max_time {
            break;
        }
        w.run_until(w.t + 1e-3)?;
    }
    let settled = r < pp.settle_ratio && vm < v_rest;
    let relax_time = w.t;
    let s = w.state_by_id();
    let f = front(
        &Body {
            x: &s.x,
            y: &s.y,
            half: &s.r,
            mass: &s.m,
        },
        Link::Contact { gap: 0.01 * dbar },
    );
    Ok(Pile {
        l0: f.length,
        h0: f.height,
        settled,
        relax_time,
        ke_over_ep: r,
        v_max: vm,
        state: s,
    })
}

/// A frame of grains (DEM or CD: both on `dem::State`).
pub fn grain_frame(t: Real, s: &State) -> Frame {
    Frame {
        t,
        x: s.x.clone(),
        y: s.y.clone(),
        half: s.r.clone(),
        vx: s.vx.clone(),
        vy: s.vy.clone(),
        sigma_yy: Vec::new(),
    }
}

/// Walls of a pile run: the base and the left wall only (the right wall is gone).
pub fn pile_walls() -> Vec<Wall> {
    vec![Wall::floor(0.0), Wall::left(0.0)]
}

/// Excite a pile at rest with `profile` carrying `e0` [J/m] and run it until `stop`.
pub fn run_pile(
    pile: &State,
    params: &DemParams,
    profile: Profile,
    e0: Real,
    stop: &StopRule,
) -> Result<PileRun, DemError> {
    run_pile_frames(pile, params, profile, e0, stop, &FrameTimes::default())
}

/// [`run_pile`] taking frames at `frames` (times [s], at sample instants); the run does not
/// stop before the last frame.
pub fn run_pile_frames(
    pile: &State,
    params: &DemParams,
    profile: Profile,
    e0: Real,
    stop: &StopRule,
    frames: &FrameTimes,
) -> Result<PileRun, DemError> {
    let mut s = pile.clone();
    s.stop();
    let top = (0..s.len()).map(|i| s.y[i] + s.r[i]).fold(0.0, Real::max);
    let vx = excitation(profile, &s.y, &s.m, top, e0);
    let e0_check = kinetic(&s.m, &vx) / e0;
    s.vx = vx;
    let dbar = 2.0 * s.radius_stats().1;
    let link = Link::Contact { gap: 0.01 * dbar };
    let mut p = params.clone();
    p.ledger = false;
    let mut w = World::new(p, s, pile_walls(), None)?;
    let g = params.gravity;
    let dts = stop.dt_sample(g);
    let run = sample_run(
        &mut w,
        stop,
        frames,
        e0,
        g,
        |w| w.t,
        |w| grain_sample(w.t, &w.state, link),
        |w| grain_frame(w.t, &w.state_by_id()),
        |w| w.run_until(w.t + dts),
    )?;
    let l0 = run.samples[0].l;
    let Sampled {
        samples,
        frames: shots,
        stopped,
    } = run;
    let st = &w.state_by_id();
    Ok(PileRun {
        samples,
        l0,
        e0,
        e0_check,
        stopped,
        steps: w.steps,
        final_bodies: (st.x.clone(), st.y.clone(), st.r.clone()),
        frames: shots,
    })
}

/// Settle the grains of a prepared pile again with other walls or parameters (kinetic
/// damping): used by tests.
pub fn requench(s: &State, params: &DemParams, walls: Vec<Wall>, ratio: Real) -> Result<State, DemError> {
    let mut w = World::new(params.clone(), s.clone(), walls, None)?;
    quench(&mut w, ratio, 20_000)?;
    Ok(w.state_by_id())
}
