//! The sequential-impulse velocity solver.
//!
//! Data layout: a manifold touches one body pair, so the solver loop loads the two body
//! velocities once per manifold, runs all of its rows on local copies, and stores them
//! once. Rows hold the cross products precomputed (`rn = r × n`, `rt = r × t`).
//!
//! This file holds the options, the solver and its stages in order (prepare, warm start,
//! iterate, end). One concept per submodule: `layout` (rows, manifolds, batches), `plan`
//! (colouring and batching), `sweep` (one sweep's arithmetic), `measures` (what a sweep
//! measures, the stop rule's verdict), `kernel` (the instruction set chosen at run time) and
//! `avx2` (the batch sweep in AVX2 intrinsics). The sweep's variants each have one too:
//! `chunked` (colour by colour in fixed chunks on threads), `domains` (the domain plan),
//! `lanes` (small islands packed into the lanes of shared batches) and `many` (a step's islands
//! solved together).

use std::time::Instant;

use deepcontact_core::math::{Real, Vector, Velocity};
use deepcontact_core::{
    ContactProblem, CoreError, Impulse, IslandSolve, ResidualNorm, SolveReport, SolverSettings,
    VelocitySolver,
};

use crate::PgsError;

mod again;
#[cfg(target_arch = "x86_64")]
mod avx2;
mod chunked;
mod domains;
mod kernel;
mod lanes;
mod layout;
mod many;
mod measures;
mod over_relaxation;
mod plan;
mod single;
mod stages;
mod sweep;
#[cfg(test)]
mod test_support;

pub(crate) use kernel::{BatchKernel, Island, KernelOp, dispatch};
pub use layout::LANES;
pub(crate) use layout::{Batch, Block, Manifold, Row, Segment, Vel};
pub(crate) use measures::{LaneSweep, Sweep, Verdict, judge};
pub use over_relaxation::OverRelaxation;
pub use stages::Stage;
pub(crate) use sweep::{Velocities, movable, sweep_batch, sweep_manifold};
use sweep::{
    apply, apply_tangent, clamp_sym, non_negative, normal_velocity, store, tangent_velocity,
};

/// Options of the PGS solver.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PgsSettings {
    /// Solve the two normal rows of a 2-point manifold together, as Box2D's block solver
    /// (default true; only polygon manifolds have two points).
    pub block_solver: bool,
    /// Validate the problem before solving (default true; costs one pass over the data).
    pub validate: bool,
    /// Order of the manifolds within a sweep (default [`Ordering::Coloured`]).
    pub ordering: Ordering,
    /// With [`Ordering::Coloured`], solve the single-point manifolds of a colour
    /// [`LANES`] at a time in structure-of-arrays batches (default true). The results are
    /// bit-identical to the one-at-a-time loop (the manifolds of a colour are independent and
    /// each lane does the scalar arithmetic); only `Σ Δλ²` is summed in another order.
    pub lanes: bool,
    /// Apply the warm start's tangent impulses as given, even outside the friction cone
    /// `|λt| ≤ μ λn`, as the original thesis code does (default false: projected onto the
    /// cone). Negative normal impulses are raised to 0 either way.
    pub raw_start: bool,
    /// Threads that share the sweep of one island in the chunked plan (default 1; 0 counts
    /// as 1; no more than the cores the process may use are started). The result is
    /// bit-identical for every thread count.
    pub threads: usize,
    /// Islands with at least this many contact points are swept in the domain plan or the
    /// chunked plan ([`domains`](Self::domains)) of [`threads`](Self::threads) (default
    /// 2048), with bodies renumbered in Z-order. Needs [`Ordering::Coloured`] and
    /// [`lanes`](Self::lanes). In the chunked plan each colour's batches are cut into fixed
    /// chunks whose impulse-change measures are combined in chunk order, whatever the thread
    /// count; the ∞ and contact norms, the impulses and the velocities are bit-identical to
    /// the unchunked sweep, only `Σ Δλ²` (the L2 norm) is summed in another order.
    pub parallel_min_points: usize,
    /// The most domains of the domain plan for islands of
    /// [`parallel_min_points`](Self::parallel_min_points) points or more (default 16; 0: the
    /// chunked plan instead; more than 63 count as 63, and the registry refuses them). The island's
    /// movable bodies are layered by a breadth-first walk of their contacts and cut into bands of
    /// layers holding about as many manifolds each (as many bands as
    /// [`domain_points`](Self::domain_points) says, up to this), each band's manifolds swept as an
    /// island of its own; a manifold's bodies lie in one band or in two neighbouring ones, so an
    /// iteration sweeps the even bands side by side on threads, then the odd ones, and threads take
    /// the bands of a phase from a queue (a slower thread takes fewer). Up to half the domains,
    /// rounded up, work on an island. Another Gauss-Seidel order than the unchunked sweep's, so
    /// other (equally valid) bits; the same bits for any thread count. The chunked plan (`0`) keeps
    /// the unchunked sweep's bits but shares every colour between threads through atomics, which
    /// scales worse.
    pub domains: usize,
    /// Contact points a domain of the domain plan holds at least (default 1 100; 0: always
    /// [`domains`](Self::domains)): an island of `n` points is cut into `n / domain_points`
    /// domains, at least 4 (two side by side in each phase) and at most `domains`. Short
    /// domains cost the one-thread sweep part-filled batches and a seam hand-over each an
    /// iteration (16 domains of a 5 260-point island: 1.23–1.32 × the plain sweep's step on
    /// one thread, 4 domains 1.06 ×, two threads the same for both; docs/PERFORMANCE.md).
    pub domain_points: usize,
    /// Batches ([`LANES`] single-point manifolds each) per chunk of the chunked plan
    /// (default 16; 0 counts as 1): the unit a thread takes, so no more threads share a colour
    /// than it has chunks. Changes only the order in which `Σ Δλ²` is summed.
    pub chunk: usize,
    /// Floating-point precision of the sweep's rows, impulses and velocities (default
    /// [`Precision::F64`]; `pgs:precision=f32`).
    pub precision: Precision,
    /// Measure the natural residual of the result into [`SolveReport::natural_residual`]
    /// (default true). The measure is one more pass over the points, in scalar code, so a
    /// provider that sweeps an island a few passes at a time and never reads it turns it off;
    /// the report then holds NaN. The impulses and
    /// velocities do not depend on it.
    pub natural_residual: bool,
    /// Over-relaxed shares of a solve's first `max_iterations − 1` sweeps (default
    /// [`OverRelaxation::NONE`]: every sweep plain; `pgs:sor=1.8/1.7/1.3`); meant for a fixed
    /// budget of passes.
    pub over_relaxation: OverRelaxation,
}

/// Floating-point precision of the velocity sweep.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Precision {
    /// `f64` throughout.
    #[default]
    F64,
    /// The iterations in `f32` (the precision of Box2D and rapier2d): the island prepared and
    /// warm-started in `f64`, then rounded once; the single-point manifolds of a colour swept
    /// [`2 × LANES`](LANES) at a time (eight `f32` lanes to one AVX2 register); the impulses and
    /// velocities widened back for the final projection, the checks and the natural residual
    /// in `f64`. Every island is swept on the calling thread in the plain coloured plan (no
    /// domain or chunked plan, no packing of small islands), so the result is the same bits
    /// for every [`PgsSettings::threads`].
    F32,
}

