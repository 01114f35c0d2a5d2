//! The scene suite: scenes × budgets × solvers × warm starts × seeds, one comparison per
//! (scene, budget) cell, merged into one summary with a scene and a budget column (what
//! `deepcontact compare --scenes … --budgets …` runs).
//!
//! **Budgets.** [`Budget::Passes`]`(K)` gives every provider the same number of constraint
//! passes per island and step, its own sweeps included: the provider may spend up to K − 1
//! ([`deepcontact_core::WarmStartContext::pass_budget`]), says what it spent
//! ([`deepcontact_core::WarmStart::passes_spent`]), and the velocity solver runs exactly
//! the rest ([`deepcontact_core::WorldSettings::budget`]). The position pass then runs a fixed
//! [`SuiteConfig::position_passes`] iterations (Box2D v2.4's 3 by default) with no early stop,
//! so penetration reflects the budget. [`Budget::Tolerance`] is the comparison's own stop rule
//! (cap and tolerance of [`Config::world`]); [`Budget::Capped`] the same rule with another cap,
//! so that a few caps side by side say how many iterations builtin needs to stop where another
//! start stops ([`equal_accuracy`]).
//!
//! **Cells** run one after another; inside a cell the seeds run side by side and each seed's
//! providers in lockstep (see [`crate::compare`]), so the times of one cell compare provider
//! against provider.

mod accuracy;
mod output;
mod stats;

pub use accuracy::{EqualAccuracy, Measure, equal_accuracy};
pub use output::{SUITE_STEPS_COLUMNS, suite_figures, suite_md, suite_steps_csv, write_suite};
pub use stats::{SuiteRow, suite_rows};

use std::fmt;
use std::str::FromStr;

use deepcontact_core::Registry;
use deepcontact_core::registry::{Spec, split_spec_list};

use crate::ExperimentError;
use crate::compare::{Config, Results, run_experiment_until};

/// How long each step's velocity solve runs in a cell.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Budget {
    /// The comparison's stop rule: iterate until the tolerance or the cap of
    /// [`Config::world`] (written `tolerance`).
    Tolerance,
    /// A fixed number of passes per island and step, the provider's included (written as
    /// the number, 2 to [`deepcontact_core::MAX_BUDGET`]).
    Passes(u32),
    /// The comparison's stop rule with a cap of this many iterations instead of the world's
    /// (written `tolerance@N`, 1 to [`MAX_CAP`]).
    Capped(u32),
}

/// The largest cap of a [`Budget::Capped`] (100 000 iterations).
pub const MAX_CAP: u32 = 100_000;

impl Budget {
    /// The velocity solve's iteration cap in a cell run with `world_cap` as the world's cap
    /// ([`deepcontact_core::SolverSettings::max_iterations`]): `None` under a pass budget.
    pub fn cap(self, world_cap: u32) -> Option<u32> {
        match self {
            Budget::Tolerance => Some(world_cap),
            Budget::Capped(n) => Some(n),
            Budget::Passes(_) => None,
        }
    }
}

impl fmt::Display for Budget {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Budget::Tolerance => f.write_str("tolerance"),
            Budget::Passes(k) => write!(f, "{k}"),
            Budget::Capped(n) => write!(f, "tolerance@{n}"),
        }
    }
}

impl FromStr for Budget {
    type Err = ExperimentError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let s = s.trim();
        if s == "tolerance" || s == "tol" {
            return Ok(Budget::Tolerance);
        }
        if let Some(cap) = s
            .strip_prefix("tolerance@")
            .or_else(|| s.strip_prefix("tol@"))
        {
            return match cap.trim().parse::<u32>() {
                Ok(n) if (1..=MAX_CAP).contains(&n) => Ok(Budget::Capped(n)),
                _ => Err(ExperimentError::Invalid(format!(
                    "budget `{s}`: the cap after `tolerance@` must be a number of iterations in \
                     1..={MAX_CAP}"
                ))),
            };
        }
        match s.parse::<u32>() {
            Ok(k) if (2..=deepcontact_core::MAX_BUDGET).contains(&k) => Ok(Budget::Passes(k)),
            _ => Err(ExperimentError::Invalid(format!(
                "budget `{s}` must be `tolerance`, `tolerance@CAP` or a number of passes in 2..={}",
                deepcontact_core::MAX_BUDGET
            ))),
        }
    }
}

