//! The world and its step pipeline.
//!
//! **Solvers that own positions (the soft step).** A velocity solver that integrates inside
//! the step, as Box2D v3's substeps do (`deepcontact-soft`), says so with
//! [`VelocitySolver::owns_positions`]. The pipeline keeps its stages and order; for such a
//! solver:
//! * before the solves, [`VelocitySolver::begin_step`] tells it the step's `dt` and gravity
//!   (every solver is told; the others ignore it). The problem's velocities still hold the
//!   whole step's gravity from IntegrateVelocities: the solver takes it back out and applies
//!   it per substep;
//! * each island is solved by [`VelocitySolver::solve_with_positions`] (one island a call,
//!   on any thread: the results do not depend on the thread count), which also returns each
//!   body's displacement over the step;
//! * IntegratePositions moves the islands' dynamic bodies by those displacements instead of
//!   `dt ×` their velocities (the same translation and rotation clamps, applied to the
//!   displacement and scaling the velocity with it); bodies in no island, and kinematic
//!   bodies, move by `dt × v` as always;
//! * PositionPass does not run on those islands (the soft contacts and relax passes already
//!   handled the overlap); the report's smallest separation is measured at the new poses.
//!
//! For every other solver (`pgs`, `psor`, `newton`) none of this runs and the step is
//! unchanged to the bit.

use std::time::Instant;

use crate::body::{Body, BodyDesc, BodyHandle, BodyKind};
use crate::broad_phase::BroadPhase;
use crate::contact::{ContactId, Impulse};
use crate::error::CoreError;
use crate::island::Islands;
use crate::math::{Pose, Real, Vector, Velocity};
use crate::narrow_phase::{NarrowPhase, RawContact};
use crate::problem::{ContactProblem, PointDesc, ProblemBody};
use crate::report::{SolveReport, StepReport};
use crate::shared_collide::{SHARED_COLLIDE_MIN_BODIES, SharedCollide};
use crate::solver::{
    PositionReport, PositionSettings, PositionSolver, SolverSettings, VelocitySolver,
};
use crate::warm_start::{GuardPolicy, Observation, WarmStart, WarmStartContext, check_output};

/// The largest pass budget [`WorldSettings::budget`] accepts (a fixed budget is a small
/// number of passes; the tolerance mode serves long solves).
pub const MAX_BUDGET: u32 = 100_000;

/// Settings of a world. Defaults are the thesis's.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WorldSettings {
    /// Gravity (default `(0, -9.81)` m/s²).
    pub gravity: Vector,
    /// Time step (default 0.01 s). Must be finite and > 0.
    pub dt: Real,
    /// Velocity solver stop rule (default: cap 1000, tolerance 1e-4, ∞-norm, ≥ 1 iteration).
    pub solver: SolverSettings,
    /// Position pass settings (default: cap 250, tolerance 1e-4, Baumgarte 0.2, slop 0.0005).
    pub position: PositionSettings,
    /// Points with separation up to this are kept as contacts (default 0: touching only,
    /// as Box2D v2.4 circles).
    pub prediction: Real,
    /// Closing speed above which restitution applies (default 1 m/s, Box2D's value).
    pub restitution_threshold: Real,
    /// Largest translation per step; faster bodies are slowed (default 2 m, Box2D's value).
    pub max_translation: Real,
    /// Largest rotation per step (default π/2, Box2D's value).
    pub max_rotation: Real,
    /// What to do when a warm start fails (default: fall back to zeros and count).
    pub guard: GuardPolicy,
    /// Threads that solve a step's islands side by side, each with its own copy of the
    /// velocity solver ([`VelocitySolver::fork`]; a solver that cannot fork solves them one
    /// after another), and then correct them side by side with copies of the position pass
    /// ([`PositionSolver::fork`]), when no island holds more than a thread's share of the
    /// points (default 1; at least 1). Providers are always called on the stepping
    /// thread in island order, every island's warm start before the first solve and every
    /// observation after the last, whatever this is, so results are bit-identical for any
    /// count.
    pub island_threads: usize,
    /// Threads of the collide stage (default 1; at least 1; no more than the cores used). A
    /// world of 4 096 bodies or more shares the whole stage out (the broad phase's bounds and
    /// cell pairs and the narrow phase, in chunks, with helpers started before the bounds); a
    /// smaller one shares the narrow phase's pairs, each thread a contiguous share of at least
    /// [`MIN_PAIRS_PER_THREAD`](crate::narrow_phase::MIN_PAIRS_PER_THREAD). The contacts are
    /// the same, in the same order, for any count.
    pub collide_threads: usize,
    /// A fixed budget of constraint passes per island and step, the provider's own included
    /// (default `None`: the velocity solve runs under [`Self::solver`]'s stop rule alone).
    /// `Some(K)` (K ≥ 2): the provider may spend up to K − 1 passes
    /// ([`WarmStartContext::pass_budget`]) and says what it spent
    /// ([`WarmStart::passes_spent`]); the solver then runs exactly K − spent iterations
    /// (at least 1), whatever [`Self::solver`]'s tolerance and cap say. A pass is one sweep
    /// over the island's contact rows.
    pub budget: Option<u32>,
}

impl Default for WorldSettings {
    fn default() -> Self {
        Self {
            gravity: Vector::new(0.0, -9.81),
            dt: 0.01,
            solver: SolverSettings::default(),
            position: PositionSettings::default(),
            prediction: 0.0,
            restitution_threshold: 1.0,
            max_translation: 2.0,
            max_rotation: 0.5 * std::f64::consts::PI,
            guard: GuardPolicy::FallbackToZero,
            island_threads: 1,
            collide_threads: 1,
            budget: None,
        }
    }
}

