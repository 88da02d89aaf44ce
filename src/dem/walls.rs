//! Straight walls: infinite lines {p : (p − origin)·normal = 0}, grains on the side the
//! normal points to. A wall has a velocity (moving right wall, compression plate) and can
//! be switched off (the column gate). Contacts use the same law as grain pairs, with the
//! wall's own [`ContactParams`](crate::dem::params::ContactParams).

use crate::math::{Real, Vec2};

/// One straight wall (not serde: `Vec2` has no serde impl without nalgebra's feature).
#[derive(Debug, Clone, PartialEq)]
pub struct Wall {
    /// Name for reports ("floor", "left", "gate", …).
    pub name: String,
    /// A point of the wall line [m].
    pub origin: Vec2,
    /// Unit normal pointing into the granular domain.
    pub normal: Vec2,
    /// Wall velocity [m/s] (the origin moves with it).
    pub velocity: Vec2,
    /// Inactive walls exert no force (a removed gate).
    pub active: bool,
}

impl Wall {
    /// Wall through `origin` with inward `normal` (normalised here), at rest, active.
    pub fn new(name: &str, origin: Vec2, normal: Vec2) -> Self {
        Self {
            name: name.to_string(),
            origin,
            normal: normal.normalize(),
            velocity: Vec2::zeros(),
            active: true,
        }
    }
    /// Floor y = y0.
    pub fn floor(y0: Real) -> Self {
        Self::new("floor", Vec2::new(0.0, y0), Vec2::new(0.0, 1.0))
    }
    /// Left wall x = x0 (grains to its right).
    pub fn left(x0: Real) -> Self {
        Self::new("left", Vec2::new(x0, 0.0), Vec2::new(1.0, 0.0))
    }
    /// Right wall x = x0 (grains to its left).
    pub fn right(name: &str, x0: Real) -> Self {
        Self::new(name, Vec2::new(x0, 0.0), Vec2::new(-1.0, 0.0))
    }
    /// Ceiling y = y0 (grains below it).
    pub fn ceiling(name: &str, y0: Real) -> Self {
        Self::new(name, Vec2::new(0.0, y0), Vec2::new(0.0, -1.0))
    }
    /// Signed distance of point p from the wall line (positive inside the domain).
    #[inline(always)]
    pub fn distance(&self, p: Vec2) -> Real {
        (p - self.origin).dot(&self.normal)
    }
}

/// Per wall, the grains that may touch it before the lists must be made again: a Verlet
/// list for walls, so the grain–wall pass visits a few hundred grains near the walls
/// instead of every grain for every wall (on the 2924-grain column, ≈ 70 contacts among
/// 5848 grain–wall slots; the distance checks were ≈ 9 % of the step).
///
/// Made from the neighbour list's build positions x₀ (every grain stays within skin/2 of
/// them until the next build) and each wall's position when made; a grain is listed when
/// its gap to the wall there is at most 1.5 skin, or when its contact slot is live (it may
/// hold a history to drop). The lists hold while no wall moved more than skin/2 along its
/// normal (or turned): an unlisted grain then has a gap > 1.5 skin − skin/2 − skin/2 > 0,
/// so it neither touches the wall nor has anything to drop — the pass would skip it —
/// and visiting only the listed grains, in grain order, gives the same results bit for
/// bit.
#[derive(Debug, Clone, Default)]
pub(crate) struct NearWalls {
    /// The listed grains: wall `wi`, grain chunk `c` at `grains[start[wi * (nc + 1) + c]..
    /// start[wi * (nc + 1) + c + 1]]`, in grain order.
    pub grains: Vec<u32>,
    /// See `grains`.
    pub start: Vec<u32>,
    /// Grain chunks per wall (nc).
    pub chunks: usize,
    /// Grains when made.
    n: usize,
    /// Each wall's origin and normal when made.
    at: Vec<(Vec2, Vec2)>,
    /// Skin the lists were made with [m].
    skin: Real,
    /// Made for every grain (no build positions): to be made again at the next use.
    all: bool,
    /// Cleared by [`NearWalls::invalidate`].
    made: bool,
}

impl NearWalls {
    /// The lists must be made again before their next use (grains added, histories
    /// restored, positions rebuilt).
    pub fn invalidate(&mut self) {
        self.made = false;
    }

    /// Whether the lists still hold for `n` grains and these walls.
    pub fn hold(&self, walls: &[Wall], n: usize) -> bool {
        self.made
            && !self.all
            && self.n == n
            && self.at.len() == walls.len()
            && walls
                .iter()
                .zip(&self.at)
                .all(|(w, &(o, nrm))| w.normal == nrm && !((w.origin - o).dot(&nrm).abs() > 0.5 * self.skin))
    }