impl serde::Serialize for Budget {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

/// Parses a comma-separated budget list such as `4,8,16,32,tolerance,tolerance@2000`.
pub fn parse_budgets(list: &str) -> Result<Vec<Budget>, ExperimentError> {
    let budgets = list
        .split(',')
        .filter(|p| !p.trim().is_empty())
        .map(str::parse)
        .collect::<Result<Vec<Budget>, _>>()?;
    if budgets.is_empty() {
        return Err(ExperimentError::Invalid("no budget given".into()));
    }
    Ok(budgets)
}

/// The suite's scenes of the must-run table: seven scene families at the sizes engines run.
pub const DEFAULT_SCENES: &str = "pile,pile:bodies=1000,box-pile,polygon-pile,pyramid:base=20,jitter=0.01,stack:count=20,jitter=0.01,ratio-stack:jitter=0.01";
/// The suite's budgets: 4 to 32 passes and the tolerance mode.
pub const DEFAULT_BUDGETS: &str = "4,8,16,32,tolerance";

/// What a suite runs.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct SuiteConfig {
    /// Providers, solvers, seeds, steps, threads and the tolerance-mode world settings of
    /// every cell; its `scene`, `bodies` and `scene_spec` are replaced by each scene.
    pub base: Config,
    /// Scene specs (default [`DEFAULT_SCENES`]).
    #[serde(serialize_with = "specs_as_strings")]
    pub scenes: Vec<Spec>,
    /// Budgets (default [`DEFAULT_BUDGETS`]).
    pub budgets: Vec<Budget>,
    /// Position iterations per step under a pass budget, run in full (default 3, Box2D
    /// v2.4's); at least 1.
    pub position_passes: u32,
}

fn specs_as_strings<S: serde::Serializer>(specs: &[Spec], s: S) -> Result<S::Ok, S::Error> {
    s.collect_seq(specs.iter().map(|x| x.to_string()))
}

impl Default for SuiteConfig {
    fn default() -> Self {
        Self {
            base: Config::default(),
            scenes: split_spec_list(DEFAULT_SCENES).unwrap_or_default(),
            budgets: parse_budgets(DEFAULT_BUDGETS).unwrap_or_default(),
            position_passes: 3,
        }
    }
}

impl SuiteConfig {
    /// The comparison of one cell: the base with `scene` and `budget` applied.
    pub fn cell_config(&self, scene: &Spec, budget: Budget) -> Config {
        let mut config = self.base.clone();
        config.scene = scene.name.clone();
        config.scene_spec = Some(scene.clone());
        match budget {
            Budget::Passes(k) => {
                config.world.budget = Some(k);
                config.world.solver.max_iterations = k;
                config.world.solver.tolerance = 0.0;
                config.world.position.max_iterations = self.position_passes;
                config.world.position.tolerance = 0.0;
            }
            Budget::Capped(n) => config.world.solver.max_iterations = n,
            Budget::Tolerance => {}
        }
        config
    }

