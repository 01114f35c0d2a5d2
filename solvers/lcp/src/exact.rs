//! An exact solver for small frictional problems (enumeration of contact states), used as
//! the oracle in tests, and a checker of the complementarity conditions.

use deepcontact_core::math::Real;
use deepcontact_core::{ContactProblem, Impulse};

use crate::LcpError;
use crate::assembly::{AssemblyMode, Delassus};

/// Largest number of points [`solve_exact`] enumerates (4 states each: 4⁸ = 65 536 active
/// sets).
pub const EXACT_MAX_POINTS: usize = 8;

/// Regularisation `δ` of [`solve_exact`], relative to the largest diagonal entry of `W`.
pub const EXACT_REGULARIZATION: Real = 1e-10;

/// State of one contact point in a solution of the frictional problem.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ContactState {
    /// `λ = 0`, normal velocity ≥ 0.
    Separated,
    /// `λn ≥ 0`, normal velocity 0, tangent velocity 0, `|λt| ≤ μ λn`.
    Sticking,
    /// `λt = +μ λn`, tangent velocity ≤ 0 (sliding towards −t).
    SlidingNegative,
    /// `λt = −μ λn`, tangent velocity ≥ 0 (sliding towards +t).
    SlidingPositive,
}

const STATES: [ContactState; 4] = [
    ContactState::Separated,
    ContactState::Sticking,
    ContactState::SlidingNegative,
    ContactState::SlidingPositive,
];

/// A solution found by [`solve_exact`].
#[derive(Debug, Clone, PartialEq)]
pub struct ExactSolution {
    /// Impulse per point.
    pub impulses: Vec<Impulse>,
    /// Relative velocity `Wλ + q` per row (`[n0, t0, n1, t1, ...]`) of the regularised
    /// system the enumeration solved (see [`solve_exact`]).
    pub velocity: Vec<Real>,
    /// State per point.
    pub states: Vec<ContactState>,
    /// Active sets tried before this one was found (including it).
    pub active_sets_tried: usize,
}

/// How far impulses are from solving the frictional problem, in impulse units (velocities
/// are multiplied by the effective masses, as in the natural-map residual).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Violation {
    /// `max |min(λn, m_n wn)|`: sign and complementarity of the normal rows.
    pub normal: Real,
    /// `max(|λt| − μ λn, 0)`: distance outside the friction cone.
    pub cone: Real,
    /// `max |λt − clamp(λt − m_t wt, ±μλn)|`: maximal dissipation (stick ⇒ wt = 0, slide ⇒
    /// λt at the bound opposing wt).
    pub friction: Real,
}

impl Violation {
    /// The largest of the three measures.
    pub fn max(&self) -> Real {
        self.normal.max(self.cone).max(self.friction)
    }
}

/// Measures how far `lambda` (row layout `[n0, t0, ...]`) is from a solution of the system
/// assembled in `del`.
pub fn violation(del: &Delassus, lambda: &[Real]) -> Violation {
    let n = del.rows();
    let mut v = Violation::default();
    if lambda.len() < n {
        return Violation {
            normal: Real::INFINITY,
            cone: Real::INFINITY,
            friction: Real::INFINITY,
        };
    }
    let mut w = vec![0.0; n];
    del.velocity_of(lambda, &mut w);
    let (m, mu) = (del.effective_mass(), del.friction());
    for p in 0..del.points() {
        let (ln, lt) = (lambda[2 * p], lambda[2 * p + 1]);
        let (wn, wt) = (w[2 * p], w[2 * p + 1]);
        v.normal = v.normal.max(ln.min(m[2 * p] * wn).abs());
        let bound = (mu[p] * ln).max(0.0);
        v.cone = v.cone.max(lt.abs() - bound);
        let y = lt - m[2 * p + 1] * wt;
        v.friction = v.friction.max((lt - y.max(-bound).min(bound)).abs());
    }
    v
}

