//! Runs every (solver, warm start, seed) world, results in (solver, warm start, seed) order.
//!
//! One job per (solver, seed), jobs in parallel: a job builds one world per warm start and
//! steps them in lockstep (step t of every provider's world, then step t + 1). With
//! [`Config::same_problems`] every world is reset to the driver's after each step. A machine that
//! speeds up or slows down during a run (turbo, other load) then changes every provider's step
//! times alike, so the times of one run compare provider against provider; run one provider
//! after another and a slow spell lands on whichever ran then.

use std::time::Instant;

use deepcontact_core::Registry;
use deepcontact_pgs::PgsPositionSolver;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use rayon::prelude::*;

use super::{Config, Results, Run, StepRecord};
use crate::ExperimentError;

/// Runs the comparison with [`crate::full_registry`].
pub fn run_experiment(config: &Config) -> Result<Results, ExperimentError> {
    run_experiment_with(config, &crate::full_registry())
}

/// Runs the comparison with providers and solvers from `registry` (so a third-party
/// provider registered there can be compared with the baselines).
pub fn run_experiment_with(
    config: &Config,
    registry: &Registry,
) -> Result<Results, ExperimentError> {
    run_experiment_until(config, registry, &|| false)
}

/// [`run_experiment_with`] that asks `stop` before every step of every world: once it answers
/// `true`, no further step starts, the running worlds end after their current step and the
/// call returns [`ExperimentError::Stopped`] (an embedding uses it for Ctrl-C; nothing has been
/// written, since outputs are written only from finished [`Results`]).
pub fn run_experiment_until(
    config: &Config,
    registry: &Registry,
    stop: &(dyn Fn() -> bool + Sync),
) -> Result<Results, ExperimentError> {
    config.validate()?;
    // Build every provider and solver once up front: spec errors surface before any work.
    for s in &config.warm_starts {
        registry.provider_from_spec(s)?;
    }
    for s in &config.solvers {
        registry.solver_from_spec(s)?;
    }
    for &seed in &config.seeds {
        config.scene_of(registry, seed)?;
    }

    let jobs: Vec<(usize, u64)> = (0..config.solvers.len())
        .flat_map(|s| config.seeds.iter().map(move |&k| (s, k)))
        .collect();
    let threads = crate::threads(config.threads);
    let pool = crate::pool(threads)?;

    let total = (jobs.len() * config.warm_starts.len()) as u64 * config.steps;
    let bar = if config.progress {
        ProgressBar::with_draw_target(Some(total), ProgressDrawTarget::stderr())
    } else {
        ProgressBar::hidden()
    };
    if let Ok(style) = ProgressStyle::with_template(
        "{elapsed_precise} [{bar:40}] {pos}/{len} steps, eta {eta} {msg}",
    ) {
        bar.set_style(style.progress_chars("=> "));
    }

    let t0 = Instant::now();
    // `collect` keeps the job order whatever thread ran which job; each job also says which
    // worker ran it, so the results can tell how many workers took part.
    let jobs: Vec<JobOutcome> = pool.install(|| {
        jobs.par_iter()
            .with_max_len(1)
            .map(|&(s, seed)| {
                let worker = rayon::current_thread_index();
                (
                    worker,
                    run_lockstep(config, registry, (s, seed), stop, &bar),
                )
            })
            .collect()
    });
    let wall_seconds = t0.elapsed().as_secs_f64();
    bar.finish_and_clear();
    let mut workers: Vec<usize> = jobs.iter().filter_map(|(w, _)| *w).collect();
    workers.sort_unstable();
    workers.dedup();
    let mut runs: Vec<Run> = jobs
        .into_iter()
        .map(|(_, job)| job)
        .collect::<Result<Vec<_>, _>>()?
        .into_iter()
        .flatten()
        .collect();
    // Solver-major, then warm start, then seed (the order of `config.seeds`).
    let seed_order = |seed: u64| config.seeds.iter().position(|&k| k == seed);
    runs.sort_by_key(|r| (r.solver, r.warm_start, seed_order(r.seed)));
    Ok(Results {
        config: config.clone(),
        solvers: config.solver_labels(),
        warm_starts: config.warm_start_labels(),
        runs,
        threads,
        workers_used: workers.len(),
        wall_seconds,
    })
}

