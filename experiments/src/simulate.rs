//! One scene with one warm start, a report per step (what `deepcontact simulate` runs).

use std::time::Instant;

use deepcontact_core::{Registry, Spec, StepReport, World, WorldSettings};
use deepcontact_pgs::{PgsPositionSettings, PgsPositionSolver};

use crate::ExperimentError;

/// What to simulate. [`SimulateConfig::default`] is the thesis pile, seed 12345, builtin.
#[derive(Debug, Clone, PartialEq)]
pub struct SimulateConfig {
    /// Scene: a name with `bodies` or a registered spec, see [`crate::scene_for`] (default `pile`).
    pub scene: String,
    /// Number of bodies (pile: circles, in a box scaled to keep the density; default 100).
    pub bodies: usize,
    /// Seed of the scene (default 12345).
    pub seed: u64,
    /// Steps to run (default 250).
    pub steps: u64,
    /// Warm-start provider spec (default `builtin`).
    pub warm_start: String,
    /// Velocity solver spec (default `pgs`).
    pub solver: String,
    /// World settings (default: the thesis's).
    pub world: WorldSettings,
    /// Threads (default 1; `pgs` only): they solve a step's islands side by side
    /// ([`WorldSettings::island_threads`]), share the narrow phase
    /// ([`WorldSettings::collide_threads`]) and share the velocity and position solve of one
    /// large island (the solver spec gains `threads=`). Results are bit-identical for any
    /// count.
    pub threads: usize,
    /// Islands with at least this many contact points run the position pass in its domain
    /// plan, shared by [`threads`](Self::threads) (default 2048, as
    /// [`PgsPositionSettings::parallel_min_points`]). Smaller islands are corrected in
    /// problem order on one thread. Another threshold gives other (equally valid) bits for
    /// islands between the two, the same bits for any thread count.
    pub position_parallel_from: usize,
}

impl Default for SimulateConfig {
    fn default() -> Self {
        Self {
            scene: "pile".into(),
            bodies: 100,
            seed: 12345,
            steps: 250,
            warm_start: "builtin".into(),
            solver: "pgs".into(),
            world: WorldSettings::default(),
            threads: 1,
            position_parallel_from: PgsPositionSettings::default().parallel_min_points,
        }
    }
}

impl SimulateConfig {
    /// The first step counted as "late": 150 for runs of 250 steps or more (the thesis's
    /// window), else the last 40 % of the run.
    pub fn late_from(&self) -> u64 {
        if self.steps >= 250 {
            150
        } else {
            self.steps * 6 / 10
        }
    }
}

/// Totals over a run.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Totals {
    /// Steps run.
    pub steps: u64,
    /// Mean velocity iterations per step.
    pub mean_iterations: f64,
    /// Mean velocity iterations from [`SimulateConfig::late_from`] on.
    pub mean_iterations_late: f64,
    /// Mean contact points per step.
    pub mean_contacts: f64,
    /// Mean ms per step.
    pub ms_per_step: f64,
    /// Nanoseconds of velocity solve per contact point per iteration.
    pub ns_per_point_iteration: f64,
    /// Warm-start fallbacks.
    pub fallbacks: usize,
    /// Steps that hit the iteration cap.
    pub capped_steps: u64,
    /// Mean milliseconds per step in each stage, from the step reports.
    pub stages: StageMs,
}

/// Mean milliseconds per step in each stage of [`World::step`], from the step reports'
/// timings (wall time).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StageMs {
    /// The collide stage: broad phase, narrow phase, the previous impulses matched.
    pub collide: f64,
    /// Building the islands and their problems.
    pub islands: f64,
    /// The warm-start provider.
    pub warm_start: f64,
    /// The velocity solver.
    pub solve: f64,
    /// The position pass.
    pub position: f64,
    /// The rest of the step: the integrations, the solver's set-up of the step, the step's
    /// measures (start errors, contact errors, kinetic energy), storing the impulses.
    pub rest: f64,
    /// The whole step (the stages above add up to it).
    pub step: f64,
}

