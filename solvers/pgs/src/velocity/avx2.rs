//! The batch sweep ([`super::sweep_batch`]) written out in AVX2 intrinsics, two batches at
//! a time. Each lane field of a [`Batch`] is one 256-bit register. One batch is a chain of
//! about eighty dependent operations (gather, friction row, normal row, scatter) and some two
//! hundred instructions, so the out-of-order window holds little more than one: running two
//! batches of a colour side by side (they share no movable body) lets their chains overlap.
//! The compiler's own vectorisation of the portable loop does not survive that restructuring,
//! hence the intrinsics. Two small islands are swept the same way, the k-th batch of one
//! beside the k-th of the other ([`sweep_two`], for [`crate::velocity::many`]). Every
//! arithmetic operation is the portable loop's, in its order, on the same IEEE doubles (no
//! fused multiply-add), and the measures are folded batch by batch, so the bits are the same.
//!
//! With sixteen registers the two batches in flight do not fit, and what does not fit is
//! spilled to the stack: a store each, and the store port (on first-generation Zen one store
//! a cycle, two for a 256-bit register) is where the sweep waits. So the second batch is
//! gathered only after the first's friction row, the first is scattered before the second's
//! normal row, and the normal row reloads the batch's fields rather than keeping the friction
//! row's loads alive across the other batch (see `normal`). A body's `(vx, vy)` moves as one 128-bit load or
//! store. Together: 0.83–0.94 × the time of a pass at 100 and 1 000 bodies in both
//! precisions (`pgs_speed`; CHANGELOG.md, 2026-12-02).

use core::arch::x86_64::{__m128d, __m256d};

use pulp::x86::V3;

use super::{Batch, Island, LANES, LaneSweep, Vel};

