//! Registration of `learned-sor` in a [`Registry`].

use std::path::Path;

use deepcontact_core::VelocitySolver;
use deepcontact_core::registry::{ProviderInfo, Registry, SpecError};
use deepcontact_pgs::PgsSettings;
use deepcontact_warmstart::{BudgetSchedules, RelaxedConfig, RelaxedWarmStart};

use crate::{RelaxError, RelaxationPolicy, ScheduledPgs, schedules_from_file, shipped_schedules};

/// `sor` with `policy`'s per-point factors, named `name`, under `config` (its `omega` is not
/// used). The registry's `learned-sor` adds the learned schedules for pass budgets to it
/// (`.with_budget_schedules(shipped_schedules()?)`, [`shipped_schedules`]).
pub fn learned_sor(
    name: &str,
    policy: RelaxationPolicy,
    config: RelaxedConfig,
) -> Result<RelaxedWarmStart, SpecError> {
    Ok(RelaxedWarmStart::new(config)?.with_relaxation(name, Box::new(policy)))
}

/// `learned-sor`'s factor of two-point manifolds ([`RelaxedConfig::pairs`]), tuned on seeds
/// 100–109 of the pyramid, the stack and the box and polygon piles (1.2–1.6 tried;
/// docs/RESEARCH.md).
pub const LEARNED_PAIRS: f64 = 1.3;

/// `learned-sor`'s largest factor under a pass budget ([`RelaxedConfig::budget_omega`]),
/// tuned at K = 8 and 16 on seeds 100–109 of the circle, box and polygon piles and the
/// 1 000-circle pile (1.4–1.6 tried; docs/RESEARCH.md). The policy was fitted to solves run to
/// a tolerance, where ω up to 1.95 on large islands pays; with a handful of sweeps it overshoots.
pub const LEARNED_BUDGET_OMEGA: f64 = 1.5;

/// `learned-sor`'s [`RelaxedConfig::mix_below`]: under a pass budget, islands with fewer than
/// this share of their points in single-point manifolds (towers of boxes, under a tenth; box
/// piles a fifth or more) get Anderson-mixed sweeps, since relaxation reaches few of their
/// rows. Set between the two from the islands' shares on seeds 100–101; on the tuning and
/// report seeds it lowers the towers' residual p99 at K = 8 and 16 (docs/RESEARCH.md).
pub const LEARNED_MIX_BELOW: f64 = 0.15;

/// `learned-sor`'s [`RelaxedConfig::heavy_alpha`]: under a pass budget, a heavy island (masses
/// more than [`RelaxedConfig::heavy_ratio`] apart) starts from its carried impulses continued
/// along their last change with this weight.
pub const LEARNED_HEAVY_ALPHA: f64 = 0.25;

