//! The wide batch sweep ([`super::sweep_batch`]) written out in AVX2 intrinsics, two batches
//! of a colour at a time (as the `f64` sweep's kernel, for the same reason: one batch's chain
//! of dependent operations leaves the out-of-order window idle). Each lane field of a
//! [`Batch32`] is one 256-bit register of eight `f32`. Every arithmetic operation is the
//! portable loop's, in its order, on the same IEEE singles (no fused multiply-add), and the
//! measures are folded batch by batch, so the bits are the same.

use core::arch::x86_64::__m256;

use pulp::x86::V3;

use super::{Batch32, Lanes, Vel32, WIDE};

/// The velocities of eight bodies as three registers `(vx₀..₇)`, `(vy₀..₇)`, `(ω₀..₇)`.
#[inline(always)]
fn gather(vel: &[Vel32], index: &[u32; WIDE]) -> [__m256; 3] {
    let v = [
        vel[index[0] as usize],
        vel[index[1] as usize],
        vel[index[2] as usize],
        vel[index[3] as usize],
        vel[index[4] as usize],
        vel[index[5] as usize],
        vel[index[6] as usize],
        vel[index[7] as usize],
    ];
    [
        pulp::cast(pulp::f32x8(
            v[0].vx, v[1].vx, v[2].vx, v[3].vx, v[4].vx, v[5].vx, v[6].vx, v[7].vx,
        )),
        pulp::cast(pulp::f32x8(
            v[0].vy, v[1].vy, v[2].vy, v[3].vy, v[4].vy, v[5].vy, v[6].vy, v[7].vy,
        )),
        pulp::cast(pulp::f32x8(
            v[0].w, v[1].w, v[2].w, v[3].w, v[4].w, v[5].w, v[6].w, v[7].w,
        )),
    ]
}

/// [`gather`] reversed: three registers back to the eight bodies at `index`, in lane order.
#[inline(always)]
fn scatter(vel: &mut [Vel32], index: &[u32; WIDE], [vx, vy, w]: [__m256; 3]) {
    let (vx, vy, w): ([f32; WIDE], [f32; WIDE], [f32; WIDE]) =
        (pulp::cast(vx), pulp::cast(vy), pulp::cast(w));
    for (lane, &i) in index.iter().enumerate() {
        vel[i as usize] = Vel32 {
            vx: vx[lane],
            vy: vy[lane],
            w: w[lane],
        };
    }
}

/// The lane registers of one batch in flight.
struct InFlight {
    a: [__m256; 3],
    b: [__m256; 3],
    dt: __m256,
    dn: __m256,
}

/// The arithmetic of a batch (methods, not closures: a closure is compiled outside the AVX2
/// context).
#[derive(Clone, Copy)]
struct Ops {
    simd: V3,
    sign: __m256,
    zero: __m256,
}

impl Ops {
    #[inline(always)]
    fn new(simd: V3) -> Self {
        Self {
            simd,
            sign: simd.avx._mm256_set1_ps(-0.0),
            zero: simd.avx._mm256_setzero_ps(),
        }
    }
    #[inline(always)]
    fn add(self, x: __m256, y: __m256) -> __m256 {
        self.simd.avx._mm256_add_ps(x, y)
    }
    #[inline(always)]
    fn sub(self, x: __m256, y: __m256) -> __m256 {
        self.simd.avx._mm256_sub_ps(x, y)
    }
    #[inline(always)]
    fn mul(self, x: __m256, y: __m256) -> __m256 {
        self.simd.avx._mm256_mul_ps(x, y)
    }
    /// `x > y ? x : y` per lane (`maxps` returns the second operand when either is NaN or
    /// both are equal).
    #[inline(always)]
    fn gt(self, x: __m256, y: __m256) -> __m256 {
        self.simd.avx._mm256_max_ps(x, y)
    }
    /// `x < y ? x : y` per lane.
    #[inline(always)]
    fn lt(self, x: __m256, y: __m256) -> __m256 {
        self.simd.avx._mm256_min_ps(x, y)
    }
    #[inline(always)]
    fn neg(self, x: __m256) -> __m256 {
        self.simd.avx._mm256_xor_ps(x, self.sign)
    }
    #[inline(always)]
    fn abs(self, x: __m256) -> __m256 {
        self.simd.avx._mm256_andnot_ps(self.sign, x)
    }
}

