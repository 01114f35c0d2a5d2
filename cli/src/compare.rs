//! `deepcontact compare`: arguments of [`deepcontact_experiments::compare`].

use std::io::Write as _;
use std::path::PathBuf;

use clap::Args;
use deepcontact_core::Registry;
use deepcontact_core::registry::split_spec_list;
use deepcontact_experiments::compare::{
    Config, DEFAULT_SEEDS, DEFAULT_WARM_STARTS, run_experiment_with, write_outputs,
};
use deepcontact_experiments::seeds::parse_seeds;

use crate::common::{CliError, SolverArgs};

/// Options of `compare`.
#[derive(Debug, Clone, Args)]
pub struct CompareArgs {
    /// Warm starts to compare: comma-separated registry specs (`random:seed=3,normal_max=4`
    /// keeps its parameters together).
    #[arg(long, default_value = DEFAULT_WARM_STARTS)]
    pub warm_starts: String,
    /// Seeds of the pile: comma-separated `a`, `a..b` (end exclusive) or `a..=b`.
    #[arg(long, default_value = DEFAULT_SEEDS)]
    pub seeds: String,
    /// Steps per world.
    #[arg(long, default_value_t = 250)]
    pub steps: u64,
    /// Circles in the pile (the box grows to keep the density).
    #[arg(long, default_value_t = 100)]
    pub bodies: usize,
    /// Scene of every world: `pile`, `thesis` (the original code's exact initial worlds,
    /// seeds 12345–12354), or `file:PATH` (the worlds of a scene file, one per seed;
    /// `deepcontact_core::scene_file`).
    #[arg(long, default_value = "pile")]
    pub scene: String,
    /// Velocity solver and stop rule (`--solver` is replaced by `--solvers` when given).
    #[command(flatten)]
    pub solver: SolverArgs,
    /// Several velocity solvers (comma-separated registry specs): one table of solver × warm start.
    #[arg(long)]
    pub solvers: Option<String>,
    /// Worker threads (default: one per core). Each world runs on one thread.
    #[arg(long)]
    pub threads: Option<usize>,
    /// Output directory (created if missing).
    #[arg(long, default_value = "results")]
    pub out: PathBuf,
    /// Skip the figures.
    #[arg(long)]
    pub no_plots: bool,
    /// Hide the progress bar.
    #[arg(long)]
    pub quiet: bool,
    /// Solve every provider's start on the problems of this warm start's world (one of
    /// `--warm-starts`, e.g. `builtin`): after each step every world becomes a copy of it, so
    /// all figures compare starts on the same contacts instead of diverging trajectories.
    #[arg(long, value_name = "WARM_START")]
    pub same_problems: Option<String>,
}

impl CompareArgs {
    /// The experiment these options describe.
    pub fn config(&self) -> Result<Config, CliError> {
        let preset = self.solver.preset()?;
        let solvers = match &self.solvers {
            Some(list) => split_spec_list(list)?,
            None => vec![self.solver.solver.parse()?],
        };
        Ok(Config {
            warm_starts: split_spec_list(&self.warm_starts)?
                .iter()
                .map(|s| preset.warm_start(s))
                .collect(),
            solvers: solvers.iter().map(|s| preset.solver(s)).collect(),
            seeds: parse_seeds(&self.seeds)?,
            steps: self.steps,
            bodies: self.bodies,
            // The preset's worlds unless a scene is named (as `simulate`).
            scene: match preset.scene() {
                Some(s) if self.scene == "pile" => s.to_string(),
                _ => self.scene.clone(),
            },
            world: preset.world(self.solver.world_settings()),
            threads: self.threads.unwrap_or(0),
            progress: !self.quiet,
            same_problems: self.same_problems.clone(),
        })
    }
}

/// Runs `compare`: the experiment, the files, and `summary.md` on stdout.
pub fn run(args: CompareArgs, registry: &Registry) -> Result<(), CliError> {
    let results = run_experiment_with(&args.config()?, registry)?;
    let outputs = write_outputs(&results, &args.out, !args.no_plots)?;
    // A closed stdout (`| head`) is not an error worth a panic: the files are written.
    let _ = writeln!(std::io::stdout().lock(), "{}", outputs.summary_md);
    eprintln!(
        "wrote {} files to {}",
        outputs.files.len(),
        args.out.display()
    );
    Ok(())
}
