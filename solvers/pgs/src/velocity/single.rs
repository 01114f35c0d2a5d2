//! The single-precision sweep ([`Precision::F32`](super::Precision::F32)): rows, impulses and
//! velocities in `f32`, the single-point manifolds of a colour [`WIDE`] at a time (eight
//! `f32` lanes fill one 256-bit AVX2 register).
//!
//! The island is prepared and warm-started in `f64` as always (stages 1 and 2); the sweep's
//! data are then rounded to `f32` once, the plan's batches of [`LANES`] taken two by two into
//! batches of [`WIDE`] lanes (the batches of one colour are independent, so two of them form
//! one), and the loop runs in `f32`; at its end the impulses and velocities are widened back,
//! and the final projection, the checks and the natural residual run in `f64` (stage 4). The
//! measures of a sweep are summed in `f32`, lane by lane in a fixed order, and widened for the
//! stop rule. The loop runs on the calling thread whatever [`PgsSettings::threads`] says, so
//! its result is the same bits for every thread count; it is compiled for the instruction set
//! detected at run time, the wide batches through a kernel in AVX2 intrinsics where the CPU has
//! them ([`avx2`]), else the portable loop (the same IEEE operations in the same order either
//! way: the same bits).
//!
//! [`PgsSettings::threads`]: super::PgsSettings::threads

use std::ops::Range;

#[cfg(target_arch = "x86_64")]
mod avx2;

use deepcontact_core::{ResidualNorm, SolveReport, SolverSettings};

use super::sweep::portable_batch;
use super::{
    Batch, LANES, Manifold, PgsSolver, Row, Sweep, Vel, Velocities, Verdict, judge, movable,
};

/// Lanes of a single-precision batch: two plan batches side by side.
pub(crate) const WIDE: usize = 2 * LANES;

/// A body velocity in `f32`, padded to 16 bytes and aligned to them: the AVX2 kernel moves a
/// body's velocity as one 128-bit load or store and transposes eight of them into lane
/// registers (and back), instead of 24 scalar loads and inserts; a store followed by the load
/// of the same body in a later batch is then forwarded whole.
#[derive(Debug, Clone, Copy, Default)]
#[repr(C, align(16))]
struct Vel32 {
    vx: f32,
    vy: f32,
    w: f32,
    /// Always zero (the kernel stores a zero lane here).
    pad: f32,
}

impl Vel32 {
    fn of(v: &Vel) -> Self {
        Self::new(v.vx as f32, v.vy as f32, v.w as f32)
    }

    /// The velocity `(vx, vy, ω)`.
    #[inline(always)]
    const fn new(vx: f32, vy: f32, w: f32) -> Self {
        Self {
            vx,
            vy,
            w,
            pad: 0.0,
        }
    }
}

/// A contact row in `f32` (as [`Row`]).
#[derive(Debug, Clone, Copy, Default)]
struct Row32 {
    nx: f32,
    ny: f32,
    rna: f32,
    rnb: f32,
    rta: f32,
    rtb: f32,
    normal_mass: f32,
    tangent_mass: f32,
    friction: f32,
    bias: f32,
    ln: f32,
    lt: f32,
}

impl Row32 {
    fn of(r: &Row) -> Self {
        Self {
            nx: r.nx as f32,
            ny: r.ny as f32,
            rna: r.rna as f32,
            rnb: r.rnb as f32,
            rta: r.rta as f32,
            rtb: r.rtb as f32,
            normal_mass: r.normal_mass as f32,
            tangent_mass: r.tangent_mass as f32,
            friction: r.friction as f32,
            bias: r.bias as f32,
            ln: r.ln as f32,
            lt: r.lt as f32,
        }
    }
}

/// The 2-point block solver's `K` and its inverse in `f32`.
#[derive(Debug, Clone, Copy)]
struct Block32 {
    k11: f32,
    k12: f32,
    k22: f32,
    i11: f32,
    i12: f32,
    i22: f32,
}

/// A manifold swept one at a time, in `f32` (as [`Manifold`]).
#[derive(Debug, Clone, Copy)]
struct Manifold32 {
    a: u32,
    b: u32,
    start: u32,
    count: u32,
    ma: f32,
    ia: f32,
    mb: f32,
    ib: f32,
    block: Option<Block32>,
}

