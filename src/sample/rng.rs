//! The project's one small random generator, shared by the DEM, CD and MPM preparations,
//! the tests and the benches: SplitMix64 (Steele, Lea & Flood 2014), deterministic and
//! independent of any crate's version.

use crate::math::Real;

/// Small deterministic generator (SplitMix64) for tests, benches and random placement.
#[derive(Debug, Clone)]
pub struct SplitMix64(pub u64);

impl SplitMix64 {
    /// Next uniform number in [0, 1).
    pub fn next_f64(&mut self) -> Real {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as Real / (1u64 << 53) as Real
    }
}