impl Default for PgsSettings {
    fn default() -> Self {
        Self {
            block_solver: true,
            validate: true,
            ordering: Ordering::Coloured,
            lanes: true,
            raw_start: false,
            threads: 1,
            parallel_min_points: 2048,
            domains: 16,
            domain_points: crate::DOMAIN_POINTS,
            chunk: crate::velocity::chunked::CHUNK,
            precision: Precision::F64,
            natural_residual: true,
            over_relaxation: OverRelaxation::NONE,
        }
    }
}

impl PgsSettings {
    /// The threads a solve with these settings shares one island of `points` contact points
    /// over: those of the domain or chunked plan (`f64`, coloured, laned, from
    /// [`parallel_min_points`](Self::parallel_min_points)), capped at this process's cores
    /// and, in the domain plan, at half the domains rounded up; else 1.
    pub fn threads_for(&self, points: usize) -> usize {
        if !self.plans_chunked(points) {
            return 1;
        }
        let threads = crate::threads::sync::effective_threads(self.threads);
        if self.domains > 0 {
            crate::threads::domain_sweep::useful_threads(threads, self.domains_for(points))
        } else {
            threads
        }
    }

    /// The domains of an island of `points` contact points in the domain plan
    /// ([`domain_points`](Self::domain_points)).
    pub(crate) fn domains_for(&self, points: usize) -> usize {
        crate::threads::partition::domains_for(points, self.domains, self.domain_points)
    }

    /// Whether an island of `points` contact points is swept in the chunked plan of
    /// [`crate::velocity::chunked`] or, with domains, the domain plan (`f64`, coloured, laned,
    /// and large enough).
    pub(crate) fn plans_chunked(&self, points: usize) -> bool {
        self.precision == Precision::F64
            && self.ordering == Ordering::Coloured
            && self.lanes
            && points >= self.parallel_min_points
    }
}

/// Order in which a sweep visits the manifolds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Ordering {
    /// The problem's order (pairs sorted by body index), as Box2D v2.4. Consecutive
    /// manifolds usually share a body, so each waits for the previous one's velocity
    /// update: the loop is bound by that dependency chain's latency.
    Sequential,
    /// Greedy graph colouring: manifolds are grouped so that no two of a colour share a
    /// dynamic body, and visited colour by colour (Box2D v3, Rapier). Still Gauss-Seidel —
    /// every row sees the latest velocities — but neighbouring manifolds of a colour are
    /// independent, so the CPU overlaps them. Deterministic (the colouring depends only
    /// on the problem).
    #[default]
    Coloured,
}

/// Projected Gauss-Seidel on sequential impulses (Box2D v2.4's `b2ContactSolver`).
#[derive(Debug, Clone, Default)]
pub struct PgsSolver {
    /// Options.
    pub settings: PgsSettings,
    pub(crate) rows: Vec<Row>,
    pub(crate) manifolds: Vec<Manifold>,
    pub(crate) vel: Vec<Vel>,
    /// Colour bit masks used per body while colouring.
    body_colours: Vec<u64>,
    /// Colour of each manifold, and the scratch copy used to reorder.
    colours: Vec<u8>,
    pub(crate) scratch: Vec<Manifold>,
    /// Batches of single-point manifolds and the sweep plan (empty: one at a time).
    pub(crate) batches: Vec<Batch>,
    pub(crate) segments: Vec<Segment>,
    /// For the chunked plan, the bodies of `vel` renumbered in Z-order of their positions (so
    /// that neighbours share cache lines); inactive: the problem's order.
    bodies: crate::threads::z_order::Renumbering,
    /// The instruction set the sweep loops run in, detected once when the solver is made:
    /// AVX2 + FMA (x86-64-v3) where the CPU has them, else the baseline. Same bits either way.
    pub(crate) arch: pulp::Arch,
    /// The domain plan's domains ([`PgsSettings::domains`]; empty otherwise).
    domains: crate::velocity::domains::Domains,
    /// The solvers of the small islands solved together ([`crate::velocity::lanes`]), one per
    /// island of a step, kept for the next.
    pub(crate) lane_solvers: Vec<PgsSolver>,
    /// The small islands of a step (their indices), and how each is swept.
    pub(crate) small_islands: Vec<usize>,
    pub(crate) small_kinds: Vec<crate::velocity::lanes::Kind>,
    /// The most threads one island's sweep has run on ([`Self::threads_used`]).
    pub(crate) threads_used: usize,
    /// The single-precision copy of the island ([`Precision::F32`]).
    single: single::Single,
    /// The batches' lanes' effective masses (normal, then tangent) under an over-relaxation
    /// schedule ([`crate::OverRelaxation`]), kept for its shares.
    batch_masses: Vec<[Real; 2 * LANES]>,
    /// The bodies of the island the plan held was built for ([`Self::solve_again`]; `None`
    /// when the buffers hold something else, e.g. small islands laid out side by side).
    planned_bodies: Option<usize>,
}

impl PgsSolver {
    /// A solver with default options.
    pub fn new() -> Self {
        Self::default()
    }

    /// A solver with the given options.
    pub fn with_settings(settings: PgsSettings) -> Self {
        Self {
            settings,
            ..Self::default()
        }
    }

    /// The most threads that one island's velocity sweep has run on with this solver since it
    /// was made (0 before its first solve; 1 when every sweep ran on the calling thread). The
    /// chunked and domain plans start no more threads than [`PgsSettings::threads`], the cores
    /// the process may use, and the work the island offers side by side (the widest colour's
    /// chunks; half the domains, rounded up). Tests read it to know that a thread count they
    /// ask for is the one that ran; it never changes a result.
    pub fn threads_used(&self) -> usize {
        self.threads_used
    }

