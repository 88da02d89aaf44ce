//! The CD world and its step, a list of named phases:
//!
//! `preflight` → `detect` → `gauss_seidel` → `update_positions` → `ledger` → `watchdog`.
//!
//! Moreau–Jean θ-scheme for rigid disks: v⁺ = v⁻ + h M⁻¹F + M⁻¹ Σ Hᵀ P (velocities and
//! impulses the unknowns, one contact solve per step), x⁺ = x⁻ + h((1−θ)v⁻ + θv⁺).
//! Sequential throughout: nothing depends on the thread count.

use crate::cd::body::{Body, BodyInfo, Extra};
use crate::cd::contacts::{Contacts, WALL_KEY};
use crate::cd::energy::{Balance, Energies, Ledger};
use crate::cd::error::CdError;
use crate::cd::params::CdParams;
use crate::cd::preflight::{check_motion, fastest};
use crate::cd::solver::{Settings, SolveInfo, apply, apply_rolling, gauss_seidel, relative_velocity};
use crate::dem::neighbors::NeighborList;
use crate::dem::state::State;
use crate::dem::walls::Wall;
use crate::math::{Real, Vec2};
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// Diagnostics of one step.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct StepInfo {
    /// NLGS sweeps.
    pub iterations: u32,
    /// η of the last sweep (relative impulse change).
    pub change: Real,
    /// Natural-map residual at exit.
    pub residual: Real,
    /// Converged before the cap.
    pub converged: bool,
    /// Active contacts (in the index set).
    pub contacts: usize,
    /// Candidate pairs within the alert distance.
    pub candidates: usize,
}

/// Counters over a run: what a CD user asks first (iterations, unconverged steps).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Stats {
    /// Steps taken.
    pub steps: u64,
    /// NLGS sweeps, summed.
    pub iterations: u64,
    /// Σ active contacts × sweeps (the throughput unit of `bench cd`).
    pub contact_iterations: u64,
    /// Steps that hit the iteration cap.
    pub unconverged: u64,
    /// Largest sweep count of a step.
    pub max_iterations: u32,
    /// Largest exit residual of a step.
    pub max_residual: Real,
    /// Largest interpenetration seen, as a fraction of the pair's smaller diameter.
    pub max_penetration: Real,
    /// Pair-list rebuilds.
    pub rebuilds: u64,
}

/// Seconds per phase.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Timers {
    /// `detect` (pair list, index set, Delassus blocks, warm start).
    pub detect: f64,
    /// `gauss_seidel`.
    pub solve: f64,
    /// `update_positions` + `ledger` + `watchdog`.
    pub update: f64,
}

/// A CD scene being integrated.
#[derive(Debug, Clone)]
pub struct World {
    /// Parameters (validated).
    pub params: CdParams,
    /// Grains (positions, radii, masses; velocities mirrored from their bodies after each
    /// step). Grains marked prescribed in the state get an immovable body.
    pub state: State,
    /// Walls.
    pub walls: Vec<Wall>,
    /// Period along x, if periodic.
    pub periodic_lx: Option<Real>,
    /// Body of each grain.
    pub body: Vec<u32>,
    /// Hot body records (grains' own bodies first, then extras).
    pub bodies: Vec<Body>,
    /// Cold body data, aligned with `bodies`.
    pub info: Vec<BodyInfo>,
    /// What each body after the grains is.
    pub extras: Vec<Extra>,
    /// Active contacts of the last step.
    pub contacts: Contacts,
    /// Impulse received by each body from contacts during the last step (x, y, torque).
    pub reaction: Vec<[Real; 3]>,
    /// Simulated time [s].
    pub t: Real,
    /// Steps taken.
    pub step_count: u64,
    /// Last step.
    pub last: StepInfo,
    /// Run counters.
    pub stats: Stats,
    /// Phase timers.
    pub timers: Timers,
    /// Cumulative ledger.
    pub ledger: Ledger,
    /// Energy watchdog on (off for drivers that inject energy by design).
    pub energy_check: bool,
    /// Per-step record (iterations, residual, contacts) when `Some` (off by default: the
    /// run counters in `stats` always hold the totals, maxima and unconverged count).
    pub log: Option<Vec<StepInfo>>,
    e0: Real,
    ek_max: Real,
    w_abs: Real,
    alert: Real,
    d_min: Real,
    skin: Real,
    neighbors: NeighborList,
    vprev: Vec<[Real; 3]>,
    vfree: Vec<[Real; 3]>,
}