impl WorldSettings {
    /// Rejects out-of-range settings with a typed error naming the setting.
    pub fn validate(&self) -> Result<(), CoreError> {
        let err = |name, value: Real, reason| {
            Err(CoreError::InvalidSetting {
                name,
                value,
                reason,
            })
        };
        if !(self.dt.is_finite() && self.dt > 0.0) {
            return err("dt", self.dt, "must be finite and > 0");
        }
        if !(self.gravity.x.is_finite() && self.gravity.y.is_finite()) {
            return err(
                "gravity",
                if self.gravity.x.is_finite() {
                    self.gravity.y
                } else {
                    self.gravity.x
                },
                "must be finite",
            );
        }
        if !(self.prediction.is_finite() && self.prediction >= 0.0) {
            return err("prediction", self.prediction, "must be finite and >= 0");
        }
        if !(self.restitution_threshold.is_finite() && self.restitution_threshold >= 0.0) {
            return err(
                "restitution_threshold",
                self.restitution_threshold,
                "must be finite and >= 0",
            );
        }
        if self.max_translation.is_nan() || self.max_translation <= 0.0 {
            return err("max_translation", self.max_translation, "must be > 0");
        }
        if self.max_rotation.is_nan() || self.max_rotation <= 0.0 {
            return err("max_rotation", self.max_rotation, "must be > 0");
        }
        if self.island_threads == 0 {
            return err("island_threads", 0.0, "must be >= 1");
        }
        if self.collide_threads == 0 {
            return err("collide_threads", 0.0, "must be >= 1");
        }
        if let Some(k) = self.budget {
            if !(2..=MAX_BUDGET).contains(&k) {
                return err(
                    "budget",
                    Real::from(k),
                    "must be in 2..=100000 passes (one for the provider at most, one for the solver at least)",
                );
            }
        }
        self.solver.validate()?;
        self.position.validate()
    }
}

/// Contacts of the current step, kept for the next step's matching.
#[derive(Debug, Default, Clone)]
struct Persistent {
    /// `(id, final impulse)` sorted by id.
    impulses: Vec<(ContactId, Impulse)>,
}

impl Persistent {
    /// For every contact (in the narrow phase's order), the impulse of the previous step's
    /// contact with the same id, if any: `out[i]` for `contacts[i]`.
    ///
    /// The narrow phase emits contacts in ascending body-pair order and `impulses` is sorted
    /// by id (pair first), so one forward cursor finds every match: linear in the contacts,
    /// where a binary search per point was O(n log n) (≈ 4 % of a 10 000-body step). A
    /// contact out of pair order (never produced today) re-seeks the cursor with a binary
    /// search, so the result never depends on the order.
    fn match_contacts(&self, contacts: &[RawContact], out: &mut Vec<Option<Impulse>>) {
        let imp = &self.impulses;
        let pair_of = |id: &ContactId| (id.body_a, id.body_b);
        out.clear();
        let mut j = 0;
        let mut prev = (0, 0);
        for c in contacts {
            let pair = pair_of(&c.id);
            if pair < prev {
                j = imp.partition_point(|(k, _)| pair_of(k) < pair);
            }
            prev = pair;
            while j < imp.len() && pair_of(&imp[j].0) < pair {
                j += 1;
            }
            let found = imp[j..]
                .iter()
                .take_while(|(k, _)| pair_of(k) == pair)
                .find(|(k, _)| *k == c.id)
                .map(|(_, impulse)| *impulse);
            out.push(found);
        }
    }
}

/// Per-step scratch buffers, taken out of the world during a step so that providers can
/// borrow the world immutably.
#[derive(Debug, Default, Clone)]
struct Scratch {
    problems: Vec<ContactProblem>,
    /// Per island: index of each point in the narrow phase's contact list.
    point_source: Vec<Vec<u32>>,
    /// Per island: what its warm start, solve and observation work on.
    islands: Vec<IslandWork>,
    /// Per narrow-phase contact: the impulse carried from the previous step, if its id matched.
    matched: Vec<Option<Impulse>>,
    local_index: Vec<u32>,
    manifold_bodies: Vec<(u32, u32)>,
    dynamic: Vec<bool>,
    /// Final impulse of every narrow-phase contact this step.
    solved: Vec<Impulse>,
    /// Whether this step's solver moves its islands' bodies itself
    /// ([`VelocitySolver::owns_positions`]).
    owns_positions: bool,
    /// With [`Self::owns_positions`], per world body: its displacement over the step, for the
    /// dynamic bodies of the islands (empty otherwise).
    displacements: Vec<Option<Pose>>,
}

/// One island's buffers for a step (reused between steps).
#[derive(Debug, Default, Clone)]
struct IslandWork {
    /// The impulses carried by contact id, one per point.
    carried: Vec<Option<Impulse>>,
    /// The checked warm start (zeros after a fallback).
    warm: Vec<Impulse>,
    /// Whether the provider's start was replaced by zeros.
    fell_back: bool,
    /// Passes the provider spent on this island's warm start.
    passes_spent: u32,
    /// The solved impulses and body velocities.
    impulses: Vec<Impulse>,
    velocities: Vec<Velocity>,
    /// The body displacements over the step, from a solver that owns positions.
    displacements: Vec<Pose>,
    report: SolveReport,
    /// The solve's error, if it failed.
    error: Option<CoreError>,
    /// The bodies' poses for the position pass, corrected in place.
    poses: Vec<Pose>,
    /// The position pass's outcome (`None` before it ran, or after an earlier island's
    /// failed).
    corrected: Option<Result<PositionReport, CoreError>>,
}

