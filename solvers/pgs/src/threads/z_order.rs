//! Z-order (Morton) keys of contact points, to put neighbours next to each other in memory.

use deepcontact_core::math::{Real, Vector};
use deepcontact_core::{ContactPoint, ProblemBody};

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

/// A renumbering of an island's bodies in Z-order of their positions, so that neighbours lie
/// close together in memory: `body_of[new]` is the problem's index of body `new`,
/// `new_index[old]` its new index (both buffers reused).
#[derive(Debug, Clone, Default)]
pub(crate) struct Renumbering {
    pub(crate) body_of: Vec<u32>,
    pub(crate) new_index: Vec<u32>,
}

impl Renumbering {
    /// Renumbers `bodies` on the grid of `z`.
    pub(crate) fn build(&mut self, z: &ZOrder, bodies: &[ProblemBody]) {
        self.body_of.clear();
        self.body_of.extend(0..bodies.len() as u32);
        self.body_of
            .sort_by_cached_key(|&b| z.key(&bodies[b as usize].position));
        self.new_index.clear();
        self.new_index.resize(bodies.len(), 0);
        for (new, &old) in self.body_of.iter().enumerate() {
            self.new_index[old as usize] = new as u32;
        }
    }

    /// Forgets the renumbering (bodies in the problem's order).
    pub(crate) fn clear(&mut self) {
        self.body_of.clear();
        self.new_index.clear();
    }

    /// Whether bodies are renumbered.
    pub(crate) fn is_active(&self) -> bool {
        !self.body_of.is_empty()
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
    fn renumbering_is_a_permutation_and_its_inverse() {
        let body = |x: Real, y: Real| ProblemBody {
            world_index: 0,
            position: Vector::new(x, y),
            angle: 0.0,
            linear_velocity: Vector::zeros(),
            angular_velocity: 0.0,
            inv_mass: 1.0,
            inv_inertia: 1.0,
        };
        // Four corners of a square, given far corner first: Z-order visits (0,0), (1,0),
        // (0,1), (1,1).
        let bodies = [
            body(1.0, 1.0),
            body(0.0, 1.0),
            body(1.0, 0.0),
            body(0.0, 0.0),
        ];
        let z = ZOrder {
            lo: Vector::zeros(),
            scale: Vector::repeat(65535.0),
        };
        let mut r = Renumbering::default();
        r.build(&z, &bodies);
        assert_eq!(r.body_of, [3, 2, 1, 0]);
        for (new, &old) in r.body_of.iter().enumerate() {
            assert_eq!(r.new_index[old as usize], new as u32);
        }
    }

    #[test]
    fn interleave_puts_x_in_the_even_bits_and_y_in_the_odd() {
        assert_eq!(interleave(1, 0), 1);
        assert_eq!(interleave(0, 1), 2);
        assert_eq!(interleave(3, 3), 15);
        assert_eq!(interleave(0xffff, 0), 0x5555_5555);
        assert_eq!(interleave(0xffff, 0xffff), 0xffff_ffff);
    }
}