impl World {
    /// New world: validates the parameters, gives every grain its own body (immovable for
    /// grains marked prescribed in `state`) and every wall a body.
    pub fn new(params: CdParams, state: State, walls: Vec<Wall>, periodic_lx: Option<Real>) -> Result<World, CdError> {
        let issues = params.validate();
        if !issues.is_empty() {
            return Err(CdError::InvalidParams(
                issues
                    .iter()
                    .map(|i| format!("{} = {} (allowed: {})", i.key, i.value, i.allowed))
                    .collect::<Vec<_>>()
                    .join("; "),
            ));
        }
        if state.is_empty() {
            return Err(CdError::Setup("a CD scene needs at least one grain".into()));
        }
        let n = state.len();
        let d_min = 2.0 * state.r.iter().cloned().fold(Real::INFINITY, Real::min);
        let r_max = state.r.iter().cloned().fold(0.0, Real::max);
        if !(d_min > 0.0 && d_min.is_finite()) {
            return Err(CdError::Setup(format!(
                "grain radii must be > 0 (smallest diameter {d_min})"
            )));
        }
        let alert = params.alert_fraction * d_min;
        let skin = params.skin_factor * alert;
        if let Some(lx) = periodic_lx
            && !(lx >= 3.0 * (2.0 * r_max + skin))
        {
            return Err(CdError::Setup(format!(
                "periodic cell width {lx:.4e} m is below 3 neighbour cells of 2 r_max + skin = {:.4e} m: widen the cell",
                2.0 * r_max + skin
            )));
        }
        let mut bodies = Vec::with_capacity(n + walls.len());
        let mut info = Vec::with_capacity(n + walls.len());
        for g in 0..n {
            let free = state.inv_m[g] > 0.0;
            let (im, ii) = if free {
                (state.inv_m[g], state.inv_i[g])
            } else {
                (0.0, 0.0)
            };
            bodies.push(Body {
                v: [state.vx[g], state.vy[g], state.w[g]],
                inv: [im, im, ii],
            });
            info.push(BodyInfo {
                mass: [state.m[g], state.m[g], state.inertia[g]],
                force: [0.0; 3],
                gravity: free,
            });
        }
        let mut extras = Vec::new();
        for (k, w) in walls.iter().enumerate() {
            bodies.push(Body {
                v: [w.velocity.x, w.velocity.y, 0.0],
                inv: [0.0; 3],
            });
            info.push(BodyInfo::default());
            extras.push(Extra::Wall(k));
        }
        let nb = bodies.len();
        let mut w = World {
            params,
            state,
            walls,
            periodic_lx,
            body: (0..n as u32).collect(),
            bodies,
            info,
            extras,
            contacts: Contacts::default(),
            reaction: vec![[0.0; 3]; nb],
            t: 0.0,
            step_count: 0,
            last: StepInfo::default(),
            stats: Stats::default(),
            timers: Timers::default(),
            ledger: Ledger::default(),
            energy_check: true,
            log: None,
            e0: 0.0,
            ek_max: 0.0,
            w_abs: 0.0,
            alert,
            d_min,
            skin,
            neighbors: NeighborList::default(),
            vprev: vec![[0.0; 3]; nb],
            vfree: vec![[0.0; 3]; nb],
        };
        w.e0 = w.energies().total();
        Ok(w)
    }