/// Solves a small frictional problem exactly by enumerating the state of every point
/// (separated, sticking, sliding either way): for each of the `4^points` active sets, the
/// equalities it implies (zero normal velocity of touching points, zero tangent velocity of
/// sticking points, `λt = ±μλn` of sliding points) are solved by Gaussian elimination with
/// full pivoting (a rank-deficient set — redundant contacts — gives its basic solution,
/// unknowns without a pivot set to 0, when the remaining equations are consistent), and the
/// first solution meeting every sign condition within `tolerance` (relative to the size of
/// `q` and of the impulses) is returned.
///
/// Redundant contacts make `W` singular, and then the solution set of an active set is an
/// affine space whose basic solution need not be admissible even when another of its points
/// is. The enumeration therefore solves the problem with `W + δI`,
/// `δ` = [`EXACT_REGULARIZATION`] × the largest diagonal entry of `W`: positive definite,
/// with a solution that solves the original problem up to `δ |λ|` in velocity.
///
/// Fails for more than [`EXACT_MAX_POINTS`] points, on an invalid problem, or when no
/// active set gives an admissible solution.
pub fn solve_exact(problem: &ContactProblem, tolerance: Real) -> Result<ExactSolution, LcpError> {
    problem.validate()?;
    let np = problem.points.len();
    if np > EXACT_MAX_POINTS {
        return Err(LcpError::TooManyPointsForExact {
            points: np,
            limit: EXACT_MAX_POINTS,
        });
    }
    if !(tolerance.is_finite() && tolerance >= 0.0) {
        return Err(LcpError::InvalidSetting {
            name: "tolerance",
            value: tolerance,
            reason: "must be finite and >= 0",
        });
    }
    let mut del = Delassus::new();
    del.assemble(problem, AssemblyMode::Dense, usize::MAX)?;
    let n = del.rows();
    let mut w = del.to_dense();
    let delta = EXACT_REGULARIZATION * del.diagonal().iter().fold(0.0, |m: Real, v| m.max(*v));
    for i in 0..n {
        w[(i, i)] += delta;
    }
    let q = del.q();
    let mu = del.friction();
    let qmax = q.iter().fold(0.0, |m: Real, v| m.max(v.abs()));
    let wmax = (0..n)
        .flat_map(|i| (0..n).map(move |j| (i, j)))
        .fold(0.0, |m: Real, (i, j)| m.max(w[(i, j)].abs()));

    let mut states = vec![ContactState::Separated; np];
    let mut unknowns: Vec<usize> = Vec::with_capacity(n); // row index of each unknown
    let mut equations: Vec<usize> = Vec::with_capacity(n); // row index of each equation
    let mut a = vec![0.0; n * n];
    let mut b = vec![0.0; n];
    let mut sol = vec![0.0; n];
    let mut lambda = vec![0.0; n];
    let mut vel = vec![0.0; n];
    let total = 4usize.pow(np as u32);
    for code in 0..total {
        let mut c = code;
        for s in states.iter_mut() {
            *s = STATES[c % 4];
            c /= 4;
        }
        let k = active_set_system(
            &states,
            &w,
            mu,
            q,
            (&mut unknowns, &mut equations),
            (&mut a, &mut b),
        );
        let consistency_tol = 1e-9 * (1.0 + qmax);
        if !gauss_full_pivot(
            &mut a[..k * k],
            &mut b[..k],
            &mut sol[..k],
            k,
            1e-12 * wmax.max(1e-300),
            consistency_tol,
        ) {
            continue;
        }
        impulses_of(&states, mu, &unknowns, &sol[..k], &mut lambda);
        del.velocity_of(&lambda, &mut vel);
        for (v, l) in vel.iter_mut().zip(&lambda) {
            *v += delta * l;
        }
        let lmax = lambda.iter().fold(0.0, |m: Real, v| m.max(v.abs()));
        let tol_l = tolerance * (1.0 + lmax);
        let tol_v = tolerance * (1.0 + qmax + wmax * lmax);
        let admissible = admissible(&states, mu, &lambda, &vel, (tol_l, tol_v));
        if admissible {
            return Ok(ExactSolution {
                impulses: lambda
                    .chunks_exact(2)
                    .map(|c| Impulse::new(c[0], c[1]))
                    .collect(),
                velocity: vel,
                states,
                active_sets_tried: code + 1,
            });
        }
    }
    Err(LcpError::NoExactSolution {
        combinations: total,
    })
}