/// The AVX2 batch kernel of one precision, written once for both: the `f64` one here (four
/// lanes of [`Batch`]) and the `f32` one of [`super::single`] (eight lanes of its wide
/// batches). It defines, in the module that invokes it, `scatter`, the lane registers of a
/// batch in flight (`InFlight`), the arithmetic (`Ops`, one method per operation over the
/// given `_mm256_*` intrinsics), the rows of a batch (`start`, `friction`, `normal`,
/// `finish`), `sweep_one` and `sweep_colour`: the batches of one colour in order, two at a
/// time. The module supplies `gather` (the bodies' velocities at a batch's indices as three
/// lane registers) and `scatter` (the reverse, in lane order).
///
/// The arguments: `sweep_colour`'s visibility; the register type, the scalar type, the lane
/// count, the batch, velocity and per-lane measures types; then the nine intrinsics (`set1`,
/// `setzero`, `add`, `sub`, `mul`, `max`, `min`, `xor`, `andnot`). Each lane's operations are
/// the same, in the same order, whatever the width.
macro_rules! avx2_kernel {
    (
        $vis:vis fn sweep_colour(
            $reg:ty,
            $real:ty,
            $width:ident,
            $batch:ty,
            $vel:ident,
            $lanes:ty $(,)?
        ),
        [$set1:ident, $setzero:ident, $add:ident, $sub:ident, $mul:ident, $max:ident, $min:ident,
         $xor:ident, $andnot:ident $(,)?] $(,)?
    ) => {
        /// The lane registers of one batch in flight: the gathered velocities of its bodies
        /// and the changes of its two rows.
        struct InFlight {
            a: [$reg; 3],
            b: [$reg; 3],
            dt: $reg,
            dn: $reg,
        }

        /// The arithmetic of a batch: the AVX2 token and the two constants it needs, with one
        /// method per operation (methods, not closures: a closure is compiled outside the AVX2
        /// context).
        #[derive(Clone, Copy)]
        struct Ops {
            simd: V3,
            sign: $reg,
            zero: $reg,
        }

        impl Ops {
            #[inline(always)]
            fn new(simd: V3) -> Self {
                Self {
                    simd,
                    sign: simd.avx.$set1(-0.0),
                    zero: simd.avx.$setzero(),
                }
            }
            #[inline(always)]
            fn add(self, x: $reg, y: $reg) -> $reg {
                self.simd.avx.$add(x, y)
            }
            #[inline(always)]
            fn sub(self, x: $reg, y: $reg) -> $reg {
                self.simd.avx.$sub(x, y)
            }
            #[inline(always)]
            fn mul(self, x: $reg, y: $reg) -> $reg {
                self.simd.avx.$mul(x, y)
            }
            /// `x > y ? x : y` per lane (`max` returns the second operand when either is NaN
            /// or both are equal).
            #[inline(always)]
            fn gt(self, x: $reg, y: $reg) -> $reg {
                self.simd.avx.$max(x, y)
            }
            /// `x < y ? x : y` per lane.
            #[inline(always)]
            fn lt(self, x: $reg, y: $reg) -> $reg {
                self.simd.avx.$min(x, y)
            }
            #[inline(always)]
            fn neg(self, x: $reg) -> $reg {
                self.simd.avx.$xor(x, self.sign)
            }
            #[inline(always)]
            fn abs(self, x: $reg) -> $reg {
                self.simd.avx.$andnot(self.sign, x)
            }
        }

        #[inline(always)]
        fn ld(x: &[$real; $width]) -> $reg {
            pulp::cast(*x)
        }

        /// Gathers batch `b`'s body velocities.
        #[inline(always)]
        fn start(o: Ops, b: &$batch, vel: &[$vel]) -> InFlight {
            InFlight {
                a: gather(o.simd, vel, &b.a),
                b: gather(o.simd, vel, &b.b),
                dt: o.zero,
                dn: o.zero,
            }
        }

        /// `apply_normal`/`apply_tangent` of the change `d` along direction `(dx, dy)` with
        /// arms `(ra, rb)`.
        #[inline(always)]
        fn apply(
            o: Ops,
            b: &$batch,
            s: &mut InFlight,
            d: $reg,
            dir: ($reg, $reg),
            arm: ($reg, $reg),
        ) {
            let (px, py) = (o.mul(d, dir.0), o.mul(d, dir.1));
            let (ma, ia, mb, ib) = (ld(&b.ma), ld(&b.ia), ld(&b.mb), ld(&b.ib));
            s.a[0] = o.sub(s.a[0], o.mul(ma, px));
            s.a[1] = o.sub(s.a[1], o.mul(ma, py));
            s.a[2] = o.sub(s.a[2], o.mul(ia, o.mul(d, arm.0)));
            s.b[0] = o.add(s.b[0], o.mul(mb, px));
            s.b[1] = o.add(s.b[1], o.mul(mb, py));
            s.b[2] = o.add(s.b[2], o.mul(ib, o.mul(d, arm.1)));
        }

        /// The relative velocity `(vB − vA)·dir + ωB rb − ωA ra`, in the portable loop's
        /// order.
        #[inline(always)]
        fn relative(o: Ops, s: &InFlight, dir: ($reg, $reg), arm: ($reg, $reg)) -> $reg {
            o.sub(
                o.add(
                    o.add(
                        o.mul(o.sub(s.b[0], s.a[0]), dir.0),
                        o.mul(o.sub(s.b[1], s.a[1]), dir.1),
                    ),
                    o.mul(s.b[2], arm.1),
                ),
                o.mul(s.a[2], arm.0),
            )
        }

        /// Friction rows: `tangent_velocity`, `clamp_sym`, then `apply_tangent`.
        #[inline(always)]
        fn friction(o: Ops, b: &mut $batch, s: &mut InFlight) {
            let (nx, ny) = (ld(&b.nx), ld(&b.ny));
            let dir = (o.neg(ny), nx);
            let arm = (ld(&b.rta), ld(&b.rtb));
            let lt0 = ld(&b.lt);
            let vt = relative(o, s, dir, arm);
            let bound = o.mul(ld(&b.friction), ld(&b.ln));
            let x = o.sub(lt0, o.mul(ld(&b.tangent_mass), vt));
            // clamp_sym: `x < -bound ? -bound : x`, then `x > bound ? bound : x`.
            let new = o.lt(bound, o.gt(o.neg(bound), x));
            let d = o.sub(new, lt0);
            b.lt = pulp::cast(new);
            apply(o, b, s, d, dir, arm);
            s.dt = d;
        }

        /// Normal rows: `normal_velocity`, `non_negative`, then `apply_normal`.
        #[inline(always)]
        fn normal(o: Ops, b: &mut $batch, s: &mut InFlight) {
            // An opaque reference: the compiler cannot reuse the friction row's loads of the
            // same fields, so it reloads them here instead of spilling them while the other
            // batch runs (a load is cheaper than a spill's store; the values are the same).
            let b = std::hint::black_box(b);
            let dir = (ld(&b.nx), ld(&b.ny));
            let arm = (ld(&b.rna), ld(&b.rnb));
            let ln0 = ld(&b.ln);
            let vn = relative(o, s, dir, arm);
            let new = o.gt(
                o.zero,
                o.sub(ln0, o.mul(ld(&b.normal_mass), o.sub(vn, ld(&b.bias)))),
            );
            let d = o.sub(new, ln0);
            b.ln = pulp::cast(new);
            apply(o, b, s, d, dir, arm);
            s.dn = d;
        }

        /// Scatters the movable bodies back (immovable and padding lanes into the sink) and
        /// folds the batch's measures into `lanes`, friction before normal.
        #[inline(always)]
        fn finish<const CONTACT: bool>(
            o: Ops,
            b: &$batch,
            s: InFlight,
            vel: &mut [$vel],
            lanes: &mut $lanes,
        ) {
            scatter(o.simd, vel, &b.wa, s.a);
            scatter(o.simd, vel, &b.wb, s.b);
            let (mut max, mut sum_sq) = (ld(&lanes.max), ld(&lanes.sum_sq));
            for d in [s.dt, s.dn] {
                max = o.gt(o.abs(d), max);
                sum_sq = o.add(sum_sq, o.mul(d, d));
            }
            lanes.max = pulp::cast(max);
            lanes.sum_sq = pulp::cast(sum_sq);
            if CONTACT {
                let t_pos = o.gt(s.dt, o.zero);
                let c = o.add(o.mul(s.dn, s.dn), o.mul(t_pos, t_pos));
                lanes.contact_sq = pulp::cast(o.gt(c, ld(&lanes.contact_sq)));
            }
        }

        /// One batch alone.
        #[inline(always)]
        fn sweep_one<const CONTACT: bool>(
            o: Ops,
            b: &mut $batch,
            vel: &mut [$vel],
            lanes: &mut $lanes,
        ) {
            let mut s = start(o, b, vel);
            friction(o, b, &mut s);
            normal(o, b, &mut s);
            finish::<CONTACT>(o, b, s, vel, lanes);
        }

        /// The batches of one colour in order, two at a time: the second's dependent chain
        /// runs beside the first's (they share no movable body; three or four at a time spill
        /// registers), the measures folded batch by batch. The second is gathered after the
        /// first's friction row and the first finished before the second's normal row, so
        /// that fewer registers are live at once (the bits do not depend on it: the two share
        /// no movable body, and the measures are folded first, then second).
        #[inline(always)]
        $vis fn sweep_colour<const CONTACT: bool>(
            simd: V3,
            batches: &mut [$batch],
            vel: &mut [$vel],
            lanes: &mut $lanes,
        ) {
            let o = Ops::new(simd);
            let mut pairs = batches.chunks_exact_mut(2);
            for pair in &mut pairs {
                let [b0, b1] = pair else {
                    unreachable!("chunks of two")
                };
                let mut s0 = start(o, b0, vel);
                friction(o, b0, &mut s0);
                let mut s1 = start(o, b1, vel);
                friction(o, b1, &mut s1);
                normal(o, b0, &mut s0);
                finish::<CONTACT>(o, b0, s0, vel, lanes);
                normal(o, b1, &mut s1);
                finish::<CONTACT>(o, b1, s1, vel, lanes);
            }
            for b in pairs.into_remainder() {
                sweep_one::<CONTACT>(o, b, vel, lanes);
            }
        }
    };
}
pub(super) use avx2_kernel;