/// A (solver, seed) job's runs and the pool worker that ran it (`None` outside a pool).
type JobOutcome = (Option<usize>, Result<Vec<Run>, ExperimentError>);

/// One provider's world of a lockstep job, with its own solvers.
struct Lane {
    world: deepcontact_core::World,
    provider: Box<dyn deepcontact_core::WarmStart>,
    velocity: Box<dyn deepcontact_core::VelocitySolver>,
    position: PgsPositionSolver,
    run: Run,
}

/// Every warm start's world of `(solver, seed)`, stepped in lockstep (see the module docs).
fn run_lockstep(
    config: &Config,
    registry: &Registry,
    (solver, seed): (usize, u64),
    stop: &(dyn Fn() -> bool + Sync),
    bar: &ProgressBar,
) -> Result<Vec<Run>, ExperimentError> {
    let mut lanes = (0..config.warm_starts.len())
        .map(|warm_start| -> Result<Lane, ExperimentError> {
            Ok(Lane {
                world: config.scene_of(registry, seed)?.build(config.world)?,
                provider: registry.provider_from_spec(&config.warm_starts[warm_start])?,
                velocity: registry.solver_from_spec(&config.solvers[solver])?,
                position: PgsPositionSolver::new(),
                run: Run {
                    solver,
                    warm_start,
                    seed,
                    steps: Vec::with_capacity(config.steps as usize),
                    curves: Vec::with_capacity(config.steps as usize),
                    diagnostics: Vec::new(),
                },
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    let driver = config.driver();
    for _ in 0..config.steps {
        for lane in &mut lanes {
            if stop() {
                return Err(ExperimentError::Stopped);
            }
            let report = lane.world.step(
                lane.provider.as_mut(),
                lane.velocity.as_mut(),
                &mut lane.position,
            )?;
            lane.run.steps.push(StepRecord::from(&report));
            lane.run.curves.push(if report.contacts > 0 {
                report.residual_curve
            } else {
                Vec::new()
            });
            bar.inc(1);
        }
        if let Some(d) = driver {
            let (before, rest) = lanes.split_at_mut(d);
            let (lane, after) = rest.split_first_mut().expect("driver index is in range");
            for other in before.iter_mut().chain(after) {
                other.world.clone_from(&lane.world);
            }
        }
    }
    Ok(lanes
        .into_iter()
        .map(|mut lane| {
            lane.run.diagnostics = lane.provider.diagnostics();
            lane.run
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use std::sync::atomic::{AtomicUsize, Ordering};

    use super::*;

    fn small() -> Config {
        Config {
            seeds: vec![12345, 12346],
            steps: 5,
            bodies: 30,
            threads: 1,
            progress: false,
            ..Config::with_warm_starts("none,builtin").unwrap()
        }
    }

    #[test]
    fn stop_ends_the_comparison_before_the_next_step() {
        let asked = AtomicUsize::new(0);
        let stop = || asked.fetch_add(1, Ordering::SeqCst) >= 3;
        let err = run_experiment_until(&small(), &crate::full_registry(), &stop).unwrap_err();
        assert!(matches!(err, ExperimentError::Stopped), "{err}");
        // One thread, jobs in order, the warm starts of a seed in lockstep: asked before each
        // of steps 0 and 1 of both worlds of the first seed (three steps ran, the fourth
        // question stopped it); the second seed's job then stops at its first question.
        assert_eq!(asked.load(Ordering::SeqCst), 4 + 1);
    }

    #[test]
    fn never_stopping_gives_the_plain_comparison() {
        let registry = crate::full_registry();
        let config = Config {
            steps: 40,
            ..small()
        };
        let a = run_experiment_until(&config, &registry, &|| false).unwrap();
        let b = run_experiment_with(&config, &registry).unwrap();
        let iterations = |r: &Results| -> Vec<u32> {
            r.runs
                .iter()
                .flat_map(|run| run.steps.iter().map(|s| s.iterations))
                .collect()
        };
        assert_eq!(iterations(&a), iterations(&b));
        assert!(
            iterations(&a).iter().any(|&i| i > 0),
            "no contact in 40 steps"
        );
        assert_eq!(a.runs.len(), 4);
    }
}
