//! Our pile: settling it and stepping it under a setting, with the per-step totals.

use std::time::Instant;

use deepcontact_benches::settle_world;
use deepcontact_core::scene::Scene;
use deepcontact_core::{CarriedWarmStart, StepReport, World, WorldSettings};
use deepcontact_pgs::{PgsPositionSolver, PgsSolver};

/// Sums over the measured steps of one setting.
#[derive(Default)]
pub struct Totals {
    /// Steps.
    pub steps: u64,
    /// Contact points, all steps.
    pub contacts: u64,
    /// Contact points × fixed iterations, all steps (0 without a fixed count).
    pub point_iterations: u64,
    /// Velocity iterations of the slowest island, all steps.
    pub iterations_max: u64,
    /// Step time from the reports, s.
    pub step: f64,
    /// Warm-start time, s.
    pub warm: f64,
    /// Velocity-solve time, s.
    pub solve: f64,
    /// Wall time around `World::step`, s.
    pub wall: f64,
    /// Fastest step's wall time, s.
    pub wall_min: f64,
}

impl Totals {
    /// Adds one step's report and wall time.
    pub fn add(&mut self, r: &StepReport, fixed: Option<u32>, wall: f64) {
        self.steps += 1;
        self.contacts += r.contacts as u64;
        if let Some(n) = fixed {
            self.point_iterations += u64::from(n) * r.contacts as u64;
        }
        self.iterations_max += u64::from(r.velocity_iterations);
        self.step += r.step_seconds;
        self.warm += r.warm_start_seconds;
        self.solve += r.solve_seconds;
        self.wall += wall;
        self.wall_min = if self.steps == 1 {
            wall
        } else {
            self.wall_min.min(wall)
        };
    }

    /// Mean milliseconds per step of a total in seconds.
    pub fn ms(&self, s: f64) -> f64 {
        s / self.steps.max(1) as f64 * 1e3
    }

    /// Mean contact points per step.
    pub fn mean_contacts(&self) -> f64 {
        self.contacts as f64 / self.steps.max(1) as f64
    }

    /// Velocity solve, ns per contact point per iteration (fixed count only).
    pub fn ns_per_point_iteration(&self) -> f64 {
        self.solve / self.point_iterations.max(1) as f64 * 1e9
    }
}

/// Our solvers stepping a world one step at a time, with the totals of the steps taken.
#[derive(Default)]
pub struct Stepper {
    solver: PgsSolver,
    position: PgsPositionSolver,
    /// The fixed iteration count, if there is one.
    pub fixed: Option<u32>,
    /// The totals so far.
    pub totals: Totals,
}

impl Stepper {
    /// A stepper with fresh solvers; `fixed` as in [`run`].
    pub fn new(fixed: Option<u32>) -> Self {
        Self {
            fixed,
            ..Self::default()
        }
    }

    /// One step of `world`, timed.
    pub fn step(&mut self, world: &mut World) -> Result<(), String> {
        let t0 = Instant::now();
        let r = world
            .step(&mut CarriedWarmStart, &mut self.solver, &mut self.position)
            .map_err(|e| e.to_string())?;
        self.totals.add(&r, self.fixed, t0.elapsed().as_secs_f64());
        Ok(())
    }
}

/// Steps `world` under `settings`, `fixed` being the fixed iteration count if there is one.
pub fn run(
    world: &mut World,
    settings: WorldSettings,
    steps: u64,
    fixed: Option<u32>,
) -> Result<Totals, String> {
    world.set_settings(settings).map_err(|e| e.to_string())?;
    let mut stepper = Stepper::new(fixed);
    for _ in 0..steps {
        stepper.step(world)?;
    }
    Ok(stepper.totals)
}

/// Our pile of `scene` settled for `steps` steps (builtin, PGS, thesis rule with the velocity
/// cap lowered to `cap`), progress on stderr every 50 steps when `trace`.
pub fn settle(scene: &Scene, steps: u64, cap: u32, trace: bool) -> Result<World, String> {
    let mut world = scene.build(settle_world(cap)).map_err(|e| e.to_string())?;
    let (mut solver, mut position) = (PgsSolver::default(), PgsPositionSolver::default());
    for s in 0..steps {
        let r = world
            .step(&mut CarriedWarmStart, &mut solver, &mut position)
            .map_err(|e| e.to_string())?;
        if trace && (s % 50 == 0 || s + 1 == steps) {
            eprintln!(
                "  step {s}: {} contacts, KE {:.3} J, {} islands, {} it, {} pos it, {:.2} ms (solve {:.2})",
                r.contacts,
                world.kinetic_energy(),
                r.islands,
                r.velocity_iterations,
                r.position_iterations,
                r.step_seconds * 1e3,
                r.solve_seconds * 1e3
            );
        }
    }
    Ok(world)
}