/// One body's `(vx, vy)` as a 128-bit register.
#[inline(always)]
fn pair(v: &Vel) -> __m128d {
    pulp::cast([v.vx, v.vy])
}

/// [`gather`] reversed: `(vx, vy)` of a body interleaved back into one 128-bit register and
/// stored whole, `ω` stored alone, in lane order.
#[inline(always)]
fn scatter(simd: V3, vel: &mut [Vel], index: &[u32; LANES], [vx, vy, w]: [__m256d; 3]) {
    let avx = simd.avx;
    // (vx₀ vy₀ | vx₂ vy₂), (vx₁ vy₁ | vx₃ vy₃).
    let xy02 = avx._mm256_unpacklo_pd(vx, vy);
    let xy13 = avx._mm256_unpackhi_pd(vx, vy);
    let xy: [__m128d; LANES] = [
        avx._mm256_castpd256_pd128(xy02),
        avx._mm256_castpd256_pd128(xy13),
        avx._mm256_extractf128_pd::<1>(xy02),
        avx._mm256_extractf128_pd::<1>(xy13),
    ];
    let w: [f64; LANES] = pulp::cast(w);
    for (lane, &i) in index.iter().enumerate() {
        let [vx, vy]: [f64; 2] = pulp::cast(xy[lane]);
        vel[i as usize] = Vel::new(vx, vy, w[lane]);
    }
}

