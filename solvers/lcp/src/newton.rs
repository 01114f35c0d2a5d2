//! A semismooth (minimum-map) Newton method on the natural map of the frictional problem.

use std::time::Instant;

use deepcontact_core::math::{Real, Velocity};
use deepcontact_core::{
    ContactProblem, CoreError, Impulse, SolveReport, SolverSettings, VelocitySolver,
};
#[cfg(feature = "sparse")]
use faer::Conj;
use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::lu::partial_pivoting::{factor as dense_lu, solve as dense_solve};
#[cfg(feature = "sparse")]
use faer::sparse::SparseColMatRef;
#[cfg(feature = "sparse")]
use faer::sparse::linalg::lu::{NumericLu, SymbolicLu, factorize_symbolic_lu};
use faer::{Mat, MatMut, Par};

use crate::LcpError;
use crate::assembly::{
    AssemblyMode, DEFAULT_DENSE_THRESHOLD, Delassus, impulses_to_rows, rows_to_impulses, sor_sweep,
    sweep_order,
};
use deepcontact_core::solver::begin_solve;

/// Relative regularisation a Newton direction is recomputed with (at least) after its line
/// search failed.
pub const RETRY_REGULARIZATION: Real = 1e-6;

/// Breakpoints of the line search below this step length are ignored (a normal impulse
/// already at zero up to round-off).
const MIN_BREAKPOINT: Real = 1e-10;

/// Options of [`NewtonSolver`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NewtonSettings {
    /// Dense or sparse storage of `W` and of the Newton matrix (default [`AssemblyMode::Auto`]).
    pub assembly: AssemblyMode,
    /// Largest number of rows handled densely in `Auto` mode (default
    /// [`DEFAULT_DENSE_THRESHOLD`] = 128 rows, i.e. 64 points).
    pub dense_threshold: usize,
    /// Relative regularisation ε of the free rows of the Newton matrix: their diagonal is
    /// `W_ii (1 + ε)` (default 1e-10). Redundant contacts make `W` singular; ε makes the step
    /// a Levenberg–Marquardt step that leaves the null space of `W` (which changes no
    /// velocity) alone. After a failed line search the direction is recomputed with ε × 100
    /// (at least [`RETRY_REGULARIZATION`]), a shorter and better-conditioned step; after a
    /// full step is accepted ε shrinks ×10 back towards this value. ≥ 0.
    pub regularization: Real,
    /// Largest ε (default 100, where the step is a heavily damped Jacobi step). When a
    /// line search fails at this ε the iteration is one projected Gauss-Seidel sweep; when
    /// the factorisation is not finite or inaccurate even at this ε the solve fails with
    /// [`LcpError::Singular`].
    pub max_regularization: Real,
    /// Armijo sufficient-decrease constant σ in (0, 0.5) of the line search on
    /// `θ = ½‖H‖²` (default 1e-4): a step α is accepted when `θ(new) ≤ (1 − 2σα) θ`.
    pub armijo: Real,
    /// Step reduction factor of the backtracking line search, in (0, 1) (default 0.5).
    pub backtrack: Real,
    /// Backtracking steps before the iteration falls back to one projected Gauss-Seidel
    /// sweep (default 8, i.e. down to α = 0.5⁸ ≈ 0.004).
    pub max_backtracks: u32,
    /// Validate the problem before solving (default true).
    pub validate: bool,
}

impl Default for NewtonSettings {
    fn default() -> Self {
        Self {
            assembly: AssemblyMode::Auto,
            dense_threshold: DEFAULT_DENSE_THRESHOLD,
            regularization: 1e-10,
            max_regularization: 1e2,
            armijo: 1e-4,
            backtrack: 0.5,
            max_backtracks: 8,
            validate: true,
        }
    }
}

