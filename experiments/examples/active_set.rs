//! What knowing the active set is worth (the route after `presolve`, docs/RESEARCH.md).
//!
//! `presolve` shows that a start with the load distribution right cuts PGS's iterations
//! 2.5–3×, but Newton needs ~10 iterations from the carried impulses to find the active set
//! (which rows separate, stick or slide), each a factorisation and a line search. If a
//! predictor gave the active set, one linear solve would give the values. This example
//! records the largest island of piles at chosen steps, takes its answer λ* (PGS to 1e-10
//! from the carried start), and measures PGS iterations to the world's tolerance from:
//! the carried start; one Newton step from it on *its own* active set (Newton's first step
//! without line search); one Newton step from it on λ*'s active set (a perfect active-set
//! predictor); and how many rows the two active sets disagree on (what a classifier must
//! get right).
//!
//! ```sh
//! cargo run --release -p deepcontact-experiments --example active_set -- 100..104
//! ```

use deepcontact_core::{ContactProblem, Impulse, SolverSettings};
use deepcontact_experiments::record::{IslandRecorder, pgs_iterations, solve_from};
use deepcontact_lcp::NewtonSolver;

/// Steps recorded in each pile.
const STEPS: [u64; 5] = [150, 175, 200, 225, 249];

/// A row's state as Newton classifies it at `lambda`: 0 separating/at a bound 0, 1 free
/// (loaded normal or sticking friction), 2 sliding. Compared between two impulse sets with
/// the same velocities test PGS would use (the natural map's projections).
fn states(problem: &ContactProblem, lambda: &[Impulse]) -> Vec<u8> {
    lambda
        .iter()
        .zip(&problem.points)
        .flat_map(|(l, p)| {
            let normal = u8::from(l.normal > 0.0);
            let bound = p.friction * l.normal;
            let tangent = if l.normal <= 0.0 {
                0
            } else if l.tangent.abs() < bound * (1.0 - 1e-9) {
                1
            } else {
                2
            };
            [normal, tangent]
        })
        .collect()
}

/// Newton iterations to the presolve's inner tolerance (1e-6, cap 100) from `start`.
fn newton_iterations(
    newton: &mut NewtonSolver,
    problem: &ContactProblem,
    start: &[Impulse],
) -> Result<u32, Box<dyn std::error::Error>> {
    let settings = SolverSettings {
        tolerance: 1e-6,
        max_iterations: 100,
        ..SolverSettings::default()
    };
    Ok(solve_from(newton, problem, start, &settings)?.0)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let arg = std::env::args().nth(1).unwrap_or_else(|| "100..104".into());
    let seeds = deepcontact_experiments::seeds::parse_seeds(&arg)?;
    let tolerance = SolverSettings::default().tolerance;
    println!(
        "| seed | step | points | it from carried | it after one Newton step, own active set | it after one step on λ*'s active set | rows whose state differs (carried vs λ*) | Newton its from carried | Newton its after the λ* step |"
    );
    println!("|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    let mut newton = NewtonSolver::new();
    let mut totals = [0.0; 6];
    let mut count = 0.0;
    for seed in seeds {
        for (step, problem, carried) in &IslandRecorder::record_pile(seed, 100, &STEPS)? {
            let (from_carried, _) = pgs_iterations(problem, carried, tolerance)?;
            let (_, exact) = pgs_iterations(problem, carried, 1e-10)?;
            let mut own = vec![Impulse::ZERO; carried.len()];
            newton.step_on_active_set(problem, carried, carried, &mut own)?;
            let (after_own, _) = pgs_iterations(problem, &own, tolerance)?;
            let mut oracle = vec![Impulse::ZERO; carried.len()];
            newton.step_on_active_set(problem, &exact, carried, &mut oracle)?;
            let (after_oracle, _) = pgs_iterations(problem, &oracle, tolerance)?;
            let newton_from_carried = newton_iterations(&mut newton, problem, carried)?;
            let newton_from_oracle = newton_iterations(&mut newton, problem, &oracle)?;
            let differ = states(problem, carried)
                .iter()
                .zip(states(problem, &exact))
                .filter(|(a, b)| **a != *b)
                .count();
            println!(
                "| {seed} | {step} | {} | {from_carried} | {after_own} | {after_oracle} | {differ} of {} | {newton_from_carried} | {newton_from_oracle} |",
                problem.len(),
                2 * problem.len()
            );
            totals[0] += f64::from(from_carried);
            totals[1] += f64::from(after_own);
            totals[2] += f64::from(after_oracle);
            totals[3] += differ as f64 / (2 * problem.len()) as f64;
            totals[4] += f64::from(newton_from_carried);
            totals[5] += f64::from(newton_from_oracle);
            count += 1.0;
        }
    }
    println!(
        "\nmean over {count} islands: iterations from carried {:.1}, after one Newton step on the carried active set {:.1}, on λ*'s active set {:.1}; rows whose state differs {:.1} %; Newton iterations to 1e-6 from carried {:.1}, after the λ* step {:.1}",
        totals[0] / count,
        totals[1] / count,
        totals[2] / count,
        100.0 * totals[3] / count,
        totals[4] / count,
        totals[5] / count
    );
    Ok(())
}