impl Manifold32 {
    fn of(m: &Manifold) -> Self {
        Self {
            a: m.a,
            b: m.b,
            start: m.start,
            count: m.count,
            ma: m.ma as f32,
            ia: m.ia as f32,
            mb: m.mb as f32,
            ib: m.ib as f32,
            block: m.block.map(|k| Block32 {
                k11: k.k11 as f32,
                k12: k.k12 as f32,
                k22: k.k22 as f32,
                i11: k.i11 as f32,
                i12: k.i12 as f32,
                i22: k.i22 as f32,
            }),
        }
    }
}

/// [`WIDE`] single-point manifolds of one colour in structure of arrays (as [`Batch`]).
#[derive(Debug, Clone, Copy, Default)]
struct Batch32 {
    a: [u32; WIDE],
    b: [u32; WIDE],
    wa: [u32; WIDE],
    wb: [u32; WIDE],
    nx: [f32; WIDE],
    ny: [f32; WIDE],
    rna: [f32; WIDE],
    rnb: [f32; WIDE],
    rta: [f32; WIDE],
    rtb: [f32; WIDE],
    normal_mass: [f32; WIDE],
    tangent_mass: [f32; WIDE],
    friction: [f32; WIDE],
    bias: [f32; WIDE],
    ma: [f32; WIDE],
    ia: [f32; WIDE],
    mb: [f32; WIDE],
    ib: [f32; WIDE],
    ln: [f32; WIDE],
    lt: [f32; WIDE],
}

impl Batch32 {
    /// Plan batches `lo` and `hi` side by side; without `hi` its lanes are padding (they read
    /// the dummy body, write the sink and change nothing: every coefficient 0).
    fn of(lo: &Batch, hi: Option<&Batch>, dummy: u32, sink: u32) -> Self {
        let mut w = Self {
            a: [dummy; WIDE],
            b: [dummy; WIDE],
            wa: [sink; WIDE],
            wb: [sink; WIDE],
            ..Self::default()
        };
        for (half, src) in [(0, Some(lo)), (LANES, hi)] {
            let Some(s) = src else { continue };
            for i in 0..LANES {
                let j = half + i;
                (w.a[j], w.b[j], w.wa[j], w.wb[j]) = (s.a[i], s.b[i], s.wa[i], s.wb[i]);
                w.nx[j] = s.nx[i] as f32;
                w.ny[j] = s.ny[i] as f32;
                w.rna[j] = s.rna[i] as f32;
                w.rnb[j] = s.rnb[i] as f32;
                w.rta[j] = s.rta[i] as f32;
                w.rtb[j] = s.rtb[i] as f32;
                w.normal_mass[j] = s.normal_mass[i] as f32;
                w.tangent_mass[j] = s.tangent_mass[i] as f32;
                w.friction[j] = s.friction[i] as f32;
                w.bias[j] = s.bias[i] as f32;
                w.ma[j] = s.ma[i] as f32;
                w.ia[j] = s.ia[i] as f32;
                w.mb[j] = s.mb[i] as f32;
                w.ib[j] = s.ib[i] as f32;
                w.ln[j] = s.ln[i] as f32;
                w.lt[j] = s.lt[i] as f32;
            }
        }
        w
    }

    /// Writes the impulses of its lanes back into the plan batches it was made of.
    fn store(&self, lo: &mut Batch, hi: Option<&mut Batch>) {
        for i in 0..LANES {
            lo.ln[i] = f64::from(self.ln[i]);
            lo.lt[i] = f64::from(self.lt[i]);
        }
        if let Some(hi) = hi {
            for i in 0..LANES {
                hi.ln[i] = f64::from(self.ln[LANES + i]);
                hi.lt[i] = f64::from(self.lt[LANES + i]);
            }
        }
    }
}

/// One colour: its wide batches, then its other manifolds one at a time.
#[derive(Debug, Clone, Default)]
struct Segment32 {
    batches: Range<usize>,
    manifolds: Range<usize>,
}

/// A sweep's measures in `f32` (as [`Sweep`]).
#[derive(Debug, Clone, Copy, Default)]
struct Measures {
    max: f32,
    sum_sq: f32,
    contact_sq: f32,
}

/// [`Measures`] per lane of the wide batches.
#[derive(Debug, Clone, Copy, Default)]
struct Lanes {
    max: [f32; WIDE],
    sum_sq: [f32; WIDE],
    contact_sq: [f32; WIDE],
}

/// The single-precision copy of a prepared island, its buffers kept between solves.
#[derive(Debug, Clone, Default)]
pub(crate) struct Single {
    vel: Vec<Vel32>,
    rows: Vec<Row32>,
    manifolds: Vec<Manifold32>,
    batches: Vec<Batch32>,
    segments: Vec<Segment32>,
}

