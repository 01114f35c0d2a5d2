//! Z-order (Morton) keys of contact points, to put neighbours next to each other in memory.

use deepcontact_core::ContactPoint;
use deepcontact_core::math::{Real, Vector};

/// The Z-order of points in the bounding box of an island's contact points, on a 65 536 ×
/// 65 536 grid.
#[derive(Debug, Clone, Copy)]
pub(crate) struct ZOrder {
    lo: Vector,
    scale: Vector,
}

impl ZOrder {
    /// The grid over the bounding box of `points`.
    pub(crate) fn of(points: &[ContactPoint]) -> Self {
        let (mut lo, mut hi) = (
            Vector::repeat(Real::INFINITY),
            Vector::repeat(-Real::INFINITY),
        );
        for p in points {
            lo = lo.inf(&p.point);
            hi = hi.sup(&p.point);
        }
        let scale = (hi - lo).map(|e| if e > 0.0 { 65535.0 / e } else { 0.0 });
        Self { lo, scale }
    }

    /// The key of `p` (a non-finite point gets some key; it is rejected elsewhere).
    pub(crate) fn key(&self, p: &Vector) -> u64 {
        let d = p - self.lo;
        let cell = |x: Real, s: Real| (x * s).clamp(0.0, 65535.0) as u32;
        interleave(cell(d.x, self.scale.x), cell(d.y, self.scale.y))
    }
}

/// The bits of two 16-bit cells `(x, y)` interleaved, x in the even bits.
fn interleave(x: u32, y: u32) -> u64 {
    let spread = |v: u32| {
        let mut v = u64::from(v & 0xffff);
        v = (v | (v << 8)) & 0x00ff_00ff;
        v = (v | (v << 4)) & 0x0f0f_0f0f;
        v = (v | (v << 2)) & 0x3333_3333;
        (v | (v << 1)) & 0x5555_5555
    };
    spread(x) | (spread(y) << 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interleave_puts_x_in_the_even_bits_and_y_in_the_odd() {
        assert_eq!(interleave(1, 0), 1);
        assert_eq!(interleave(0, 1), 2);
        assert_eq!(interleave(3, 3), 15);
        assert_eq!(interleave(0xffff, 0), 0x5555_5555);
        assert_eq!(interleave(0xffff, 0xffff), 0xffff_ffff);
    }
}