impl StageMs {
    /// Adds one step's report (seconds) to the sums (still in seconds until [`Self::mean`]).
    fn add(&mut self, r: &StepReport) {
        let timed = r.collide_seconds
            + r.islands_seconds
            + r.warm_start_seconds
            + r.solve_seconds
            + r.position_seconds;
        self.collide += r.collide_seconds;
        self.islands += r.islands_seconds;
        self.warm_start += r.warm_start_seconds;
        self.solve += r.solve_seconds;
        self.position += r.position_seconds;
        self.rest += (r.step_seconds - timed).max(0.0);
        self.step += r.step_seconds;
    }

    /// The sums of `steps` steps as milliseconds per step.
    fn mean(self, steps: f64) -> Self {
        let ms = |s: f64| s * 1e3 / steps;
        Self {
            collide: ms(self.collide),
            islands: ms(self.islands),
            warm_start: ms(self.warm_start),
            solve: ms(self.solve),
            position: ms(self.position),
            rest: ms(self.rest),
            step: ms(self.step),
        }
    }
}

/// The solver spec `spec` with `threads` threads: `pgs` gains `threads=N` (a `threads` it
/// already has must agree); other solvers run on one thread and refuse more.
pub fn threaded_spec(spec: &str, threads: usize) -> Result<Spec, ExperimentError> {
    let mut spec: Spec = spec.parse()?;
    if threads == 0 || threads > deepcontact_pgs::MAX_THREADS as usize {
        return Err(ExperimentError::Invalid(format!(
            "--threads {threads}: must be 1 to {}",
            deepcontact_pgs::MAX_THREADS
        )));
    }
    if threads == 1 {
        return Ok(spec);
    }
    if spec.name != "pgs" {
        return Err(ExperimentError::Invalid(format!(
            "--threads {threads}: only the pgs solver runs on several threads, not {}",
            spec.name
        )));
    }
    let n = threads.to_string();
    match spec.params.get("threads") {
        Some(given) if *given != n => Err(ExperimentError::Invalid(format!(
            "--threads {threads} disagrees with the solver's threads={given}"
        ))),
        _ => {
            spec.params.insert("threads".into(), n);
            Ok(spec)
        }
    }
}

/// Runs a scene, calling `each` for every step report; returns the world and the totals.
pub fn run_scene(
    config: &SimulateConfig,
    registry: &Registry,
    mut each: impl FnMut(&StepReport),
) -> Result<(World, Totals), ExperimentError> {
    let mut warm = registry.build_provider(&config.warm_start)?;
    let mut solver = registry.solver_from_spec(&threaded_spec(&config.solver, config.threads)?)?;
    let mut position = PgsPositionSolver::with_settings(PgsPositionSettings {
        threads: config.threads,
        parallel_min_points: config.position_parallel_from,
        ..PgsPositionSettings::default()
    });
    let scene = crate::scene_for(registry, &config.scene, config.seed, config.bodies)?;
    let mut world = scene.build(WorldSettings {
        island_threads: config.threads.max(1),
        collide_threads: config.threads.max(1),
        ..config.world
    })?;
    let late_from = config.late_from();
    let mut t = Totals {
        steps: config.steps,
        ..Totals::default()
    };
    let (mut iters, mut late, mut late_n, mut contacts, mut point_iters, mut solve_s) =
        (0u64, 0u64, 0u64, 0u64, 0.0, 0.0);
    let t0 = Instant::now();
    for s in 0..config.steps {
        let r = world.step(&mut warm, &mut solver, &mut position)?;
        iters += u64::from(r.velocity_iterations);
        if s >= late_from {
            late += u64::from(r.velocity_iterations);
            late_n += 1;
        }
        contacts += r.contacts as u64;
        point_iters += r.contacts as f64 * f64::from(r.velocity_iterations);
        solve_s += r.solve_seconds;
        t.stages.add(&r);
        t.fallbacks += r.fallbacks;
        t.capped_steps += u64::from(r.capped_islands > 0);
        each(&r);
    }
    let elapsed = t0.elapsed().as_secs_f64();
    let n = config.steps.max(1) as f64;
    t.mean_iterations = iters as f64 / n;
    t.mean_iterations_late = late as f64 / late_n.max(1) as f64;
    t.mean_contacts = contacts as f64 / n;
    t.ms_per_step = elapsed * 1e3 / n;
    t.stages = t.stages.mean(n);
    t.ns_per_point_iteration = if point_iters > 0.0 {
        solve_s * 1e9 / point_iters
    } else {
        0.0
    };
    Ok((world, t))
}
