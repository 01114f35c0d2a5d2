//! `deepcontact simulate`: one scene, one warm start, a report per step.

use clap::Args;
use deepcontact_core::Registry;
use deepcontact_experiments::simulate::{SimulateConfig, run_scene};

use crate::common::{CliError, SolverArgs};

/// Options of `simulate`.
#[derive(Debug, Clone, Args)]
pub struct SimulateArgs {
    /// Scene: pile, pyramid, stack, resting_ball, thesis (the original code's world of
    /// `--seed`, 12345–12354), or `file:PATH` (a scene file, `deepcontact_core::scene_file`).
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
    /// Threads (pgs only): islands solved and corrected side by side, the narrow phase's pairs
    /// shared, and one large island's velocity and position solve shared (from 2048 contact
    /// points); results bit-identical for any count.
    #[arg(long, default_value_t = 1)]
    pub threads: usize,
    /// Islands with at least this many contact points run the position pass in its domain
    /// plan, shared by the threads (smaller ones in problem order on one thread). Another
    /// value than the default gives other, equally valid, bits for the islands in between;
    /// the same bits for any thread count
    #[arg(long, default_value_t = SimulateConfig::default().position_parallel_from)]
    pub position_parallel_from: usize,
    /// Print a table row every this many steps.
    #[arg(long, default_value_t = 25)]
    pub every: u64,
}

impl SimulateArgs {
    /// The run these options describe (with `--preset thesis`: the original's rules, and its
    /// initial world when the scene is the pile).
    pub fn config(&self) -> Result<SimulateConfig, CliError> {
        let preset = self.solver.preset()?;
        let scene = match preset.scene() {
            Some(s) if self.scene == "pile" => s.to_string(),
            _ => self.scene.clone(),
        };
        let warm: deepcontact_core::Spec = self.warm_start.parse()?;
        Ok(SimulateConfig {
            scene,
            bodies: self.bodies,
            seed: self.seed,
            steps: self.steps,
            warm_start: preset.warm_start(&warm).to_string(),
            solver: self.solver.solver_spec()?,
            world: self.solver.preset_world_settings()?,
            threads: self.threads,
            position_parallel_from: self.position_parallel_from,
        })
    }
}

/// Runs `simulate`.
pub fn run(args: SimulateArgs, registry: &Registry) -> Result<(), CliError> {
    let config = args.config()?;
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
    let (world, totals) = run_scene(&config, registry, |r| {
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
            config.late_from(),
            totals.mean_iterations_late,
            totals.mean_contacts,
            totals.ms_per_step,
            totals.ns_per_point_iteration,
            totals.capped_steps,
            totals.fallbacks
        );
        let st = &totals.stages;
        println!(
            "ms per step by stage: collide {:.3}, islands {:.3}, warm start {:.3}, velocity solve {:.3}, \
             position pass {:.3}, rest {:.3} (step {:.3})",
            st.collide, st.islands, st.warm_start, st.solve, st.position, st.rest, st.step
        );
    }
    if let Some(path) = &args.render {
        deepcontact_experiments::render::render_world(&world, path)?;
        if !args.json {
            println!("rendered {}", path.display());
        }
    }
    Ok(())
}