impl NewtonSettings {
    /// Rejects out-of-range values.
    pub fn validate(&self) -> Result<(), LcpError> {
        let check = |name, value: Real, ok: bool, reason| {
            if ok {
                Ok(())
            } else {
                Err(LcpError::InvalidSetting {
                    name,
                    value,
                    reason,
                })
            }
        };
        check(
            "regularization",
            self.regularization,
            self.regularization.is_finite() && self.regularization >= 0.0,
            "must be finite and >= 0",
        )?;
        check(
            "max_regularization",
            self.max_regularization,
            self.max_regularization.is_finite() && self.max_regularization >= self.regularization,
            "must be finite and >= regularization",
        )?;
        check(
            "armijo",
            self.armijo,
            self.armijo > 0.0 && self.armijo < 0.5,
            "must be in (0, 0.5)",
        )?;
        check(
            "backtrack",
            self.backtrack,
            self.backtrack > 0.0 && self.backtrack < 1.0,
            "must be in (0, 1)",
        )
    }
}

/// What the last Newton solve did besides the figures of its [`SolveReport`].
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct NewtonStats {
    /// Newton iterations (same as the report's `iterations`).
    pub iterations: u32,
    /// LU factorisations (more than the iterations when ε had to grow).
    pub factorizations: u32,
    /// Backtracking steps taken by the line search, in all.
    pub backtracks: u32,
    /// Directions recomputed with a larger regularisation after a failed line search.
    pub retries: u32,
    /// Iterations that fell back to a projected Gauss-Seidel sweep.
    pub fallback_sweeps: u32,
    /// Largest relative regularisation used.
    pub max_regularization: Real,
    /// Whether the Newton matrix was dense.
    pub dense: bool,
}

/// How the Newton matrix treats one row.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum RowState {
    /// `l < λ − m w < u`: the row's velocity equation `(W Δ)_i = −w_i`.
    Free,
    /// Projection active at a constant bound (a normal at 0, a row with zero mass):
    /// `Δ_i = −H_i`.
    Fixed,
    /// Tangent at `+μ λn`: `Δt − μ Δn = −H_t`.
    Upper,
    /// Tangent at `−μ λn`: `Δt + μ Δn = −H_t`.
    Lower,
}

/// Scratch memory for faer's factorisations (a `MemBuffer` is not `Debug`).
struct Scratch(MemBuffer);

impl std::fmt::Debug for Scratch {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Scratch({} bytes)", self.0.len())
    }
}

impl Scratch {
    fn reserve(&mut self, req: StackReq) -> Result<(), LcpError> {
        if !MemStack::new(&mut self.0).can_hold(req) {
            self.0 = MemBuffer::try_new(req).map_err(|_| LcpError::Factorization {
                rows: 0,
                reason: format!(
                    "cannot allocate {} bytes of scratch",
                    req.unaligned_bytes_required()
                ),
            })?;
        }
        Ok(())
    }
}

/// Semismooth Newton on the natural map of the frictional contact problem, started from the
/// warm start.
///
/// With `w = Wλ + q` and `m` the effective masses, the natural map
/// `H(λ) = λ − proj(λ − m ∘ w)` (normal rows projected onto `[0, ∞)`, tangent rows onto
/// `[−μλn, μλn]` with the *current* `λn`) vanishes exactly at the solutions;
/// `max |H|` is the natural-map residual deepcontact-pgs reports. The start is projected onto
/// the cone, then each iteration:
///
/// 1. classifies every row (free, at a constant bound, or at a friction bound `±μλn`);
/// 2. solves the generalised-Jacobian system `K Δ = −H` of all rows at once — free rows
///    take the row of `W` (diagonal × (1 + ε)), bound rows an identity row, friction-bound
///    rows also the `∓μ` coupling to their normal (so sliding friction follows the normal
///    impulse within the step: a true Newton step for `H`, not a fixed point on the friction
///    bounds) — with faer's partial-pivoting LU, dense or sparse (the sparse symbolic
///    analysis is done once per solve: `K` keeps the pattern of `W`); ε grows ×100 while the
///    solution is not finite or inaccurate;
/// 3. line search on `θ = ½‖H‖²` along `λ ← proj(λ + αΔ)` (Armijo): α = 1, β, β², …, then
///    the first breakpoint where a normal impulse reaches zero;
/// 4. if no step is accepted: the same with the friction bounds lagged (no coupling, the
///    symmetric system of a fixed point on the bounds), then with ε × 100 (a shorter
///    Levenberg–Marquardt step), and at the largest ε one projected Gauss-Seidel sweep
///    instead (so an iteration always moves). ε shrinks ×10 after every accepted step.
///
/// The iteration records `max |Δλ|` and `sqrt(Σ Δλ²)` of the change it made (the first one
/// measured from the start as given), so the stop rule of [`SolverSettings`] and every figure
/// work as for PGS; since a short line-search step can be small far from a solution, the solve
/// stops only when the natural map is below the tolerance too. The returned impulses are on the
/// friction cone and the velocities are `v_free + M⁻¹ Jᵀ λ`.
///
/// Limits: the frictional problem is not monotone; on contrived problems (several sliding
/// contacts with nearly coincident points on one body, mass ratios of 1e4) the method may
/// hit the cap with a small but non-zero residual instead of converging (see the tests).
#[derive(Debug)]
pub struct NewtonSolver {
    /// Options.
    pub settings: NewtonSettings,
    delassus: Delassus,
    order: Vec<u32>,
    x: Vec<Real>,
    prev: Vec<Real>,
    w: Vec<Real>,
    h: Vec<Real>,
    rhs: Vec<Real>,
    d: Vec<Real>,
    kd: Vec<Real>,
    trial: Vec<Real>,
    w_trial: Vec<Real>,
    state: Vec<RowState>,
    k_dense: Mat<Real>,
    perm: Vec<usize>,
    perm_inv: Vec<usize>,
    #[cfg(feature = "sparse")]
    k_values: Vec<Real>,
    #[cfg(feature = "sparse")]
    symbolic: Option<SymbolicLu<usize>>,
    #[cfg(feature = "sparse")]
    numeric: NumericLu<usize, Real>,
    mem: Scratch,
    stats: NewtonStats,
    /// Whether the current Newton matrix couples friction bounds to their normals.
    coupled: bool,
}

