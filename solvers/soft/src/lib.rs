//! # deepcontact-soft
//!
//! The soft-step baseline: Box2D v3's contact solver (v3.1, `src/solver.c`,
//! `src/contact_solver.c`) as a [`VelocitySolver`]. Per world step, `substeps` substeps of
//! length `h = dt / substeps`, each:
//!
//! 1. **integrate velocities** — gravity `h g` (no damping);
//! 2. **warm start** — the points' accumulated impulses applied (for the first substep, the
//!    world's start impulses divided by the substep count; after that, the previous
//!    substep's);
//! 3. **solve** — one pass with soft contacts ([`soft`]: stiffness `hertz`, damping ratio
//!    `damping`, push-out at most `push` m/s);
//! 4. **integrate positions** — the bodies' displacements `Δp += h v`, `Δθ += h ω`;
//! 5. **relax** — `relax` passes without bias (rigid rows at the new positions);
//!
//! then, once, **restitution**, and **store**. The contacts are not collided again inside
//! the step: each point's separation follows its bodies' displacements,
//! `s = s₀ + (Δp_b + rot(Δθ_b) r_b − r_b − Δp_a − rot(Δθ_a) r_a + r_a) · n`, with the normal
//! and the anchors of the narrow phase.
//!
//! **Positions.** The soft step moves the bodies inside the step, so the solver owns its
//! islands' positions ([`VelocitySolver::owns_positions`] is `true`): the world calls
//! [`VelocitySolver::begin_step`] with `dt` and gravity before its solves, solves each island
//! with [`VelocitySolver::solve_with_positions`], moves the island's dynamic bodies by the
//! displacements returned there (not by `dt × v`) and runs no position pass on them.
//! Gravity: the world has already added the whole step's `dt g` to the velocities in the
//! problem; the solver takes it back out (`v₀ = v − dt g`) and adds `h g` per substep.
//!
//! **Units of the impulses.** The start handed to a solve and the impulses it returns are
//! the world's: N·s accumulated over the whole step. A substep's accumulated impulse is
//! N·s over the substep: the first substep's warm start is the start divided by the substep
//! count, and the returned impulse is the sum of the substeps' accumulated impulses (and
//! restitution's). A resting box of mass `m` returns `≈ m g dt`, and its next step warm
//! starts each substep with `≈ m g h`, as Box2D's persistent substep impulse.
//!
//! **Passes.** A pass is one sweep over the rows (solve or relax); the warm start and
//! restitution are not counted. The report's `iterations` is the passes spent, one residual
//! per pass (max and root-sum-square of the impulse changes, converted to N·s per step: the
//! substep change × the substep count). How a fixed budget `K` maps onto substeps:
//! [`schedule`]. The soft step never stops early: `converged` says whether the last pass's
//! change met the stop rule (a relax pass after a soft pass rarely changes nothing, so most
//! steps count as capped), and `natural_residual` is measured as `pgs` measures it, on the
//! rigid problem at the final velocities.
//!
//! **Order.** Rows are swept in the problem's manifold order, normal rows first, then
//! friction rows (Box2D v3.1's order; its colouring changes only the order of manifolds).
//! Islands are independent and the arithmetic does not depend on threads, so results are
//! bit-identical for any thread count. Buffers are kept in the solver (no allocation per
//! pass).
//!
//! Use it as `soft` in the comparison (`--solvers pgs,soft`) or pass [`SoftSolver`] to
//! `World::step` (it moves its islands' bodies itself; pass the PGS position solver anyway, it
//! skips them).
//!
//! Guides, with code that CI compiles and runs: [embed the solver in your
//! engine](https://github.com/deepcontact/deepcontact/blob/main/docs/guide/embed.md), [reproduce
//! the thesis and run the
//! suite](https://github.com/deepcontact/deepcontact/blob/main/docs/guide/reproduce.md), [use
//! deepcontact from your own
//! crate](https://github.com/deepcontact/deepcontact/blob/main/docs/guide/depend.md).
#![warn(missing_docs)]

mod integrate;
mod prepare;
mod registry;
mod restitution;
pub mod schedule;
pub mod soft;
mod solve;
mod store;
mod warm_start;

use std::time::Instant;

use deepcontact_core::math::{Pose, Real, Vector, Velocity};
use deepcontact_core::{
    ContactProblem, CoreError, Impulse, SolveReport, SolverSettings, VelocitySolver,
};

pub use registry::register;
pub use schedule::Schedule;
pub use soft::{ContactSoftness, Softness};

use prepare::Island;
use solve::{PassParams, pass};