    /// Rejects empty lists, duplicates and every cell's invalid config (before any work).
    pub fn validate(&self, registry: &Registry) -> Result<(), ExperimentError> {
        let invalid = |m: String| Err(ExperimentError::Invalid(m));
        if self.scenes.is_empty() {
            return invalid("no scene given".into());
        }
        if self.budgets.is_empty() {
            return invalid("no budget given".into());
        }
        if self.position_passes == 0 {
            return invalid("--position-passes must be at least 1".into());
        }
        let labels: Vec<String> = self.scenes.iter().map(Spec::to_string).collect();
        for (i, l) in labels.iter().enumerate() {
            if labels[..i].contains(l) {
                return invalid(format!("scene `{l}` is listed twice"));
            }
        }
        // `tolerance` and `tolerance@N` with N the world's cap run the same cells.
        let world_cap = self.base.world.solver.max_iterations;
        let key = |b: &Budget| b.cap(world_cap).ok_or(*b);
        for (i, b) in self.budgets.iter().enumerate() {
            if let Some(same) = self.budgets[..i].iter().find(|a| key(a) == key(b)) {
                return invalid(format!("budget `{b}` runs the same cells as `{same}`"));
            }
        }
        for scene in &self.scenes {
            for &budget in &self.budgets {
                let config = self.cell_config(scene, budget);
                config.validate()?;
                if let Some(&seed) = config.seeds.first() {
                    config.scene_of(registry, seed)?;
                }
            }
        }
        Ok(())
    }
}

/// One (scene, budget) cell's comparison.
#[derive(Debug, Clone)]
pub struct Cell {
    /// Scene label (its spec as text).
    pub scene: String,
    /// The cell's budget.
    pub budget: Budget,
    /// The comparison.
    pub results: Results,
}

/// Everything a suite measured, cells in (scene, budget) order.
#[derive(Debug, Clone)]
pub struct SuiteResults {
    /// The config it ran.
    pub config: SuiteConfig,
    /// One per scene and budget.
    pub cells: Vec<Cell>,
    /// Wall time of the whole suite (s).
    pub wall_seconds: f64,
}