impl IslandWork {
    /// Solves `problem` from this island's warm start with `solver`, the error kept in
    /// [`Self::error`]: under a `budget`, exactly the passes the provider left
    /// ([`budget_settings`]), else `settings`; a solver that `owns_positions` also returns
    /// the bodies' displacements.
    fn solve(
        &mut self,
        solver: &mut dyn VelocitySolver,
        problem: &ContactProblem,
        settings: &SolverSettings,
        budget: Option<u32>,
        owns_positions: bool,
    ) {
        self.reset_buffers(problem);
        let settings = match budget {
            Some(k) => budget_settings(settings, k, self.passes_spent),
            None => *settings,
        };
        let result = if owns_positions {
            self.displacements.clear();
            self.displacements
                .resize(problem.bodies.len(), Pose::default());
            solver.solve_with_positions(
                problem,
                &settings,
                &mut self.impulses,
                &mut self.velocities,
                &mut self.displacements,
                &mut self.report,
            )
        } else {
            solver.solve(
                problem,
                &settings,
                &mut self.impulses,
                &mut self.velocities,
                &mut self.report,
            )
        };
        self.error = result.err();
    }

    /// The solve's buffers made ready for `problem`: the impulses start from the warm start,
    /// one velocity slot per body.
    fn reset_buffers(&mut self, problem: &ContactProblem) {
        self.impulses.clear();
        self.impulses.extend_from_slice(&self.warm);
        self.velocities.clear();
        self.velocities
            .resize(problem.bodies.len(), Velocity::default());
    }
}

/// A 2D rigid-body world stepped Box2D-style with pluggable warm start and solvers.
///
/// `Clone` copies everything a step depends on (bodies, settings, step index, the previous
/// step's contacts and impulses), so a clone steps bit-identically to the original: a
/// snapshot to branch experiments from.
#[derive(Debug, Default, Clone)]
pub struct World {
    bodies: Vec<Body>,
    settings: WorldSettings,
    step_index: u64,
    broad: BroadPhase,
    narrow: NarrowPhase,
    /// The collide stage of a large world on several threads.
    shared_collide: SharedCollide,
    islands: Islands,
    persistent: Persistent,
    scratch: Scratch,
}

impl World {
    /// An empty world with validated settings.
    pub fn new(settings: WorldSettings) -> Result<Self, CoreError> {
        settings.validate()?;
        Ok(Self {
            settings,
            ..Self::default()
        })
    }

    /// Adds a body; parameters are validated here, before the body is added (a non-finite
    /// pose or velocity, a negative or non-finite friction or restitution, a dynamic body's
    /// density not finite and > 0, a shape of no size: a
    /// [`CoreError::InvalidBodyParameter`] naming the body index and field, or a
    /// [`CoreError::DegeneratePolygon`]); a refused body leaves the world as it was.
    pub fn add_body(&mut self, desc: &BodyDesc) -> Result<BodyHandle, CoreError> {
        let body = Body::from_desc(desc, self.bodies.len())?;
        self.bodies.push(body);
        Ok(BodyHandle((self.bodies.len() - 1) as u32))
    }

    /// A world holding `bodies`, in order (handle `i` is `bodies[i]`); each is validated as
    /// by [`Self::add_body`], and the first bad one is the error.
    pub fn with_bodies(settings: WorldSettings, bodies: &[BodyDesc]) -> Result<Self, CoreError> {
        let mut w = Self::new(settings)?;
        for b in bodies {
            w.add_body(b)?;
        }
        Ok(w)
    }

    /// All bodies, indexed by handle.
    pub fn bodies(&self) -> &[Body] {
        &self.bodies
    }

    /// Mutable access to one body (to push it, teleport it, ...). Its state is re-validated
    /// when the next step starts.
    pub fn body_mut(&mut self, handle: BodyHandle) -> Result<&mut Body, CoreError> {
        self.bodies
            .get_mut(handle.0 as usize)
            .ok_or(CoreError::UnknownBody(handle.0 as usize))
    }

    /// The settings.
    pub fn settings(&self) -> &WorldSettings {
        &self.settings
    }

    /// Replaces the settings after validating them.
    pub fn set_settings(&mut self, settings: WorldSettings) -> Result<(), CoreError> {
        settings.validate()?;
        self.settings = settings;
        Ok(())
    }

    /// Index of the next step (the number of steps taken so far).
    pub fn step_index(&self) -> u64 {
        self.step_index
    }

    /// Contacts of the last step: `(id, final impulse)` sorted by id.
    pub fn contacts(&self) -> &[(ContactId, Impulse)] {
        &self.persistent.impulses
    }

    /// Contact points (with normals) of the last step's narrow phase, grouped by manifold.
    pub fn raw_contacts(&self) -> &[crate::narrow_phase::RawContact] {
        &self.narrow.contacts
    }

    /// The contact problems of the last step, one per island (empty before the first step).
    pub fn last_problems(&self) -> &[ContactProblem] {
        &self.scratch.problems
    }

    /// Total kinetic energy of the dynamic bodies.
    pub fn kinetic_energy(&self) -> Real {
        self.bodies.iter().map(Body::kinetic_energy).sum()
    }

    fn check_state(&self) -> Result<(), CoreError> {
        let step = self.step_index;
        for (i, b) in self.bodies.iter().enumerate() {
            let bad = |field| {
                Err(CoreError::NonFiniteState {
                    body: i,
                    field,
                    step,
                })
            };
            if !(b.position.x.is_finite() && b.position.y.is_finite()) {
                return bad("position");
            }
            if !b.angle.is_finite() {
                return bad("angle");
            }
            if !(b.linear_velocity.x.is_finite() && b.linear_velocity.y.is_finite()) {
                return bad("linear velocity");
            }
            if !b.angular_velocity.is_finite() {
                return bad("angular velocity");
            }
        }
        Ok(())
    }