impl Single {
    /// Wide batches of the last island (tests read it to know the wide sweep ran).
    #[cfg(test)]
    pub(crate) fn wide_batches(&self) -> usize {
        self.batches.len()
    }

    /// Rounds the prepared, warm-started island of `s` to `f32`.
    fn load(&mut self, s: &PgsSolver) {
        self.vel.clear();
        self.vel.extend(s.vel.iter().map(Vel32::of));
        self.rows.clear();
        self.rows.extend(s.rows.iter().map(Row32::of));
        self.manifolds.clear();
        self.batches.clear();
        self.segments.clear();
        if s.segments.is_empty() {
            self.manifolds
                .extend(s.manifolds.iter().map(Manifold32::of));
            self.segments.push(Segment32 {
                batches: 0..0,
                manifolds: 0..self.manifolds.len(),
            });
            return;
        }
        // The plan's dummy body and sink, the last two velocity slots.
        let sink = s.vel.len() as u32 - 1;
        let dummy = sink - 1;
        for seg in &s.segments {
            let (b0, m0) = (self.batches.len(), self.manifolds.len());
            for pair in s.batches[seg.batches.clone()].chunks(2) {
                self.batches
                    .push(Batch32::of(&pair[0], pair.get(1), dummy, sink));
            }
            self.manifolds
                .extend(s.scratch[seg.manifolds.clone()].iter().map(Manifold32::of));
            self.segments.push(Segment32 {
                batches: b0..self.batches.len(),
                manifolds: m0..self.manifolds.len(),
            });
        }
    }

    /// Widens the impulses and velocities back into `s` (rows of the manifolds swept one at a
    /// time, the plan's batches, every velocity).
    fn store(&self, s: &mut PgsSolver) {
        for (v, w) in s.vel.iter_mut().zip(&self.vel) {
            (v.vx, v.vy, v.w) = (f64::from(w.vx), f64::from(w.vy), f64::from(w.w));
        }
        for m in &self.manifolds {
            for k in m.start..m.start + m.count {
                let (r, w) = (&mut s.rows[k as usize], &self.rows[k as usize]);
                (r.ln, r.lt) = (f64::from(w.ln), f64::from(w.lt));
            }
        }
        for (seg, wide) in s.segments.iter().zip(&self.segments) {
            let plan = &mut s.batches[seg.batches.clone()];
            for (pair, w) in plan.chunks_mut(2).zip(&self.batches[wide.batches.clone()]) {
                let (lo, hi) = pair.split_at_mut(1);
                w.store(&mut lo[0], hi.first_mut());
            }
        }
    }

    /// One Gauss-Seidel sweep in `f32`, the wide batches through `kernel`; its measures
    /// widened.
    #[inline(always)]
    fn iterate<const CONTACT: bool, K: WideKernel>(&mut self, kernel: K) -> Sweep {
        let mut acc = Measures::default();
        let mut lanes = Lanes::default();
        for seg in &self.segments {
            kernel.sweep::<CONTACT>(
                &mut self.batches[seg.batches.clone()],
                &mut self.vel,
                &mut lanes,
            );
            for m in &self.manifolds[seg.manifolds.clone()] {
                sweep_manifold::<CONTACT>(m, &mut self.rows, &mut self.vel, &mut acc);
            }
        }
        for i in 0..WIDE {
            acc.max = acc.max.max(lanes.max[i]);
            acc.sum_sq += lanes.sum_sq[i];
            acc.contact_sq = acc.contact_sq.max(lanes.contact_sq[i]);
        }
        Sweep {
            max: f64::from(acc.max),
            sum_sq: f64::from(acc.sum_sq),
            contact_sq: f64::from(acc.contact_sq),
        }
    }

    /// Sweeps until the stop rule holds, the cap is reached or a change is not finite.
    #[inline(always)]
    fn solve_loop<K: WideKernel>(
        &mut self,
        settings: &SolverSettings,
        report: &mut SolveReport,
        kernel: K,
    ) -> (u32, Verdict) {
        let mut it = 0;
        while it < settings.max_iterations {
            let sweep = if settings.norm == ResidualNorm::Contact {
                self.iterate::<true, K>(kernel)
            } else {
                self.iterate::<false, K>(kernel)
            };
            it += 1;
            match judge(settings, it, &sweep, Some(report)) {
                Verdict::Continue => {}
                end => return (it, end),
            }
        }
        (it, Verdict::Continue)
    }
}