    /// Stage 1, prepare: copy the problem into rows, manifolds and packed velocities.
    /// Stage 1: the island's plan (rows from `problem`'s points with `start`, their effective
    /// masses multiplied by `scale`'s factor when one is given; manifolds, block factors,
    /// colouring and batches).
    fn prepare(&mut self, problem: &ContactProblem, start: &[Impulse], scale: Option<&[Real]>) {
        self.reset_plan();
        self.planned_bodies = Some(problem.bodies.len());
        // The chunked plan's grid (none for the plain sweep: not a pass over the points more).
        let z = self
            .plans_chunked(problem.points.len())
            .then(|| crate::threads::z_order::ZOrder::of(&problem.points));
        match &z {
            Some(z) => self.bodies.build(z, &problem.bodies),
            None => self.bodies.clear(),
        }
        let vel = |b: &deepcontact_core::ProblemBody| Vel {
            vx: b.linear_velocity.x,
            vy: b.linear_velocity.y,
            w: b.angular_velocity,
        };
        self.vel.clear();
        if self.bodies.is_active() {
            let bodies = &problem.bodies;
            self.vel.extend(
                self.bodies
                    .body_of
                    .iter()
                    .map(|&b| vel(&bodies[b as usize])),
            );
        } else {
            self.vel.extend(problem.bodies.iter().map(vel));
        }
        self.rows.clear();
        let raw = self.settings.raw_start;
        self.rows.extend(
            problem
                .points
                .iter()
                .zip(start)
                .map(|(p, s)| Row::of(p, s, raw)),
        );
        if let Some(scale) = scale {
            for (row, &f) in self.rows.iter_mut().zip(scale) {
                row.normal_mass *= f;
                row.tangent_mass *= f;
            }
        }
        self.manifolds.clear();
        for &(s, e) in &problem.manifolds {
            if e == s {
                continue;
            }
            let p = &problem.points[s as usize];
            let (ba, bb) = (
                &problem.bodies[p.body_a as usize],
                &problem.bodies[p.body_b as usize],
            );
            let mut m = Manifold {
                a: p.body_a,
                b: p.body_b,
                start: s,
                count: e - s,
                ma: ba.inv_mass,
                ia: ba.inv_inertia,
                mb: bb.inv_mass,
                ib: bb.inv_inertia,
                block: None,
            };
            if self.settings.block_solver && m.count == 2 {
                let (r1, r2) = (&self.rows[s as usize], &self.rows[s as usize + 1]);
                let k11 = m.ma + m.mb + m.ia * r1.rna * r1.rna + m.ib * r1.rnb * r1.rnb;
                let k22 = m.ma + m.mb + m.ia * r2.rna * r2.rna + m.ib * r2.rnb * r2.rnb;
                let k12 = m.ma + m.mb + m.ia * r1.rna * r2.rna + m.ib * r1.rnb * r2.rnb;
                let det = k11 * k22 - k12 * k12;
                // Box2D's condition-number guard: k11² < 1000 det.
                if det > 0.0 && k11 * k11 < 1000.0 * det {
                    let inv = 1.0 / det;
                    m.block = Some(Block {
                        k11,
                        k12,
                        k22,
                        i11: k22 * inv,
                        i22: k11 * inv,
                        i12: -k12 * inv,
                    });
                }
            }
            self.manifolds.push(m);
        }
        if self.bodies.is_active() {
            let new = &self.bodies.new_index;
            for m in &mut self.manifolds {
                (m.a, m.b) = (new[m.a as usize], new[m.b as usize]);
            }
        }
        // The domain plan colours each of its parts instead (after the warm start).
        if self.settings.ordering == Ordering::Coloured && !self.plans_domains(problem.points.len())
        {
            self.colour(problem.bodies.len(), z.as_ref().map(|z| (z, problem)));
        }
    }

    /// Whether an island of `points` contact points is swept in the chunked plan of
    /// [`crate::velocity::chunked`] (coloured, laned, and large enough).
    pub(crate) fn plans_chunked(&self, points: usize) -> bool {
        self.settings.plans_chunked(points)
    }

    /// Whether an island of `points` contact points is swept in the domain plan of
    /// [`crate::velocity::domains`].
    fn plans_domains(&self, points: usize) -> bool {
        self.plans_chunked(points) && self.settings.domains > 0
    }

    /// Stage 2, warm start: apply the start impulses to the velocities.
    fn warm_start(&mut self) {
        for m in &self.manifolds {
            let (mut va, mut vb) = (self.vel[m.a as usize], self.vel[m.b as usize]);
            for r in &self.rows[m.start as usize..(m.start + m.count) as usize] {
                apply(m, r, &mut va, &mut vb, r.ln, r.lt);
            }
            store(self.vel.as_mut_slice(), m, va, vb);
        }
    }

    /// Stage 3, one Gauss-Seidel sweep. Returns its impulse changes' measures; the
    /// per-contact measure only with `CONTACT` (the hot loop carries no extra work otherwise).
    /// Inlined into [`Self::solve_loop`]'s instruction-set context.
    #[inline(always)]
    pub(crate) fn iterate<const CONTACT: bool, K: BatchKernel>(&mut self, kernel: K) -> Sweep {
        let (plan, vel) = self.plan();
        plan.sweep::<CONTACT, K>(kernel, vel)
    }

    /// [`Self::iterate`] on the velocities `vel` instead of the solver's own: those of the
    /// island a domain of the domain plan belongs to, when the domains share one thread and
    /// the plan's bodies are the island's ([`crate::velocity::domains`]).
    #[inline(always)]
    pub(crate) fn iterate_on<const CONTACT: bool, K: BatchKernel>(
        &mut self,
        kernel: K,
        vel: &mut [Vel],
    ) -> Sweep {
        self.plan().0.sweep::<CONTACT, K>(kernel, vel)
    }

    /// The sweep plan, apart from the velocities it sweeps.
    #[inline(always)]
    fn plan(&mut self) -> (Plan<'_>, &mut [Vel]) {
        let Self {
            manifolds,
            segments,
            batches,
            scratch,
            rows,
            vel,
            ..
        } = self;
        (
            Plan {
                manifolds,
                segments,
                batches,
                serial: scratch,
                rows,
            },
            vel,
        )
    }

    /// Stage 3's loop on this thread: sweep until the stop rule holds, the cap is reached or
    /// a change is not finite. Returns the iterations run and the last verdict. The whole
    /// loop runs compiled for the solver's instruction set ([`SolveLoop`]).
    fn solve_loop(
        &mut self,
        settings: &SolverSettings,
        report: &mut SolveReport,
    ) -> (u32, Verdict) {
        dispatch(
            self.arch,
            SolveLoop {
                sweeps: self,
                settings,
                report,
            },
        )
    }

    /// Friction rows were clamped against the normal impulse of the previous sweep; a
    /// last projection onto the final cone `|λt| ≤ μ λn` (its change applied to the
    /// velocities, so both stay consistent) makes the returned impulses admissible even
    /// when the cap was hit. The change is at most μ × the last normal change.
    fn project_friction(&mut self) {
        for m in &self.manifolds {
            let (mut va, mut vb) = (self.vel[m.a as usize], self.vel[m.b as usize]);
            for r in &mut self.rows[m.start as usize..(m.start + m.count) as usize] {
                let new = clamp_sym(r.lt, r.friction * r.ln);
                if new != r.lt {
                    let d = new - r.lt;
                    r.lt = new;
                    apply_tangent(m, r, &mut va, &mut vb, d);
                }
            }
            store(self.vel.as_mut_slice(), m, va, vb);
        }
    }

    /// The error for a sweep that produced a non-finite impulse or velocity.
    fn diverged(&self, iteration: u32) -> PgsError {
        let point = self
            .rows
            .iter()
            .position(|r| !(r.ln.is_finite() && r.lt.is_finite()))
            .unwrap_or(0);
        PgsError::Diverged { point, iteration }
    }

    /// Natural-map residual of the current impulses and velocities, in impulse units.
    fn natural_residual(&self) -> Real {
        let mut res: Real = 0.0;
        for m in &self.manifolds {
            let (va, vb) = (&self.vel[m.a as usize], &self.vel[m.b as usize]);
            for r in &self.rows[m.start as usize..(m.start + m.count) as usize] {
                let rn = r.ln
                    - non_negative(r.ln - r.normal_mass * (normal_velocity(r, va, vb) - r.bias));
                let rt = r.lt
                    - clamp_sym(
                        r.lt - r.tangent_mass * tangent_velocity(r, va, vb),
                        r.friction * r.ln,
                    );
                res = res.max(rn.abs()).max(rt.abs());
            }
        }
        res
    }
}

/// A solver's sweep plan, borrowed apart from the velocities it sweeps: the manifolds (swept
/// one at a time when there are no segments), the segments of batches and one-at-a-time
/// manifolds, and the rows.
struct Plan<'a> {
    manifolds: &'a [Manifold],
    segments: &'a [Segment],
    batches: &'a mut [Batch],
    serial: &'a [Manifold],
    rows: &'a mut [Row],
}