    /// Builds the contact problems of the current contacts (after the narrow phase).
    fn build_problems(&mut self, s: &mut Scratch) -> Result<(), CoreError> {
        let nb = self.bodies.len();
        s.dynamic.clear();
        s.dynamic.extend(self.bodies.iter().map(Body::is_dynamic));
        s.manifold_bodies.clear();
        for &(start, _) in &self.narrow.manifolds_ranges {
            let id = self.narrow.contacts[start as usize].id;
            s.manifold_bodies.push((id.body_a, id.body_b));
        }
        self.islands.build(&s.dynamic, &s.manifold_bodies);
        let n_islands = self.islands.len();
        while s.problems.len() < n_islands {
            s.problems.push(ContactProblem::new());
            s.point_source.push(Vec::new());
        }
        s.problems.truncate(n_islands);
        s.point_source.truncate(n_islands);
        s.local_index.clear();
        s.local_index.resize(nb, u32::MAX);
        let threshold = self.settings.restitution_threshold;
        for k in 0..n_islands {
            let problem = &mut s.problems[k];
            let source = &mut s.point_source[k];
            problem.clear();
            source.clear();
            let (ms, me) = self.islands.ranges[k];
            for &m in &self.islands.manifolds[ms as usize..me as usize] {
                let (cs, ce) = self.narrow.manifolds_ranges[m as usize];
                let (a, b) = s.manifold_bodies[m as usize];
                let mut local = |w: u32, problem: &mut ContactProblem| {
                    let li = s.local_index[w as usize];
                    if li != u32::MAX {
                        return li;
                    }
                    let body = &self.bodies[w as usize];
                    let li = problem.add_body(ProblemBody {
                        world_index: w,
                        position: body.position,
                        angle: body.angle,
                        linear_velocity: body.linear_velocity,
                        angular_velocity: body.angular_velocity,
                        inv_mass: body.inv_mass,
                        inv_inertia: body.inv_inertia,
                    });
                    s.local_index[w as usize] = li;
                    li
                };
                let la = local(a, problem);
                let lb = local(b, problem);
                let (ma, mb) = (
                    &self.bodies[a as usize].material,
                    &self.bodies[b as usize].material,
                );
                let friction = (ma.friction * mb.friction).sqrt();
                let restitution = ma.restitution.max(mb.restitution);
                problem.begin_manifold();
                for c in cs..ce {
                    let raw = &self.narrow.contacts[c as usize];
                    problem.add_point(&PointDesc {
                        id: raw.id,
                        body_a: la,
                        body_b: lb,
                        point: raw.point,
                        normal: raw.normal,
                        separation: raw.separation,
                        friction,
                        restitution,
                        restitution_threshold: threshold,
                    })?;
                    source.push(c);
                }
            }
            for b in &problem.bodies {
                s.local_index[b.world_index as usize] = u32::MAX;
            }
        }
        Ok(())
    }

    /// Advances the world by one step of `dt`, running the [`Stage`]s in the order of
    /// [`Stage::ORDER`]. A failing stage ends the step with its error (the world keeps the
    /// state that stage found).
    pub fn step(
        &mut self,
        warm_start: &mut dyn WarmStart,
        solver: &mut dyn VelocitySolver,
        position_solver: &mut dyn PositionSolver,
    ) -> Result<StepReport, CoreError> {
        let t_step = Instant::now();
        self.check_state()?;
        self.settings.validate()?;
        if self.step_index == 0 {
            warm_start.reset();
        }
        let mut report = StepReport {
            step: self.step_index,
            ..StepReport::default()
        };
        let mut plugins = Plugins {
            warm_start,
            solver,
            position_solver,
        };
        let mut s = std::mem::take(&mut self.scratch);
        let result = Stage::ORDER.iter().try_for_each(|&stage| {
            let t0 = Instant::now();
            self.run_stage(stage, &mut s, &mut plugins, &mut report)?;
            if let Some(seconds) = stage.timer(&mut report) {
                *seconds += t0.elapsed().as_secs_f64();
            }
            Ok(())
        });
        self.scratch = s;
        result?;
        self.step_index += 1;
        report.kinetic_energy = self.kinetic_energy();
        report.step_seconds = t_step.elapsed().as_secs_f64();
        Ok(report)
    }

    /// Runs one stage of [`Self::step`].
    fn run_stage(
        &mut self,
        stage: Stage,
        s: &mut Scratch,
        plugins: &mut Plugins<'_>,
        report: &mut StepReport,
    ) -> Result<(), CoreError> {
        match stage {
            Stage::IntegrateVelocities => self.integrate_velocities(),
            Stage::Collide => self.collide(s),
            Stage::Islands => {
                self.build_problems(s)?;
                report.islands = s.problems.len();
            }
            Stage::SolveIslands => {
                s.islands.resize_with(s.problems.len(), IslandWork::default);
                for k in 0..s.problems.len() {
                    self.warm_start_island(k, s, plugins, report)?;
                }
                let t0 = Instant::now();
                plugins
                    .solver
                    .begin_step(self.settings.dt, self.settings.gravity);
                s.owns_positions = plugins.solver.owns_positions();
                s.displacements.clear();
                if s.owns_positions {
                    s.displacements.resize(self.bodies.len(), None);
                }
                self.solve_islands(s, plugins.solver);
                report.solve_seconds += t0.elapsed().as_secs_f64();
                for k in 0..s.problems.len() {
                    self.observe_island(k, s, plugins, report)?;
                }
                report.finish_islands();
            }
            Stage::IntegratePositions => self.integrate_positions(s),
            Stage::PositionPass => self.position_pass(s, plugins.position_solver, report)?,
            Stage::StoreImpulses => self.store_impulses(s),
        }
        Ok(())
    }

    /// Gravity only; no damping, as in the thesis.
    fn integrate_velocities(&mut self) {
        let dv = self.settings.dt * self.settings.gravity;
        for b in self
            .bodies
            .iter_mut()
            .filter(|b| b.kind == BodyKind::Dynamic)
        {
            b.linear_velocity += dv;
        }
    }

