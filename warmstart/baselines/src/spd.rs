//! A small dense symmetric positive (semi-)definite solve: the coarse and Anderson
//! least-squares systems of a few to a hundred unknowns.

use deepcontact_core::Real;

/// Solves the symmetric positive semi-definite `n × n` system `a x = b` in place (`b`
/// becomes `x`): `ridge ×` the largest diagonal entry added to the diagonal (Tikhonov), then
/// elimination without pivoting. `false` (and `b` unusable) if a pivot falls to
/// `min_pivot ×` that entry or the solution is not finite.
pub(crate) fn solve_spd(
    a: &mut [Real],
    b: &mut [Real],
    n: usize,
    ridge: Real,
    min_pivot: Real,
) -> bool {
    let scale = (0..n).map(|i| a[i * n + i]).fold(0.0, Real::max);
    if !(scale > 0.0 && scale.is_finite()) {
        return false;
    }
    for i in 0..n {
        a[i * n + i] += ridge * scale;
    }
    for k in 0..n {
        let pivot = a[k * n + k];
        if pivot <= min_pivot * scale {
            return false;
        }
        for r in k + 1..n {
            let factor = a[r * n + k] / pivot;
            if factor == 0.0 {
                continue;
            }
            for c in k..n {
                a[r * n + c] -= factor * a[k * n + c];
            }
            b[r] -= factor * b[k];
        }
    }
    for k in (0..n).rev() {
        let mut s = b[k];
        for c in k + 1..n {
            s -= a[k * n + c] * b[c];
        }
        b[k] = s / a[k * n + k];
    }
    b.iter().all(|x| x.is_finite())
}
