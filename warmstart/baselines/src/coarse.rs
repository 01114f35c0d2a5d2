//! The `coarse` provider: carried impulses corrected on a coarse level of layers or cells,
//! between PGS sweeps (a two-grid cycle).
//!
//! PGS is slow at the error that redistributes load through a pile: a change of the load
//! a body carries has to travel down, one contact a sweep (docs/RESEARCH.md). The coarse
//! level lumps the island's loaded contacts into horizontal layers of height `h` (by the
//! height of the contact point) and gives each layer one unknown, a normal impulse `c_g`
//! added to every loaded contact of the layer: `Δλ = P c`, `P` the layers' indicator
//! columns over the normal rows. The Galerkin coarse problem `(Pᵀ W P) c = Pᵀ r` — `W` the
//! Delassus operator `J M⁻¹ Jᵀ` (matrix-free), `r = b − J v(λ)` the normal rows' velocity
//! error — moves a whole layer's load at once. With a cell `width`, the groups are cells
//! `layer` high and `width` wide instead (by the contact point's height and abscissa), so that
//! the coarse level also moves load sideways. A round is `sweeps` PGS sweeps (smoothing),
//! the correction (projected onto the friction cones), and `sweeps` sweeps again; the
//! sweeps and the coarse solve are provider time, each coarse solve counted as one pass.

use deepcontact_core::{
    CarriedWarmStart, ContactProblem, Impulse, Real, SpecError, Velocity, WarmStart,
    WarmStartContext, WarmStartError,
};
use deepcontact_pgs::PgsSolver;

use crate::inner::{InnerSolve, in_range, sweeper};
use crate::rows::{apply_jt, in_cone, row_velocity, velocities_after};

/// Parameters of [`CoarseWarmStart`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CoarseConfig {
    /// Height of a layer (m; default 1, two circle radii of the pile; > 0).
    pub layer: Real,
    /// PGS sweeps before and after each correction (default 4, in 1..=1000).
    pub sweeps: u32,
    /// Rounds of sweeps, correction, sweeps (default 2, in 1..=100).
    pub rounds: u32,
    /// Width of a cell (m; default infinite: whole layers; > 0).
    pub width: Real,
}

impl Default for CoarseConfig {
    fn default() -> Self {
        Self {
            layer: 1.0,
            sweeps: 4,
            rounds: 2,
            width: Real::INFINITY,
        }
    }
}

/// Most cells an island's points span (larger islands get larger cells; the coarse solve is
/// dense).
const MAX_GROUPS: usize = 256;

/// Carried impulses corrected on a coarse level of layers or cells between PGS sweeps (see
/// the module docs). Buffers are kept between calls.
#[derive(Debug)]
pub struct CoarseWarmStart {
    config: CoarseConfig,
    inner: InnerSolve,
    solver: PgsSolver,
    /// Per point: its group (layer or cell), or `usize::MAX` when not loaded.
    group_of: Vec<usize>,
    /// Per cell: its index among the non-empty cells (scratch).
    cell_index: Vec<usize>,
    /// Row-sized scratch (impulses as rows, a group's indicator).
    flat: Vec<Real>,
    indicator: Vec<Real>,
    v: Vec<Velocity>,
    dv: Vec<Velocity>,
    /// The coarse system (`groups × groups`) and its right-hand side.
    matrix: Vec<Real>,
    rhs: Vec<Real>,
    last_passes: u32,
}

impl CoarseWarmStart {
    /// A provider under `config` (validated).
    pub fn new(config: CoarseConfig) -> Result<Self, SpecError> {
        if !(config.layer.is_finite() && config.layer > 0.0) {
            return Err(SpecError::InvalidParameter {
                spec: "coarse".into(),
                param: "layer".into(),
                value: config.layer.to_string(),
                reason: "must be finite and > 0".into(),
            });
        }
        if config.width.is_nan() || config.width <= 0.0 {
            return Err(SpecError::InvalidParameter {
                spec: "coarse".into(),
                param: "width".into(),
                value: config.width.to_string(),
                reason: "must be > 0 (inf: whole layers)".into(),
            });
        }
        in_range("coarse", "rounds", config.rounds, 1..=100)?;
        let inner = InnerSolve::new("coarse", "sweeps", config.sweeps, 1000, 0.0)?;
        Ok(Self {
            config,
            inner,
            solver: sweeper(),
            group_of: Vec::new(),
            cell_index: Vec::new(),
            flat: Vec::new(),
            indicator: Vec::new(),
            v: Vec::new(),
            dv: Vec::new(),
            matrix: Vec::new(),
            rhs: Vec::new(),
            last_passes: 0,
        })
    }

    /// `sweeps` PGS sweeps on `impulses`, counted.
    fn smooth(
        &mut self,
        problem: &ContactProblem,
        impulses: &mut [Impulse],
        cap: u32,
    ) -> Result<(), WarmStartError> {
        self.inner.run(
            &mut self.solver,
            problem,
            impulses,
            "coarse sweeps",
            Some(cap),
        )?;
        self.last_passes += self.inner.passes();
        Ok(())
    }