    /// Make the lists for grain chunks of `chunk` grains: radii `r`, build positions
    /// `x0`, `y0` (empty: list every grain, and make the lists again at the next use),
    /// skin `skin`, live flags `live` (`wall * n + grain`).
    pub fn make(
        &mut self,
        walls: &[Wall],
        (x0, y0): (&[Real], &[Real]),
        r: &[Real],
        skin: Real,
        live: &[u8],
        chunk: usize,
    ) {
        let n = r.len();
        let nc = n.div_ceil(chunk);
        let all = x0.len() != n || y0.len() != n;
        self.grains.clear();
        self.start.clear();
        self.at.clear();
        for (wi, wall) in walls.iter().enumerate() {
            for c in 0..nc {
                self.start.push(self.grains.len() as u32);
                for a in c * chunk..((c + 1) * chunk).min(n) {
                    // NaN positions are listed (the pass and the watchdog see them)
                    let near =
                        all || live[wi * n + a] != 0 || !(r[a] - wall.distance(Vec2::new(x0[a], y0[a])) < -1.5 * skin);
                    if near {
                        self.grains.push(a as u32);
                    }
                }
            }
            self.start.push(self.grains.len() as u32);
            self.at.push((wall.origin, wall.normal));
        }
        (self.chunks, self.n, self.skin, self.all, self.made) = (nc, n, skin, all, true);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sample::rng::SplitMix64;

    /// Grains moved by at most skin/2 and walls by at most skin/2 along their normal
    /// (what `NearWalls::hold` allows): every grain that touches a wall is listed for it.
    /// Fails with a listing criterion below a gap of skin (the two half-skin moves close
    /// a gap of skin; 1.5 skin is a margin).
    #[test]
    fn listed_grains_cover_every_contact_the_bounds_allow() {
        let mut rng = SplitMix64(7);
        let mut u = move || rng.next_f64();
        let (n, skin, chunk) = (3000, 0.2, 64);
        let r: Vec<Real> = (0..n).map(|_| 0.5 + 0.5 * u()).collect();
        let x0: Vec<Real> = (0..n).map(|_| 20.0 * u() - 10.0).collect();
        let y0: Vec<Real> = (0..n).map(|_| 20.0 * u() - 10.0).collect();
        let walls0 = vec![
            Wall::floor(-10.0),
            Wall::left(-10.0),
            Wall::right("r", 10.0),
            Wall::new("slant", Vec2::new(0.0, 8.0), Vec2::new(-1.0, -2.0)),
        ];
        let live = vec![0u8; MAX_WALLS_TEST * n];
        let mut near = NearWalls::default();
        near.make(&walls0, (&x0, &y0), &r, skin, &live, chunk);
        let nc = n.div_ceil(chunk);
        let listed = |wi: usize, a: usize| {
            let c = a / chunk;
            let at = wi * (nc + 1) + c;
            near.grains[near.start[at] as usize..near.start[at + 1] as usize].contains(&(a as u32))
        };
        let mut touching = 0;
        for trial in 0..200 {
            let mut walls = walls0.clone();
            for w in &mut walls {
                let d = 0.5 * skin * (2.0 * u() - 1.0);
                w.origin += w.normal * d;
            }
            // the last trials push every wall and grain (almost) the full half skin
            // towards each other
            let worst = trial >= 190;
            let half = 0.5 * skin * (1.0 - 1e-9);
            for (wi, w) in walls.iter_mut().enumerate() {
                if worst {
                    w.origin = walls0[wi].origin + w.normal * half;
                }
            }
            assert!(near.hold(&walls, n));
            for a in 0..n {
                let (ang, len) = (u() * std::f64::consts::TAU, 0.5 * skin * u().sqrt());
                for (wi, w) in walls.iter().enumerate() {
                    let p = if worst {
                        Vec2::new(x0[a], y0[a]) - w.normal * half
                    } else {
                        Vec2::new(x0[a] + len * ang.cos(), y0[a] + len * ang.sin())
                    };
                    if r[a] - w.distance(p) > 0.0 {
                        touching += 1;
                        assert!(listed(wi, a), "grain {a} touches wall {wi} unlisted (trial {trial})");
                    }
                }
            }
        }
        assert!(touching > 1000, "too few contacts tested: {touching}");
        // lists stay short: a band of 1.5 skin plus a radius along each wall
        assert!(near.grains.len() < n, "{} listed", near.grains.len());
        // a wall moved past half the skin, or turned, voids the lists
        let mut w = walls0.clone();
        let shift = w[0].normal * (0.51 * skin);
        w[0].origin += shift;
        assert!(!near.hold(&w, n));
        let mut w = walls0.clone();
        w[1].normal = Vec2::new(1.0, 1e-9).normalize();
        assert!(!near.hold(&w, n));
        assert!(!near.hold(&walls0[..3], n));
        assert!(!near.hold(&walls0, n + 1));
        near.invalidate();
        assert!(!near.hold(&walls0, n));
    }

    /// A live slot (a history that may need dropping) is listed however far the grain is.
    #[test]
    fn live_slots_are_listed() {
        let (x0, y0, r) = (vec![0.0, 0.0], vec![5.0, 6.0], vec![0.5, 0.5]);
        let mut live = vec![0u8; 2 * 2];
        live[2 + 1] = 1; // wall 1, grain 1
        let walls = vec![Wall::floor(0.0), Wall::floor(0.0)];
        let mut near = NearWalls::default();
        near.make(&walls, (&x0, &y0), &r, 0.1, &live, 256);
        assert_eq!(near.grains, vec![1]);
        assert_eq!(near.start, vec![0, 0, 0, 1]);
    }

    const MAX_WALLS_TEST: usize = 4;
}