    /// Broad and narrow phase, then the previous step's impulses matched by contact id.
    fn collide(&mut self, s: &mut Scratch) {
        let prediction = self.settings.prediction;
        let threads = crate::threads::effective_threads(self.settings.collide_threads);
        if threads > 1 && self.bodies.len() >= SHARED_COLLIDE_MIN_BODIES {
            self.shared_collide
                .collide(&self.bodies, prediction, threads, &mut self.narrow);
        } else {
            let pairs = self.broad.find_pairs(&self.bodies, prediction);
            self.narrow
                .collide_on(&self.bodies, pairs, prediction, threads);
        }
        self.persistent
            .match_contacts(&self.narrow.contacts, &mut s.matched);
        s.solved.clear();
        s.solved.resize(self.narrow.contacts.len(), Impulse::ZERO);
    }

    /// Island `k`'s carried impulses and its checked warm start (zeros and a count on failure,
    /// or the error, as the guard policy says).
    fn warm_start_island(
        &self,
        k: usize,
        s: &mut Scratch,
        plugins: &mut Plugins<'_>,
        report: &mut StepReport,
    ) -> Result<(), CoreError> {
        let settings = self.settings;
        let n = s.problems[k].points.len();
        let work = &mut s.islands[k];
        work.carried.clear();
        work.carried
            .extend(s.point_source[k].iter().map(|&c| s.matched[c as usize]));
        work.warm.clear();
        work.warm.resize(n, Impulse::ZERO);
        let mut ctx = self.island_context(&s.problems, k, &work.carried);
        // The provider may spend all but the solver's one pass of a fixed budget.
        if let Some(budget) = settings.budget {
            ctx = ctx.with_pass_budget(budget - 1);
        }
        let t0 = Instant::now();
        let provided = plugins
            .warm_start
            .warm_start(&ctx, &mut work.warm)
            .and_then(|_| check_output(&work.warm, n));
        report.warm_start_seconds += t0.elapsed().as_secs_f64();
        work.passes_spent = plugins.warm_start.passes_spent();
        work.fell_back = provided.is_err();
        if let Err(e) = provided {
            match settings.guard {
                GuardPolicy::FallbackToZero => {
                    report.fallbacks += 1;
                    work.warm.fill(Impulse::ZERO);
                }
                GuardPolicy::Error => {
                    return Err(CoreError::WarmStart {
                        provider: plugins.warm_start.name().to_string(),
                        step: self.step_index,
                        island: k,
                        source: e,
                    });
                }
            }
        }
        Ok(())
    }