    /// Glue `grains` into one rigid clump body with inverse masses `inv` (0 = imposed
    /// component), masses `mass` (for energies), applied force `force` and initial
    /// velocity `v`. Returns the body index. The grains' own bodies become unused.
    pub fn add_clump(
        &mut self,
        grains: &[usize],
        inv: [Real; 3],
        mass: [Real; 3],
        force: [Real; 3],
        v: [Real; 3],
    ) -> usize {
        let id = self.bodies.len();
        self.bodies.push(Body { v, inv });
        self.info.push(BodyInfo {
            mass,
            force,
            gravity: false,
        });
        self.extras.push(Extra::Clump);
        self.reaction.push([0.0; 3]);
        self.vprev.push([0.0; 3]);
        self.vfree.push([0.0; 3]);
        for &g in grains {
            self.body[g] = id as u32;
            self.bodies[g] = Body::default();
            self.info[g] = BodyInfo::default();
        }
        self.e0 = self.energies().total();
        id
    }

    /// Adaptive step: h = min(h_max, 0.4 alert / v_max) from the start-of-step speeds, so the
    /// pre-flight (h v ≤ alert/2) passes with a 20 % margin. Returns the step chosen.
    pub fn adapt_dt(&mut self, h_max: Real) -> Real {
        let (_, v) = fastest(&self.bodies);
        let h = if v > 0.0 {
            h_max.min(0.4 * self.alert / v)
        } else {
            h_max
        };
        self.params.dt = h;
        h
    }

    /// Alert distance [m].
    pub fn alert_distance(&self) -> Real {
        self.alert
    }
    /// Smallest grain diameter [m].
    pub fn d_min(&self) -> Real {
        self.d_min
    }
    /// Number of grains.
    pub fn len(&self) -> usize {
        self.state.len()
    }
    /// No grains.
    pub fn is_empty(&self) -> bool {
        self.state.is_empty()
    }

    /// Advance `steps` steps.
    pub fn run(&mut self, steps: u64) -> Result<(), CdError> {
        for _ in 0..steps {
            self.step()?;
        }
        Ok(())
    }

    /// One Moreau–Jean step.
    pub fn step(&mut self) -> Result<StepInfo, CdError> {
        let t0 = Instant::now();
        self.preflight()?;
        self.detect()?;
        let t1 = Instant::now();
        let solve = self.gauss_seidel();
        let t2 = Instant::now();
        self.ledger_step();
        self.update_positions()?;
        self.watchdog()?;
        self.timers.detect += (t1 - t0).as_secs_f64();
        self.timers.solve += (t2 - t1).as_secs_f64();
        self.timers.update += t2.elapsed().as_secs_f64();
        let info = StepInfo {
            iterations: solve.iterations,
            change: solve.change,
            residual: solve.residual,
            converged: solve.converged,
            contacts: self.contacts.len(),
            candidates: self.contacts.candidates,
        };
        let s = &mut self.stats;
        s.steps += 1;
        s.iterations += info.iterations as u64;
        s.contact_iterations += info.iterations as u64 * info.contacts as u64;
        s.unconverged += (!info.converged) as u64;
        s.max_iterations = s.max_iterations.max(info.iterations);
        s.max_residual = s.max_residual.max(info.residual);
        self.last = info;
        if let Some(l) = self.log.as_mut() {
            l.push(info);
        }
        self.step_count += 1;
        self.t += self.params.dt;
        Ok(info)
    }

    /// Refuse a step in which the fastest body (at the start of the step) would move more
    /// than half the alert distance.
    fn preflight(&mut self) -> Result<(), CdError> {
        for (k, e) in self.extras.iter().enumerate() {
            if let Extra::Wall(w) = *e {
                let wv = self.walls[w].velocity;
                let b = &mut self.bodies[self.state.len() + k];
                b.v = [wv.x, wv.y, 0.0];
            }
        }
        let (i, v) = fastest(&self.bodies);
        check_motion(self.step_count, self.t, i, v, self.params.dt, self.alert, self.d_min)
    }

