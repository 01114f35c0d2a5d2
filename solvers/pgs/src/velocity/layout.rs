//! The data of a velocity solve laid out for its loops: rows, manifolds, the
//! structure-of-arrays batches of single-point manifolds, and body velocities.

use deepcontact_core::Impulse;
use deepcontact_core::math::{Real, cross};

/// One contact point laid out for the solver loop.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Row {
    pub(super) nx: Real,
    pub(super) ny: Real,
    pub(super) rna: Real,
    pub(super) rnb: Real,
    pub(super) rta: Real,
    pub(super) rtb: Real,
    pub(super) normal_mass: Real,
    pub(super) tangent_mass: Real,
    pub(super) friction: Real,
    pub(super) bias: Real,
    pub(super) ln: Real,
    pub(super) lt: Real,
}

impl Row {
    /// Point `p`'s row, starting from `s` projected onto the cone λn ≥ 0, |λt| ≤ μ λn (with
    /// `raw`, the tangent as given); a NaN start passes through to the non-finite check of
    /// the first sweep (a negative bound would make the friction clamp panic).
    #[inline]
    pub(super) fn of(p: &deepcontact_core::ContactPoint, s: &Impulse, raw: bool) -> Self {
        let t = p.tangent();
        let (start_normal, start_tangent) = Self::start(s, p.friction, raw);
        Row {
            nx: p.normal.x,
            ny: p.normal.y,
            rna: cross(&p.r_a, &p.normal),
            rnb: cross(&p.r_b, &p.normal),
            rta: cross(&p.r_a, &t),
            rtb: cross(&p.r_b, &t),
            normal_mass: p.normal_mass,
            tangent_mass: p.tangent_mass,
            friction: p.friction,
            bias: p.velocity_bias,
            ln: start_normal,
            lt: start_tangent,
        }
    }

    /// The start `s` as a row holds it: the normal impulse clamped at 0, the tangent one
    /// into the cone of `friction` (left as given when `raw`).
    pub(super) fn start(s: &Impulse, friction: Real, raw: bool) -> (Real, Real) {
        let normal = if s.normal < 0.0 { 0.0 } else { s.normal };
        let bound = friction * normal;
        let tangent = if raw {
            s.tangent
        } else if s.tangent > bound {
            bound
        } else if s.tangent < -bound {
            -bound
        } else {
            s.tangent
        };
        (normal, tangent)
    }
}

/// One manifold: its body pair with their inverse masses, its rows, and block-solver data.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Manifold {
    pub(crate) a: u32,
    pub(crate) b: u32,
    pub(crate) start: u32,
    pub(crate) count: u32,
    pub(crate) ma: Real,
    pub(crate) ia: Real,
    pub(crate) mb: Real,
    pub(crate) ib: Real,
    pub(crate) block: Option<Block>,
}

/// Block-solver data of a 2-point manifold: `K` and its inverse.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Block {
    pub(super) k11: Real,
    pub(super) k12: Real,
    pub(super) k22: Real,
    pub(super) i11: Real,
    pub(super) i12: Real,
    pub(super) i22: Real,
}

/// Manifolds solved side by side in one batch.
pub const LANES: usize = 4;

/// [`LANES`] single-point manifolds of one colour in structure-of-arrays form: each field
/// holds one value per lane. Padding lanes point at a dummy immovable body with zero masses,
/// so their impulse changes are exactly zero.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Batch {
    pub(super) a: [u32; LANES],
    pub(super) b: [u32; LANES],
    /// Where each lane's new velocity of `a` (of `b`) is stored: the body itself when it is
    /// movable, else a sink slot that nothing reads (so the scatter needs no branch; an
    /// immovable body is never written, and padding lanes write the sink too).
    pub(super) wa: [u32; LANES],
    pub(super) wb: [u32; LANES],
    /// Row of each lane in `rows` (`u32::MAX` for padding).
    pub(super) row: [u32; LANES],
    pub(super) nx: [Real; LANES],
    pub(super) ny: [Real; LANES],
    pub(super) rna: [Real; LANES],
    pub(super) rnb: [Real; LANES],
    pub(super) rta: [Real; LANES],
    pub(super) rtb: [Real; LANES],
    pub(super) normal_mass: [Real; LANES],
    pub(super) tangent_mass: [Real; LANES],
    pub(super) friction: [Real; LANES],
    pub(super) bias: [Real; LANES],
    pub(super) ma: [Real; LANES],
    pub(super) ia: [Real; LANES],
    pub(super) mb: [Real; LANES],
    pub(super) ib: [Real; LANES],
    pub(super) ln: [Real; LANES],
    pub(super) lt: [Real; LANES],
}