    /// What a provider sees of island `k` of `problems` (its warm start and its observation).
    fn island_context<'a>(
        &'a self,
        problems: &'a [ContactProblem],
        k: usize,
        carried: &'a [Option<Impulse>],
    ) -> WarmStartContext<'a> {
        WarmStartContext::new(&problems[k], carried, self.step_index, self.settings.dt)
            .with_gravity(self.settings.gravity)
            .with_world(self, k, problems.len())
    }

    /// Every island's velocity solve from its warm start, spread over `island_threads` threads
    /// as [`schedule`] decides: side by side on forks of the solver, or the largest island
    /// first on the solver's own threads and the others side by side after it, or one after
    /// another. An island's result does not depend on which thread solved it.
    fn solve_islands(&self, s: &mut Scratch, solver: &mut dyn VelocitySolver) {
        let settings = &self.settings.solver;
        let budget = self.settings.budget;
        let owns_positions = s.owns_positions;
        let solve =
            |solver: &mut dyn VelocitySolver, problem: &ContactProblem, w: &mut IslandWork| {
                w.solve(solver, problem, settings, budget, owns_positions);
            };
        let plan = schedule(&s.problems, self.settings.island_threads, |points| {
            solver.threads_for(points)
        });
        if let Some(k) = plan.first {
            solve(solver, &s.problems[k], &mut s.islands[k]);
        }
        // Every worker, the stepping thread included, on a fork: a fork runs one thread, so
        // the workers share the cores among islands instead of each sharing out its island.
        let forks: Vec<_> = (0..plan.forks).map_while(|_| solver.fork()).collect();
        if forks.len() >= 2 {
            on_forks(
                &s.problems,
                &mut s.islands,
                &plan.rest,
                forks,
                |solver, problem, w| {
                    solve(solver.as_mut(), problem, w);
                },
            );
            return;
        }
        if budget.is_some() || owns_positions {
            // Each island has its own share of the budget, or a solver that moves its bodies
            // solves it: one call per island.
            for &k in &plan.rest {
                solve(solver, &s.problems[k], &mut s.islands[k]);
            }
            return;
        }
        // The rest in one call: the solver may sweep small ones side by side.
        let mut islands: Vec<crate::IslandSolve<'_>> = s
            .problems
            .iter()
            .zip(&mut s.islands)
            .enumerate()
            .filter(|&(k, _)| plan.first != Some(k))
            .map(|(_, (problem, w))| {
                w.reset_buffers(problem);
                crate::IslandSolve::new(problem, &mut w.impulses, &mut w.velocities, &mut w.report)
            })
            .collect();
        solver.solve_many(settings, &mut islands);
        let errors: Vec<Option<CoreError>> = islands.into_iter().map(|i| i.result.err()).collect();
        for (&k, error) in plan.rest.iter().zip(errors) {
            s.islands[k].error = error;
        }
    }

    /// Island `k` after its solve: the solver's error if it failed, else the provider's
    /// observation, the report, and the solved impulses and velocities written back.
    fn observe_island(
        &mut self,
        k: usize,
        s: &mut Scratch,
        plugins: &mut Plugins<'_>,
        report: &mut StepReport,
    ) -> Result<(), CoreError> {
        let work = &mut s.islands[k];
        if let Some(e) = work.error.take() {
            return Err(e);
        }
        // The start as the solver applied it (the solver has its own copy by now).
        crate::warm_start::project_start(
            &s.problems[k].points,
            &mut work.warm,
            plugins.solver.projects_start(),
        );
        let mut ctx = self.island_context(&s.problems, k, &work.carried);
        // The same budget as the island's warm start: sweeps a provider runs after the solve
        // (`tail`'s) are part of its passes.
        if let Some(budget) = self.settings.budget {
            ctx = ctx.with_pass_budget(budget - 1);
        }
        // What a provider does after the solve is part of its cost.
        let t0 = Instant::now();
        plugins.warm_start.observe(
            &ctx,
            &Observation {
                start: &work.warm,
                solved: &work.impulses,
                fell_back: work.fell_back,
                report: &work.report,
            },
        );
        report.warm_start_seconds += t0.elapsed().as_secs_f64();
        report.add_island(&work.report, &work.warm, &work.impulses);
        report.add_contact_errors(&s.problems[k], &work.velocities, &work.impulses);
        report.provider_passes += u64::from(work.passes_spent);
        for (p, imp) in s.point_source[k].iter().zip(&work.impulses) {
            s.solved[*p as usize] = *imp;
        }
        for (pb, v) in s.problems[k].bodies.iter().zip(&work.velocities) {
            let body = &mut self.bodies[pb.world_index as usize];
            if body.kind == BodyKind::Dynamic {
                body.linear_velocity = v.linear;
                body.angular_velocity = v.angular;
            }
        }
        if s.owns_positions {
            for (pb, d) in s.problems[k].bodies.iter().zip(&work.displacements) {
                if self.bodies[pb.world_index as usize].kind == BodyKind::Dynamic {
                    s.displacements[pb.world_index as usize] = Some(*d);
                }
            }
        }
        Ok(())
    }

    /// Positions from the solved velocities, with Box2D's translation and rotation clamps;
    /// the dynamic bodies of the islands of a solver that owns positions move by the
    /// displacements it returned instead (the same clamps on the displacement, the velocity
    /// scaled with it).
    fn integrate_positions(&mut self, s: &Scratch) {
        let settings = self.settings;
        let dt = settings.dt;
        for (i, b) in self
            .bodies
            .iter_mut()
            .enumerate()
            .filter(|(_, b)| b.kind != BodyKind::Static)
        {
            if let Some(Some(d)) = s.displacements.get(i) {
                let mut dp = d.position;
                if dp.norm_squared() > settings.max_translation.powi(2) {
                    let ratio = settings.max_translation / dp.norm();
                    dp *= ratio;
                    b.linear_velocity *= ratio;
                }
                let mut da = d.angle;
                if da.abs() > settings.max_rotation {
                    let ratio = settings.max_rotation / da.abs();
                    da *= ratio;
                    b.angular_velocity *= ratio;
                }
                b.position += dp;
                b.angle += da;
                continue;
            }
            let mut v = b.linear_velocity;
            let dx = dt * v;
            if dx.norm_squared() > settings.max_translation.powi(2) {
                v *= settings.max_translation / dx.norm();
                b.linear_velocity = v;
            }
            let mut w = b.angular_velocity;
            if (dt * w).abs() > settings.max_rotation {
                w *= settings.max_rotation / (dt * w).abs();
                b.angular_velocity = w;
            }
            b.position += dt * v;
            b.angle += dt * w;
        }
    }

    /// The position pass per island (not warm-started), spread over the threads as
    /// [`schedule`] decides. An island's pass reads and writes its own bodies' poses only, so
    /// the bits are the same either way. After a failure, the islands after it in island
    /// order are not written back (as if the islands had been corrected one after another).
    fn position_pass(
        &mut self,
        s: &mut Scratch,
        position_solver: &mut dyn PositionSolver,
        report: &mut StepReport,
    ) -> Result<(), CoreError> {
        let mut min_sep = Real::INFINITY;
        if s.owns_positions {
            // The solver moved these islands' bodies: no position pass, the separations at
            // the new poses.
            for problem in &s.problems {
                min_sep = min_sep.min(self.min_separation_now(problem));
            }
            report.min_separation = if min_sep.is_finite() { min_sep } else { 0.0 };
            return Ok(());
        }
        for (problem, w) in s.problems.iter().zip(&mut s.islands) {
            w.poses.clear();
            w.poses.extend(problem.bodies.iter().map(|pb| {
                let b = &self.bodies[pb.world_index as usize];
                Pose::new(b.position, b.angle)
            }));
            w.corrected = None;
        }
        let settings = &self.settings.position;
        let plan = schedule(&s.problems, self.settings.island_threads, |points| {
            position_solver.threads_for(points)
        });
        if let Some(k) = plan.first {
            let w = &mut s.islands[k];
            w.corrected =
                Some(position_solver.solve_positions(&s.problems[k], settings, &mut w.poses));
        }
        let forks: Vec<_> = (0..plan.forks)
            .map_while(|_| position_solver.fork())
            .collect();
        if forks.len() < 2 {
            for &k in &plan.rest {
                let w = &mut s.islands[k];
                let corrected =
                    position_solver.solve_positions(&s.problems[k], settings, &mut w.poses);
                let failed = corrected.is_err();
                w.corrected = Some(corrected);
                if failed {
                    break;
                }
            }
        } else {
            on_forks(
                &s.problems,
                &mut s.islands,
                &plan.rest,
                forks,
                |pass, problem, w| {
                    w.corrected = Some(pass.solve_positions(problem, settings, &mut w.poses));
                },
            );
        }
        // In island order, up to the first failure (the bodies of the islands before it
        // moved, as if the islands had been corrected one after another).
        for (problem, w) in s.problems.iter().zip(&mut s.islands) {
            let Some(corrected) = w.corrected.take() else {
                break;
            };
            let pr = corrected?;
            report.position_iterations = report.position_iterations.max(pr.iterations);
            min_sep = min_sep.min(pr.min_separation);
            for (pb, pose) in problem.bodies.iter().zip(&w.poses) {
                let body = &mut self.bodies[pb.world_index as usize];
                if body.kind == BodyKind::Dynamic {
                    body.position = pose.position;
                    body.angle = pose.angle;
                }
            }
        }
        report.min_separation = if min_sep.is_finite() { min_sep } else { 0.0 };
        Ok(())
    }

    /// The smallest separation of `problem`'s points at the bodies' current poses (m;
    /// infinite without points): each point's separation moved by its bodies' displacements
    /// since the problem was built, `(Δc_b + rot(Δθ_b) r_b − r_b − Δc_a − rot(Δθ_a) r_a + r_a)
    /// · n`, the normal held fixed.
    fn min_separation_now(&self, problem: &ContactProblem) -> Real {
        let moved = |pb: &ProblemBody, r: &Vector| {
            let b = &self.bodies[pb.world_index as usize];
            (b.position - pb.position) + crate::math::rotate(r, b.angle - pb.angle) - r
        };
        problem
            .points
            .iter()
            .map(|p| {
                let (a, b) = (
                    &problem.bodies[p.body_a as usize],
                    &problem.bodies[p.body_b as usize],
                );
                p.separation + (moved(b, &p.r_b) - moved(a, &p.r_a)).dot(&p.normal)
            })
            .fold(Real::INFINITY, Real::min)
    }

    /// Keeps this step's impulses, sorted by id, for the next step's matching.
    fn store_impulses(&mut self, s: &Scratch) {
        self.persistent.impulses.clear();
        self.persistent.impulses.extend(
            self.narrow
                .contacts
                .iter()
                .zip(&s.solved)
                .map(|(c, imp)| (c.id, *imp)),
        );
        self.persistent.impulses.sort_unstable_by_key(|a| a.0);
    }
}