    /// Free velocities, pair list refresh, index set, Delassus blocks, warm start.
    fn detect(&mut self) -> Result<(), CdError> {
        let h = self.params.dt;
        let g = self.params.gravity;
        // free velocities: v_free = v⁻ + h M⁻¹ F
        for (k, (b, inf)) in self.bodies.iter_mut().zip(self.info.iter()).enumerate() {
            self.vprev[k] = b.v;
            let gy = if inf.gravity { -g * inf.mass[1] } else { 0.0 };
            for c in 0..3 {
                let f = inf.force[c] + if c == 1 { gy } else { 0.0 };
                b.v[c] += h * b.inv[c] * f;
            }
            self.vfree[k] = b.v;
        }
        // pair list: rebuild once a grain moved (skin − alert)/2 since the last build
        let lim = 0.5 * (self.skin - self.alert);
        let s = &self.state;
        let stale = self.neighbors.x0.len() != s.len()
            || (0..s.len()).any(|i| {
                let (dx, dy) = (s.x[i] - self.neighbors.x0[i], s.y[i] - self.neighbors.y0[i]);
                dx * dx + dy * dy > lim * lim
            });
        if stale {
            self.neighbors
                .build(&mut self.state, self.skin, self.periodic_lx, |_, _| 0.0);
            self.stats.rebuilds += 1;
        }
        self.contacts.begin();
        let (mu, muw) = (self.params.friction, self.params.wall_friction);
        let e = [self.params.restitution_n, self.params.restitution_t];
        let lx = self.periodic_lx.unwrap_or(0.0);
        let alert = self.alert;
        let s = &self.state;
        let nl = &self.neighbors;
        let mut worst = (0.0, 0u32, 0u32);
        for k in 0..nl.len() {
            let (i, j) = (nl.pi[k] as usize, nl.pj[k] as usize);
            let dx = s.x[j] + nl.shift[k] * lx - s.x[i];
            let dy = s.y[j] - s.y[i];
            let rs = s.r[i] + s.r[j];
            let cut = rs + alert;
            let d2 = dx * dx + dy * dy;
            if d2 >= cut * cut {
                continue;
            }
            let (a, b) = (self.body[i] as usize, self.body[j] as usize);
            if a == b {
                continue;
            }
            let dist = d2.sqrt();
            let gap = dist - rs;
            let dmin = 2.0 * s.r[i].min(s.r[j]);
            if -gap / dmin > worst.0 {
                worst = (-gap / dmin, i as u32, j as u32);
            }
            let n = [dx / dist, dy / dist];
            self.contacts.consider(
                ((i as u64) << 32) | j as u64,
                a,
                b,
                n,
                s.r[i],
                s.r[j],
                gap,
                dmin,
                mu,
                e,
                h,
                &self.bodies,
                &self.vprev,
                &self.vfree,
            );
        }
        let n_grains = s.len();
        for (w, wall) in self.walls.iter().enumerate() {
            if !wall.active {
                continue;
            }
            let a = n_grains + self.extras.iter().position(|x| *x == Extra::Wall(w)).unwrap_or(0);
            for gi in 0..n_grains {
                let gap = wall.distance(Vec2::new(s.x[gi], s.y[gi])) - s.r[gi];
                if gap >= alert {
                    continue;
                }
                let b = self.body[gi] as usize;
                let dmin = 2.0 * s.r[gi];
                if -gap / dmin > worst.0 {
                    worst = (-gap / dmin, gi as u32, u32::MAX - w as u32);
                }
                self.contacts.consider(
                    ((WALL_KEY + w as u64) << 32) | gi as u64,
                    a,
                    b,
                    [wall.normal.x, wall.normal.y],
                    0.0,
                    s.r[gi],
                    gap,
                    dmin,
                    muw,
                    e,
                    h,
                    &self.bodies,
                    &self.vprev,
                    &self.vfree,
                );
            }
        }
        self.stats.max_penetration = self.stats.max_penetration.max(worst.0);
        if worst.0 > self.params.max_penetration {
            return Err(CdError::Penetration {
                step: self.step_count,
                t: self.t,
                i: worst.1,
                j: worst.2,
                fraction: worst.0,
                limit: self.params.max_penetration,
            });
        }
        self.contacts.warm_start();
        for r in &self.contacts.rows {
            if r.p != [0.0, 0.0] {
                apply(r, &mut self.bodies, r.p);
            }
        }
        if self.params.rolling_friction > 0.0 {
            for (r, &m) in self.contacts.rows.iter().zip(self.contacts.mr.iter()) {
                if m != 0.0 {
                    apply_rolling(r, &mut self.bodies, m);
                }
            }
        }
        Ok(())
    }

