//! Registration of the baseline providers.

use deepcontact_core::registry::{Params, ProviderInfo, Registry, SpecError};
use deepcontact_core::{CarriedWarmStart, Impulse, ResidualNorm, ZeroWarmStart};

use crate::{
    AndersonConfig, AndersonWarmStart, BestOfWarmStart, CoarseConfig, CoarseWarmStart,
    ConstantWarmStart, ExtrapolatedWarmStart, KrylovConfig, KrylovWarmStart, OracleConfig,
    OracleOrder, OracleWarmStart, PresolveConfig, PresolveWarmStart, RandomConfig, RandomWarmStart,
    RelaxedConfig, RelaxedWarmStart, Rounded, Schedule, ShockWarmStart, TailConfig, TailWarmStart,
};

/// Registers `none`, `builtin`, `random`, `bad`, `copy`, `copy2` and `copy0` (the oracles
/// build their solver through the registry, default `pgs`, so register a solver too).
///
/// ```
/// let mut registry = deepcontact_core::Registry::empty();
/// deepcontact_pgs::register(&mut registry);
/// deepcontact_warmstart::register(&mut registry);
/// let provider = registry.build_provider("copy2").unwrap();
/// assert_eq!(provider.name(), "copy2");
/// assert!(registry.provider_info("copy2").unwrap().oracle);
/// ```
pub fn register(registry: &mut Registry) {
    register_thesis_baselines(registry);
    register_oracles(registry);
    register_contenders(registry);
}

/// `none`, `builtin`, `random` and `bad`.
fn register_thesis_baselines(registry: &mut Registry) {
    registry.register_provider("none", "zeros (cold start)", |_, _| {
        Ok(Box::new(ZeroWarmStart))
    });
    registry.register_provider(
        "builtin",
        "last step's impulses matched by contact id",
        |_, _| Ok(Box::new(CarriedWarmStart)),
    );
    registry.register_provider(
        "random",
        "normal U(normal_min, normal_max), tangent U(-tangent_max, tangent_max), seeded; \
         seed=0, normal_min=0, normal_max=5, tangent_max=2",
        |p, _| {
            let d = RandomConfig::default();
            let config = RandomConfig {
                seed: p.u64("seed", d.seed)?,
                normal_min: p.f64("normal_min", d.normal_min)?,
                normal_max: p.f64("normal_max", d.normal_max)?,
                tangent_max: p.f64("tangent_max", d.tangent_max)?,
            };
            Ok(Box::new(RandomWarmStart::new(config)?))
        },
    );
    registry.register_provider(
        "bad",
        "the same impulse everywhere; value=50 sets both, normal= and tangent= override one",
        |p, _| {
            let value = p.f64("value", ConstantWarmStart::BAD.normal)?;
            let normal = p.f64("normal", value)?;
            let tangent = p.f64("tangent", value)?;
            Ok(Box::new(ConstantWarmStart::new(
                "bad",
                Impulse::new(normal, tangent),
            )?))
        },
    );
}

/// `copy`, `copy2` and `copy0`.
fn register_oracles(registry: &mut Registry) {
    registry.register_provider(
        "copy",
        ProviderInfo::new(
            "oracle: solve this step's problem first and start from that; \
             solver=pgs, tolerance=1e-6, max_iterations=10000, norm=inf|l2|contact, order=world|reversed|shuffled, order_seed=0, decimals= (round, as copy2/copy0)",
        )
        .oracle(),
        |p, r| {
            let oracle = build_oracle(p, r)?;
            if p.string("decimals").is_none() {
                return Ok(Box::new(oracle));
            }
            let decimals = p.u64("decimals", 0)?;
            let decimals = decimals_u32(p.name(), decimals)?;
            Ok(Box::new(Rounded::new(oracle, decimals)?))
        },
    );
    registry.register_provider(
        "copy2",
        ProviderInfo::new(
            "copy rounded to 2 decimals; solver=pgs, tolerance=1e-6, max_iterations=10000, norm=inf|l2|contact, order=world|reversed|shuffled, order_seed=0",
        )
        .oracle(),
        |p, r| Ok(Box::new(Rounded::new(build_oracle(p, r)?, 2)?)),
    );
    registry.register_provider(
        "copy0",
        ProviderInfo::new(
            "copy rounded to 0 decimals (normals clamped to >= 0); solver=pgs, tolerance=1e-6, max_iterations=10000, norm=inf|l2|contact, order=world|reversed|shuffled, order_seed=0",
        )
        .oracle(),
        |p, r| Ok(Box::new(Rounded::new(build_oracle(p, r)?, 0)?)),
    );
}