/// How one step's islands are spread over the threads ([`schedule`]).
#[derive(Debug, Clone, PartialEq, Eq)]
struct Schedule {
    /// The island solved first, alone, by the solver itself on the threads it shares an
    /// island over (`None`: no island is).
    first: Option<usize>,
    /// The other islands, in island order.
    rest: Vec<usize>,
    /// Forks to run `rest` side by side on (0 or 1: one after another on the solver).
    forks: usize,
}

/// The least number of contact points the islands run on forks must hold together: below it
/// a fork's thread costs more than the islands' sweeps (tens of microseconds against a few
/// nanoseconds a point and pass).
const FORK_MIN_POINTS: usize = 64;

/// How to spread `problems` over `island_threads` threads, given the threads the solver
/// shares one island of so many points over (`threads_for`):
/// - every island side by side on forks, largest first, when no island outweighs a thread's
///   share of the points, or when the largest is solved on one thread anyway (it then runs on
///   one fork while the others take the rest);
/// - else the largest first, shared out by the solver, then the others side by side on forks;
/// - one after another when there is one thread, or the islands on forks would hold fewer than
///   [`FORK_MIN_POINTS`] points together, or fewer than two islands are left.
fn schedule(
    problems: &[ContactProblem],
    island_threads: usize,
    threads_for: impl Fn(usize) -> usize,
) -> Schedule {
    let sizes: Vec<usize> = problems.iter().map(ContactProblem::len).collect();
    schedule_sizes(&sizes, island_threads, threads_for)
}

/// [`schedule`] of islands of `sizes` contact points.
fn schedule_sizes(
    sizes: &[usize],
    island_threads: usize,
    threads_for: impl Fn(usize) -> usize,
) -> Schedule {
    let points: usize = sizes.iter().sum();
    // The first of the largest islands.
    let (largest, size) =
        sizes.iter().enumerate().fold(
            (0, 0),
            |best, (k, &n)| if n > best.1 { (k, n) } else { best },
        );
    let outweighs = size * island_threads.min(sizes.len()) > points;
    let first = (island_threads > 1 && outweighs && threads_for(size) > 1).then_some(largest);
    let rest: Vec<usize> = (0..sizes.len()).filter(|&k| first != Some(k)).collect();
    let on_forks = points - first.map_or(0, |_| size);
    let forks = island_threads.min(rest.len());
    let forks = if forks > 1 && on_forks >= FORK_MIN_POINTS {
        forks
    } else {
        0
    };
    Schedule { first, rest, forks }
}

/// Runs `job` on the islands `which`, each fork on a thread of its own (the calling thread's
/// included): islands claimed one at a time from a counter, largest first (so that the last
/// to finish is a small one), each in a slot of its own. An island's result depends on the
/// island alone, so which fork took it does not show in the bits.
fn on_forks<F: Send>(
    problems: &[ContactProblem],
    islands: &mut [IslandWork],
    which: &[usize],
    forks: Vec<F>,
    job: impl Fn(&mut F, &ContactProblem, &mut IslandWork) + Sync,
) {
    let mut order = which.to_vec();
    order.sort_by_key(|&k| std::cmp::Reverse(problems[k].len()));
    let slots: Vec<_> = problems
        .iter()
        .zip(islands)
        .map(std::sync::Mutex::new)
        .collect();
    let next = std::sync::atomic::AtomicUsize::new(0);
    let work = |fork: &mut F| {
        loop {
            let claim = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            let Some(slot) = order.get(claim).map(|&k| &slots[k]) else {
                return;
            };
            let mut slot = slot
                .lock()
                .unwrap_or_else(std::sync::PoisonError::into_inner);
            let (problem, w) = &mut *slot;
            job(fork, problem, w);
        }
    };
    crate::threads::on_threads(forks, |mut fork| work(&mut fork));
}

/// The stop rule of an island under a fixed budget of `budget` passes of which the provider
/// spent `spent`: exactly the rest, at least one (the minimum equals the cap, so no tolerance
/// ends it early).
fn budget_settings(settings: &SolverSettings, budget: u32, spent: u32) -> SolverSettings {
    let passes = budget.saturating_sub(spent).max(1);
    SolverSettings {
        max_iterations: passes,
        min_iterations: passes,
        tolerance: 0.0,
        ..*settings
    }
}

/// The plug-ins of one step.
struct Plugins<'a> {
    warm_start: &'a mut dyn WarmStart,
    solver: &'a mut dyn VelocitySolver,
    position_solver: &'a mut dyn PositionSolver,
}