    fn gauss_seidel(&mut self) -> SolveInfo {
        let p = &self.params;
        let s = Settings {
            tolerance: p.tolerance,
            residual_tolerance: p.residual_tolerance,
            max_iterations: p.max_iterations,
            relaxation: p.relaxation,
        };
        let c = &mut self.contacts;
        let roll = (p.rolling_friction > 0.0).then_some((c.mr.as_mut_slice(), c.r_eff.as_slice(), p.rolling_friction));
        if p.coloured_sweeps {
            crate::cd::colour::gauss_seidel(&mut c.rows, &mut self.bodies, &s, roll)
        } else {
            gauss_seidel(&mut c.rows, &mut self.bodies, &s, roll)
        }
    }

    /// Contact work split (collisional / frictional), reactions, θ-term, external work.
    fn ledger_step(&mut self) {
        let h = self.params.dt;
        let th = self.params.theta;
        let g = self.params.gravity;
        for r in self.reaction.iter_mut() {
            *r = [0.0; 3];
        }
        let (mut coll, mut fric) = (0.0, 0.0);
        if self.params.rolling_friction > 0.0 {
            for (k, r) in self.contacts.rows.iter().enumerate() {
                let m = self.contacts.mr[k];
                if m == 0.0 {
                    continue;
                }
                let (a, b) = (r.a as usize, r.b as usize);
                let wrel = 0.5 * (self.bodies[b].v[2] - self.bodies[a].v[2] + self.vprev[b][2] - self.vprev[a][2]);
                fric -= m * wrel;
                self.reaction[b][2] += m;
                self.reaction[a][2] -= m;
            }
        }
        for (r, um) in self.contacts.rows.iter().zip(self.contacts.um.iter()) {
            let up = relative_velocity(r, &self.bodies[r.a as usize].v, &self.bodies[r.b as usize].v);
            coll -= r.p[0] * 0.5 * (up[0] + um[0]);
            fric -= r.p[1] * 0.5 * (up[1] + um[1]);
            let t = [-r.n[1], r.n[0]];
            let px = r.p[0] * r.n[0] + r.p[1] * t[0];
            let py = r.p[0] * r.n[1] + r.p[1] * t[1];
            let rb = &mut self.reaction[r.b as usize];
            rb[0] += px;
            rb[1] += py;
            rb[2] -= r.rb * r.p[1];
            let ra = &mut self.reaction[r.a as usize];
            ra[0] -= px;
            ra[1] -= py;
            ra[2] -= r.ra * r.p[1];
        }
        let (mut num, mut wext) = (0.0, 0.0);
        for k in 0..self.bodies.len() {
            let (b, inf, vm) = (&self.bodies[k], &self.info[k], &self.vprev[k]);
            for c in 0..3 {
                let vbar = 0.5 * (vm[c] + b.v[c]);
                if b.inv[c] == 0.0 {
                    wext -= self.reaction[k][c] * vbar;
                } else {
                    let vth = (1.0 - th) * vm[c] + th * b.v[c];
                    let fg = if c == 1 && inf.gravity { -g * inf.mass[1] } else { 0.0 };
                    wext += h * inf.force[c] * vth;
                    num += h * (th - 0.5) * (inf.force[c] + fg) * (b.v[c] - vm[c]);
                }
            }
        }
        self.ledger.collisional += coll;
        self.ledger.frictional += fric;
        self.ledger.numerical += num;
        self.ledger.external_work += wext;
        self.w_abs += wext.abs();
    }