/// `anderson` and `coarse`: PGS sweeps accelerated by mixing or by a coarse level.
fn register_accelerated(registry: &mut Registry) {
    registry.register_provider(
        "anderson",
        "builtin refined by Anderson-accelerated PGS sweeps; window=5, sweeps=4 (per map \
         evaluation), rounds=40, tolerance=1e-4, omega=1 (over-relaxed single-point rows, in (0, 2))",
        |p, _| {
            let d = AndersonConfig::default();
            let config = AndersonConfig {
                window: u32_param(p, "window", d.window)?,
                sweeps: u32_param(p, "sweeps", d.sweeps)?,
                rounds: u32_param(p, "rounds", d.rounds)?,
                tolerance: p.f64("tolerance", d.tolerance)?,
                omega: p.f64("omega", d.omega)?,
            };
            Ok(Box::new(AndersonWarmStart::new(config)?))
        },
    );
    registry.register_provider(
        "coarse",
        "builtin corrected on a coarse level of horizontal layers (or cells) between PGS sweeps; \
         layer=1 (m), sweeps=4 (before and after each correction), rounds=2, width=inf (m; a \
         finite width: cells layer high and width wide)",
        |p, _| {
            let d = CoarseConfig::default();
            let config = CoarseConfig {
                layer: p.f64("layer", d.layer)?,
                sweeps: u32_param(p, "sweeps", d.sweeps)?,
                rounds: u32_param(p, "rounds", d.rounds)?,
                width: p.f64("width", d.width)?,
            };
            Ok(Box::new(CoarseWarmStart::new(config)?))
        },
    );
}

/// `sor`: over-relaxed sweeps from the carried impulses (or another provider's start).
fn register_sor(registry: &mut Registry) {
    registry.register_provider(
        "sor",
        "carried impulses refined by over-relaxed Gauss-Seidel sweeps (PGS on effective masses scaled by omega); \
         omega=1.7, sweeps=300, tolerance=1e-4 (tuned on seeds 100–109), pairs=1 (two-point manifolds' factor; above 1 they are split into over-relaxed point rows), budget_omega=2 \
         (largest factor under a pass budget), max_points=none (larger islands get the start unswept), schedule=none (factors for equal shares of the \
         sweeps, e.g. 1.8/1.2), start=builtin (a registered provider's name: the start the sweeps refine), mix_below=0 (under a pass budget, \
         islands with fewer than this share of their points in single-point manifolds get Anderson-mixed single sweeps instead), \
         heavy_ratio=10 (an island whose movable bodies' masses differ more is heavy: not mixed), heavy_alpha=0 (under a pass budget, \
         a heavy island starts from its carried impulses continued along their last change by this weight)",
        |p, r| {
            let d = RelaxedConfig::default();
            let config = RelaxedConfig {
                omega: p.f64("omega", d.omega)?,
                sweeps: u32_param(p, "sweeps", d.sweeps)?,
                tolerance: p.f64("tolerance", d.tolerance)?,
                pairs: p.f64("pairs", d.pairs)?,
                budget_omega: p.f64("budget_omega", d.budget_omega)?,
                max_points: usize::try_from(p.u64("max_points", d.max_points as u64)?)
                    .unwrap_or(usize::MAX),
                schedule: match p.string("schedule") {
                    Some(text) => Schedule::parse("sor", text)?,
                    None => d.schedule,
                },
                mix_below: p.f64("mix_below", d.mix_below)?,
                heavy_ratio: p.f64("heavy_ratio", d.heavy_ratio)?,
                heavy_alpha: p.f64("heavy_alpha", d.heavy_alpha)?,
            };
            let provider = RelaxedWarmStart::new(config)?;
            Ok(Box::new(match p.string("start") {
                None | Some("builtin") => provider,
                Some(name) => provider.with_start(r.build_provider(name)?),
            }))
        },
    );
}

