//! What an iteration and a solve's set-up of deepcontact-lcp's Newton and PSOR solvers cost in
//! PGS passes of the same island, measured, beside what `NewtonWork::pass_cost` and
//! `PsorWork::pass_cost` count from the island's structure (the weight a pass budget gives a
//! provider's inner solve, e.g. `presolve`'s).
//!
//! Each listed scene is stepped with carried impulses and PGS; every `--every`-th step, each
//! island of 8 points or more is timed from its start: a PGS pass as the slope between 50 and
//! 250 iterations, a Newton iteration as the slope between 1 and 6, a PSOR sweep between 1 and
//! 21, a set-up as the time of one iteration less that slope (minimum of 5 runs each; Newton's
//! analysis of an unchanged contact graph reused, as in a solve from step to step).
//!
//! ```sh
//! cargo run --release -p deepcontact-benches --example pass_weights -- \
//!     --steps 250 --every 25 pile "pile:bodies=1000" box-pile "pyramid:base=20,jitter=0.01"
//! ```

use std::time::Instant;

use deepcontact_core::{
    ContactProblem, CoreError, Impulse, ResidualNorm, SolveReport, SolverSettings, Velocity,
    VelocitySolver, WorldSettings,
};
use deepcontact_lcp::{NewtonSolver, PsorSolver};
use deepcontact_pgs::{PgsPositionSolver, PgsSolver};

fn main() {
    if let Err(e) = run() {
        eprintln!("pass_weights: {e}");
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
        let mut pgs = PgsSolver::new();
        let pass = (fastest(&mut pgs, problem, start, 250)?.0
            - fastest(&mut pgs, problem, start, 50)?.0)
            / 200.0;
        let mut newton = NewtonSolver::new();
        let newton_cost = newton.pass_cost(problem, None)?;
        let (one, _) = fastest(&mut newton, problem, start, 1)?;
        let (six, ran) = fastest(&mut newton, problem, start, 6)?;
        let mut psor = PsorSolver::new();
        let psor_cost = psor.pass_cost(problem, None)?;
        let (first, _) = fastest(&mut psor, problem, start, 1)?;
        let (more, _) = fastest(&mut psor, problem, start, 21)?;
        if ran < 2 || pass <= 0.0 {
            return Ok(());
        }
        let iteration = (six - one) / f64::from(ran - 1);
        let sweep = (more - first) / 20.0;
        println!(
            "{:<28} {:>6} {:>7.1} {:>7} {:>7.1} {:>7} {:>7.1} {:>7} {:>7.1} {:>7}",
            self.scene,
            problem.len(),
            iteration / pass,
            newton_cost.per_iteration,
            (one - iteration) / pass,
            newton_cost.set_up,
            sweep / pass,
            psor_cost.per_iteration,
            (first - sweep) / pass,
            psor_cost.set_up,
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
                println!("usage: pass_weights [--steps 250] [--every 25] [--seed 100] SCENE...");
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
        "passes measured and counted: a Newton iteration, its set-up, a PSOR sweep, its set-up"
    );
    println!(
        "{:<28} {:>6} {:>7} {:>7} {:>7} {:>7} {:>7} {:>7} {:>7} {:>7}",
        "scene",
        "points",
        "newton",
        "counted",
        "set-up",
        "counted",
        "psor",
        "counted",
        "set-up",
        "counted"
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
