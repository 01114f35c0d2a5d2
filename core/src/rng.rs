//! A portable, seeded random number generator.
//!
//! Scenes and random providers must mean the same thing for the same seed on
//! every platform and every release of this crate, so the conversions from
//! raw bits to floats and normals are written out here (ChaCha8 bits, 53-bit
//! uniforms, Box–Muller normals) rather than delegated to a distribution crate
//! whose algorithms may change.

use crate::math::Real;
use rand_chacha::ChaCha8Rng;
use rand_core::{Rng, SeedableRng};

/// Seeded ChaCha8 generator with portable float conversions.
#[derive(Debug, Clone)]
pub struct PortableRng {
    inner: ChaCha8Rng,
    spare_normal: Option<Real>,
}

impl PortableRng {
    /// A generator for `seed`; the same seed gives the same stream everywhere.
    pub fn new(seed: u64) -> Self {
        Self {
            inner: ChaCha8Rng::seed_from_u64(seed),
            spare_normal: None,
        }
    }

    /// Raw 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.inner.next_u64()
    }

    /// Uniform in `[0, 1)` with 53 bits of precision.
    pub fn uniform(&mut self) -> Real {
        (self.next_u64() >> 11) as Real * (1.0 / (1u64 << 53) as Real)
    }

    /// Uniform in `[lo, hi)`.
    pub fn uniform_range(&mut self, lo: Real, hi: Real) -> Real {
        lo + (hi - lo) * self.uniform()
    }

    /// Standard normal by the Box–Muller transform (pairs are cached).
    pub fn normal(&mut self) -> Real {
        if let Some(z) = self.spare_normal.take() {
            return z;
        }
        // u1 in (0, 1] so that ln(u1) is finite.
        let u1 = 1.0 - self.uniform();
        let u2 = self.uniform();
        let r = (-2.0 * u1.ln()).sqrt();
        let (s, c) = (std::f64::consts::TAU * u2).sin_cos();
        self.spare_normal = Some(r * s);
        r * c
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn same_seed_same_stream_and_moments_are_sane() {
        let mut a = PortableRng::new(7);
        let mut b = PortableRng::new(7);
        let n = 20_000;
        let (mut sum, mut sum2) = (0.0, 0.0);
        for _ in 0..n {
            let x = a.normal();
            assert_eq!(x.to_bits(), b.normal().to_bits());
            sum += x;
            sum2 += x * x;
        }
        let mean = sum / n as Real;
        let var = sum2 / n as Real - mean * mean;
        assert!(mean.abs() < 0.03, "mean {mean}");
        assert!((var - 1.0).abs() < 0.05, "var {var}");
        let u = a.uniform();
        assert!((0.0..1.0).contains(&u));
    }
}