impl Default for NewtonSolver {
    fn default() -> Self {
        Self::with_settings(NewtonSettings::default())
    }
}

impl NewtonSolver {
    /// A solver with default options.
    pub fn new() -> Self {
        Self::default()
    }

    /// A solver with the given options.
    pub fn with_settings(settings: NewtonSettings) -> Self {
        Self {
            settings,
            delassus: Delassus::new(),
            order: Vec::new(),
            x: Vec::new(),
            prev: Vec::new(),
            w: Vec::new(),
            h: Vec::new(),
            rhs: Vec::new(),
            d: Vec::new(),
            kd: Vec::new(),
            trial: Vec::new(),
            w_trial: Vec::new(),
            state: Vec::new(),
            k_dense: Mat::new(),
            perm: Vec::new(),
            perm_inv: Vec::new(),
            #[cfg(feature = "sparse")]
            k_values: Vec::new(),
            #[cfg(feature = "sparse")]
            symbolic: None,
            #[cfg(feature = "sparse")]
            numeric: NumericLu::new(),
            mem: Scratch(MemBuffer::new(StackReq::EMPTY)),
            stats: NewtonStats::default(),
            coupled: true,
        }
    }

    /// The system assembled by the last solve.
    pub fn delassus(&self) -> &Delassus {
        &self.delassus
    }

    /// Counters of the last solve.
    pub fn last_stats(&self) -> NewtonStats {
        self.stats
    }