/// Registers `learned-sor`: the shipped policy, or `path=policy.json`; `name=` renames it,
/// `sweeps=` (300) and `tolerance=` (1e-4) bound its sweeps as `sor`'s; `pairs=`
/// ([`LEARNED_PAIRS`]) relaxes two-point manifolds; under a pass budget the sweeps follow the
/// learned schedule of that budget (`schedules=shipped`, [`shipped_schedules`]; or a file's,
/// `schedules=PATH`; or, with `schedules=none`, the policy's factors capped at `budget_omega=`,
/// [`LEARNED_BUDGET_OMEGA`]); `max_points=` leaves larger islands unswept; `mix_below=`
/// ([`LEARNED_MIX_BELOW`]) and `heavy_ratio=` (10) send towers of boxes under a budget to
/// Anderson-mixed sweeps ([`RelaxedConfig::mix_below`]).
pub fn register(registry: &mut Registry) {
    registry.register_provider(
        "learned-sor",
        ProviderInfo::new(
            "sor whose per-contact relaxation factor is picked by a learned policy (six features, fitted on seeds 0-99; \
             models/learned-sor.json); path=policy.json, name=learned-sor, sweeps=300, tolerance=1e-4, pairs=1.3 (two-point manifolds split into rows relaxed by it without a pass budget; \
             1 keeps them blocks), \
             schedules=shipped (under a pass budget, a learned factor per share of the sweeps, fitted per budget; models/learned-schedule.json; \
             a path reads another file, none keeps the policy's factors capped by budget_omega), \
             budget_omega=1.5 (largest policy factor under a pass budget with schedules=none), max_points=none (larger islands get the carried impulses unswept), \
             mix_below=0.15 (under a pass budget, islands with fewer than this share of their points in single-point manifolds, towers of boxes, get \
             Anderson-mixed single sweeps instead; 0: never), heavy_ratio=10 (an island whose movable bodies' masses differ more is heavy: not mixed), \
             heavy_alpha=0.25 (under a pass budget, a heavy island starts from its carried impulses continued along their last change by this weight)",
        )
        .learned(),
        |p, _| {
            let build = |e: RelaxError| SpecError::Build {
                spec: "learned-sor".into(),
                reason: e.to_string(),
            };
            let policy = match p.string("path") {
                Some(path) => RelaxationPolicy::from_file(Path::new(path)),
                None => RelaxationPolicy::shipped(),
            }
            .map_err(build)?;
            let name = p.string("name").unwrap_or("learned-sor");
            let d = RelaxedConfig::default();
            let sweeps = p.u64("sweeps", u64::from(d.sweeps))?;
            let config = RelaxedConfig {
                sweeps: u32::try_from(sweeps).unwrap_or(u32::MAX),
                tolerance: p.f64("tolerance", d.tolerance)?,
                pairs: p.f64("pairs", LEARNED_PAIRS)?,
                budget_omega: p.f64("budget_omega", LEARNED_BUDGET_OMEGA)?,
                max_points: usize::try_from(p.u64("max_points", d.max_points as u64)?)
                    .unwrap_or(usize::MAX),
                mix_below: p.f64("mix_below", LEARNED_MIX_BELOW)?,
                heavy_ratio: p.f64("heavy_ratio", d.heavy_ratio)?,
                heavy_alpha: p.f64("heavy_alpha", LEARNED_HEAVY_ALPHA)?,
                ..d
            };
            let schedules = match p.string("schedules") {
                None | Some("shipped") => shipped_schedules(),
                Some("none") => Ok(BudgetSchedules::default()),
                Some(path) => schedules_from_file(Path::new(path)),
            }
            .map_err(build)?;
            Ok(Box::new(
                learned_sor(name, policy, config)?.with_budget_schedules(schedules),
            ))
        },
    );
    register_learned_pgs(registry);
}

/// `learned-pgs`: PGS sweeping a budget's first passes by the learned schedule of that budget
/// ([`ScheduledPgs`]); `schedules=shipped|PATH` as `learned-sor`'s, `threads=N` as `pgs`'s.
fn register_learned_pgs(registry: &mut Registry) {
    registry.register_solver(
        "learned-pgs",
        "pgs whose first max_iterations - 1 sweeps follow the learned schedule of that pass budget \
         (models/learned-schedule.json, fitted for learned-sor's sweeps): single-point manifolds \
         over-relaxed share by share, the last sweep plain, inside the world's own solve; a cap \
         over twice the table's largest budget (a tolerance solve) is swept plain. \
         schedules=shipped|PATH, threads=N (as pgs; default 1)",
        |p| {
            let schedules = match p.string("schedules") {
                None | Some("shipped") => shipped_schedules(),
                Some(path) => schedules_from_file(Path::new(path)),
            }
            .map_err(|e| SpecError::Build {
                spec: "learned-pgs".into(),
                reason: e.to_string(),
            })?;
            let threads = p.u64("threads", 1)?;
            if !(1..=deepcontact_pgs::MAX_THREADS).contains(&threads) {
                return Err(p.invalid(
                    "threads",
                    &threads.to_string(),
                    format!("must be 1 to {}", deepcontact_pgs::MAX_THREADS),
                ));
            }
            let settings = PgsSettings {
                threads: threads as usize,
                ..PgsSettings::default()
            };
            Ok(Box::new(ScheduledPgs::new(settings, schedules)) as Box<dyn VelocitySolver>)
        },
    );
}