/// The stages of [`World::step`]; [`Stage::ORDER`] is the order they run in, stated once.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stage {
    /// Gravity into the dynamic bodies' velocities.
    IntegrateVelocities,
    /// Broad phase, narrow phase (parry2d manifolds, one [`ContactId`] per point) and the
    /// previous step's impulses matched by id.
    Collide,
    /// Islands (union-find over touching dynamic bodies) and one [`ContactProblem`] each.
    Islands,
    /// Every island's warm start (checked, zeros on failure), in island order → every
    /// island's velocity solve (side by side with [`WorldSettings::island_threads`]) → every
    /// island's observation, in island order.
    SolveIslands,
    /// Positions from velocities, clamped per step (or, for the islands of a solver that
    /// owns positions, by the displacements it returned; see the module docs).
    IntegratePositions,
    /// Non-linear Gauss-Seidel position correction per island (none for the islands of a
    /// solver that owns positions).
    PositionPass,
    /// This step's impulses kept for the next step's matching.
    StoreImpulses,
}

impl Stage {
    /// The order of a step.
    pub const ORDER: [Stage; 7] = [
        Stage::IntegrateVelocities,
        Stage::Collide,
        Stage::Islands,
        Stage::SolveIslands,
        Stage::IntegratePositions,
        Stage::PositionPass,
        Stage::StoreImpulses,
    ];

    /// The field of `report` that times this stage as a whole, if one does (the solve and
    /// the warm starts are timed inside [`Stage::SolveIslands`]).
    fn timer(self, report: &mut StepReport) -> Option<&mut Real> {
        match self {
            Stage::Collide => Some(&mut report.collide_seconds),
            Stage::Islands => Some(&mut report.islands_seconds),
            Stage::PositionPass => Some(&mut report.position_seconds),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::{FORK_MIN_POINTS, Schedule, Scratch, WorldSettings, schedule_sizes};
    use crate::shared_collide::SHARED_COLLIDE_MIN_BODIES;
    use crate::shared_collide::tests::{bits, strewn_world};

    #[test]
    fn a_large_world_shares_its_collide_stage_out_with_the_contacts_of_one_thread() {
        let collide = |collide_threads| {
            let settings = WorldSettings {
                collide_threads,
                ..WorldSettings::default()
            };
            let mut world = strewn_world(3000, 1500, 60.0, 4, settings);
            assert!(world.bodies.len() >= SHARED_COLLIDE_MIN_BODIES);
            let mut s = Scratch::default();
            world.collide(&mut s);
            let shared = world.shared_collide.called();
            (bits(&world.narrow), s.matched.len(), shared)
        };
        let (one, matched, shared) = collide(1);
        assert!(!shared, "one collide thread took the shared stage");
        assert!(one.1.len() > 1000 && matched == one.0.len());
        let (two, _, shared) = collide(2);
        if crate::threads::cores() >= 2 {
            assert!(shared, "two collide threads did not share the stage");
        } else {
            assert_ne!(std::env::var("CI").as_deref(), Ok("true"), "CI on one core");
        }
        assert!(one == two);
    }

    /// A solver that shares islands from `from` points over `threads` threads.
    fn shares(from: usize, threads: usize) -> impl Fn(usize) -> usize {
        move |points| if points >= from { threads } else { 1 }
    }

    #[test]
    fn a_dominant_island_solved_on_one_thread_runs_beside_the_others() {
        // 1 200 of 2 000 points in one island that the solver sweeps on one thread: every
        // island on forks (the largest on one while the other takes the rest), not one after
        // another (2 000 points' time instead of 1 200).
        let sizes = [400, 1200, 400];
        let plan = schedule_sizes(&sizes, 2, shares(2048, 2));
        let want = Schedule {
            first: None,
            rest: vec![0, 1, 2],
            forks: 2,
        };
        assert_eq!(plan, want);
    }

    #[test]
    fn a_dominant_island_the_solver_shares_goes_first_and_the_rest_side_by_side() {
        let sizes = [400, 4000, 300, 100];
        let plan = schedule_sizes(&sizes, 2, shares(2048, 2));
        let want = Schedule {
            first: Some(1),
            rest: vec![0, 2, 3],
            forks: 2,
        };
        assert_eq!(plan, want);
        // The rest too small to be worth a thread: one after another.
        let plan = schedule_sizes(&[4000, 20, 30], 2, shares(2048, 2));
        assert_eq!((plan.first, plan.forks), (Some(0), 0));
        const { assert!(50 < FORK_MIN_POINTS) };
        // One island left: nothing to run side by side.
        let plan = schedule_sizes(&[4000, 300], 2, shares(2048, 2));
        assert_eq!((plan.first, plan.rest, plan.forks), (Some(0), vec![1], 0));
    }

    #[test]
    fn balanced_islands_run_on_forks_and_one_thread_runs_them_in_order() {
        let sizes = [300, 250, 260, 290];
        let plan = schedule_sizes(&sizes, 2, shares(256, 2));
        assert_eq!((plan.first, plan.forks), (None, 2));
        let plan = schedule_sizes(&sizes, 1, shares(256, 2));
        let want = Schedule {
            first: None,
            rest: vec![0, 1, 2, 3],
            forks: 0,
        };
        assert_eq!(plan, want);
        // More threads than islands: a fork per island (none outweighing a quarter).
        assert_eq!(schedule_sizes(&[270; 4], 8, shares(256, 2)).forks, 4);
        // With four threads the largest of `sizes` outweighs its share: it goes first.
        let plan = schedule_sizes(&sizes, 8, shares(256, 2));
        assert_eq!((plan.first, plan.forks), (Some(0), 3));
        // No islands, or too few points: nothing on forks.
        assert_eq!(schedule_sizes(&[], 2, shares(256, 2)).forks, 0);
        assert_eq!(schedule_sizes(&[10, 12, 9], 2, shares(256, 2)).forks, 0);
    }
}