    /// The groups of the loaded points: cells `layer` high and `width` wide (an infinite width:
    /// whole layers), both sizes grown by a quarter at a time until at most [`MAX_GROUPS`] cells
    /// span the points, empty cells dropped; their count (0: nothing to correct).
    fn groups(&mut self, problem: &ContactProblem, impulses: &[Impulse]) -> usize {
        let loaded = |k: usize| impulses[k].normal > 0.0;
        let mut lo = [Real::INFINITY; 2];
        let mut hi = [Real::NEG_INFINITY; 2];
        for k in (0..impulses.len()).filter(|&k| loaded(k)) {
            let p = problem.points[k].point;
            for (i, x) in [p.x, p.y].into_iter().enumerate() {
                lo[i] = lo[i].min(x);
                hi[i] = hi[i].max(x);
            }
        }
        if !lo.iter().chain(&hi).all(|x| x.is_finite()) {
            return 0;
        }
        let (mut w, mut h) = (self.config.width, self.config.layer);
        // Counted in floating point: a tiny cell over a wide island overflows no integer.
        let span = |i: usize, size: Real| ((hi[i] - lo[i]) / size).floor() + 1.0;
        while span(0, w) * span(1, h) > MAX_GROUPS as Real {
            w *= 1.25;
            h *= 1.25;
        }
        let (cols, rows) = (span(0, w) as usize, span(1, h) as usize);
        self.group_of.clear();
        self.group_of.extend((0..impulses.len()).map(|k| {
            if loaded(k) {
                let p = problem.points[k].point;
                let col = (((p.x - lo[0]) / w) as usize).min(cols - 1);
                let row = (((p.y - lo[1]) / h) as usize).min(rows - 1);
                row * cols + col
            } else {
                usize::MAX
            }
        }));
        // Empty cells dropped (the coarse matrix has no zero rows), the rest numbered in
        // cell order.
        self.cell_index.clear();
        self.cell_index.resize(rows * cols, usize::MAX);
        for &g in self.group_of.iter().filter(|&&g| g != usize::MAX) {
            self.cell_index[g] = 0;
        }
        let mut count = 0;
        for c in self.cell_index.iter_mut().filter(|c| **c != usize::MAX) {
            *c = count;
            count += 1;
        }
        for g in self.group_of.iter_mut().filter(|g| **g != usize::MAX) {
            *g = self.cell_index[*g];
        }
        count
    }

    /// One coarse correction of `impulses` (normal rows of loaded points, by group).
    fn correct(&mut self, problem: &ContactProblem, impulses: &mut [Impulse]) {
        let count = self.groups(problem, impulses);
        if count == 0 {
            return;
        }
        let rows = 2 * impulses.len();
        velocities_after(problem, impulses, &mut self.flat, &mut self.v);
        self.rhs.clear();
        self.rhs.resize(count, 0.0);
        for (k, &g) in self.group_of.iter().enumerate() {
            if g != usize::MAX {
                let p = &problem.points[k];
                self.rhs[g] += p.velocity_bias - row_velocity(problem, 2 * k, &self.v);
            }
        }
        // Column g of Pᵀ W P: W applied to group g's indicator, summed over each group.
        self.matrix.clear();
        self.matrix.resize(count * count, 0.0);
        for g in 0..count {
            self.indicator.clear();
            self.indicator.resize(rows, 0.0);
            for (k, &group) in self.group_of.iter().enumerate() {
                if group == g {
                    self.indicator[2 * k] = 1.0;
                }
            }
            self.dv.resize(problem.bodies.len(), Velocity::default());
            apply_jt(problem, &self.indicator, &mut self.dv);
            for (k, &h) in self.group_of.iter().enumerate() {
                if h != usize::MAX {
                    self.matrix[h * count + g] += row_velocity(problem, 2 * k, &self.dv);
                }
            }
        }
        if !crate::spd::solve_spd(&mut self.matrix, &mut self.rhs, count, 1e-9, 1e-12) {
            return;
        }
        for ((imp, p), &g) in impulses.iter_mut().zip(&problem.points).zip(&self.group_of) {
            if g != usize::MAX {
                *imp = in_cone(imp.normal + self.rhs[g], imp.tangent, p.friction);
            }
        }
        self.last_passes += 1;
    }
}

impl WarmStart for CoarseWarmStart {
    fn name(&self) -> &str {
        "coarse"
    }

    fn warm_start(
        &mut self,
        ctx: &WarmStartContext<'_>,
        out: &mut [Impulse],
    ) -> Result<(), WarmStartError> {
        self.last_passes = 0;
        CarriedWarmStart.warm_start(ctx, out)?;
        if out.is_empty() {
            return Ok(());
        }
        let problem = ctx.problem;
        let budget = ctx.pass_budget.map(|b| b.saturating_sub(1));
        let left = |spent: u32| budget.map_or(u32::MAX, |b| b.saturating_sub(spent));
        for _ in 0..self.config.rounds {
            for correct in [false, true] {
                if correct {
                    if left(self.last_passes) == 0 {
                        return Ok(());
                    }
                    self.correct(problem, out);
                }
                let cap = self.config.sweeps.min(left(self.last_passes));
                if cap == 0 {
                    return Ok(());
                }
                self.smooth(problem, out, cap)?;
            }
        }
        Ok(())
    }

    fn passes_spent(&self) -> u32 {
        self.last_passes
    }
}