/// The linear system of one active set into `a` (row-major, `k × k`) and `b`, returning `k`.
/// Unknowns: `λn` of every touching point, `λt` of every sticking point; equations: `wn = 0`
/// for touching points, `wt = 0` for sticking points. The column of a sliding point's `λn`
/// includes its tangent, `λt = ∓μ λn` (`Vec`s: the unknowns' and equations' rows, reused).
fn active_set_system(
    states: &[ContactState],
    w: &faer::Mat<Real>,
    mu: &[Real],
    q: &[Real],
    (unknowns, equations): (&mut Vec<usize>, &mut Vec<usize>),
    (a, b): (&mut [Real], &mut [Real]),
) -> usize {
    unknowns.clear();
    equations.clear();
    for (p, s) in states.iter().enumerate() {
        if *s != ContactState::Separated {
            unknowns.push(2 * p);
            equations.push(2 * p);
        }
        if *s == ContactState::Sticking {
            unknowns.push(2 * p + 1);
            equations.push(2 * p + 1);
        }
    }
    let k = unknowns.len();
    for (ei, &row) in equations.iter().enumerate() {
        for (ui, &col) in unknowns.iter().enumerate() {
            let p = col / 2;
            let mut v = w[(row, col)];
            if col % 2 == 0 {
                match states[p] {
                    ContactState::SlidingNegative => v += mu[p] * w[(row, col + 1)],
                    ContactState::SlidingPositive => v -= mu[p] * w[(row, col + 1)],
                    _ => {}
                }
            }
            a[ei * k + ui] = v;
        }
        b[ei] = -q[row];
    }
    k
}

/// Every row's impulse (`lambda`, two rows a point) from the active set's solution `sol` of
/// its `unknowns`: zero where no unknown, `∓μ λn` on a sliding point's tangent row.
fn impulses_of(
    states: &[ContactState],
    mu: &[Real],
    unknowns: &[usize],
    sol: &[Real],
    lambda: &mut [Real],
) {
    lambda.fill(0.0);
    for (&row, &x) in unknowns.iter().zip(sol) {
        lambda[row] = x;
    }
    for (p, s) in states.iter().enumerate() {
        match s {
            ContactState::SlidingNegative => lambda[2 * p + 1] = mu[p] * lambda[2 * p],
            ContactState::SlidingPositive => lambda[2 * p + 1] = -mu[p] * lambda[2 * p],
            _ => {}
        }
    }
}

/// Whether impulses `lambda` with velocities `vel` solve the problem in the states assumed,
/// within `tol_l` in impulse and `tol_v` in velocity: normal impulse and velocity
/// non-negative, tangent impulse inside the cone, a sliding point moving against its friction.
fn admissible(
    states: &[ContactState],
    mu: &[Real],
    lambda: &[Real],
    vel: &[Real],
    (tol_l, tol_v): (Real, Real),
) -> bool {
    states.iter().enumerate().all(|(p, s)| {
        let (ln, lt, wn, wt) = (lambda[2 * p], lambda[2 * p + 1], vel[2 * p], vel[2 * p + 1]);
        let normal_ok = ln >= -tol_l && wn >= -tol_v;
        let cone_ok = lt.abs() <= mu[p] * ln + tol_l;
        normal_ok
            && cone_ok
            && match s {
                ContactState::Separated | ContactState::Sticking => true,
                ContactState::SlidingNegative => wt <= tol_v,
                ContactState::SlidingPositive => wt >= -tol_v,
            }
    })
}

