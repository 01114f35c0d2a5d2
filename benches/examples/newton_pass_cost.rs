//! What a Newton iteration and a Newton solve's set-up cost in PGS passes of the same island,
//! measured, beside what `NewtonWork::pass_cost` counts from the island's structure (the
//! weight a pass budget gives a provider's Newton solve, e.g. `presolve`'s).
//!
//! Each listed scene is stepped with carried impulses and PGS; every `--every`-th step, each
//! island of 8 points or more is timed from its start: a PGS pass as the slope between 50 and
//! 250 iterations, a Newton iteration as the slope between 1 and 6, the set-up as the time of
//! one iteration less that slope (minimum of 5 runs each; the analysis of an unchanged contact
//! graph reused, as in a solve from step to step).
//!
//! ```sh
//! cargo run --release -p deepcontact-benches --example newton_pass_cost -- \
//!     --steps 250 --every 25 pile "pile:bodies=1000" box-pile "pyramid:base=20,jitter=0.01"
//! ```

use std::time::Instant;

use deepcontact_core::{
    ContactProblem, CoreError, Impulse, ResidualNorm, SolveReport, SolverSettings, Velocity,
    VelocitySolver, WorldSettings,
};
use deepcontact_lcp::NewtonSolver;
use deepcontact_pgs::{PgsPositionSolver, PgsSolver};

fn main() {
    if let Err(e) = run() {
        eprintln!("newton_pass_cost: {e}");
        std::process::exit(2);
    }
}

/// Repetitions of each timed solve (the minimum is kept).
const REPEATS: usize = 5;

/// Seconds of the fastest of [`REPEATS`] solves of `problem` from `start` by `solver`, exactly
/// `iterations` iterations each (no stop rule), and the iterations the last one ran.
fn fastest(
    solver: &mut dyn VelocitySolver,
    problem: &ContactProblem,
    start: &[Impulse],
    iterations: u32,
) -> Result<(f64, u32), CoreError> {
    let settings = SolverSettings {
        max_iterations: iterations,
        tolerance: 0.0,
        norm: ResidualNorm::Infinity,
        min_iterations: 1,
    };
    let mut best = f64::INFINITY;
    let mut ran = 0;
    for _ in 0..REPEATS {
        let mut impulses = start.to_vec();
        let mut velocities = vec![Velocity::default(); problem.bodies.len()];
        let mut report = SolveReport::default();
        let t = Instant::now();
        solver.solve(
            problem,
            &settings,
            &mut impulses,
            &mut velocities,
            &mut report,
        )?;
        best = best.min(t.elapsed().as_secs_f64());
        ran = report.iterations;
    }
    Ok((best, ran))
}

/// PGS that, on the steps it is told to, times each island of 8 points or more before solving
/// it and prints a line.
struct Timing {
    pgs: PgsSolver,
    measure: bool,
    scene: String,
}

impl Timing {
    fn line(&self, problem: &ContactProblem, start: &[Impulse]) -> Result<(), CoreError> {
        let mut newton = NewtonSolver::new();
        let cost = newton
            .work(problem)
            .map_err(|e| e.into_core("newton"))?
            .pass_cost();
        let mut pgs = PgsSolver::new();
        let pass = (fastest(&mut pgs, problem, start, 250)?.0
            - fastest(&mut pgs, problem, start, 50)?.0)
            / 200.0;
        let (one, _) = fastest(&mut newton, problem, start, 1)?;
        let (six, ran) = fastest(&mut newton, problem, start, 6)?;
        if ran < 2 || pass <= 0.0 {
            return Ok(());
        }
        let iteration = (six - one) / f64::from(ran - 1);
        println!(
            "{:<28} {:>6} {:>10.1} {:>10} {:>10.1} {:>10}",
            self.scene,
            problem.len(),
            iteration / pass,
            cost.per_iteration,
            (one - iteration) / pass,
            cost.set_up
        );
        Ok(())
    }
}

impl VelocitySolver for Timing {
    fn name(&self) -> &str {
        "pgs"
    }

    fn solve(
        &mut self,
        problem: &ContactProblem,
        settings: &SolverSettings,
        impulses: &mut [Impulse],
        velocities: &mut [Velocity],
        report: &mut SolveReport,
    ) -> Result<(), CoreError> {
        if self.measure && problem.len() >= 8 {
            self.line(problem, impulses)?;
        }
        self.pgs
            .solve(problem, settings, impulses, velocities, report)
    }
}

fn run() -> Result<(), Box<dyn std::error::Error>> {
    let (mut steps, mut every, mut seed) = (250u64, 25u64, 100u64);
    let mut scenes = Vec::new();
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        let mut value = || args.next().ok_or(format!("{a} needs a value"));
        match a.as_str() {
            "--steps" => steps = value()?.parse()?,
            "--every" => every = value()?.parse()?,
            "--seed" => seed = value()?.parse()?,
            "-h" | "--help" => {
                println!(
                    "usage: newton_pass_cost [--steps 250] [--every 25] [--seed 100] SCENE..."
                );
                return Ok(());
            }
            _ => scenes.push(a),
        }
    }
    if scenes.is_empty() {
        return Err("name at least one scene".into());
    }
    if every == 0 {
        return Err("--every must be at least 1".into());
    }
    let registry = deepcontact_experiments::full_registry();
    println!(
        "{:<28} {:>6} {:>10} {:>10} {:>10} {:>10}",
        "scene", "points", "iteration", "counted", "set-up", "counted"
    );
    for scene in scenes {
        let mut world = registry
            .build_scene(&scene, seed)?
            .build(WorldSettings::default())?;
        let mut provider = registry.build_provider("builtin")?;
        let mut timing = Timing {
            pgs: PgsSolver::new(),
            measure: false,
            scene,
        };
        let mut position = PgsPositionSolver::new();
        for step in 0..steps {
            timing.measure = step % every == every - 1;
            world.step(provider.as_mut(), &mut timing, &mut position)?;
        }
    }
    Ok(())
}