/// How a sweep runs the wide batches of a colour: the portable loop ([`sweep_batch`]) or,
/// with AVX2 detected, the same operations in its intrinsics ([`avx2`], two batches side by
/// side). Both give the same bits.
trait WideKernel: Copy {
    /// Sweeps the wide batches of one colour in order on `vel`, folding their measures into
    /// `lanes`.
    fn sweep<const CONTACT: bool>(self, b: &mut [Batch32], vel: &mut [Vel32], lanes: &mut Lanes);
}

/// [`WideKernel`] of the portable loop.
#[derive(Debug, Clone, Copy)]
struct Portable;

impl WideKernel for Portable {
    #[inline(always)]
    fn sweep<const CONTACT: bool>(self, b: &mut [Batch32], vel: &mut [Vel32], lanes: &mut Lanes) {
        for batch in b {
            sweep_batch::<CONTACT, _>(batch, vel, lanes);
        }
    }
}

#[cfg(target_arch = "x86_64")]
impl WideKernel for pulp::x86::V3 {
    #[inline(always)]
    fn sweep<const CONTACT: bool>(self, b: &mut [Batch32], vel: &mut [Vel32], lanes: &mut Lanes) {
        avx2::sweep_colour::<CONTACT>(self, b, vel, lanes);
    }
}

/// [`Single::solve_loop`] as an operation of [`pulp::Arch::dispatch`]: compiled once per
/// instruction set, with that set's [`WideKernel`].
struct SolveLoop<'a, K> {
    single: &'a mut Single,
    settings: &'a SolverSettings,
    report: &'a mut SolveReport,
    kernel: K,
}

impl<K: WideKernel> pulp::WithSimd for SolveLoop<'_, K> {
    type Output = (u32, Verdict);

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _simd: S) -> Self::Output {
        self.single
            .solve_loop(self.settings, self.report, self.kernel)
    }
}

impl PgsSolver {
    /// Stage 3 in single precision on this thread: the iterations run and the verdict, the
    /// results widened back into the solver's `f64` buffers.
    pub(crate) fn run_single(
        &mut self,
        settings: &SolverSettings,
        report: &mut SolveReport,
    ) -> (u32, Verdict) {
        let mut single = std::mem::take(&mut self.single);
        single.load(self);
        let run = dispatch(self.arch, &mut single, settings, report);
        single.store(self);
        self.single = single;
        run
    }
}

/// Runs the loop of `single` compiled for `arch`: with AVX2 detected, with the intrinsics
/// kernel of [`avx2`]; otherwise with the portable loop.
#[inline]
fn dispatch(
    arch: pulp::Arch,
    single: &mut Single,
    settings: &SolverSettings,
    report: &mut SolveReport,
) -> (u32, Verdict) {
    #[cfg(target_arch = "x86_64")]
    if let pulp::Arch::V3(simd) = arch {
        return <pulp::x86::V3 as pulp::Simd>::vectorize(
            simd,
            SolveLoop {
                single,
                settings,
                report,
                kernel: simd,
            },
        );
    }
    arch.dispatch(SolveLoop {
        single,
        settings,
        report,
        kernel: Portable,
    })
}

/// `x` clamped to `[-bound, bound]` (as the `f64` sweep's `clamp_sym`).
#[inline(always)]
fn clamp_sym(x: f32, bound: f32) -> f32 {
    let lo = -bound;
    let x = if x < lo { lo } else { x };
    if x > bound { bound } else { x }
}

/// `max(x, 0)` that keeps a NaN (as the `f64` sweep's `non_negative`).
#[inline(always)]
fn non_negative(x: f32) -> f32 {
    if x < 0.0 { 0.0 } else { x }
}

portable_batch!(
    /// [`WIDE`] single-point manifolds of one colour: the `f64` batch sweep's arithmetic in
    /// `f32`.
    fn sweep_batch(f32, WIDE, Batch32, Vel32, Lanes)
);

/// Relative normal velocity of row `r`.
#[inline(always)]
fn normal_velocity(r: &Row32, va: &Vel32, vb: &Vel32) -> f32 {
    (vb.vx - va.vx) * r.nx + (vb.vy - va.vy) * r.ny + vb.w * r.rnb - va.w * r.rna
}

/// Applies a normal impulse change `dn` of row `r`.
#[inline(always)]
fn apply_normal(m: &Manifold32, r: &Row32, va: &mut Vel32, vb: &mut Vel32, dn: f32) {
    let (px, py) = (dn * r.nx, dn * r.ny);
    va.vx -= m.ma * px;
    va.vy -= m.ma * py;
    va.w -= m.ia * (dn * r.rna);
    vb.vx += m.mb * px;
    vb.vy += m.mb * py;
    vb.w += m.ib * (dn * r.rnb);
}

