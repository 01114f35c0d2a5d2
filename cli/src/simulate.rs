//! `deepcontact simulate`: one scene, one warm start, a report per step.

use std::time::Instant;

use clap::Args;
use deepcontact_core::{StepReport, World, scene};
use deepcontact_pgs::PgsPositionSolver;

use crate::common::{CliError, SolverArgs, registry};

/// Options of `simulate`.
#[derive(Debug, Clone, Args)]
pub struct SimulateArgs {
    /// Scene: pile, pyramid, stack, resting_ball.
    #[arg(long, default_value = "pile")]
    pub scene: String,
    /// Number of bodies (pile: circles, in a box scaled to keep the density).
    #[arg(long, default_value_t = 100)]
    pub bodies: usize,
    /// Seed of the scene.
    #[arg(long, default_value_t = 12345)]
    pub seed: u64,
    /// Steps to run.
    #[arg(long, default_value_t = 250)]
    pub steps: u64,
    /// Warm-start provider (registry spec, e.g. `none`, `builtin`).
    #[arg(long, default_value = "builtin")]
    pub warm_start: String,
    /// Stop rule and solver.
    #[command(flatten)]
    pub solver: SolverArgs,
    /// Print one JSON object per step (all StepReport fields) instead of the table.
    #[arg(long)]
    pub json: bool,
    /// Draw the final state (bodies, walls, contact normals) to this PNG.
    #[arg(long)]
    pub render: Option<std::path::PathBuf>,
    /// Print a table row every this many steps.
    #[arg(long, default_value_t = 25)]
    pub every: u64,
}

/// Totals over a run.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Totals {
    /// Steps run.
    pub steps: u64,
    /// Mean velocity iterations per step.
    pub mean_iterations: f64,
    /// Mean velocity iterations over steps 150–250 (or the last 40% of the run).
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
}

/// Runs a scene and calls `each` for every step report; returns the world and the totals.
pub fn run_scene(
    args: &SimulateArgs,
    mut each: impl FnMut(&StepReport),
) -> Result<(World, Totals), CliError> {
    let registry = registry();
    let mut warm = registry.build_provider(&args.warm_start)?;
    let mut solver = registry.build_solver(&args.solver.solver)?;
    let mut position = PgsPositionSolver::new();
    let scene = scene::by_name(&args.scene, args.seed, args.bodies)?;
    let mut world = scene.build(args.solver.world_settings())?;
    let late_from = if args.steps >= 250 {
        150
    } else {
        args.steps * 6 / 10
    };
    let mut t = Totals {
        steps: args.steps,
        ..Totals::default()
    };
    let (mut iters, mut late, mut late_n, mut contacts, mut point_iters, mut solve_s) =
        (0u64, 0u64, 0u64, 0u64, 0.0, 0.0);
    let t0 = Instant::now();
    for s in 0..args.steps {
        let r = world.step(&mut warm, &mut solver, &mut position)?;
        iters += r.velocity_iterations as u64;
        if s >= late_from {
            late += r.velocity_iterations as u64;
            late_n += 1;
        }
        contacts += r.contacts as u64;
        point_iters += r.contacts as f64 * r.velocity_iterations as f64;
        solve_s += r.solve_seconds;
        t.fallbacks += r.fallbacks;
        t.capped_steps += u64::from(r.capped_islands > 0);
        each(&r);
    }
    let elapsed = t0.elapsed().as_secs_f64();
    let n = args.steps.max(1) as f64;
    t.mean_iterations = iters as f64 / n;
    t.mean_iterations_late = late as f64 / late_n.max(1) as f64;
    t.mean_contacts = contacts as f64 / n;
    t.ms_per_step = elapsed * 1e3 / n;
    t.ns_per_point_iteration = if point_iters > 0.0 {
        solve_s * 1e9 / point_iters
    } else {
        0.0
    };
    Ok((world, t))
}

/// Runs `simulate`.
pub fn run(args: SimulateArgs) -> Result<(), CliError> {
    let bar = if args.json {
        indicatif::ProgressBar::hidden()
    } else {
        let b = indicatif::ProgressBar::new(args.steps);
        b.set_style(
            indicatif::ProgressStyle::with_template("{bar:40} {pos}/{len} steps {elapsed_precise}")
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        b
    };
    let mut rows = Vec::new();
    let every = args.every.max(1);
    let mut json_err = None;
    let (world, totals) = run_scene(&args, |r| {
        if args.json {
            match serde_json::to_string(r) {
                Ok(line) => println!("{line}"),
                Err(e) => json_err = Some(e.to_string()),
            }
        } else if r.step % every == 0 || r.step + 1 == args.steps {
            rows.push(format!(
                "{:>6} {:>9} {:>8} {:>10} {:>10.3e} {:>9} {:>9.3}",
                r.step,
                r.contacts,
                r.islands,
                r.velocity_iterations,
                r.final_residual(),
                r.position_iterations,
                r.step_seconds * 1e3
            ));
        }
        bar.inc(1);
    })?;
    bar.finish_and_clear();
    if let Some(e) = json_err {
        return Err(CliError::Usage(format!(
            "cannot serialise a step report: {e}"
        )));
    }
    if !args.json {
        println!(
            "scene {} ({} bodies), seed {}, warm start {}, solver {}, tolerance {:e}, cap {}",
            args.scene,
            world.bodies().len(),
            args.seed,
            args.warm_start,
            args.solver.solver,
            args.solver.tolerance,
            args.solver.max_iterations
        );
        println!(
            "{:>6} {:>9} {:>8} {:>10} {:>10} {:>9} {:>9}",
            "step", "contacts", "islands", "iterations", "residual", "pos.iter", "ms"
        );
        for row in &rows {
            println!("{row}");
        }
        println!(
            "totals: {} steps, mean iterations {:.1} (steps {}+: {:.1}), mean contacts {:.1}, {:.3} ms/step, \
             {:.2} ns per contact per iteration, capped steps {}, fallbacks {}",
            totals.steps,
            totals.mean_iterations,
            if args.steps >= 250 {
                150
            } else {
                args.steps * 6 / 10
            },
            totals.mean_iterations_late,
            totals.mean_contacts,
            totals.ms_per_step,
            totals.ns_per_point_iteration,
            totals.capped_steps,
            totals.fallbacks
        );
    }
    if let Some(path) = &args.render {
        crate::render::render_world(&world, path)?;
        if !args.json {
            println!("rendered {}", path.display());
        }
    }
    Ok(())
}
