//! Contact arrays and the `detect` phase: candidate pairs closer than the alert distance
//! (grain–grain from the DEM's Verlet cell list, grain–wall by a direct scan), the
//! Moreau–Jean index set, Delassus blocks, and the warm start carried by contact key.
//!
//! Index set (Siconos' rule with γ = ½): a candidate with gap g and free relative normal
//! velocity u_free,n (start-of-step velocity plus the applied forces' impulse) is active
//! when g + ½ h u_free,n ≤ 0. Only active contacts enter the Gauss–Seidel sweep.

use crate::cd::body::Body;
use crate::math::Real;

/// One active contact as the Gauss–Seidel sweep reads it (array of structs: the sweep
/// touches every field of a row at once).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Row {
    /// Body on the "from" side (n points from a to b).
    pub a: u32,
    /// Body on the "to" side.
    pub b: u32,
    /// Unit normal n (from a to b); the tangent is t = (−n_y, n_x).
    pub n: [Real; 2],
    /// Lever arm of a (its radius; 0 for a wall).
    pub ra: Real,
    /// Lever arm of b.
    pub rb: Real,
    /// Delassus block W = H M⁻¹ Hᵀ: (W_nn, W_nt, W_tt).
    pub w: [Real; 3],
    /// Coulomb coefficient μ of the pair.
    pub mu: Real,
    /// Restitution part of Moreau's formal velocity: (ε_n u⁻_n, ε_t u⁻_t) for an impact
    /// (u⁻_n < 0), else 0. The local problem is posed on q = u⁺ + bias.
    pub bias: [Real; 2],
    /// Impulse (P_n, P_t) [N·s/m].
    pub p: [Real; 2],
}

/// Contacts of the current step: hot rows plus cold data aligned with them.
#[derive(Debug, Clone, Default)]
pub struct Contacts {
    /// Active contacts, sorted by key.
    pub rows: Vec<Row>,
    /// Key of each row: (i << 32) | j for grains i < j; ((WALL_KEY + w) << 32) | g for a
    /// wall.
    pub key: Vec<u64>,
    /// Gap at the start of the step [m] (negative: interpenetration).
    pub gap: Vec<Real>,
    /// Start-of-step relative velocity (u⁻_n, u⁻_t) (for the ledger).
    pub um: Vec<[Real; 2]>,
    /// Smaller diameter of the pair (for the penetration watchdog) [m].
    pub dmin: Vec<Real>,
    /// Candidate pairs within the alert distance this step (active or not).
    pub candidates: usize,
    /// Rolling moment impulse M_r of each row [N·s] (used only with rolling resistance).
    pub mr: Vec<Real>,
    /// Rolling radius r_eff of each row [m].
    pub r_eff: Vec<Real>,
    pub(crate) old_mr: Vec<Real>,
    // previous step's impulses by key (warm start)
    pub(crate) old_key: Vec<u64>,
    pub(crate) old_p: Vec<[Real; 2]>,
}

/// Wall keys start here (above any grain index).
pub const WALL_KEY: u64 = 0xFFFF_0000;

impl Contacts {
    /// Number of active contacts.
    pub fn len(&self) -> usize {
        self.rows.len()
    }
    /// No active contacts.
    pub fn is_empty(&self) -> bool {
        self.rows.is_empty()
    }

    /// Move this step's impulses aside and clear the rows (start of `detect`).
    pub(crate) fn begin(&mut self) {
        self.old_key.clear();
        self.old_p.clear();
        self.old_key.extend_from_slice(&self.key);
        self.old_p.extend(self.rows.iter().map(|r| r.p));
        std::mem::swap(&mut self.old_mr, &mut self.mr);
        self.mr.clear();
        self.r_eff.clear();
        self.rows.clear();
        self.key.clear();
        self.gap.clear();
        self.um.clear();
        self.dmin.clear();
        self.candidates = 0;
    }

    /// Warm start: copy the previous impulses of rows whose key survived (sorted merge;
    /// both key lists are ascending).
    pub(crate) fn warm_start(&mut self) {
        let (mut a, mut b) = (0usize, 0usize);
        while a < self.old_key.len() && b < self.key.len() {
            match self.old_key[a].cmp(&self.key[b]) {
                std::cmp::Ordering::Less => a += 1,
                std::cmp::Ordering::Greater => b += 1,
                std::cmp::Ordering::Equal => {
                    self.rows[b].p = self.old_p[a];
                    if let Some(&m) = self.old_mr.get(a) {
                        self.mr[b] = m;
                    }
                    a += 1;
                    b += 1;
                }
            }
        }
    }

    /// Consider one candidate pair: geometry (unit normal `n` from a to b, gap), bodies,
    /// lever arms. Appends a row if the pair is in the index set. `vprev` are the
    /// start-of-step velocities, `vfree` the free ones (start velocity + h M⁻¹ F).
    /// Activation slack 1e-9 d: exactly touching grains placed in floating point must not
    /// fall out of the index set by a rounding-level positive gap.
    #[inline]
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn consider(
        &mut self,
        key: u64,
        a: usize,
        b: usize,
        n: [Real; 2],
        ra: Real,
        rb: Real,
        gap: Real,
        dmin: Real,
        mu: Real,
        e: [Real; 2],
        h: Real,
        bodies: &[Body],
        vprev: &[[Real; 3]],
        vfree: &[[Real; 3]],
    ) {
        self.candidates += 1;
        let (ba, bb) = (&bodies[a], &bodies[b]);
        let t = [-n[1], n[0]];
        let rel = |va: &[Real; 3], vb: &[Real; 3]| -> [Real; 2] {
            let dv = [vb[0] - va[0], vb[1] - va[1]];
            [
                dv[0] * n[0] + dv[1] * n[1],
                dv[0] * t[0] + dv[1] * t[1] - va[2] * ra - vb[2] * rb,
            ]
        };
        let uf = rel(&vfree[a], &vfree[b]);
        if gap + 0.5 * h * uf[0] > 1e-9 * dmin {
            return;
        }
        let um = rel(&vprev[a], &vprev[b]);
        // Delassus block: translational D = diag(1/m_x, 1/m_y) of both, rotation on t only
        let dx = ba.inv[0] + bb.inv[0];
        let dy = ba.inv[1] + bb.inv[1];
        let wnn = dx * n[0] * n[0] + dy * n[1] * n[1];
        let wnt = dx * n[0] * t[0] + dy * n[1] * t[1];
        let wtt = dx * t[0] * t[0] + dy * t[1] * t[1] + ba.inv[2] * ra * ra + bb.inv[2] * rb * rb;
        if wnn <= 0.0 && wtt <= 0.0 {
            return; // two immovable bodies: nothing to solve
        }
        let impact = um[0] < 0.0;
        let bias = if impact {
            [e[0] * um[0], e[1] * um[1]]
        } else {
            [0.0, 0.0]
        };
        self.rows.push(Row {
            a: a as u32,
            b: b as u32,
            n,
            ra,
            rb,
            w: [wnn, wnt, wtt],
            mu,
            bias,
            p: [0.0, 0.0],
        });
        self.key.push(key);
        self.gap.push(gap);
        self.um.push(um);
        self.dmin.push(dmin);
        self.mr.push(0.0);
        self.r_eff.push(if ra > 0.0 && rb > 0.0 {
            ra * rb / (ra + rb)
        } else {
            ra.max(rb)
        });
    }
}
