//! The learned schedules: one relaxation schedule per pass budget, fitted on the simulator.
//!
//! Under a budget of `K` passes `learned-sor` sweeps by a schedule (a factor ω for each equal
//! share of its `K − 1` sweeps, deepcontact-warmstart's [`Schedule`]) instead of its per-point
//! policy, whose factors were fitted to solves run to a tolerance. The schedules are fitted by an
//! evolution strategy per budget on the circle, box and polygon piles of training seeds 0–99 and
//! selected on 100–109 (`models/train/schedule.py`, `models/learned-schedule.json`).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use deepcontact_core::Real;
use deepcontact_warmstart::{BudgetSchedules, Schedule};
use serde::{Deserialize, Serialize};

use crate::RelaxError;

/// The schedule file format this build reads.
pub const SCHEDULE_FORMAT: &str = "deepcontact-schedule/1";

/// The JSON file of the learned schedules (`models/learned-schedule.json`): the format, the
/// factors per budget (keys: the budget `K` in passes), and free-form training facts.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ScheduleFile {
    /// [`SCHEDULE_FORMAT`].
    pub format: String,
    /// Per budget `K` (a decimal key ≥ 2), the factors of its schedule (1 to
    /// [`Schedule::MAX`], each in [1, 2)).
    pub schedules: BTreeMap<String, Vec<Real>>,
    /// How the schedules were fitted (not read).
    #[serde(default)]
    pub training: serde_json::Value,
}

/// Reads learned schedules from JSON text (`path` names it in errors).
pub fn schedules_from_json(text: &str, path: &Path) -> Result<BudgetSchedules, RelaxError> {
    let format = |reason: String| RelaxError::Format {
        path: path.to_path_buf(),
        reason,
    };
    let file: ScheduleFile = serde_json::from_str(text).map_err(|e| format(e.to_string()))?;
    if file.format != SCHEDULE_FORMAT {
        return Err(format(format!(
            "format `{}`, this build reads `{SCHEDULE_FORMAT}`",
            file.format
        )));
    }
    let invalid = |reason: String| RelaxError::Schedule {
        path: path.to_path_buf(),
        reason,
    };
    if file.schedules.is_empty() {
        return Err(invalid("no schedule".into()));
    }
    let mut table = Vec::with_capacity(file.schedules.len());
    for (key, factors) in &file.schedules {
        let budget = key
            .parse::<u32>()
            .ok()
            .filter(|&k| k >= 2)
            .ok_or_else(|| invalid(format!("budget `{key}` is not a pass count ≥ 2")))?;
        let schedule = Schedule::new("learned-sor", factors)
            .map_err(|e| invalid(format!("budget {budget}: {e}")))?;
        table.push((budget, schedule));
    }
    Ok(BudgetSchedules::new(table))
}

/// Reads a schedule file.
pub fn schedules_from_file(path: &Path) -> Result<BudgetSchedules, RelaxError> {
    let text = std::fs::read_to_string(path).map_err(|source| RelaxError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    schedules_from_json(&text, path)
}

/// The shipped schedules (`models/learned-schedule.json`, built in).
pub fn shipped_schedules() -> Result<BudgetSchedules, RelaxError> {
    schedules_from_json(
        include_str!("../model/learned-schedule.json"),
        &PathBuf::from("<embedded>/models/learned-schedule.json"),
    )
}
