//! Watchdog, run every `params.watchdog.every` steps: non-finite state, excessive
//! overlap, and mechanical energy rising above what was put in (E_0 + external work),
//! each reported as a [`DemError`] naming step, time and grain.

use crate::dem::error::DemError;
use crate::dem::integrate::grain_ke;
use crate::dem::world::World;

impl World {
    /// Check the state now.
    pub fn watchdog(&mut self) -> Result<(), DemError> {
        let s = &self.state;
        let (step, t) = (self.steps, self.t);
        for i in 0..s.len() {
            if !(s.x[i].is_finite()
                && s.y[i].is_finite()
                && s.vx[i].is_finite()
                && s.vy[i].is_finite()
                && s.w[i].is_finite())
            {
                return Err(DemError::NonFinite {
                    step,
                    t,
                    grain: i as u32,
                });
            }
        }
        let lim = self.params.watchdog.max_overlap_fraction;
        if self.info.max_overlap_fraction > lim {
            let (i, j) = self.info.max_pair;
            return Err(DemError::Overlap {
                step,
                t,
                i,
                j,
                fraction: self.info.max_overlap_fraction,
                limit: lim,
            });
        }
        if self.energy_check {
            let e = self.energies();
            let mech = e.ep + e.ek() + e.erot;
            let input = self.e0 + self.ledger.external_work;
            let scale = self.e0.abs().max(self.ledger.external_work.abs()).max(1e-12);
            let allowed = input + self.params.watchdog.energy_rise_fraction * scale;
            if mech > allowed {
                let grain = (0..s.len())
                    .max_by(|&a, &b| grain_ke(s, a).partial_cmp(&grain_ke(s, b)).unwrap())
                    .unwrap_or(0);
                return Err(DemError::EnergyRise {
                    step,
                    t,
                    grain: grain as u32,
                    energy: mech,
                    allowed,
                });
            }
        }
        Ok(())
    }
}