impl Plan<'_> {
    /// One Gauss-Seidel sweep over `vel`: each segment's batches, then its one-at-a-time
    /// manifolds. Returns the impulse changes' measures (the per-contact one only with
    /// `CONTACT`).
    #[inline(always)]
    fn sweep<const CONTACT: bool, K: BatchKernel>(self, kernel: K, vel: &mut [Vel]) -> Sweep {
        let mut acc = Sweep::default();
        if self.segments.is_empty() {
            for m in self.manifolds {
                sweep_manifold::<CONTACT, _>(m, self.rows, vel, &mut acc);
            }
            return acc;
        }
        let mut lanes = LaneSweep::default();
        for seg in self.segments {
            kernel.sweep::<CONTACT>(&mut self.batches[seg.batches.clone()], vel, &mut lanes);
            for m in &self.serial[seg.manifolds.clone()] {
                sweep_manifold::<CONTACT, _>(m, self.rows, vel, &mut acc);
            }
        }
        acc.add_lanes(&lanes);
        acc
    }
}

/// What stage 3's loop sweeps once an iteration: a solver's own plan, or the domains of the
/// domain plan on one thread ([`crate::velocity::domains`]).
pub(crate) trait Sweeps {
    /// One Gauss-Seidel sweep (the per-contact measure only with `CONTACT`), inlined into the
    /// loop's instruction-set context.
    fn sweep_once<const CONTACT: bool, K: BatchKernel>(&mut self, kernel: K) -> Sweep;
}

impl Sweeps for PgsSolver {
    #[inline(always)]
    fn sweep_once<const CONTACT: bool, K: BatchKernel>(&mut self, kernel: K) -> Sweep {
        self.iterate::<CONTACT, K>(kernel)
    }
}

/// Stage 3's loop as an operation of [`pulp::Arch::dispatch`]: sweep until the stop rule
/// holds, the cap is reached or a change is not finite, every iteration's residuals recorded in
/// `report`; the iterations run and the last verdict. The whole loop (every sweep, its kernels
/// inlined) is compiled once per instruction set — with AVX2 and FMA enabled, each lane field
/// of a [`Batch`] is one 256-bit register. The arithmetic is the same IEEE operations in the
/// same order (Rust never contracts `a * b + c` into a fused multiply-add), so the bits do not
/// depend on the instruction set. (A closure in place of [`Sweeps`] is compiled outside that
/// context: its kernels become calls, ≈ 35 × slower.)
pub(crate) struct SolveLoop<'a, S> {
    pub(crate) sweeps: &'a mut S,
    pub(crate) settings: &'a SolverSettings,
    pub(crate) report: &'a mut SolveReport,
}

impl<S: Sweeps> KernelOp for SolveLoop<'_, S> {
    type Output = (u32, Verdict);

    #[inline(always)]
    fn run<K: BatchKernel>(self, kernel: K) -> Self::Output {
        let contact = self.settings.norm == ResidualNorm::Contact;
        let mut it = 0;
        while it < self.settings.max_iterations {
            let sweep = if contact {
                self.sweeps.sweep_once::<true, K>(kernel)
            } else {
                self.sweeps.sweep_once::<false, K>(kernel)
            };
            it += 1;
            match judge(self.settings, it, &sweep, Some(self.report)) {
                Verdict::Continue => {}
                end => return (it, end),
            }
        }
        (it, Verdict::Continue)
    }
}

impl PgsSolver {
    /// Stages 1 and 2 of a solve: checks, prepare, warm start.
    pub(crate) fn begin(
        &mut self,
        problem: &ContactProblem,
        settings: &SolverSettings,
        impulses: &[Impulse],
        velocities: &[Velocity],
        report: &mut SolveReport,
    ) -> Result<(), CoreError> {
        self.begin_scaled(problem, settings, impulses, velocities, report, None)
    }

    /// [`Self::begin`] with the rows' effective masses multiplied by `scale`'s factors.
    pub(crate) fn begin_scaled(
        &mut self,
        problem: &ContactProblem,
        settings: &SolverSettings,
        impulses: &[Impulse],
        velocities: &[Velocity],
        report: &mut SolveReport,
        scale: Option<&[Real]>,
    ) -> Result<(), CoreError> {
        deepcontact_core::solver::begin_solve(
            problem,
            settings,
            self.settings.validate,
            impulses,
            velocities,
            report,
        )?;
        self.prepare(problem, impulses, scale);
        self.warm_start();
        report
            .residual_inf
            .reserve(settings.max_iterations.min(4096) as usize);
        report
            .residual_l2
            .reserve(settings.max_iterations.min(4096) as usize);
        Ok(())
    }

    /// Stage 3 in the plan the island's size calls for: the iterations run and the verdict.
    pub(crate) fn run(
        &mut self,
        points: usize,
        settings: &SolverSettings,
        report: &mut SolveReport,
    ) -> (u32, Verdict) {
        let (it, verdict, threads) = if self.settings.precision == Precision::F32 {
            let (it, verdict) = self.run_single(settings, report);
            (it, verdict, 1)
        } else if self.plans_domains(points) {
            self.domains.build(
                self.settings.domains_for(points),
                crate::threads::sync::effective_threads(self.settings.threads),
                &self.manifolds,
                &self.rows,
                &self.vel,
                self.settings,
            );
            let run = self.domains.solve(
                crate::threads::sync::effective_threads(self.settings.threads),
                self.arch,
                settings,
                report,
                &mut self.vel,
            );
            self.domains.write_back(&mut self.rows, &mut self.vel);
            run
        } else if self.plans_chunked(points) && !self.segments.is_empty() {
            crate::velocity::chunked::solve_chunked(
                &mut crate::velocity::chunked::Sweepable {
                    batches: &mut self.batches,
                    segments: &self.segments,
                    serial: &self.scratch,
                    rows: &mut self.rows,
                    vel: &mut self.vel,
                },
                self.settings.chunk.max(1),
                crate::threads::sync::effective_threads(self.settings.threads),
                self.arch,
                settings,
                report,
            )
        } else {
            let (it, verdict) = self.solve_loop(settings, report);
            (it, verdict, 1)
        };
        self.threads_used = self.threads_used.max(threads);
        (it, verdict)
    }

    /// Stage 4 of a solve that ran `it` iterations to `verdict`: the final projection, the
    /// checks, and the impulses, velocities and natural residual stored.
    pub(crate) fn end(
        &mut self,
        it: u32,
        verdict: Verdict,
        impulses: &mut [Impulse],
        velocities: &mut [Velocity],
        report: &mut SolveReport,
    ) -> Result<(), CoreError> {
        self.sync_rows();
        if verdict == Verdict::Diverged {
            return Err(self.diverged(it).into());
        }
        report.converged = verdict == Verdict::Converged;
        report.iterations = it;
        self.project_friction();
        let finite = |v: &Vel| v.vx.is_finite() && v.vy.is_finite() && v.w.is_finite();
        if !(self
            .rows
            .iter()
            .all(|r| r.ln.is_finite() && r.lt.is_finite())
            && self.vel.iter().all(finite))
        {
            return Err(self.diverged(it).into());
        }
        // Store impulses and velocities.
        for (imp, r) in impulses.iter_mut().zip(&self.rows) {
            *imp = Impulse::new(r.ln, r.lt);
        }
        let velocity = |v: &Vel| Velocity::new(Vector::new(v.vx, v.vy), v.w);
        if !self.bodies.is_active() {
            for (out, v) in velocities.iter_mut().zip(&self.vel) {
                *out = velocity(v);
            }
        } else {
            for (&b, v) in self.bodies.body_of.iter().zip(&self.vel) {
                velocities[b as usize] = velocity(v);
            }
        }
        report.natural_residual = if self.settings.natural_residual {
            self.natural_residual()
        } else {
            Real::NAN
        };
        Ok(())
    }
}