#[inline(always)]
fn ld(x: &[f32; WIDE]) -> __m256 {
    pulp::cast(*x)
}

/// Gathers batch `b`'s body velocities.
#[inline(always)]
fn start(o: Ops, b: &Batch32, vel: &[Vel32]) -> InFlight {
    InFlight {
        a: gather(vel, &b.a),
        b: gather(vel, &b.b),
        dt: o.zero,
        dn: o.zero,
    }
}

/// Applies the change `d` along `dir` with arms `arm`.
#[inline(always)]
fn apply(
    o: Ops,
    b: &Batch32,
    s: &mut InFlight,
    d: __m256,
    dir: (__m256, __m256),
    arm: (__m256, __m256),
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

/// The relative velocity `(vB − vA)·dir + ωB rb − ωA ra`, in the portable loop's order.
#[inline(always)]
fn relative(o: Ops, s: &InFlight, dir: (__m256, __m256), arm: (__m256, __m256)) -> __m256 {
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

/// Friction rows.
#[inline(always)]
fn friction(o: Ops, b: &mut Batch32, s: &mut InFlight) {
    let (nx, ny) = (ld(&b.nx), ld(&b.ny));
    let dir = (o.neg(ny), nx);
    let arm = (ld(&b.rta), ld(&b.rtb));
    let lt0 = ld(&b.lt);
    let vt = relative(o, s, dir, arm);
    let bound = o.mul(ld(&b.friction), ld(&b.ln));
    let x = o.sub(lt0, o.mul(ld(&b.tangent_mass), vt));
    let new = o.lt(bound, o.gt(o.neg(bound), x));
    let d = o.sub(new, lt0);
    b.lt = pulp::cast(new);
    apply(o, b, s, d, dir, arm);
    s.dt = d;
}

/// Normal rows.
#[inline(always)]
fn normal(o: Ops, b: &mut Batch32, s: &mut InFlight) {
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

/// Scatters the movable bodies back and folds the batch's measures into `lanes`, friction
/// before normal.
#[inline(always)]
fn finish<const CONTACT: bool>(
    o: Ops,
    b: &Batch32,
    s: InFlight,
    vel: &mut [Vel32],
    lanes: &mut Lanes,
) {
    scatter(vel, &b.wa, s.a);
    scatter(vel, &b.wb, s.b);
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

/// The wide batches of one colour in order, two at a time (they share no movable body), the
/// measures folded batch by batch.
#[inline(always)]
pub(super) fn sweep_colour<const CONTACT: bool>(
    simd: V3,
    batches: &mut [Batch32],
    vel: &mut [Vel32],
    lanes: &mut Lanes,
) {
    let o = Ops::new(simd);
    let mut pairs = batches.chunks_exact_mut(2);
    for pair in &mut pairs {
        let [b0, b1] = pair else {
            unreachable!("chunks of two")
        };
        let (mut s0, mut s1) = (start(o, b0, vel), start(o, b1, vel));
        friction(o, b0, &mut s0);
        friction(o, b1, &mut s1);
        normal(o, b0, &mut s0);
        normal(o, b1, &mut s1);
        finish::<CONTACT>(o, b0, s0, vel, lanes);
        finish::<CONTACT>(o, b1, s1, vel, lanes);
    }
    for b in pairs.into_remainder() {
        let mut s = start(o, b, vel);
        friction(o, b, &mut s);
        normal(o, b, &mut s);
        finish::<CONTACT>(o, b, s, vel, lanes);
    }
}
