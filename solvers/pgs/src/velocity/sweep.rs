//! The arithmetic of one sweep: a manifold's rows one at a time, a batch's lanes side by
//! side, and the impulse changes applied to the bodies.

use deepcontact_core::math::Real;

use super::{Batch, Block, LANES, LaneSweep, Manifold, Row, Sweep, Vel};

/// `x` clamped to `[-bound, bound]` as `f64::clamp` does it, without its panic for a
/// NaN or negative bound (a NaN then reaches the divergence check).
#[inline(always)]
pub(super) fn clamp_sym(x: Real, bound: Real) -> Real {
    let lo = -bound;
    let x = if x < lo { lo } else { x };
    if x > bound { bound } else { x }
}

/// `max(x, 0)` that keeps a NaN (for the divergence check) and is the same in every lane.
#[inline(always)]
pub(super) fn non_negative(x: Real) -> Real {
    if x < 0.0 { 0.0 } else { x }
}

/// One manifold's rows: friction first (bounded by the current normal impulse), then the
/// normal rows (block solver for a 2-point manifold with a well-conditioned `K`).
#[inline(always)]
pub(crate) fn sweep_manifold<const CONTACT: bool, V: Velocities + ?Sized>(
    m: &Manifold,
    rows: &mut [Row],
    vel: &mut V,
    acc: &mut Sweep,
) {
    let rows = &mut rows[m.start as usize..(m.start + m.count) as usize];
    // Accumulated in locals (registers), written back once.
    let (mut mx, mut sq, mut cs) = (acc.max, acc.sum_sq, acc.contact_sq);
    let (mut va, mut vb) = (vel.get(m.a), vel.get(m.b));
    // The original's per-contact measure: the largest signed friction change (from 0), and
    // the normal change of a one-point manifold.
    let (mut t_pos, mut n_one): (Real, Real) = (0.0, 0.0);
    for r in rows.iter_mut() {
        let vt = tangent_velocity(r, &va, &vb);
        let new = clamp_sym(r.lt - r.tangent_mass * vt, r.friction * r.ln);
        let d = new - r.lt;
        r.lt = new;
        apply_tangent(m, r, &mut va, &mut vb, d);
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
    store(vel, m, va, vb);
}

/// The batch sweep of one precision, written once for both: [`sweep_batch`] here (`f64`,
/// [`LANES`] lanes) and the `f32` one of [`super::single`] (its wide batches). It defines, in
/// the module that invokes it, `sweep_batch` with the given attributes and visibility over the
/// given scalar type, lane count, batch, velocity and per-lane measures types (each lane's
/// operations in the same order whatever the width); it calls that module's `clamp_sym` and
/// `non_negative` and reads and writes the velocities through [`Velocities`] (in scope there).
macro_rules! portable_batch {
    (
        $(#[$attr:meta])*
        $vis:vis fn sweep_batch($real:ty, $width:ident, $batch:ty, $vel:ident, $lanes:ty)
    ) => {
        $(#[$attr])*
        #[inline(always)]
        $vis fn sweep_batch<const CONTACT: bool, V: Velocities<$vel> + ?Sized>(
            b: &mut $batch,
            vel: &mut V,
            lanes: &mut $lanes,
        ) {
            let mut t_pos: [$real; $width] = [0.0; $width];
            let (mut avx, mut avy, mut aw): ([$real; $width], [$real; $width], [$real; $width]) =
                ([0.0; $width], [0.0; $width], [0.0; $width]);
            let (mut bvx, mut bvy, mut bw): ([$real; $width], [$real; $width], [$real; $width]) =
                ([0.0; $width], [0.0; $width], [0.0; $width]);
            for i in 0..$width {
                let (va, vb) = (vel.get(b.a[i]), vel.get(b.b[i]));
                (avx[i], avy[i], aw[i]) = (va.vx, va.vy, va.w);
                (bvx[i], bvy[i], bw[i]) = (vb.vx, vb.vy, vb.w);
            }
            // Friction rows: `tangent_velocity`, clamp, then `apply_tangent`.
            for i in 0..$width {
                let vt = (bvx[i] - avx[i]) * -b.ny[i]
                    + (bvy[i] - avy[i]) * b.nx[i]
                    + bw[i] * b.rtb[i]
                    - aw[i] * b.rta[i];
                let new = clamp_sym(b.lt[i] - b.tangent_mass[i] * vt, b.friction[i] * b.ln[i]);
                let d = new - b.lt[i];
                b.lt[i] = new;
                let (px, py) = (d * -b.ny[i], d * b.nx[i]);
                avx[i] -= b.ma[i] * px;
                avy[i] -= b.ma[i] * py;
                aw[i] -= b.ia[i] * (d * b.rta[i]);
                bvx[i] += b.mb[i] * px;
                bvy[i] += b.mb[i] * py;
                bw[i] += b.ib[i] * (d * b.rtb[i]);
                lanes.max[i] = lanes.max[i].max(d.abs());
                lanes.sum_sq[i] += d * d;
                if CONTACT {
                    t_pos[i] = d.max(0.0);
                }
            }
            // Normal rows: `normal_velocity`, projection, then `apply_normal`.
            for i in 0..$width {
                let vn = (bvx[i] - avx[i]) * b.nx[i]
                    + (bvy[i] - avy[i]) * b.ny[i]
                    + bw[i] * b.rnb[i]
                    - aw[i] * b.rna[i];
                let new = non_negative(b.ln[i] - b.normal_mass[i] * (vn - b.bias[i]));
                let d = new - b.ln[i];
                b.ln[i] = new;
                let (px, py) = (d * b.nx[i], d * b.ny[i]);
                avx[i] -= b.ma[i] * px;
                avy[i] -= b.ma[i] * py;
                aw[i] -= b.ia[i] * (d * b.rna[i]);
                bvx[i] += b.mb[i] * px;
                bvy[i] += b.mb[i] * py;
                bw[i] += b.ib[i] * (d * b.rnb[i]);
                lanes.max[i] = lanes.max[i].max(d.abs());
                lanes.sum_sq[i] += d * d;
                if CONTACT {
                    lanes.contact_sq[i] = lanes.contact_sq[i].max(d * d + t_pos[i] * t_pos[i]);
                }
            }
            // Movable bodies back; immovable and padding lanes into the sink (the batch's
            // `wa`, `wb`).
            for i in 0..$width {
                vel.set(b.wa[i], $vel::new(avx[i], avy[i], aw[i]));
                vel.set(b.wb[i], $vel::new(bvx[i], bvy[i], bw[i]));
            }
        }
    };
}
pub(super) use portable_batch;

portable_batch!(
    /// [`LANES`] single-point manifolds of one colour: gather the body velocities, run the
    /// friction row and the normal row of every lane with exactly the arithmetic of
    /// [`sweep_manifold`] (so each lane's result is bit-identical to it), scatter the movable
    /// bodies back. The lanes' bodies are distinct (one colour), except immovable ones, which
    /// are read but never written (their lanes store into the sink slot instead).
    pub(crate) fn sweep_batch(Real, LANES, Batch, Vel, LaneSweep)
);

/// Whether a body with these inverse masses can move.
#[inline(always)]
pub(crate) fn movable(inv_mass: Real, inv_inertia: Real) -> bool {
    inv_mass != 0.0 || inv_inertia != 0.0
}

/// Writes the manifold's body velocities back; immovable bodies are never written, so
/// manifolds sharing only a wall stay independent.
#[inline(always)]
pub(super) fn store<V: Velocities + ?Sized>(vel: &mut V, m: &Manifold, va: Vel, vb: Vel) {
    if movable(m.ma, m.ia) {
        vel.set(m.a, va);
    }
    if movable(m.mb, m.ib) {
        vel.set(m.b, vb);
    }
}

/// Body velocities as a sweep reads and writes them: a plain slice on one thread, shared
/// atomic cells when threads split a colour ([`crate::velocity::chunked`]); `T` is the
/// velocity of one body (the `f32` sweep's own type in [`super::single`]).
pub(crate) trait Velocities<T = Vel> {
    /// Velocity of body `i`.
    fn get(&self, i: u32) -> T;
    /// Sets the velocity of body `i`.
    fn set(&mut self, i: u32, v: T);
}

impl<T: Copy> Velocities<T> for [T] {
    #[inline(always)]
    fn get(&self, i: u32) -> T {
        self[i as usize]
    }

    #[inline(always)]
    fn set(&mut self, i: u32, v: T) {
        self[i as usize] = v;
    }
}

/// Relative normal velocity `(vB + ωB × rB − vA − ωA × rA) · n`.
#[inline(always)]
pub(super) fn normal_velocity(r: &Row, va: &Vel, vb: &Vel) -> Real {
    (vb.vx - va.vx) * r.nx + (vb.vy - va.vy) * r.ny + vb.w * r.rnb - va.w * r.rna
}

/// Relative tangent velocity along `t = (−n.y, n.x)`; `(ω × r) · t = ω (r × t)`.
#[inline(always)]
pub(super) fn tangent_velocity(r: &Row, va: &Vel, vb: &Vel) -> Real {
    (vb.vx - va.vx) * -r.ny + (vb.vy - va.vy) * r.nx + vb.w * r.rtb - va.w * r.rta
}

/// Applies the impulse change `(dn, dt)` of row `r` to the manifold's two bodies.
#[inline(always)]
pub(super) fn apply(m: &Manifold, r: &Row, va: &mut Vel, vb: &mut Vel, dn: Real, dt: Real) {
    let (px, py) = (dn * r.nx - dt * r.ny, dn * r.ny + dt * r.nx);
    va.vx -= m.ma * px;
    va.vy -= m.ma * py;
    va.w -= m.ia * (dn * r.rna + dt * r.rta);
    vb.vx += m.mb * px;
    vb.vy += m.mb * py;
    vb.w += m.ib * (dn * r.rnb + dt * r.rtb);
}

/// [`apply`] of a normal impulse change `dn` alone (`P = dn n`).
#[inline(always)]
fn apply_normal(m: &Manifold, r: &Row, va: &mut Vel, vb: &mut Vel, dn: Real) {
    let (px, py) = (dn * r.nx, dn * r.ny);
    va.vx -= m.ma * px;
    va.vy -= m.ma * py;
    va.w -= m.ia * (dn * r.rna);
    vb.vx += m.mb * px;
    vb.vy += m.mb * py;
    vb.w += m.ib * (dn * r.rnb);
}

/// [`apply`] of a tangent impulse change `dt` alone (`P = dt t`, `t = (−n.y, n.x)`).
#[inline(always)]
pub(super) fn apply_tangent(m: &Manifold, r: &Row, va: &mut Vel, vb: &mut Vel, dt: Real) {
    let (px, py) = (dt * -r.ny, dt * r.nx);
    va.vx -= m.ma * px;
    va.vy -= m.ma * py;
    va.w -= m.ia * (dt * r.rta);
    vb.vx += m.mb * px;
    vb.vy += m.mb * py;
    vb.w += m.ib * (dt * r.rtb);
}

/// Box2D v2.4's 2-point block solver for the normal rows: solve the mixed LCP
/// `vn = K x + b, x ≥ 0, vn ≥ 0, x·vn = 0` on the accumulated impulses by enumerating
/// the four cases (both active, only 1, only 2, none). Returns the two Δλn.
#[inline]
fn solve_block(
    m: &Manifold,
    rows: &mut [Row],
    k: &Block,
    va: &mut Vel,
    vb: &mut Vel,
) -> (Real, Real) {
    let (r1, r2) = (rows[0], rows[1]);
    let (a1, a2) = (r1.ln, r2.ln);
    // b = vn − bias − K a
    let b1 = normal_velocity(&r1, va, vb) - r1.bias - (k.k11 * a1 + k.k12 * a2);
    let b2 = normal_velocity(&r2, va, vb) - r2.bias - (k.k12 * a1 + k.k22 * a2);
    let candidates = [
        // Case 1: both points active, x = −K⁻¹ b.
        (-(k.i11 * b1 + k.i12 * b2), -(k.i12 * b1 + k.i22 * b2)),
        // Case 2: only the first.
        (-r1.normal_mass * b1, 0.0),
        // Case 3: only the second.
        (0.0, -r2.normal_mass * b2),
        // Case 4: none.
        (0.0, 0.0),
    ];
    // If no case holds (round-off), keep the current impulses.
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