    /// [`VelocitySolver::solve`] with this crate's error type.
    pub fn solve_lcp(
        &mut self,
        problem: &ContactProblem,
        settings: &SolverSettings,
        impulses: &mut [Impulse],
        velocities: &mut [Velocity],
        report: &mut SolveReport,
    ) -> Result<(), LcpError> {
        let t0 = Instant::now();
        self.settings.validate()?;
        settings.require_norm_supported(self.name())?;
        begin_solve(
            problem,
            settings,
            self.settings.validate,
            impulses,
            velocities,
            report,
        )?;
        self.delassus.assemble(
            problem,
            self.settings.assembly,
            self.settings.dense_threshold,
        )?;
        sweep_order(problem, &mut self.order);
        let n = self.delassus.rows();
        self.stats = NewtonStats {
            dense: self.delassus.is_dense(),
            ..NewtonStats::default()
        };
        self.prepare(n)?;

        impulses_to_rows(impulses, &mut self.prev);
        if let Some(row) = self.prev.iter().position(|v| !v.is_finite()) {
            return Err(LcpError::NonFinite {
                what: "start impulse",
                row,
                iteration: 0,
            });
        }
        self.x.clear();
        self.x.extend_from_slice(&self.prev);
        self.delassus.project(&mut self.x);
        self.delassus.velocity_of(&self.x, &mut self.w);

        let scale = self
            .delassus
            .diagonal()
            .iter()
            .fold(0.0, |m: Real, &v| m.max(v));
        let scale = if scale > 0.0 { scale } else { 1.0 };
        let base = self.settings.regularization;
        let max_reg = self.settings.max_regularization;
        let mut reg = base;
        let mut it = 0;
        while it < settings.max_iterations {
            it += 1;
            let theta = self.classify();
            if theta > 0.0 {
                let mut accepted = false;
                'attempts: loop {
                    // The exact generalised Jacobian first; if its step fails, the one with
                    // the friction bounds lagged (held at ±μλn of this iterate).
                    for coupled in [true, false] {
                        self.coupled = coupled;
                        reg = self.newton_direction(it, reg, scale)?;
                        let ls = self.line_search(theta);
                        if ls.is_some() {
                            accepted = true;
                            reg = (reg * 0.1).max(base);
                            break 'attempts;
                        }
                    }
                    if reg >= max_reg {
                        break;
                    }
                    // Levenberg–Marquardt: a shorter, better-conditioned step.
                    self.stats.retries += 1;
                    reg = (reg * 100.0).max(RETRY_REGULARIZATION).min(max_reg);
                }
                if !accepted {
                    self.stats.fallback_sweeps += 1;
                    self.trial.copy_from_slice(&self.x);
                    let (_, _, finite) =
                        sor_sweep(&self.delassus, &self.order, &mut self.trial, 1.0);
                    if !finite {
                        let row = self.trial.iter().position(|v| !v.is_finite()).unwrap_or(0);
                        return Err(LcpError::NonFinite {
                            what: "impulse",
                            row,
                            iteration: it,
                        });
                    }
                    self.delassus.velocity_of(&self.trial, &mut self.w_trial);
                }
                std::mem::swap(&mut self.x, &mut self.trial);
                std::mem::swap(&mut self.w, &mut self.w_trial);
            }
            let mut max_d: Real = 0.0;
            let mut sum_sq: Real = 0.0;
            for (p, &x) in self.prev.iter_mut().zip(&self.x) {
                let d = x - *p;
                max_d = max_d.max(d.abs());
                sum_sq += d * d;
                *p = x;
            }
            let l2 = sum_sq.sqrt();
            report.residual_inf.push(max_d);
            report.residual_l2.push(l2);
            if !(max_d.is_finite() && l2.is_finite()) {
                let row = self.x.iter().position(|v| !v.is_finite()).unwrap_or(0);
                return Err(LcpError::NonFinite {
                    what: "impulse",
                    row,
                    iteration: it,
                });
            }
            // A Newton iteration can make a tiny change without being converged (a short
            // line-search step): the natural map must be small too.
            let (h_inf, h_l2) = self.natural_norms();
            if settings.converged(it, max_d, l2, Real::INFINITY)
                && settings.converged(it, h_inf, h_l2, Real::INFINITY)
            {
                report.converged = true;
                break;
            }
        }
        report.iterations = it;
        self.stats.iterations = it;
        // Iterates are admissible except after a fallback sweep (friction clamped against the
        // normal of its sweep): project onto the final cone, as PGS does.
        self.delassus.project(&mut self.x);
        self.delassus.velocity_of(&self.x, &mut self.w);
        rows_to_impulses(&self.x, impulses);
        self.delassus.body_velocities(&self.x, velocities);
        report.natural_residual = self.delassus.natural_residual(&self.x, &self.w);
        report.seconds = t0.elapsed().as_secs_f64();
        Ok(())
    }

    /// Sizes the buffers, runs the sparse symbolic analysis and reserves faer's scratch.
    fn prepare(&mut self, n: usize) -> Result<(), LcpError> {
        for v in [
            &mut self.w,
            &mut self.h,
            &mut self.rhs,
            &mut self.d,
            &mut self.kd,
            &mut self.trial,
            &mut self.w_trial,
        ] {
            v.clear();
            v.resize(n, 0.0);
        }
        self.state.clear();
        self.state.resize(n, RowState::Free);
        let req = if self.delassus.is_dense() {
            #[cfg(feature = "sparse")]
            {
                self.symbolic = None;
            }
            self.k_dense.resize_with(n, n, |_, _| 0.0);
            self.perm.resize(n, 0);
            self.perm_inv.resize(n, 0);
            dense_lu::lu_in_place_scratch::<usize, Real>(n, n, Par::Seq, Default::default()).or(
                dense_solve::solve_in_place_scratch::<usize, Real>(n, 1, Par::Seq),
            )
        } else {
            self.prepare_sparse(n)?
        };
        self.mem.reserve(req)
    }

    /// The sparse symbolic analysis of `W`'s pattern and the scratch it needs.
    #[cfg(feature = "sparse")]
    fn prepare_sparse(&mut self, n: usize) -> Result<StackReq, LcpError> {
        let symbolic = factorize_symbolic_lu(self.delassus.sparse_symbolic(), Default::default())
            .map_err(|e| LcpError::Factorization {
            rows: n,
            reason: format!("{e:?}"),
        })?;
        let req = symbolic
            .factorize_numeric_lu_scratch::<Real>(Par::Seq, Default::default())
            .or(symbolic.solve_in_place_scratch::<Real>(1, Par::Seq));
        self.symbolic = Some(symbolic);
        // faer 0.24's simplicial LU keeps the column pointers of a larger previous
        // matrix and then fails an assertion in the solve: start from fresh numeric
        // storage for every new pattern (it is reused across the iterations of a solve).
        self.numeric = NumericLu::new();
        self.k_values.clear();
        self.k_values.resize(self.delassus.nnz(), 0.0);
        Ok(req)
    }

    /// Without the `sparse` feature a sparse-assembled system cannot be factorised.
    #[cfg(not(feature = "sparse"))]
    fn prepare_sparse(&mut self, n: usize) -> Result<StackReq, LcpError> {
        Err(LcpError::Factorization {
            rows: n,
            reason: "sparse LU needs the `sparse` feature of deepcontact-lcp (on by default); \
                     use assembly=dense"
                .into(),
        })
    }

    /// Classifies the rows at the current iterate, fills `h = H(x)` and the Newton
    /// right-hand side, and returns `θ = ½‖H‖²`.
    #[allow(clippy::needless_range_loop)] // rows 2p and 2p + 1 of several arrays
    fn classify(&mut self) -> Real {
        let del = &self.delassus;
        let (m, mu) = (del.effective_mass(), del.friction());
        let mut theta = 0.0;
        for p in 0..del.points() {
            let (n, t) = (2 * p, 2 * p + 1);
            let (ln, lt) = (self.x[n], self.x[t]);
            let yn = ln - m[n] * self.w[n];
            let hn = ln - yn.max(0.0);
            self.h[n] = hn;
            if m[n] > 0.0 && yn > 0.0 {
                self.state[n] = RowState::Free;
                self.rhs[n] = -self.w[n];
            } else {
                self.state[n] = RowState::Fixed;
                self.rhs[n] = -hn;
            }
            let bound = (mu[p] * ln).max(0.0);
            let yt = lt - m[t] * self.w[t];
            let ht = lt - yt.max(-bound).min(bound);
            self.h[t] = ht;
            self.rhs[t] = -ht;
            self.state[t] = if m[t] <= 0.0 {
                RowState::Fixed
            } else if yt >= bound {
                RowState::Upper
            } else if yt <= -bound {
                RowState::Lower
            } else {
                self.rhs[t] = -self.w[t];
                RowState::Free
            };
            theta += hn * hn + ht * ht;
        }
        0.5 * theta
    }

    /// Solves `K d = rhs` into `self.d` with relative regularisation `reg`, growing it
    /// until the solution is finite and accurate; returns the regularisation used.
    fn newton_direction(
        &mut self,
        iteration: u32,
        mut reg: Real,
        scale: Real,
    ) -> Result<Real, LcpError> {
        let n = self.delassus.rows();
        loop {
            self.stats.factorizations += 1;
            self.stats.max_regularization = self.stats.max_regularization.max(reg);
            self.d.copy_from_slice(&self.rhs);
            let factored = if self.delassus.is_dense() {
                self.solve_dense(reg, scale)
            } else {
                self.solve_sparse(reg, scale)
            };
            if factored && self.step_is_accurate(reg, scale) {
                return Ok(reg);
            }
            if reg >= self.settings.max_regularization {
                return Err(LcpError::Singular {
                    rows: n,
                    regularization: reg,
                    iteration,
                });
            }
            reg = (reg * 100.0)
                .max(1e-12)
                .min(self.settings.max_regularization);
        }
    }

    /// Regularised diagonal entry of a free row: `W_ii (1 + reg)` (at least `reg × 1e-12 ×
    /// scale` above `W_ii`, for a row whose diagonal vanishes).
    #[inline(always)]
    fn regularized(w_ii: Real, reg: Real, scale: Real) -> Real {
        w_ii + reg * w_ii.max(1e-12 * scale)
    }

    /// The coefficient `K_rc` for a non-free row `r`.
    #[inline(always)]
    fn bound_row_entry(&self, r: usize, c: usize) -> Real {
        if r == c {
            return 1.0;
        }
        if !self.coupled {
            return 0.0;
        }
        let mu = self.delassus.friction()[r / 2];
        match self.state[r] {
            RowState::Upper if c + 1 == r => -mu,
            RowState::Lower if c + 1 == r => mu,
            _ => 0.0,
        }
    }

    /// Dense LU of `K` (faer, partial pivoting, in place in a reused buffer).
    fn solve_dense(&mut self, reg: Real, scale: Real) -> bool {
        let n = self.delassus.rows();
        let Some(w) = self.delassus.dense() else {
            return false;
        };
        self.k_dense.as_mut().copy_from(w);
        for r in 0..n {
            if self.state[r] == RowState::Free {
                self.k_dense[(r, r)] = Self::regularized(w[(r, r)], reg, scale);
            } else {
                for c in 0..n {
                    let v = self.bound_row_entry(r, c);
                    self.k_dense[(r, c)] = v;
                }
            }
        }
        let stack = MemStack::new(&mut self.mem.0);
        let (_, perm) = dense_lu::lu_in_place(
            self.k_dense.as_mut(),
            &mut self.perm,
            &mut self.perm_inv,
            Par::Seq,
            &mut *stack,
            Default::default(),
        );
        let lu = self.k_dense.as_ref();
        dense_solve::solve_in_place(
            lu,
            lu,
            perm,
            MatMut::from_column_major_slice_mut(&mut self.d, n, 1),
            Par::Seq,
            stack,
        );
        true
    }

    /// Without the `sparse` feature there is no sparse factorisation (never reached: `prepare`
    /// refuses sparse systems).
    #[cfg(not(feature = "sparse"))]
    fn solve_sparse(&mut self, _reg: Real, _scale: Real) -> bool {
        false
    }

    /// Sparse LU of `K` (faer, same pattern as `W`; symbolic analysis done in `prepare`).
    #[cfg(feature = "sparse")]
    fn solve_sparse(&mut self, reg: Real, scale: Real) -> bool {
        let n = self.delassus.rows();
        let Some(w) = self.delassus.sparse() else {
            return false;
        };
        for c in 0..n {
            let (s, e) = (w.symbolic().col_ptr()[c], w.symbolic().col_ptr()[c + 1]);
            for k in s..e {
                let r = w.symbolic().row_idx()[k];
                let v = if self.state[r] == RowState::Free {
                    if r == c {
                        Self::regularized(w.val()[k], reg, scale)
                    } else {
                        w.val()[k]
                    }
                } else {
                    self.bound_row_entry(r, c)
                };
                self.k_values[k] = v;
            }
        }
        let Some(symbolic) = self.symbolic.as_ref() else {
            return false;
        };
        let k = SparseColMatRef::new(self.delassus.sparse_symbolic(), &self.k_values);
        let stack = MemStack::new(&mut self.mem.0);
        let Ok(lu) = symbolic.factorize_numeric_lu(
            &mut self.numeric,
            k,
            Par::Seq,
            &mut *stack,
            Default::default(),
        ) else {
            return false;
        };
        lu.solve_in_place_with_conj(
            Conj::No,
            MatMut::from_column_major_slice_mut(&mut self.d, n, 1),
            Par::Seq,
            stack,
        );
        true
    }

    /// Whether `d` is finite and solves `K d = rhs` to a relative accuracy of 1e-8.
    fn step_is_accurate(&mut self, reg: Real, scale: Real) -> bool {
        if self.d.iter().any(|v| !v.is_finite()) {
            return false;
        }
        self.kd.fill(0.0);
        self.delassus.mul_add(&self.d, &mut self.kd);
        let mu = self.delassus.friction();
        let mut res: Real = 0.0;
        let mut rhs_max: Real = 0.0;
        let mut d_max: Real = 0.0;
        for r in 0..self.d.len() {
            let kd = match self.state[r] {
                RowState::Free => {
                    let w_ii = self.delassus.diagonal()[r];
                    self.kd[r] + (Self::regularized(w_ii, reg, scale) - w_ii) * self.d[r]
                }
                RowState::Fixed => self.d[r],
                RowState::Upper if self.coupled => self.d[r] - mu[r / 2] * self.d[r - 1],
                RowState::Lower if self.coupled => self.d[r] + mu[r / 2] * self.d[r - 1],
                RowState::Upper | RowState::Lower => self.d[r],
            };
            res = res.max((kd - self.rhs[r]).abs());
            rhs_max = rhs_max.max(self.rhs[r].abs());
            d_max = d_max.max(self.d[r].abs());
        }
        res <= 1e-8 * (rhs_max + scale.max(1.0) * d_max) || res == 0.0
    }

    /// Projected backtracking line search along `d`; leaves the accepted point in `trial`
    /// and its velocities in `w_trial`. Returns the accepted step, or `None`.
    ///
    /// Tries α = 1, β, β², … and then the first breakpoint (the largest α at which no
    /// normal impulse has crossed zero yet) when it is shorter: near-redundant contacts give
    /// Newton steps that are long along a nearly singular direction of `W`, and it is the
    /// first contact leaving (λn reaching 0) that makes progress there.
    fn line_search(&mut self, theta: Real) -> Option<Real> {
        let (sigma, beta) = (self.settings.armijo, self.settings.backtrack);
        let mut alpha = 1.0;
        for k in 0..=self.settings.max_backtracks {
            if self.try_step(alpha, theta, sigma) {
                self.stats.backtracks += k;
                return Some(alpha);
            }
            alpha *= beta;
        }
        self.stats.backtracks += self.settings.max_backtracks;
        let breakpoint = self
            .x
            .iter()
            .zip(&self.d)
            .step_by(2)
            .filter(|&(&x, &d)| x > 0.0 && d < 0.0 && x > MIN_BREAKPOINT * -d)
            .fold(Real::INFINITY, |m: Real, (&x, &d)| m.min(x / -d));
        (breakpoint < alpha / beta && self.try_step(breakpoint, theta, sigma)).then_some(breakpoint)
    }

    /// Evaluates `proj(x + αd)` into `trial` / `w_trial`; true if it passes the Armijo test.
    fn try_step(&mut self, alpha: Real, theta: Real, sigma: Real) -> bool {
        for ((t, &x), &d) in self.trial.iter_mut().zip(&self.x).zip(&self.d) {
            *t = x + alpha * d;
        }
        self.delassus.project(&mut self.trial);
        self.delassus.velocity_of(&self.trial, &mut self.w_trial);
        let theta_t = self.merit();
        theta_t.is_finite() && theta_t <= (1.0 - 2.0 * sigma * alpha) * theta
    }

    /// `(max |H|, ‖H‖₂)` at the current iterate.
    fn natural_norms(&self) -> (Real, Real) {
        let (inf, sq) = self.delassus.natural_norms(&self.x, &self.w);
        (inf, sq.sqrt())
    }

    /// `½‖H‖²` at `trial` (with `w_trial`).
    fn merit(&self) -> Real {
        0.5 * self.delassus.natural_norms(&self.trial, &self.w_trial).1
    }
}

impl VelocitySolver for NewtonSolver {
    fn name(&self) -> &str {
        "newton"
    }

    fn solve(
        &mut self,
        problem: &ContactProblem,
        settings: &SolverSettings,
        impulses: &mut [Impulse],
        velocities: &mut [Velocity],
        report: &mut SolveReport,
    ) -> Result<(), CoreError> {
        self.solve_lcp(problem, settings, impulses, velocities, report)
            .map_err(|e| e.into_core("newton"))
    }
}