/// The velocities of four bodies as three registers `(vx₀..₃)`, `(vy₀..₃)`, `(ω₀..₃)`: a
/// body's `(vx, vy)` as one 128-bit load, bodies `k` and `k + 2` paired in a 256-bit
/// register, then one unpack each for `vx` and `vy`; the `ω` one at a time.
#[inline(always)]
fn gather(simd: V3, vel: &[Vel], index: &[u32; LANES]) -> [__m256d; 3] {
    let avx = simd.avx;
    // A closure holding no intrinsics (one that did would be compiled outside the AVX2
    // context, its intrinsics calls).
    let at = |lane: usize| &vel[index[lane] as usize];
    let (v0, v1, v2, v3) = (at(0), at(1), at(2), at(3));
    // (vx₀ vy₀ | vx₂ vy₂), (vx₁ vy₁ | vx₃ vy₃).
    let xy02 = avx._mm256_set_m128d(pair(v2), pair(v0));
    let xy13 = avx._mm256_set_m128d(pair(v3), pair(v1));
    [
        avx._mm256_unpacklo_pd(xy02, xy13),
        avx._mm256_unpackhi_pd(xy02, xy13),
        pulp::cast(pulp::f64x4(v0.w, v1.w, v2.w, v3.w)),
    ]
}

avx2_kernel!(
    pub(crate) fn sweep_colour(__m256d, f64, LANES, Batch, Vel, LaneSweep),
    [
        _mm256_set1_pd,
        _mm256_setzero_pd,
        _mm256_add_pd,
        _mm256_sub_pd,
        _mm256_mul_pd,
        _mm256_max_pd,
        _mm256_min_pd,
        _mm256_xor_pd,
        _mm256_andnot_pd,
    ],
);

/// The batches of two islands side by side, the k-th of one beside the k-th of the other
/// (the islands share nothing), each island's batches in their order and its measures folded
/// batch by batch; the longer island's remaining batches one at a time.
#[inline(always)]
pub(crate) fn sweep_two<const CONTACT: bool>(simd: V3, a: Island<'_>, b: Island<'_>) {
    let o = Ops::new(simd);
    let n = a.batches.len().min(b.batches.len());
    let (head_a, tail_a) = a.batches.split_at_mut(n);
    let (head_b, tail_b) = b.batches.split_at_mut(n);
    for (x, y) in head_a.iter_mut().zip(head_b.iter_mut()) {
        let mut sx = start(o, x, a.vel);
        friction(o, x, &mut sx);
        let mut sy = start(o, y, b.vel);
        friction(o, y, &mut sy);
        normal(o, x, &mut sx);
        finish::<CONTACT>(o, x, sx, a.vel, a.lanes);
        normal(o, y, &mut sy);
        finish::<CONTACT>(o, y, sy, b.vel, b.lanes);
    }
    for (batches, vel, lanes) in [
        (tail_a, &mut *a.vel, &mut *a.lanes),
        (tail_b, b.vel, b.lanes),
    ] {
        for x in batches {
            sweep_one::<CONTACT>(o, x, vel, lanes);
        }
    }
}

#[cfg(test)]
mod tests {
    use deepcontact_core::rng::PortableRng;

    use super::*;
    use crate::velocity::BatchKernel;
    use crate::velocity::kernel::Portable;

