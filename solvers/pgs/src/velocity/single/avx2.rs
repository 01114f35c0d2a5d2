//! The wide batch sweep ([`super::sweep_batch`]) written out in AVX2 intrinsics, two batches
//! of a colour at a time (as the `f64` sweep's kernel, for the same reason: one batch's chain
//! of dependent operations leaves the out-of-order window idle). Each lane field of a
//! [`Batch32`] is one 256-bit register of eight `f32`. Every arithmetic operation is the
//! portable loop's, in its order, on the same IEEE singles (no fused multiply-add), and the
//! measures are folded batch by batch, so the bits are the same. The kernel is the `f64` one's
//! body ([`avx2_kernel`]) with `f32` registers and eight lanes; only `gather` is its own.

use core::arch::x86_64::__m256;

use pulp::x86::V3;

use super::super::avx2::avx2_kernel;
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

avx2_kernel!(
    pub(super) fn sweep_colour(__m256, f32, WIDE, Batch32, Vel32, Lanes),
    [
        _mm256_set1_ps,
        _mm256_setzero_ps,
        _mm256_add_ps,
        _mm256_sub_ps,
        _mm256_mul_ps,
        _mm256_max_ps,
        _mm256_min_ps,
        _mm256_xor_ps,
        _mm256_andnot_ps,
    ],
);
