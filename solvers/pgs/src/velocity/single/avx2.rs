//! The wide batch sweep ([`super::sweep_batch`]) written out in AVX2 intrinsics, two batches
//! of a colour at a time (as the `f64` sweep's kernel, for the same reason: one batch's chain
//! of dependent operations leaves the out-of-order window idle). Each lane field of a
//! [`Batch32`] is one 256-bit register of eight `f32`. Every arithmetic operation is the
//! portable loop's, in its order, on the same IEEE singles (no fused multiply-add), and the
//! measures are folded batch by batch, so the bits are the same. The kernel is the `f64` one's
//! body ([`avx2_kernel`]) with `f32` registers and eight lanes; `gather` and `scatter` are its
//! own (a body's padded velocity moved as one 128-bit register, eight transposed).

use core::arch::x86_64::{__m128, __m256};

use pulp::x86::V3;

use super::super::avx2::avx2_kernel;
use super::{Batch32, Lanes, Vel32, WIDE};

/// One body's velocity as a 128-bit register `(vx, vy, ω, 0)`.
#[inline(always)]
fn row(v: Vel32) -> __m128 {
    pulp::cast([v.vx, v.vy, v.w, v.pad])
}

/// The velocities of eight bodies as three registers `(vx₀..₇)`, `(vy₀..₇)`, `(ω₀..₇)`: one
/// 128-bit load a body, lanes `k` and `k + 4` paired in a 256-bit register, then the 4 × 4
/// transpose of each 128-bit half (unpack, then shuffle).
#[inline(always)]
fn gather(simd: V3, vel: &[Vel32], index: &[u32; WIDE]) -> [__m256; 3] {
    let avx = simd.avx;
    let at = |lane: usize| row(vel[index[lane] as usize]);
    // r_k = (v_k | v_{k+4}).
    let r0 = avx._mm256_set_m128(at(4), at(0));
    let r1 = avx._mm256_set_m128(at(5), at(1));
    let r2 = avx._mm256_set_m128(at(6), at(2));
    let r3 = avx._mm256_set_m128(at(7), at(3));
    // (vx₀ vx₁ vy₀ vy₁ | vx₄ vx₅ vy₄ vy₅), (vx₂ vx₃ vy₂ vy₃ | …), (ω₀ ω₁ 0 0 | ω₄ ω₅ 0 0), …
    let xy01 = avx._mm256_unpacklo_ps(r0, r1);
    let xy23 = avx._mm256_unpacklo_ps(r2, r3);
    let w01 = avx._mm256_unpackhi_ps(r0, r1);
    let w23 = avx._mm256_unpackhi_ps(r2, r3);
    [
        avx._mm256_shuffle_ps::<0b01_00_01_00>(xy01, xy23),
        avx._mm256_shuffle_ps::<0b11_10_11_10>(xy01, xy23),
        avx._mm256_shuffle_ps::<0b01_00_01_00>(w01, w23),
    ]
}

/// [`gather`] reversed: the transpose back to one `(vx, vy, ω, 0)` a body, stored in lane
/// order, one 128-bit store a body.
#[inline(always)]
fn scatter(simd: V3, vel: &mut [Vel32], index: &[u32; WIDE], [vx, vy, w]: [__m256; 3]) {
    let avx = simd.avx;
    let zero = avx._mm256_setzero_ps();
    // (vx₀ vy₀ vx₁ vy₁ | vx₄ vy₄ vx₅ vy₅), (vx₂ vy₂ vx₃ vy₃ | …), (ω₀ 0 ω₁ 0 | ω₄ 0 ω₅ 0), …
    let xy01 = avx._mm256_unpacklo_ps(vx, vy);
    let xy23 = avx._mm256_unpackhi_ps(vx, vy);
    let w01 = avx._mm256_unpacklo_ps(w, zero);
    let w23 = avx._mm256_unpackhi_ps(w, zero);
    // l_k = (v_k | v_{k+4}).
    let l = [
        avx._mm256_shuffle_ps::<0b01_00_01_00>(xy01, w01),
        avx._mm256_shuffle_ps::<0b11_10_11_10>(xy01, w01),
        avx._mm256_shuffle_ps::<0b01_00_01_00>(xy23, w23),
        avx._mm256_shuffle_ps::<0b11_10_11_10>(xy23, w23),
    ];
    for (lane, &i) in index.iter().enumerate() {
        let half = if lane < 4 {
            avx._mm256_castps256_ps128(l[lane])
        } else {
            avx._mm256_extractf128_ps::<1>(l[lane - 4])
        };
        let [vx, vy, w, _]: [f32; 4] = pulp::cast(half);
        vel[i as usize] = Vel32::new(vx, vy, w);
    }
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