/// Solves the `k × k` system `a x = b` (row-major `a`) by Gaussian elimination with full
/// pivoting. Pivots below `pivot_tol` end the elimination; the unknowns without a pivot
/// are set to 0 and the remaining equations must hold within `consistency_tol`.
/// Returns false for an inconsistent system.
fn gauss_full_pivot(
    a: &mut [Real],
    b: &mut [Real],
    x: &mut [Real],
    k: usize,
    pivot_tol: Real,
    consistency_tol: Real,
) -> bool {
    let mut col_of = [0usize; 2 * EXACT_MAX_POINTS];
    for (i, c) in col_of.iter_mut().enumerate().take(k) {
        *c = i;
    }
    let mut rank = 0;
    while rank < k {
        // Find the largest remaining entry.
        let (mut pr, mut pc, mut pv) = (rank, rank, 0.0);
        for r in rank..k {
            for c in rank..k {
                let v = a[r * k + c].abs();
                if v > pv {
                    (pr, pc, pv) = (r, c, v);
                }
            }
        }
        if pv <= pivot_tol {
            break;
        }
        // Swap rows rank <-> pr and columns rank <-> pc.
        if pr != rank {
            for c in 0..k {
                a.swap(rank * k + c, pr * k + c);
            }
            b.swap(rank, pr);
        }
        if pc != rank {
            for r in 0..k {
                a.swap(r * k + rank, r * k + pc);
            }
            col_of.swap(rank, pc);
        }
        let piv = a[rank * k + rank];
        for r in rank + 1..k {
            let f = a[r * k + rank] / piv;
            if f != 0.0 {
                for c in rank..k {
                    a[r * k + c] -= f * a[rank * k + c];
                }
                b[r] -= f * b[rank];
            }
        }
        rank += 1;
    }
    // Remaining equations must be consistent (their coefficients are below the tolerance).
    if b[rank..k].iter().any(|v| v.abs() > consistency_tol) {
        return false;
    }
    // Back substitution on the leading rank × rank block; the rest of the unknowns are 0.
    let mut y = [0.0; 2 * EXACT_MAX_POINTS];
    for r in (0..rank).rev() {
        let mut s = b[r];
        for c in r + 1..rank {
            s -= a[r * k + c] * y[c];
        }
        y[r] = s / a[r * k + r];
    }
    for xi in x.iter_mut().take(k) {
        *xi = 0.0;
    }
    for r in 0..rank {
        x[col_of[r]] = y[r];
    }
    x.iter().take(k).all(|v| v.is_finite())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gauss_solves_regular_and_rank_deficient_systems() {
        // Regular 2x2.
        let mut a = [2.0, 1.0, 1.0, 3.0];
        let mut b = [3.0, 5.0];
        let mut x = [0.0; 2];
        assert!(gauss_full_pivot(&mut a, &mut b, &mut x, 2, 1e-12, 1e-9));
        assert!(
            (x[0] - 0.8).abs() < 1e-12 && (x[1] - 1.4).abs() < 1e-12,
            "{x:?}"
        );
        // Rank 1, consistent: x0 + x1 = 2 twice -> basic solution.
        let mut a = [1.0, 1.0, 1.0, 1.0];
        let mut b = [2.0, 2.0];
        assert!(gauss_full_pivot(&mut a, &mut b, &mut x, 2, 1e-12, 1e-9));
        assert!(
            (x[0] + x[1] - 2.0).abs() < 1e-12 && (x[0] == 0.0 || x[1] == 0.0),
            "{x:?}"
        );
        // Rank 1, inconsistent.
        let mut a = [1.0, 1.0, 1.0, 1.0];
        let mut b = [2.0, 3.0];
        assert!(!gauss_full_pivot(&mut a, &mut b, &mut x, 2, 1e-12, 1e-9));
    }
}