/// Options of the soft-step solver (the `soft:` spec's parameters).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SoftSettings {
    /// Substeps per world step in the tolerance mode (default 4, Box2D v3's; ≥ 1). A fixed
    /// budget sets its own ([`schedule`]).
    pub substeps: u32,
    /// Relax passes per substep (default 1, Box2D v3's).
    pub relax: u32,
    /// Contact stiffness (Hz, default 30, Box2D v3's `contactHertz`; ≥ 0, 0 = rigid without
    /// push-out), used up to a quarter of the substep rate; contacts with an immovable body
    /// use twice this.
    pub hertz: Real,
    /// Contact damping ratio (dimensionless, default 10, Box2D v3's `contactDampingRatio`;
    /// ≥ 0).
    pub damping: Real,
    /// Largest push-out speed of an overlap (m/s, default 3, Box2D v3's
    /// `contactPushMaxVelocity`; > 0).
    pub push: Real,
    /// Validate the problem before solving (default true; one pass over the data).
    pub validate: bool,
}

impl Default for SoftSettings {
    fn default() -> Self {
        Self {
            substeps: 4,
            relax: 1,
            hertz: 30.0,
            damping: 10.0,
            push: 3.0,
            validate: true,
        }
    }
}

impl SoftSettings {
    /// Rejects a zero substep count, a negative or non-finite stiffness or damping ratio, and
    /// a push-out speed that is not finite and positive.
    pub fn validate(&self) -> Result<(), CoreError> {
        let bad = |name, value, reason| {
            Err(CoreError::InvalidSetting {
                name,
                value,
                reason,
            })
        };
        if self.substeps == 0 {
            return bad("soft.substeps", 0.0, "must be >= 1");
        }
        if !(self.hertz.is_finite() && self.hertz >= 0.0) {
            return bad("soft.hertz", self.hertz, "must be finite and >= 0");
        }
        if !(self.damping.is_finite() && self.damping >= 0.0) {
            return bad("soft.damping", self.damping, "must be finite and >= 0");
        }
        if !(self.push.is_finite() && self.push > 0.0) {
            return bad("soft.push", self.push, "must be finite and > 0");
        }
        Ok(())
    }
}

/// The soft-step solver (Box2D v3 style; see the crate docs).
#[derive(Debug, Clone)]
pub struct SoftSolver {
    /// Options.
    pub settings: SoftSettings,
    /// The world step's length (s) and gravity (m/s²), from
    /// [`VelocitySolver::begin_step`] (defaults: the world's, 0.01 s and (0, −9.81)).
    dt: Real,
    gravity: Vector,
    island: Island,
    /// Where [`VelocitySolver::solve`] puts the displacements it does not return.
    displacements: Vec<Pose>,
}

impl Default for SoftSolver {
    fn default() -> Self {
        Self::with_settings(SoftSettings::default())
    }
}

impl SoftSolver {
    /// A solver with default options.
    pub fn new() -> Self {
        Self::default()
    }

    /// A solver with the given options (checked when solving).
    pub fn with_settings(settings: SoftSettings) -> Self {
        Self {
            settings,
            dt: 0.01,
            gravity: Vector::new(0.0, -9.81),
            island: Island::default(),
            displacements: Vec::new(),
        }
    }

    /// The step length (s) and gravity (m/s²) the next solves use.
    pub fn step(&self) -> (Real, Vector) {
        (self.dt, self.gravity)
    }

    /// The checks before a step: the shared prologue ([`begin_solve`]), the norm, the
    /// options, the displacement buffer's length and the step length of [`Self::begin_step`].
    ///
    /// [`begin_solve`]: deepcontact_core::solver::begin_solve
    fn begin(
        &self,
        problem: &ContactProblem,
        settings: &SolverSettings,
        impulses: &[Impulse],
        velocities: &[Velocity],
        displacements: &[Pose],
        report: &mut SolveReport,
    ) -> Result<(), CoreError> {
        deepcontact_core::solver::begin_solve(
            problem,
            settings,
            self.settings.validate,
            impulses,
            velocities,
            report,
        )?;
        settings.require_norm_supported("soft")?;
        self.settings.validate()?;
        if displacements.len() != problem.bodies.len() {
            return Err(CoreError::LengthMismatch {
                what: "displacements",
                expected: problem.bodies.len(),
                got: displacements.len(),
            });
        }
        if !(self.dt.is_finite() && self.dt > 0.0) {
            return Err(CoreError::InvalidSetting {
                name: "dt",
                value: self.dt,
                reason: "must be finite and > 0",
            });
        }
        Ok(())
    }