    /// x⁺ = x⁻ + h((1−θ)v⁻ + θv⁺); mirror velocities into the state; walls move.
    fn update_positions(&mut self) -> Result<(), CdError> {
        let h = self.params.dt;
        let th = self.params.theta;
        for (k, b) in self.bodies.iter().enumerate() {
            if !(b.v[0].is_finite() && b.v[1].is_finite() && b.v[2].is_finite()) {
                return Err(CdError::NonFinite {
                    step: self.step_count,
                    t: self.t,
                    grain: k as u32,
                });
            }
        }
        let mut fast = (0usize, 0.0);
        let s = &mut self.state;
        for gi in 0..s.len() {
            let k = self.body[gi] as usize;
            let (vm, vp) = (self.vprev[k], self.bodies[k].v);
            let vt = [
                (1.0 - th) * vm[0] + th * vp[0],
                (1.0 - th) * vm[1] + th * vp[1],
                (1.0 - th) * vm[2] + th * vp[2],
            ];
            s.x[gi] += h * vt[0];
            s.y[gi] += h * vt[1];
            s.theta[gi] += h * vt[2];
            s.vx[gi] = vp[0];
            s.vy[gi] = vp[1];
            s.w[gi] = vp[2];
            let sp = (vt[0] * vt[0] + vt[1] * vt[1]).sqrt();
            if sp > fast.1 {
                fast = (gi, sp);
            }
        }
        for w in self.walls.iter_mut() {
            w.origin += h * w.velocity;
        }
        // after the step the real condition: nothing moved more than the alert distance
        check_motion(self.step_count, self.t, fast.0, fast.1, h, 2.0 * self.alert, self.d_min)
    }

    fn watchdog(&mut self) -> Result<(), CdError> {
        let en = self.energies();
        self.ek_max = self.ek_max.max(en.ek + en.erot);
        if !self.energy_check {
            return Ok(());
        }
        let m: Real = self.state.m.iter().sum();
        let scale = self.ek_max + self.w_abs + m * self.params.gravity * self.d_min;
        let allowed = self.e0 + self.ledger.external_work + self.params.energy_rise * scale;
        if en.total() > allowed {
            return Err(CdError::EnergyRise {
                step: self.step_count,
                t: self.t,
                energy: en.total(),
                allowed,
            });
        }
        Ok(())
    }

    /// Energies of free components (grains' own bodies and clumps) [J/m].
    pub fn energies(&self) -> Energies {
        let mut e = Energies::default();
        let g = self.params.gravity;
        for (k, (b, inf)) in self.bodies.iter().zip(self.info.iter()).enumerate() {
            for c in 0..2 {
                if b.inv[c] > 0.0 {
                    e.ek += 0.5 * inf.mass[c] * b.v[c] * b.v[c];
                }
            }
            if b.inv[2] > 0.0 {
                e.erot += 0.5 * inf.mass[2] * b.v[2] * b.v[2];
            }
            if k < self.state.len() && inf.gravity && b.inv[1] > 0.0 {
                e.ep += inf.mass[1] * g * self.state.y[k];
            }
        }
        e
    }

    /// Energy balance E + D − E_0 − W.
    pub fn balance(&self) -> Balance {
        let now = self.energies();
        Balance {
            e0: self.e0,
            now,
            ledger: self.ledger,
            residual: now.total() + self.ledger.dissipated() - self.e0 - self.ledger.external_work,
        }
    }

    /// Reset the energy reference (after a driver changes velocities by hand).
    pub fn reset_energy_reference(&mut self) {
        self.e0 = self.energies().total() + self.ledger.dissipated() - self.ledger.external_work;
    }
}