/// Runs every cell with `registry`, asking `stop` before every step (see
/// [`run_experiment_until`]); `on_cell` hears of each finished cell (for progress lines).
pub fn run_suite(
    config: &SuiteConfig,
    registry: &Registry,
    stop: &(dyn Fn() -> bool + Sync),
    on_cell: &mut dyn FnMut(&Cell),
) -> Result<SuiteResults, ExperimentError> {
    config.validate(registry)?;
    let t0 = std::time::Instant::now();
    let mut cells = Vec::with_capacity(config.scenes.len() * config.budgets.len());
    for scene in &config.scenes {
        for &budget in &config.budgets {
            let results = run_experiment_until(&config.cell_config(scene, budget), registry, stop)?;
            let cell = Cell {
                scene: scene.to_string(),
                budget,
                results,
            };
            on_cell(&cell);
            cells.push(cell);
        }
    }
    Ok(SuiteResults {
        config: config.clone(),
        cells,
        wall_seconds: t0.elapsed().as_secs_f64(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn small() -> SuiteConfig {
        SuiteConfig {
            base: Config {
                seeds: vec![3],
                steps: 45,
                threads: 1,
                progress: false,
                ..Config::with_warm_starts("none,builtin,sor").unwrap()
            },
            scenes: split_spec_list("pile:bodies=40,pyramid:base=4").unwrap(),
            budgets: parse_budgets("8,tolerance").unwrap(),
            position_passes: 3,
        }
    }

    #[test]
    fn a_suite_gives_one_row_per_scene_budget_and_provider_with_the_budget_spent() {
        let registry = crate::full_registry();
        let mut heard = Vec::new();
        let results = run_suite(&small(), &registry, &|| false, &mut |c| {
            heard.push((c.scene.clone(), c.budget));
        })
        .unwrap();
        assert_eq!(heard.len(), 4);
        let rows = suite_rows(&results);
        assert_eq!(rows.len(), 2 * 2 * 3);
        assert_eq!(
            (rows[0].scene.as_str(), rows[0].budget),
            ("pile:bodies=40", Budget::Passes(8))
        );
        for r in &rows {
            assert!(
                r.contact_steps > 0,
                "{} {}: no contact",
                r.scene,
                r.warm_start
            );
            if r.budget == Budget::Passes(8) {
                assert!(
                    (r.provider_passes + r.solver_passes - 8.0).abs() < 1e-9,
                    "{} {}: {} + {}",
                    r.scene,
                    r.warm_start,
                    r.provider_passes,
                    r.solver_passes
                );
                assert_eq!(r.provider_passes > 0.0, r.warm_start == "sor");
            } else {
                assert!(r.natural_residual_max_builtin_converged.is_some());
            }
            assert!(r.step_vs_builtin.is_some());
        }
        let csv = String::from_utf8(suite_steps_csv(&results).unwrap()).unwrap();
        assert_eq!(csv.lines().next(), Some(SUITE_STEPS_COLUMNS));
        assert_eq!(csv.lines().count(), 1 + 4 * 3 * 45);
        let md = suite_md(&results, &rows);
        assert!(
            md.contains("## `pyramid:base=4`") && md.contains("| 8 | pgs | sor |"),
            "{md}"
        );
    }

    #[test]
    fn a_capped_tolerance_budget_caps_the_solve_and_gives_the_equal_accuracy_table() {
        let mut config = small();
        config.base.warm_starts = Config::with_warm_starts("builtin,sor").unwrap().warm_starts;
        config.scenes = split_spec_list("pile:bodies=40").unwrap();
        config.budgets = parse_budgets("tolerance,tolerance@3").unwrap();
        let results = run_suite(&config, &crate::full_registry(), &|| false, &mut |_| {}).unwrap();
        let rows = suite_rows(&results);
        let capped: Vec<&SuiteRow> = rows
            .iter()
            .filter(|r| r.budget == Budget::Capped(3))
            .collect();
        assert_eq!(capped.len(), 2);
        for r in &capped {
            assert!(
                r.solver_passes <= 3.0,
                "{}: {}",
                r.warm_start,
                r.solver_passes
            );
        }
        assert!(
            capped[0].warm_start == "builtin" && capped[0].capped_steps > 0,
            "builtin never reached the cap of 3"
        );
        let tolerance = rows
            .iter()
            .find(|r| r.budget == Budget::Tolerance && r.warm_start == "builtin")
            .unwrap();
        assert!(tolerance.solver_passes > 3.0, "{}", tolerance.solver_passes);
        let found = equal_accuracy(&rows, config.base.world.solver.max_iterations);
        assert_eq!(found.len(), 2 * 2, "{found:?}");
        assert!(found.iter().all(|e| e.builtin_caps == (3, 1000)));
        let md = suite_md(&results, &rows);
        assert!(md.contains("## At equal accuracy"), "{md}");
        assert!(
            md.contains("| `pile:bodies=40` | pgs | sor | 3 | p99 |"),
            "{md}"
        );
    }

    #[test]
    fn budgets_parse_and_bad_ones_are_refused() {
        assert_eq!(
            parse_budgets("4, 32,tol").unwrap(),
            [Budget::Passes(4), Budget::Passes(32), Budget::Tolerance]
        );
        assert_eq!(
            parse_budgets("tolerance@2000, tol@1").unwrap(),
            [Budget::Capped(2000), Budget::Capped(1)]
        );
        assert_eq!(Budget::Capped(2000).to_string(), "tolerance@2000");
        for bad in [
            "1",
            "x",
            "",
            "100001",
            "tolerance@0",
            "tolerance@",
            "tol@x",
            "tolerance@100001",
        ] {
            assert!(parse_budgets(bad).is_err(), "{bad}");
        }
        for same in ["8,8", "tolerance,tolerance@1000"] {
            let mut twice = small();
            twice.budgets = parse_budgets(same).unwrap();
            assert!(twice.validate(&crate::full_registry()).is_err(), "{same}");
        }
        let mut unknown = small();
        unknown.scenes = split_spec_list("pile,nosuch").unwrap();
        assert!(unknown.validate(&crate::full_registry()).is_err());
    }
}