impl Batch {
    /// A batch of padding lanes only: reading the `dummy` body, writing the `sink`.
    pub(crate) fn empty(dummy: u32, sink: u32) -> Self {
        Batch {
            a: [dummy; LANES],
            b: [dummy; LANES],
            wa: [sink; LANES],
            wb: [sink; LANES],
            row: [u32::MAX; LANES],
            ..Batch::default()
        }
    }

    /// Lane `to` becomes lane `from` of `src`, its bodies and write targets moved by
    /// `offset` slots (the source island's velocities placed `offset` slots in).
    pub(crate) fn set_lane(&mut self, to: usize, src: &Batch, from: usize, offset: u32) {
        self.a[to] = src.a[from] + offset;
        self.b[to] = src.b[from] + offset;
        self.wa[to] = src.wa[from] + offset;
        self.wb[to] = src.wb[from] + offset;
        self.row[to] = src.row[from];
        for (dst, src) in [
            (&mut self.nx, &src.nx),
            (&mut self.ny, &src.ny),
            (&mut self.rna, &src.rna),
            (&mut self.rnb, &src.rnb),
            (&mut self.rta, &src.rta),
            (&mut self.rtb, &src.rtb),
            (&mut self.normal_mass, &src.normal_mass),
            (&mut self.tangent_mass, &src.tangent_mass),
            (&mut self.friction, &src.friction),
            (&mut self.bias, &src.bias),
            (&mut self.ma, &src.ma),
            (&mut self.ia, &src.ia),
            (&mut self.mb, &src.mb),
            (&mut self.ib, &src.ib),
            (&mut self.ln, &src.ln),
            (&mut self.lt, &src.lt),
        ] {
            dst[to] = src[from];
        }
    }

    /// How many lanes hold a manifold (they come first; the rest are padding).
    pub(crate) fn width(&self) -> usize {
        self.row.iter().take_while(|&&r| r != u32::MAX).count()
    }

    /// The impulses of lane `from` of `src` into lane `to` (all a sweep changes in a batch).
    pub(crate) fn set_impulses(&mut self, to: usize, src: &Batch, from: usize) {
        self.ln[to] = src.ln[from];
        self.lt[to] = src.lt[from];
    }
}

/// One colour of the sweep: its batches, then its other manifolds one at a time.
#[derive(Debug, Clone, Default)]
pub(crate) struct Segment {
    pub(crate) batches: std::ops::Range<usize>,
    pub(crate) manifolds: std::ops::Range<usize>,
}

/// Velocity `(vx, vy, ω)` of one body, aligned to 32 bytes (8 of padding): the AVX2 kernel
/// moves `(vx, vy)` as one 128-bit load or store, which at a 24-byte stride would be
/// misaligned for every other body and split across two cache lines for one in eight
/// (aligned: 0.97–0.99 × the `f64` pass, `pgs_speed`; CHANGELOG.md, 2026-12-02).
#[derive(Debug, Clone, Copy, Default)]
#[repr(C, align(32))]
pub(crate) struct Vel {
    pub(crate) vx: Real,
    pub(crate) vy: Real,
    pub(crate) w: Real,
}

impl Vel {
    /// The velocity `(vx, vy, ω)`.
    #[inline(always)]
    pub(crate) const fn new(vx: Real, vy: Real, w: Real) -> Self {
        Self { vx, vy, w }
    }
}
