//! Recorded islands for offline studies of warm starts: run a pile with the carried warm
//! start and keep, at chosen steps, the largest island's problem and the start builtin gave
//! it; then measure PGS from any start on the recorded problem.
//!
//! ```
//! use deepcontact_experiments::record::{IslandRecorder, pgs_iterations};
//!
//! let islands = IslandRecorder::record_pile(100, 60, &[59]).unwrap();
//! let (step, problem, carried) = &islands[0];
//! assert_eq!(*step, 59);
//! let (iterations, _answer) = pgs_iterations(problem, carried, 1e-4).unwrap();
//! assert!(iterations >= 1);
//! ```

use deepcontact_core::{
    CarriedWarmStart, ContactProblem, Impulse, SolveReport, SolverSettings, Velocity,
    VelocitySolver, WarmStart, WarmStartContext, WarmStartError, WorldSettings, scene,
};
use deepcontact_pgs::{PgsPositionSolver, PgsSolver};

use crate::ExperimentError;

/// One recorded island: the step, its problem and builtin's start for it.
pub type RecordedIsland = (u64, ContactProblem, Vec<Impulse>);

/// The carried warm start (`builtin`) that records, at each of its steps, the largest
/// island's problem and the start it gave it.
#[derive(Debug, Default)]
pub struct IslandRecorder {
    steps: Vec<u64>,
    taken: Vec<RecordedIsland>,
}

impl IslandRecorder {
    /// A recorder of the largest island at each of `steps`.
    pub fn new(steps: &[u64]) -> Self {
        Self {
            steps: steps.to_vec(),
            taken: Vec::new(),
        }
    }

    /// The islands recorded so far, in step order.
    pub fn into_islands(self) -> Vec<RecordedIsland> {
        self.taken
    }

    /// Runs `scene::pile(seed, bodies)` with builtin and the default PGS for `max(steps) + 1`
    /// steps and returns the recorded islands (steps without contacts record nothing).
    pub fn record_pile(
        seed: u64,
        bodies: usize,
        steps: &[u64],
    ) -> Result<Vec<RecordedIsland>, ExperimentError> {
        let mut world = scene::pile(seed, bodies)?.build(WorldSettings::default())?;
        let mut recorder = Self::new(steps);
        let (mut solver, mut position) = (PgsSolver::new(), PgsPositionSolver::new());
        let last = steps.iter().copied().max().unwrap_or(0);
        for _ in 0..=last {
            world.step(&mut recorder, &mut solver, &mut position)?;
        }
        Ok(recorder.into_islands())
    }
}

impl WarmStart for IslandRecorder {
    fn name(&self) -> &str {
        "builtin"
    }

    fn warm_start(
        &mut self,
        ctx: &WarmStartContext<'_>,
        out: &mut [Impulse],
    ) -> Result<(), WarmStartError> {
        CarriedWarmStart.warm_start(ctx, out)?;
        if self.steps.contains(&ctx.step) {
            let largest = self
                .taken
                .last()
                .is_some_and(|(s, p, _)| *s == ctx.step && p.len() >= ctx.problem.len());
            if !largest {
                self.taken.retain(|(s, _, _)| *s != ctx.step);
                self.taken
                    .push((ctx.step, ctx.problem.clone(), out.to_vec()));
            }
        }
        Ok(())
    }
}

/// Default-PGS iterations from `start` to `tolerance` on `problem` (cap 1 000, or 200 000
/// below a tolerance of 1e-8), and the impulses it ends at.
pub fn pgs_iterations(
    problem: &ContactProblem,
    start: &[Impulse],
    tolerance: f64,
) -> Result<(u32, Vec<Impulse>), ExperimentError> {
    let settings = SolverSettings {
        tolerance,
        max_iterations: if tolerance < 1e-8 { 200_000 } else { 1000 },
        ..SolverSettings::default()
    };
    solve_from(&mut PgsSolver::new(), problem, start, &settings)
}

/// Iterations of `solver` from `start` on `problem` under `settings`, and the impulses it
/// ends at.
pub fn solve_from(
    solver: &mut dyn VelocitySolver,
    problem: &ContactProblem,
    start: &[Impulse],
    settings: &SolverSettings,
) -> Result<(u32, Vec<Impulse>), ExperimentError> {
    let mut lambda = start.to_vec();
    let mut velocities = vec![Velocity::default(); problem.bodies.len()];
    let mut report = SolveReport::default();
    solver.solve(problem, settings, &mut lambda, &mut velocities, &mut report)?;
    Ok((report.iterations, lambda))
}