impl VelocitySolver for PgsSolver {
    fn name(&self) -> &str {
        "pgs"
    }

    /// The same settings on one thread (a fork solves one island beside others; the result
    /// does not depend on the thread count).
    fn fork(&self) -> Option<Box<dyn VelocitySolver>> {
        Some(Box::new(PgsSolver::with_settings(PgsSettings {
            threads: 1,
            ..self.settings
        })))
    }

    fn threads_for(&self, points: usize) -> usize {
        self.settings.threads_for(points)
    }

    fn solve(
        &mut self,
        problem: &ContactProblem,
        settings: &SolverSettings,
        impulses: &mut [Impulse],
        velocities: &mut [Velocity],
        report: &mut SolveReport,
    ) -> Result<(), CoreError> {
        let t0 = Instant::now();
        self.begin(problem, settings, impulses, velocities, report)?;
        let (it, verdict) = self.run_scheduled(problem, settings, report);
        self.end(it, verdict, impulses, velocities, report)?;
        report.seconds = t0.elapsed().as_secs_f64();
        Ok(())
    }

    fn solve_many(&mut self, settings: &SolverSettings, islands: &mut [IslandSolve<'_>]) {
        self.solve_islands(settings, islands);
    }

    /// `false` with [`PgsSettings::raw_start`] (tangents applied as given).
    fn projects_start(&self) -> bool {
        !self.settings.raw_start
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use deepcontact_core::{CarriedWarmStart, WorldSettings, scene};

    fn pile_problem() -> ContactProblem {
        let mut world = scene::pile(12345, 100)
            .unwrap()
            .build(WorldSettings::default())
            .unwrap();
        let (mut s, mut p) = (PgsSolver::new(), crate::PgsPositionSolver::new());
        for _ in 0..130 {
            world.step(&mut CarriedWarmStart, &mut s, &mut p).unwrap();
        }
        world
            .last_problems()
            .iter()
            .max_by_key(|p| p.len())
            .unwrap()
            .clone()
    }

    #[test]
    fn colouring_never_puts_two_manifolds_on_one_movable_body_in_a_colour() {
        let problem = pile_problem();
        let mut solver = PgsSolver::new();
        solver.prepare(&problem, &vec![Impulse::ZERO; problem.len()], None);
        assert_eq!(solver.manifolds.len(), problem.manifolds.len());
        let mut colours = solver.colours.clone();
        colours.sort_unstable();
        let mut seen = std::collections::HashSet::new();
        for (i, m) in solver.manifolds.iter().enumerate() {
            if i > 0 && colours[i] != colours[i - 1] {
                seen.clear();
            }
            if colours[i] == 64 {
                continue;
            }
            for (body, im, ii) in [(m.a, m.ma, m.ia), (m.b, m.mb, m.ib)] {
                if movable(im, ii) {
                    assert!(
                        seen.insert(body),
                        "body {body} twice in colour {}",
                        colours[i]
                    );
                }
            }
        }
    }

    /// Without the natural residual's measure a solve leaves the same impulses and velocities,
    /// bit for bit, and says it did not measure (NaN), where the default measures a residual
    /// the cut solve left above zero.
    #[test]
    fn a_solve_without_the_natural_residual_leaves_the_same_bits() {
        let problem = pile_problem();
        let start = vec![Impulse::ZERO; problem.len()];
        let off = PgsSettings {
            natural_residual: false,
            ..PgsSettings::default()
        };
        let on = solve_bits(&problem, &start, PgsSettings::default(), 8);
        assert_eq!(on.2, 8);
        assert_eq!(on, solve_bits(&problem, &start, off, 8));
        let residual = |settings| {
            let (mut imp, mut report) = (start.clone(), SolveReport::default());
            let mut vel = vec![Velocity::default(); problem.bodies.len()];
            let stop = SolverSettings {
                max_iterations: 8,
                ..SolverSettings::default()
            };
            PgsSolver::with_settings(settings)
                .solve(&problem, &stop, &mut imp, &mut vel, &mut report)
                .unwrap();
            report.natural_residual
        };
        let measured = residual(PgsSettings::default());
        assert!(measured > 0.0 && measured.is_finite(), "{measured}");
        assert!(residual(off).is_nan());
    }

    #[test]
    fn coloured_and_sequential_orders_reach_the_same_velocities() {
        let problem = pile_problem();
        let settings = SolverSettings {
            tolerance: 1e-10,
            max_iterations: 100_000,
            ..SolverSettings::default()
        };
        let mut out = Vec::new();
        for ordering in [Ordering::Sequential, Ordering::Coloured] {
            let mut solver = PgsSolver::with_settings(PgsSettings {
                ordering,
                ..PgsSettings::default()
            });
            let mut imp = vec![Impulse::ZERO; problem.len()];
            let mut vel = vec![Velocity::default(); problem.bodies.len()];
            let mut report = SolveReport::default();
            solver
                .solve(&problem, &settings, &mut imp, &mut vel, &mut report)
                .unwrap();
            assert!(report.converged);
            out.push(vel);
        }
        for (v1, v2) in out[0].iter().zip(&out[1]) {
            assert!(
                (v1.linear - v2.linear).norm() < 1e-6 && (v1.angular - v2.angular).abs() < 1e-6
            );
        }
    }

    /// Solves `problem` from `start` with the given options; returns the impulses and
    /// velocities as bits.
    fn solve_bits(
        problem: &ContactProblem,
        start: &[Impulse],
        settings: PgsSettings,
        iterations: u32,
    ) -> (Vec<u64>, Vec<u64>, u32) {
        let stop = SolverSettings {
            max_iterations: iterations,
            ..SolverSettings::default()
        };
        solve_bits_with(problem, start, settings, &stop).0
    }

    /// [`solve_bits`] under the stop rule `stop`; also returns the L2 residuals as bits.
    fn solve_bits_with(
        problem: &ContactProblem,
        start: &[Impulse],
        settings: PgsSettings,
        stop: &SolverSettings,
    ) -> ((Vec<u64>, Vec<u64>, u32), Vec<u64>) {
        solve_bits_on(problem, start, settings, stop, pulp::Arch::new())
    }

    /// Impulses and velocities as bits, and the iterations run; then the L2 residuals as bits.
    type SolveBits = ((Vec<u64>, Vec<u64>, u32), Vec<u64>);

    /// [`solve_bits_with`] with the sweeps compiled for `arch`.
    fn solve_bits_on(
        problem: &ContactProblem,
        start: &[Impulse],
        settings: PgsSettings,
        stop: &SolverSettings,
        arch: pulp::Arch,
    ) -> SolveBits {
        solve_bits_and_threads(problem, start, settings, stop, arch).0
    }

    /// A solver with `settings` (sweeping with `arch`) after solving `problem` from `start`
    /// under `stop`, with the impulses, velocities and report of the solve.
    fn solved(
        problem: &ContactProblem,
        start: &[Impulse],
        settings: PgsSettings,
        stop: &SolverSettings,
        arch: pulp::Arch,
    ) -> (PgsSolver, Vec<Impulse>, Vec<Velocity>, SolveReport) {
        let mut solver = PgsSolver::with_settings(settings);
        solver.arch = arch;
        let mut imp = start.to_vec();
        let mut vel = vec![Velocity::default(); problem.bodies.len()];
        let mut report = SolveReport::default();
        solver
            .solve(problem, stop, &mut imp, &mut vel, &mut report)
            .unwrap();
        (solver, imp, vel, report)
    }

    /// [`solve_bits_on`], and the threads the sweep ran on ([`PgsSolver::threads_used`]).
    fn solve_bits_and_threads(
        problem: &ContactProblem,
        start: &[Impulse],
        settings: PgsSettings,
        stop: &SolverSettings,
        arch: pulp::Arch,
    ) -> (SolveBits, usize) {
        let (solver, imp, vel, report) = solved(problem, start, settings, stop, arch);
        let l2 = report.residual_l2.iter().map(|r| r.to_bits()).collect();
        let bits = (
            imp.iter()
                .flat_map(|i| [i.normal.to_bits(), i.tangent.to_bits()])
                .collect(),
            vel.iter()
                .flat_map(|v| {
                    [
                        v.linear.x.to_bits(),
                        v.linear.y.to_bits(),
                        v.angular.to_bits(),
                    ]
                })
                .collect(),
            report.iterations,
        );
        ((bits, l2), solver.threads_used())
    }

    /// The cores this process may use; a machine with one core cannot show that threads
    /// agree, so under `CI=true` (whose machines have two or more) that is a failure.
    fn cores() -> usize {
        let cores = std::thread::available_parallelism().map_or(1, std::num::NonZero::get);
        assert!(
            cores >= 2 || std::env::var("CI").as_deref() != Ok("true"),
            "CI=true on a machine with {cores} core: no second thread can run"
        );
        cores
    }

    /// The pile's largest island and the pyramid's (2-point manifolds, swept one at a time
    /// by thread 0 of the chunked plan).
    fn pile_and_pyramid() -> Vec<ContactProblem> {
        let mut problems = vec![pile_problem()];
        let mut world = scene::pyramid(6).build(WorldSettings::default()).unwrap();
        let (mut s, mut p) = (PgsSolver::new(), crate::PgsPositionSolver::new());
        for _ in 0..40 {
            world.step(&mut CarriedWarmStart, &mut s, &mut p).unwrap();
        }
        problems.extend(world.last_problems().iter().cloned());
        problems
    }

    /// A start with load on every point (growing with the point's index).
    fn loaded_start(problem: &ContactProblem) -> Vec<Impulse> {
        (0..problem.len())
            .map(|i| Impulse::new(0.01 * i as Real, 0.001 * i as Real))
            .collect()
    }

    /// A tight stop rule (1e-6) in each norm.
    fn tight_stops() -> [SolverSettings; 3] {
        [
            ResidualNorm::Infinity,
            ResidualNorm::Contact,
            ResidualNorm::L2,
        ]
        .map(|norm| SolverSettings {
            norm,
            tolerance: 1e-6,
            ..SolverSettings::default()
        })
    }

    /// The solver's impulses (rows) and velocities as bits.
    fn state_bits(solver: &PgsSolver) -> (Vec<u64>, Vec<u64>) {
        let rows = solver
            .rows
            .iter()
            .flat_map(|r| [r.ln.to_bits(), r.lt.to_bits()])
            .collect();
        let vel = solver
            .vel
            .iter()
            .flat_map(|v| [v.vx.to_bits(), v.vy.to_bits(), v.w.to_bits()])
            .collect();
        (rows, vel)
    }

    /// Runs `sweep` (a loop straight past the clamp to the machine's cores) on the 100-body
    /// pile from zero with 1 to 5 threads, after `settings`' prepare and warm start, and checks
    /// that every run converges to the same bits (impulses, velocities, iterations, L2 curve).
    fn same_bits_on_one_to_five_threads(
        settings: PgsSettings,
        sweep: impl Fn(&mut PgsSolver, usize, &SolverSettings, &mut SolveReport) -> (u32, Verdict),
    ) {
        let problem = pile_problem();
        let stop = SolverSettings {
            tolerance: 1e-5,
            ..SolverSettings::default()
        };
        let runs: Vec<_> = (1..=5)
            .map(|threads| {
                let mut solver = PgsSolver::with_settings(settings);
                solver.prepare(&problem, &vec![Impulse::ZERO; problem.len()], None);
                solver.warm_start();
                let mut report = SolveReport::default();
                let (it, verdict) = sweep(&mut solver, threads, &stop, &mut report);
                let (rows, vel) = state_bits(&solver);
                (it, verdict, rows, vel, report.residual_l2)
            })
            .collect();
        assert_eq!(runs[0].1, Verdict::Converged);
        assert!(runs[0].0 > 10);
        for r in &runs[1..] {
            assert!(r == &runs[0]);
        }
    }

    #[test]
    fn chunked_plan_gives_the_same_bits_on_one_to_five_real_threads() {
        // One batch a chunk, so that a 100-body island has chunks for five threads.
        same_bits_on_one_to_five_threads(
            PgsSettings::default(),
            |solver, threads, stop, report| {
                let run = crate::velocity::chunked::solve_chunked(
                    &mut crate::velocity::chunked::Sweepable {
                        batches: &mut solver.batches,
                        segments: &solver.segments,
                        serial: &solver.scratch,
                        rows: &mut solver.rows,
                        vel: &mut solver.vel,
                    },
                    1,
                    threads,
                    solver.arch,
                    stop,
                    report,
                );
                solver.sync_rows();
                assert_eq!(run.2, threads, "threads that ran");
                (run.0, run.1)
            },
        );
    }

    #[test]
    fn chunked_sweep_is_bit_identical_on_one_two_and_more_threads_than_cores() {
        // One batch a chunk, so that the pile's colours have chunks for several threads; the
        // thread counts asked for are 1, 2 and one more than the cores (capped at the cores).
        // The pyramid's manifolds all have two points (no batches): thread 0 sweeps them.
        let cores = cores();
        for (k, problem) in pile_and_pyramid().iter().enumerate() {
            let start = loaded_start(problem);
            for stop in tight_stops() {
                let norm = stop.norm;
                let unchunked = solve_bits_with(problem, &start, PgsSettings::default(), &stop);
                let runs: Vec<_> = [1, 2, cores + 1]
                    .map(|threads| {
                        let settings = PgsSettings {
                            threads,
                            parallel_min_points: 0,
                            domains: 0,
                            chunk: 1,
                            ..PgsSettings::default()
                        };
                        let (bits, used) = solve_bits_and_threads(
                            problem,
                            &start,
                            settings,
                            &stop,
                            pulp::Arch::new(),
                        );
                        let expected = if k == 0 { threads.min(cores) } else { 1 };
                        assert_eq!(used, expected, "problem {k}: {threads} threads asked for");
                        bits
                    })
                    .into();
                assert!(runs[0].0.2 > 1, "ran {} iterations", runs[0].0.2);
                assert_eq!(runs[0], runs[1], "{norm:?}: 1 and 2 threads");
                assert_eq!(runs[0], runs[2], "{norm:?}: 1 and {cores} threads");
                if norm != ResidualNorm::L2 {
                    // Only Σ Δλ² is summed in chunk order.
                    assert_eq!(runs[0].0, unchunked.0, "{norm:?}: chunked and unchunked");
                }
            }
        }
    }

    #[test]
    fn more_threads_than_cores_run_on_the_cores() {
        // The chunked plan (one batch a chunk) and the domain plan (8 domains: 4 side by
        // side) asked for 64 threads run on the cores, or on the work there is if less.
        let cores = cores();
        let problem = pile_problem();
        let start = loaded_start(&problem);
        for (domains, most) in [(0, usize::MAX), (8, 4)] {
            let settings = PgsSettings {
                threads: 64,
                parallel_min_points: 0,
                domains,
                domain_points: 0,
                chunk: 1,
                ..PgsSettings::default()
            };
            let stop = SolverSettings::default();
            let (_, used) =
                solve_bits_and_threads(&problem, &start, settings, &stop, pulp::Arch::new());
            assert_eq!(used, cores.min(most), "{domains} domains");
        }
    }

    #[test]
    fn f32_gives_the_same_bits_on_any_thread_count_and_instruction_set() {
        // Settings under which an f64 solve of the pile would share it between threads (every
        // island large, two and four threads, domain and chunked plans): the f32 path sweeps
        // on the calling thread in wide batches, the same bits every time.
        let detected = pulp::Arch::new();
        for (k, problem) in pile_and_pyramid().into_iter().enumerate() {
            let start = loaded_start(&problem);
            let stop = SolverSettings {
                tolerance: 1e-4,
                ..SolverSettings::default()
            };
            let run = |threads, domains, arch| {
                let settings = PgsSettings {
                    threads,
                    parallel_min_points: 0,
                    domains,
                    chunk: 1,
                    precision: Precision::F32,
                    ..PgsSettings::default()
                };
                solve_bits_and_threads(&problem, &start, settings, &stop, arch)
            };
            let (first, on) = run(1, 0, detected);
            assert_eq!(on, 1);
            assert!(first.0.2 > 1, "ran {} iterations", first.0.2);
            for (threads, domains) in [(2, 0), (4, 0), (2, 3), (4, 8)] {
                let (bits, on) = run(threads, domains, detected);
                assert_eq!(on, 1, "{threads} threads, {domains} domains ran on {on}");
                assert_eq!(bits, first, "{threads} threads, {domains} domains");
            }
            assert_eq!(
                run(2, 3, pulp::Arch::Scalar).0,
                first,
                "baseline, problem {k}"
            );
        }
    }

    #[test]
    fn f32_converges_on_the_pile_in_wide_batches_near_the_f64_solution() {
        let problem = pile_problem();
        let start = vec![Impulse::default(); problem.len()];
        let stop = SolverSettings {
            tolerance: 1e-5,
            max_iterations: 2000,
            ..SolverSettings::default()
        };
        let solve = |precision| {
            let mut solver = PgsSolver::with_settings(PgsSettings {
                precision,
                ..PgsSettings::default()
            });
            let (mut imp, mut report) = (start.clone(), SolveReport::default());
            let mut vel = vec![Velocity::default(); problem.bodies.len()];
            solver
                .solve(&problem, &stop, &mut imp, &mut vel, &mut report)
                .unwrap();
            (imp, report, solver.single.wide_batches())
        };
        let (wide, single, batches) = solve(Precision::F32);
        let (exact, double, _) = solve(Precision::F64);
        assert!(batches > 0, "the pile was swept in {batches} wide batches");
        assert!(single.converged && double.converged);
        assert!(
            single.iterations <= 2 * double.iterations,
            "f32 {} iterations, f64 {}",
            single.iterations,
            double.iterations
        );
        let scale = exact.iter().map(|i| i.normal.abs()).fold(0.0, Real::max);
        let gap = wide
            .iter()
            .zip(&exact)
            .map(|(a, b)| {
                (a.normal - b.normal)
                    .abs()
                    .max((a.tangent - b.tangent).abs())
            })
            .fold(0.0, Real::max);
        assert!(
            gap < 1e-2 * scale,
            "largest impulse gap {gap}, largest impulse {scale}"
        );
    }

    #[test]
    fn precision_is_a_registry_parameter_and_a_bad_value_a_typed_error() {
        let mut registry = deepcontact_core::registry::Registry::default();
        crate::register(&mut registry);
        assert!(registry.build_solver("pgs:precision=f32").is_ok());
        assert!(registry.build_solver("pgs:precision=f64").is_ok());
        let err = registry.build_solver("pgs:precision=f16").err().unwrap();
        assert!(
            matches!(
                &err,
                deepcontact_core::registry::SpecError::InvalidParameter { param, value, .. }
                    if param == "precision" && value == "f16"
            ),
            "{err}"
        );
    }

    #[test]
    fn detected_instruction_set_and_baseline_give_the_same_bits() {
        // The detected set (AVX2 + FMA on most x86-64 machines) against the baseline build of
        // the same loops: plain, chunked on one thread (whole loop dispatched) and on two (each
        // item dispatched), both sweep variants (`CONTACT` or not).
        let detected = pulp::Arch::new();
        let cores = cores();
        for (k, problem) in pile_and_pyramid().into_iter().enumerate() {
            let start = loaded_start(&problem);
            // (threads, parallel_from, domains); the chunked plans one batch a chunk, so that
            // two threads share the pile's colours.
            let plans = [
                (1, usize::MAX, 0),
                (1, 0, 0),
                (2, 0, 0),
                (1, 0, 2),
                (2, 0, 3),
            ];
            for (threads, parallel_min_points, domains) in plans {
                for norm in [ResidualNorm::Infinity, ResidualNorm::Contact] {
                    let stop = SolverSettings {
                        norm,
                        tolerance: 1e-6,
                        ..SolverSettings::default()
                    };
                    let settings = PgsSettings {
                        threads,
                        parallel_min_points,
                        domains,
                        chunk: 1,
                        ..PgsSettings::default()
                    };
                    let (baseline, on_baseline) = solve_bits_and_threads(
                        &problem,
                        &start,
                        settings,
                        &stop,
                        pulp::Arch::Scalar,
                    );
                    let (fast, on_detected) =
                        solve_bits_and_threads(&problem, &start, settings, &stop, detected);
                    if k == 0 {
                        // The pile: the plans on two threads ran on two.
                        let expected = threads.min(cores);
                        assert_eq!((on_baseline, on_detected), (expected, expected));
                    }
                    assert!(baseline.0.2 > 1, "ran {} iterations", baseline.0.2);
                    assert_eq!(
                        baseline, fast,
                        "{threads} threads, {domains} domains, {norm:?}"
                    );
                }
            }
        }
    }

    #[test]
    fn lanes_are_bit_identical_to_one_manifold_at_a_time() {
        // Circles (single-point manifolds, batched) and a pyramid of boxes (2-point
        // manifolds with the block solver, one at a time), from zero and carried starts.
        let problems = pile_and_pyramid();
        let mut batched = 0;
        for problem in &problems {
            let carried: Vec<Impulse> = (0..problem.len())
                .map(|i| Impulse::new(0.01 * i as Real, 0.001 * i as Real))
                .collect();
            for start in [vec![Impulse::ZERO; problem.len()], carried] {
                let one = PgsSettings {
                    lanes: false,
                    ..PgsSettings::default()
                };
                let reference = solve_bits(problem, &start, one, 300);
                let lanes = solve_bits(problem, &start, PgsSettings::default(), 300);
                assert_eq!(reference, lanes);
            }
            let mut solver = PgsSolver::new();
            solver.prepare(problem, &vec![Impulse::ZERO; problem.len()], None);
            batched += solver.batches.len();
        }
        assert!(batched > 0, "no batch was formed");
    }

    #[test]
    fn domain_plan_is_bit_identical_for_one_to_four_threads_and_up_to_eight_domains() {
        // Every norm, 1 to 8 domains (8 give all four threads a domain of each phase), a
        // start with load on every point; the residuals of every iteration are compared too.
        for problem in pile_and_pyramid() {
            let start = loaded_start(&problem);
            for stop in tight_stops() {
                let norm = stop.norm;
                for domains in [1, 2, 3, 5, 8] {
                    let runs: Vec<_> = (1..=4)
                        .map(|threads| {
                            let settings = PgsSettings {
                                threads,
                                parallel_min_points: 0,
                                domains,
                                domain_points: 0,
                                ..PgsSettings::default()
                            };
                            solve_bits_with(&problem, &start, settings, &stop)
                        })
                        .collect();
                    assert!(runs[0].0.2 > 1, "ran {} iterations", runs[0].0.2);
                    for (k, r) in runs.iter().enumerate().skip(1) {
                        assert!(
                            r == &runs[0],
                            "{norm:?}, {domains} domains: {} threads differ from 1",
                            k + 1
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn the_default_domain_plan_cuts_a_small_island_into_four_domains() {
        // The pile's island (a few hundred points) in the domain plan with the default
        // `domains` (16) and `domain_points` (1 100): four domains, not sixteen.
        let problem = pile_problem();
        let settings = PgsSettings {
            parallel_min_points: 0,
            ..PgsSettings::default()
        };
        let stop = SolverSettings::default();
        let (solver, _, _, report) = solved(
            &problem,
            &loaded_start(&problem),
            settings,
            &stop,
            pulp::Arch::new(),
        );
        assert!(
            report.iterations > 1,
            "ran {} iterations",
            report.iterations
        );
        assert_eq!(solver.domains.partition.n, 4);
    }

    #[test]
    fn domain_plan_gives_the_same_bits_on_one_to_five_real_threads() {
        // 8 domains of the 100-body pile on up to five threads (more threads than the 4 even
        // domains work on none).
        let settings = PgsSettings {
            parallel_min_points: 0,
            ..PgsSettings::default()
        };
        same_bits_on_one_to_five_threads(settings, |solver, threads, stop, report| {
            // The parts built on the same threads as the sweep.
            let d = &mut solver.domains;
            d.build(
                8,
                threads,
                &solver.manifolds,
                &solver.rows,
                &solver.vel,
                solver.settings,
            );
            let run = d.solve(threads, solver.arch, stop, report, &mut solver.vel);
            d.write_back(&mut solver.rows, &mut solver.vel);
            // No more threads than the 4 even domains.
            assert_eq!(run.2, threads.min(4), "threads that ran");
            (run.0, run.1)
        });
    }

    #[test]
    fn domain_plan_reaches_the_unchunked_sweeps_accuracy() {
        // Another Gauss-Seidel order, the same problem: at a tight tolerance both stop at a
        // natural residual of the same order, and the velocities agree to that order.
        for problem in pile_and_pyramid() {
            let stop = SolverSettings {
                tolerance: 1e-9,
                max_iterations: 20_000,
                ..SolverSettings::default()
            };
            let solve = |settings: PgsSettings| {
                let mut solver = PgsSolver::with_settings(settings);
                let mut imp = vec![Impulse::ZERO; problem.len()];
                let mut vel = vec![Velocity::default(); problem.bodies.len()];
                let mut report = SolveReport::default();
                solver
                    .solve(&problem, &stop, &mut imp, &mut vel, &mut report)
                    .unwrap();
                (vel, report)
            };
            let (plain, plain_report) = solve(PgsSettings::default());
            let (split, split_report) = solve(PgsSettings {
                parallel_min_points: 0,
                threads: 2,
                ..PgsSettings::default()
            });
            assert!(plain_report.converged && split_report.converged);
            assert!(
                split_report.natural_residual < 1e-6,
                "domain plan stopped at {:e}",
                split_report.natural_residual
            );
            let scale = plain
                .iter()
                .map(|v| v.linear.norm().max(v.angular.abs()))
                .fold(1.0, Real::max);
            for (a, b) in plain.iter().zip(&split) {
                let d = (a.linear - b.linear)
                    .norm()
                    .max((a.angular - b.angular).abs());
                assert!(d < 1e-5 * scale, "velocities differ by {d:e}");
            }
        }
    }

    #[test]
    fn domains_share_movable_bodies_only_with_their_neighbours() {
        // Every manifold in exactly one domain, every row once; a movable body moved by one domain
        // or by two neighbouring ones (then it is a seam body, linked in both), so two domains
        // of one parity never move the same body.
        let problem = pile_problem();
        let mut solver = PgsSolver::with_settings(PgsSettings {
            parallel_min_points: 0,
            ..PgsSettings::default()
        });
        solver.prepare(&problem, &vec![Impulse::ZERO; problem.len()], None);
        for n in 1..=9 {
            let d = &mut solver.domains;
            d.build(
                n,
                n % 3 + 1,
                &solver.manifolds,
                &solver.rows,
                &solver.vel,
                solver.settings,
            );
            let manifolds: usize = d.parts.iter().map(|p| p.manifolds.len()).sum();
            assert_eq!(manifolds, solver.manifolds.len(), "{n} domains");
            let mut rows: Vec<u32> = d.rows_of.iter().flatten().copied().collect();
            rows.sort_unstable();
            assert_eq!(rows, (0..problem.len() as u32).collect::<Vec<_>>());
            let mut movers = vec![Vec::new(); solver.vel.len()];
            for (p, part) in d.parts.iter().enumerate() {
                for m in &part.manifolds {
                    for (b, moves) in [(m.a, movable(m.ma, m.ia)), (m.b, movable(m.mb, m.ib))] {
                        let body = d.partition.bodies_of[p][b as usize] as usize;
                        if moves && !movers[body].contains(&p) {
                            movers[body].push(p);
                        }
                    }
                }
            }
            let mut seams = Vec::new();
            for (body, domains) in movers.iter().enumerate() {
                match domains[..] {
                    [] | [_] => {}
                    [p, q] => {
                        assert_eq!(p.abs_diff(q), 1, "body {body} in domains {p} and {q}");
                        seams.push(body as u32);
                    }
                    _ => panic!("body {body} moved by domains {domains:?}"),
                }
            }
            assert_eq!(d.partition.shared, seams, "{n} domains");
            // Each domain links exactly its seam bodies to their shared values.
            for (p, range) in d.partition.link_ranges.iter().enumerate() {
                let linked: Vec<u32> = d.partition.links[range.clone()]
                    .iter()
                    .map(|&(s, k)| {
                        let body = d.partition.bodies_of[p][s as usize];
                        assert_eq!(body, d.partition.shared[k as usize]);
                        body
                    })
                    .collect();
                let own: Vec<u32> = seams
                    .iter()
                    .copied()
                    .filter(|&b| movers[b as usize].contains(&p))
                    .collect();
                assert_eq!(linked, own, "domain {p} of {n}");
            }
            let used = d.parts.iter().filter(|p| !p.manifolds.is_empty()).count();
            assert_eq!(
                used, n,
                "{n} domains of a 100-body pile: {used} hold manifolds"
            );
            assert_eq!(seams.is_empty(), n == 1, "{n} domains");
        }
    }
}
