//! `deepcontact compare`: arguments of [`deepcontact_experiments::compare`].

use std::io::Write as _;
use std::path::PathBuf;

use clap::Args;
use deepcontact_core::Registry;
use deepcontact_core::registry::{Spec, split_spec_list};
use deepcontact_experiments::compare::{
    Config, DEFAULT_SEEDS, DEFAULT_WARM_STARTS, run_experiment_with, write_outputs,
};
use deepcontact_experiments::seeds::parse_seeds;
use deepcontact_experiments::suite::{
    DEFAULT_BUDGETS, DEFAULT_SCENES, SuiteConfig, parse_budgets, run_suite, write_suite,
};

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
    /// Run the scene suite over these registered scene specs (`deepcontact list`), e.g.
    /// `pile,box-pile:bodies=1000,pyramid:base=20`: one summary with a scene and a budget
    /// column (`--scene` and `--bodies` are then unused). `suite`, alone or beside other specs
    /// (`suite,pile:bodies=300`), names the seven scenes of the suite.
    #[arg(long)]
    pub scenes: Option<String>,
    /// Fixed budgets of constraint passes per island and step, the provider's own sweeps
    /// included, comma-separated, `tolerance` for the stop rule of `--tolerance` and
    /// `--max-iterations`, `tolerance@N` for that rule with a cap of N iterations, e.g.
    /// `4,8,16,32,tolerance` (runs the suite; default with `--scenes`: that list). With
    /// builtin at two caps or more the summary adds a table at equal accuracy: the cap and step
    /// at which builtin stops where each other row stops.
    #[arg(long)]
    pub budgets: Option<String>,
    /// One fixed budget of passes per island and step (`--budgets K`).
    #[arg(long, conflicts_with = "budgets")]
    pub budget: Option<u32>,
    /// Position iterations per step under a pass budget, run in full (Box2D v2.4's 3).
    #[arg(long, default_value_t = 3)]
    pub position_passes: u32,
}

impl CompareArgs {
    /// Whether these options ask for the scene suite (scenes or budgets given).
    pub fn is_suite(&self) -> bool {
        self.scenes.is_some() || self.budgets.is_some() || self.budget.is_some()
    }

    /// The suite these options describe: [`Self::config`] over the scenes and budgets.
    pub fn suite_config(&self) -> Result<SuiteConfig, CliError> {
        let base = self.config()?;
        let scenes = match self.scenes.as_deref() {
            None => match &base.scene_spec {
                Some(spec) => vec![spec.clone()],
                None => vec![single_scene_spec(&base.scene, base.bodies)?],
            },
            Some(list) => scene_specs(list)?,
        };
        let budgets = match (&self.budgets, self.budget) {
            (Some(list), _) => parse_budgets(list)?,
            (None, Some(k)) => parse_budgets(&k.to_string())?,
            (None, None) => parse_budgets(DEFAULT_BUDGETS)?,
        };
        Ok(SuiteConfig {
            base,
            scenes,
            budgets,
            position_passes: self.position_passes,
        })
    }

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
            scene_spec: None,
            threads: self.threads.unwrap_or(0),
            progress: !self.quiet,
            same_problems: self.same_problems.clone(),
        })
    }
}

/// `--scene NAME --bodies N` as a registered scene spec, for a suite of one scene: the
/// piles take `bodies`, the stacked scenes their size where `bodies` is not the default 100.
fn single_scene_spec(scene: &str, bodies: usize) -> Result<Spec, CliError> {
    let key = match scene {
        "pile" | "box-pile" | "polygon-pile" => Some("bodies"),
        "pyramid" => Some("base"),
        "stack" | "ratio-stack" => Some("count"),
        _ => None,
    };
    let text = match key {
        Some("bodies") => format!("{scene}:bodies={bodies}"),
        Some(k) if bodies != 100 => format!("{scene}:{k}={bodies}"),
        _ => scene.to_string(),
    };
    Ok(text.parse()?)
}

/// Runs the suite of `args` and writes its files; its `summary.md` goes to stdout.
fn run_suite_command(args: &CompareArgs, registry: &Registry) -> Result<(), CliError> {
    let config = args.suite_config()?;
    let cells = config.scenes.len() * config.budgets.len();
    let mut done = 0;
    let results = run_suite(&config, registry, &|| false, &mut |cell| {
        done += 1;
        if !args.quiet {
            eprintln!(
                "[{done}/{cells}] {} budget {}: {:.1} s",
                cell.scene, cell.budget, cell.results.wall_seconds
            );
        }
    })?;
    let (files, md) = write_suite(&results, &args.out, !args.no_plots)?;
    let _ = writeln!(std::io::stdout().lock(), "{md}");
    eprintln!("wrote {} files to {}", files.len(), args.out.display());
    Ok(())
}

/// Runs `compare`: the experiment, the files, and `summary.md` on stdout.
pub fn run(args: CompareArgs, registry: &Registry) -> Result<(), CliError> {
    if args.is_suite() {
        return run_suite_command(&args, registry);
    }
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

/// The scene specs of `--scenes`, each `suite` replaced by the suite's seven scenes in place.
fn scene_specs(list: &str) -> Result<Vec<Spec>, CliError> {
    let mut specs = Vec::new();
    for spec in split_spec_list(list)? {
        if spec.name != "suite" {
            specs.push(spec);
        } else if spec.params.is_empty() {
            specs.extend(split_spec_list(DEFAULT_SCENES)?);
        } else {
            return Err(CliError::Usage(format!(
                "--scenes: `suite` takes no parameters (got `{list}`); name a scene with its \
                 parameters beside it, e.g. `suite,pile:bodies=300`"
            )));
        }
    }
    Ok(specs)
}

#[cfg(test)]
mod tests {
    use clap::Parser;

    use crate::{Cli, Command};

    fn scene_names(scenes: &str) -> Vec<String> {
        let cli = Cli::try_parse_from(["deepcontact", "compare", "--scenes", scenes]).unwrap();
        let Command::Compare(args) = cli.command else {
            panic!("not the compare command");
        };
        let suite = args.suite_config().unwrap();
        suite.scenes.iter().map(|s| s.to_string()).collect()
    }

    #[test]
    fn the_suite_named_beside_other_scenes_expands_in_place() {
        let alone = scene_names("suite");
        assert_eq!(alone.len(), 7, "{alone:?}");
        let mixed = scene_names("pile:bodies=300,suite,stack:count=5");
        assert_eq!(mixed.len(), 9, "{mixed:?}");
        assert_eq!(mixed[0], "pile:bodies=300");
        assert_eq!(mixed[1..8], alone[..]);
        assert_eq!(mixed[8], "stack:count=5");
    }
}
