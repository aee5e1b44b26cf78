//! SplitMix64 (Steele, Lea & Flood 2014): the one small deterministic generator of the
//! crate, for RANSAC samples and robust starts. Not for cryptography; the twin's
//! image noise uses its own xoshiro256++ seeded from this generator.

/// A SplitMix64 state. The same seed always gives the same sequence on every platform.
#[derive(Debug, Clone)]
pub struct SplitMix64(pub u64);

impl SplitMix64 {
    /// The next 64 random bits.
    #[inline]
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// An index in `0..n` (the modulo bias is below `n / 2^64`); 0 for `n = 0`.
    #[inline]
    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64().checked_rem(n as u64).unwrap_or(0)) as usize
    }

    /// A uniform number in `(0, 1)` with 53 random bits (never 0 or 1).
    #[inline]
    pub fn uniform(&mut self) -> f64 {
        ((self.next_u64() >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }

    /// A standard normal number (Box-Muller, one of the pair).
    pub fn normal(&mut self) -> f64 {
        let (a, b) = (self.uniform(), self.uniform());
        (-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reference_sequence() {
        // The first outputs for seed 0 of the reference implementation (Vigna's splitmix64.c).
        let mut r = SplitMix64(0);
        assert_eq!(r.next_u64(), 0xE220_A839_7B1D_CDAF);
        assert_eq!(r.next_u64(), 0x6E78_9E6A_A1B9_65F4);
        let mut r = SplitMix64(7);
        for _ in 0..1000 {
            assert!(r.below(13) < 13);
            let u = r.uniform();
            assert!(u > 0.0 && u < 1.0);
        }
    }
}