/// One manifold's rows, friction first, then the normal rows (the block solver for a 2-point
/// manifold that has one): the `f64` sweep's arithmetic in `f32`.
#[inline(always)]
fn sweep_manifold<const CONTACT: bool>(
    m: &Manifold32,
    rows: &mut [Row32],
    vel: &mut [Vel32],
    acc: &mut Measures,
) {
    let rows = &mut rows[m.start as usize..(m.start + m.count) as usize];
    let (mut mx, mut sq, mut cs) = (acc.max, acc.sum_sq, acc.contact_sq);
    let (mut va, mut vb) = (vel[m.a as usize], vel[m.b as usize]);
    let (mut t_pos, mut n_one) = (0.0f32, 0.0f32);
    for r in rows.iter_mut() {
        let vt = (vb.vx - va.vx) * -r.ny + (vb.vy - va.vy) * r.nx + vb.w * r.rtb - va.w * r.rta;
        let new = clamp_sym(r.lt - r.tangent_mass * vt, r.friction * r.ln);
        let d = new - r.lt;
        r.lt = new;
        let (px, py) = (d * -r.ny, d * r.nx);
        va.vx -= m.ma * px;
        va.vy -= m.ma * py;
        va.w -= m.ia * (d * r.rta);
        vb.vx += m.mb * px;
        vb.vy += m.mb * py;
        vb.w += m.ib * (d * r.rtb);
        mx = mx.max(d.abs());
        sq += d * d;
        if CONTACT {
            t_pos = t_pos.max(d);
        }
    }
    if let Some(k) = &m.block {
        let (d1, d2) = solve_block(m, rows, k, &mut va, &mut vb);
        mx = mx.max(d1.abs()).max(d2.abs());
        sq += d1 * d1 + d2 * d2;
    } else {
        for r in rows.iter_mut() {
            let vn = normal_velocity(r, &va, &vb);
            let new = non_negative(r.ln - r.normal_mass * (vn - r.bias));
            let d = new - r.ln;
            r.ln = new;
            apply_normal(m, r, &mut va, &mut vb, d);
            mx = mx.max(d.abs());
            sq += d * d;
            n_one = d;
        }
        if m.count != 1 {
            n_one = 0.0;
        }
    }
    if CONTACT {
        cs = cs.max(n_one * n_one + t_pos * t_pos);
    }
    (acc.max, acc.sum_sq, acc.contact_sq) = (mx, sq, cs);
    if movable(f64::from(m.ma), f64::from(m.ia)) {
        vel[m.a as usize] = va;
    }
    if movable(f64::from(m.mb), f64::from(m.ib)) {
        vel[m.b as usize] = vb;
    }
}

/// Box2D v2.4's 2-point block solver in `f32` (the `f64` sweep's `solve_block`).
#[inline]
fn solve_block(
    m: &Manifold32,
    rows: &mut [Row32],
    k: &Block32,
    va: &mut Vel32,
    vb: &mut Vel32,
) -> (f32, f32) {
    let (r1, r2) = (rows[0], rows[1]);
    let (a1, a2) = (r1.ln, r2.ln);
    let b1 = normal_velocity(&r1, va, vb) - r1.bias - (k.k11 * a1 + k.k12 * a2);
    let b2 = normal_velocity(&r2, va, vb) - r2.bias - (k.k12 * a1 + k.k22 * a2);
    let candidates = [
        (-(k.i11 * b1 + k.i12 * b2), -(k.i12 * b1 + k.i22 * b2)),
        (-r1.normal_mass * b1, 0.0),
        (0.0, -r2.normal_mass * b2),
        (0.0, 0.0),
    ];
    let mut x = (a1, a2);
    for (case, &(x1, x2)) in candidates.iter().enumerate() {
        let vn1 = k.k11 * x1 + k.k12 * x2 + b1;
        let vn2 = k.k12 * x1 + k.k22 * x2 + b2;
        let ok = match case {
            0 => x1 >= 0.0 && x2 >= 0.0,
            1 => x1 >= 0.0 && vn2 >= 0.0,
            2 => x2 >= 0.0 && vn1 >= 0.0,
            _ => b1 >= 0.0 && b2 >= 0.0,
        };
        if ok {
            x = (x1, x2);
            break;
        }
    }
    let (d1, d2) = (x.0 - a1, x.1 - a2);
    rows[0].ln = x.0;
    rows[1].ln = x.1;
    apply_normal(m, &r1, va, vb, d1);
    apply_normal(m, &r2, va, vb, d2);
    (d1, d2)
}