    /// The whole soft step of one island; see [`VelocitySolver::solve_with_positions`].
    fn solve_step(
        &mut self,
        problem: &ContactProblem,
        settings: &SolverSettings,
        impulses: &mut [Impulse],
        velocities: &mut [Velocity],
        displacements: &mut [Pose],
        report: &mut SolveReport,
    ) -> Result<(), CoreError> {
        let t0 = Instant::now();
        self.begin(
            problem,
            settings,
            impulses,
            velocities,
            displacements,
            report,
        )?;
        let schedule = Schedule::new(self.settings.substeps, self.settings.relax, settings);
        let n = Real::from(schedule.substeps);
        let h = self.dt / n;
        let softness = ContactSoftness::new(self.settings.hertz, self.settings.damping, h);
        // Stage 1: prepare (takes the step's gravity back out of the velocities).
        self.island.prepare(
            problem,
            impulses,
            schedule.substeps,
            self.dt,
            self.gravity,
            &softness,
        )?;
        let passes = schedule.passes() as usize;
        report.residual_inf.reserve(passes);
        report.residual_l2.reserve(passes);
        let solve = PassParams {
            inv_h: 1.0 / h,
            push: self.settings.push,
            use_bias: true,
        };
        let relax = PassParams {
            use_bias: false,
            ..solve
        };
        // Per-pass measures in N·s per step (a substep's change × the substep count).
        let mut record = |m: solve::PassMeasure| {
            report.residual_inf.push(m.max * n);
            report.residual_l2.push(m.sum_sq.sqrt() * n);
        };
        for _ in 0..schedule.substeps {
            // Stage 2: integrate velocities (h g).
            integrate::integrate_velocities(&mut self.island.bodies, h, self.gravity);
            // Stage 3: warm start.
            warm_start::warm_start(&mut self.island);
            // Stage 4: solve, with the soft bias.
            record(pass(&mut self.island, solve));
            // Stage 5: integrate positions.
            integrate::integrate_positions(&mut self.island.bodies, h);
            // Stage 6: relax, without bias.
            for _ in 0..schedule.relax {
                record(pass(&mut self.island, relax));
            }
            // This substep's impulses into the step's sums.
            for p in &mut self.island.points {
                p.total_normal += p.normal;
                p.total_tangent += p.tangent;
            }
        }
        // Stage 7: restitution.
        restitution::restitution(&mut self.island);
        // Stage 8: store.
        store::store(&self.island, impulses, velocities, displacements);
        check_finite(impulses, velocities, displacements)?;
        report.iterations = schedule.passes();
        report.natural_residual = store::natural_residual(problem, impulses, velocities);
        report.converged = settings.converged(
            report.iterations,
            report.final_residual(),
            report.residual_l2.last().copied().unwrap_or(0.0),
            0.0,
        );
        report.seconds = t0.elapsed().as_secs_f64();
        Ok(())
    }
}

/// A typed error unless every impulse, velocity and displacement the step wrote is finite.
fn check_finite(
    impulses: &[Impulse],
    velocities: &[Velocity],
    displacements: &[Pose],
) -> Result<(), CoreError> {
    let finite = impulses.iter().all(Impulse::is_finite)
        && velocities.iter().zip(displacements).all(|(v, d)| {
            v.linear.x.is_finite()
                && v.linear.y.is_finite()
                && v.angular.is_finite()
                && d.position.x.is_finite()
                && d.position.y.is_finite()
                && d.angle.is_finite()
        });
    if finite {
        Ok(())
    } else {
        Err(CoreError::Solver {
            solver: "soft".into(),
            reason: "non-finite impulse, velocity or displacement".into(),
        })
    }
}

impl VelocitySolver for SoftSolver {
    fn name(&self) -> &str {
        "soft"
    }

    /// The soft step with the displacements dropped: the velocities and impulses of
    /// [`VelocitySolver::solve_with_positions`], for a caller that integrates positions
    /// itself.
    fn solve(
        &mut self,
        problem: &ContactProblem,
        settings: &SolverSettings,
        impulses: &mut [Impulse],
        velocities: &mut [Velocity],
        report: &mut SolveReport,
    ) -> Result<(), CoreError> {
        let mut displacements = std::mem::take(&mut self.displacements);
        displacements.clear();
        displacements.resize(problem.bodies.len(), Pose::default());
        let result = self.solve_step(
            problem,
            settings,
            impulses,
            velocities,
            &mut displacements,
            report,
        );
        self.displacements = displacements;
        result
    }

    /// The same options and step (`dt`, gravity), fresh buffers.
    fn fork(&self) -> Option<Box<dyn VelocitySolver>> {
        let mut fork = SoftSolver::with_settings(self.settings);
        (fork.dt, fork.gravity) = (self.dt, self.gravity);
        Some(Box::new(fork))
    }

    /// Keeps the step's `dt` (s) and `gravity` (m/s²) for the solves of the step.
    fn begin_step(&mut self, dt: Real, gravity: Vector) {
        self.dt = dt;
        self.gravity = gravity;
    }

    /// `true`: the soft step integrates positions inside its substeps.
    fn owns_positions(&self) -> bool {
        true
    }

    /// The soft step of the crate docs; `displacements` receives each body's change of
    /// position (m) and angle (rad) over the step (`Σ h v`, `Σ h ω` over the substeps).
    fn solve_with_positions(
        &mut self,
        problem: &ContactProblem,
        settings: &SolverSettings,
        impulses: &mut [Impulse],
        velocities: &mut [Velocity],
        displacements: &mut [Pose],
        report: &mut SolveReport,
    ) -> Result<(), CoreError> {
        self.solve_step(
            problem,
            settings,
            impulses,
            velocities,
            displacements,
            report,
        )
    }
}

#[cfg(test)]
mod tests;