/// The classical contenders of docs/RESEARCH.md: `tail`, `extrapolate`, `krylov`, `shock`,
/// `best` (and `sor`, [`register_sor`]).
fn register_contenders(registry: &mut Registry) {
    register_sor(registry);
    register_accelerated(registry);
    registry.register_provider(
        "tail",
        "builtin plus the extrapolated rest of last step's solve (Aitken along the slow mode); \
         sweeps=2, max_rate=0.995, extrapolate=true, factor=1, solver=pgs",
        |p, r| {
            let d = TailConfig::default();
            let config = TailConfig {
                sweeps: u32_param(p, "sweeps", d.sweeps)?,
                max_rate: p.f64("max_rate", d.max_rate)?,
                extrapolate: p.choice("extrapolate", &["true", "false"])? != Some("false"),
                factor: p.f64("factor", d.factor)?,
            };
            let solver = r.build_solver(p.string("solver").unwrap_or("pgs"))?;
            Ok(Box::new(TailWarmStart::new(solver, config)?))
        },
    );
    registry.register_provider(
        "extrapolate",
        "carried impulses continued linearly in time, λ_t + alpha (λ_t − λ_{t−1}); alpha=0.25 (tuned on seeds 100–109)",
        |p, _| Ok(Box::new(ExtrapolatedWarmStart::new(p.f64("alpha", 0.25)?)?)),
    );
    registry.register_provider(
        "krylov",
        "builtin plus conjugate-gradient steps on the carried active set; iterations=10, friction=true, rounds=1, regularization=0 (CG on W_AA + eps diag W)",
        |p, _| {
            let d = KrylovConfig::default();
            let config = KrylovConfig {
                iterations: u32_param(p, "iterations", d.iterations)?,
                friction: p.choice("friction", &["true", "false"])? != Some("false"),
                rounds: u32_param(p, "rounds", d.rounds)?,
                regularization: p.f64("regularization", d.regularization)?,
            };
            Ok(Box::new(KrylovWarmStart::new(config)?))
        },
    );
    registry.register_provider(
        "presolve",
        "carried impulses refined by a bounded solve with another solver; solver=newton, iterations=20 (tuned on seeds 100–109), \
         tolerance=1e-6; with newton also on_failed_step=retry|stop, backtracks=8",
        |p, r| {
            let d = PresolveConfig::default();
            let config = PresolveConfig {
                iterations: u32_param(p, "iterations", d.iterations)?,
                tolerance: p.f64("tolerance", d.tolerance)?,
            };
            let mut solver = p.string("solver").unwrap_or("newton").to_string();
            let newton_only = p.string("on_failed_step").is_some() || p.string("backtracks").is_some();
            let stop = p.choice("on_failed_step", &["stop", "retry"])? == Some("stop");
            let backtracks = p.u64("backtracks", 8)?;
            if solver == "newton" {
                solver = format!(
                    "newton:stop_on_failed_step={stop},max_backtracks={backtracks}"
                );
            } else if newton_only {
                return Err(p.invalid(
                    "solver",
                    &solver,
                    "on_failed_step and backtracks need solver=newton",
                ));
            }
            let solver = r.build_solver(&solver)?;
            Ok(Box::new(PresolveWarmStart::new(solver, config)?))
        },
    );
    registry.register_provider(
        "shock",
        "normal loads propagated top-down through the contact graph, blended with the carried impulses; blend=0.5",
        |p, _| Ok(Box::new(ShockWarmStart::new(p.f64("blend", 0.5)?)?)),
    );
    registry.register_provider(
        "best",
        "of the candidate starts, the one with the smallest one-sweep residual; of=builtin+extrapolate+tail+shock \
         (registered provider names, default parameters)",
        |p, r| {
            let list = p.string("of").unwrap_or("builtin+extrapolate+tail+shock");
            let candidates = list
                .split('+')
                .map(|name| r.build_provider(name))
                .collect::<Result<Vec<_>, _>>()?;
            Ok(Box::new(BestOfWarmStart::new(candidates)?))
        },
    );
}

/// A `u32` parameter, or `default`; above `u32::MAX` is a typed error.
fn u32_param(p: &mut Params<'_>, key: &'static str, default: u32) -> Result<u32, SpecError> {
    let value = p.u64(key, u64::from(default))?;
    u32::try_from(value).map_err(|_| SpecError::InvalidParameter {
        spec: p.name().into(),
        param: key.into(),
        value: value.to_string(),
        reason: "too large".into(),
    })
}

fn decimals_u32(spec: &str, d: u64) -> Result<u32, SpecError> {
    u32::try_from(d).map_err(|_| SpecError::InvalidParameter {
        spec: spec.into(),
        param: "decimals".into(),
        value: d.to_string(),
        reason: "too large".into(),
    })
}

/// The oracle's parameters: `solver` (a registry solver spec, default `pgs`), `tolerance`
/// (default 1e-6, ≥ 0), `max_iterations` (default 10 000, 1 ..= u32::MAX) and `norm`
/// (`inf` default, `l2`, `contact`: the original code's rule), `order` (`world` default,
/// `reversed`, `shuffled`: see [`OracleOrder`]) and `order_seed` (default 0, for `shuffled`).
fn build_oracle(p: &mut Params<'_>, registry: &Registry) -> Result<OracleWarmStart, SpecError> {
    let d = OracleConfig::default();
    let spec = p.name().to_string();
    let invalid = |param: &str, value: String, reason: &str| SpecError::InvalidParameter {
        spec: spec.clone(),
        param: param.into(),
        value,
        reason: reason.into(),
    };
    let tolerance = p.f64("tolerance", d.tolerance)?;
    if tolerance < 0.0 {
        return Err(invalid("tolerance", tolerance.to_string(), "must be >= 0"));
    }
    let max_iterations = p.u64("max_iterations", u64::from(d.max_iterations))?;
    let max_iterations = match u32::try_from(max_iterations) {
        Ok(m) if m >= 1 => m,
        _ => {
            return Err(invalid(
                "max_iterations",
                max_iterations.to_string(),
                "must be in 1..=4294967295",
            ));
        }
    };
    let norm = match p.choice("norm", &["inf", "l2", "contact"])? {
        None | Some("inf") => ResidualNorm::Infinity,
        Some("l2") => ResidualNorm::L2,
        Some(_) => ResidualNorm::Contact,
    };
    let order_seed = p.u64("order_seed", 0)?;
    let order = match p.choice("order", &["world", "reversed", "shuffled"])? {
        None | Some("world") => OracleOrder::World,
        Some("reversed") => OracleOrder::Reversed,
        Some(_) => OracleOrder::Shuffled(order_seed),
    };
    let solver = registry.build_solver(p.string("solver").unwrap_or("pgs"))?;
    OracleWarmStart::new(
        solver,
        OracleConfig {
            tolerance,
            max_iterations,
            norm,
            order,
        },
    )
}