    /// `n` random batches of one colour over `bodies` bodies (each movable body in at most
    /// one lane; some lanes immovable or padding), with the odd special value a start or a
    /// velocity can carry (a NaN, a negative zero, a zero friction bound).
    fn colour(rng: &mut PortableRng, n: usize, bodies: u32) -> (Vec<Batch>, Vec<Vel>) {
        let (dummy, sink) = (bodies, bodies + 1);
        let mut vel: Vec<Vel> = (0..bodies)
            .map(|_| Vel {
                vx: rng.uniform_range(-2.0, 2.0),
                vy: rng.uniform_range(-2.0, 2.0),
                w: rng.uniform_range(-5.0, 5.0),
            })
            .collect();
        vel.extend([Vel::default(); 2]);
        let mut next = 0;
        let mut batches = Vec::new();
        for _ in 0..n {
            let mut b = Batch::empty(dummy, sink);
            for lane in 0..LANES {
                if rng.uniform() < 0.1 {
                    continue; // padding
                }
                let (a, bb) = (next, next + 1);
                next += 2;
                let a_moves = rng.uniform() < 0.8;
                b.a[lane] = a;
                b.b[lane] = bb;
                b.wa[lane] = if a_moves { a } else { sink };
                b.wb[lane] = bb;
                b.row[lane] = lane as u32;
                let angle = rng.uniform_range(0.0, std::f64::consts::TAU);
                (b.nx[lane], b.ny[lane]) = (angle.cos(), angle.sin());
                for f in [&mut b.rna, &mut b.rnb, &mut b.rta, &mut b.rtb] {
                    f[lane] = rng.uniform_range(-0.5, 0.5);
                }
                b.normal_mass[lane] = rng.uniform_range(0.1, 2.0);
                b.tangent_mass[lane] = rng.uniform_range(0.1, 2.0);
                b.friction[lane] = if rng.uniform() < 0.1 { 0.0 } else { 0.6 };
                b.bias[lane] = rng.uniform_range(-0.1, 0.1);
                (b.ma[lane], b.ia[lane]) = if a_moves { (1.0, 2.0) } else { (0.0, 0.0) };
                (b.mb[lane], b.ib[lane]) = (rng.uniform_range(0.5, 2.0), 3.0);
                b.ln[lane] = match rng.next_u64() % 8 {
                    0 => f64::NAN,
                    1 => -0.0,
                    _ => rng.uniform_range(0.0, 3.0),
                };
                b.lt[lane] = rng.uniform_range(-1.0, 1.0);
            }
            batches.push(b);
        }
        (batches, vel)
    }

    #[test]
    fn avx2_pairs_are_bit_identical_to_the_portable_loop_on_random_colours() {
        // CI's machines have AVX2: there a missing AVX2 is a failure, not a pass that
        // compared nothing.
        let Some(simd) = V3::try_new() else {
            assert!(
                std::env::var("CI").as_deref() != Ok("true"),
                "CI=true on a machine without AVX2 + FMA: the AVX2 kernel is not tested"
            );
            eprintln!("no AVX2 on this machine: nothing to compare");
            return;
        };
        let bits = |x: &[f64]| x.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        let mut rng = PortableRng::new(7);
        // Odd and even counts: pairs, and a last batch alone.
        for n in [1, 2, 3, 6, 7] {
            for contact in [false, true] {
                let (batches, vel) = colour(&mut rng, n, 8 * n as u32);
                let run = |fast: bool| {
                    let (mut batches, mut vel) = (batches.clone(), vel.clone());
                    let mut lanes = LaneSweep::default();
                    // Two sweeps, so the second starts from the first's impulses.
                    for _ in 0..2 {
                        match (fast, contact) {
                            // The token proves AVX2: the intrinsics run (as calls) here too.
                            (true, true) => {
                                sweep_colour::<true>(simd, &mut batches, &mut vel, &mut lanes)
                            }
                            (true, false) => {
                                sweep_colour::<false>(simd, &mut batches, &mut vel, &mut lanes)
                            }
                            (false, true) => {
                                Portable.sweep::<true>(&mut batches, &mut vel, &mut lanes)
                            }
                            (false, false) => {
                                Portable.sweep::<false>(&mut batches, &mut vel, &mut lanes)
                            }
                        }
                    }
                    let mut out = bits(&lanes.max);
                    out.extend(bits(&lanes.sum_sq));
                    out.extend(bits(&lanes.contact_sq));
                    for b in &batches {
                        out.extend(bits(&b.ln));
                        out.extend(bits(&b.lt));
                    }
                    // The sink is never read; everything else must match.
                    for v in &vel[..vel.len() - 1] {
                        out.extend(bits(&[v.vx, v.vy, v.w]));
                    }
                    out
                };
                assert_eq!(run(true), run(false), "{n} batches, contact {contact}");
            }
        }
    }
}
