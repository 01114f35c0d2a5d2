//! deepcontact's providers inside rapier2d: every provider × budget × suite scene, judged by
//! penetration, normal velocity error, kinetic energy of the pile and wall time; prints a
//! Markdown table.
//!
//! ```text
//! cargo run --release --example compare -- [--steps 300] [--seeds 12345,12346]
//!     [--scenes box-pile:bodies=100,...] [--providers native,none,builtin,sor,learned-sor]
//!     [--budgets 1x1,1x2,1x4,1x8,4x1]
//! ```
//! A budget `SxK` is `S` substeps (`num_solver_iterations`) of `K` PGS passes
//! (`num_internal_pgs_iterations`); rapier's default is `4x1`. `native` is rapier2d without
//! hooks; every other name is a deepcontact provider from `full_registry()` driving rapier's
//! warm starts through `WarmStartHooks`, one problem per manifold, or one per island with the
//! suffix `@island` (`sor@island`); a further `+passes` caps the provider's own sweeps at the
//! solver's passes per step, `S × K` (`WarmStartContext::pass_budget`; without it `sor` sweeps
//! until its tolerance, up to 300). dt is deepcontact's 0.01 s.

use std::time::Instant;

use deepcontact_rapier2d::{Grouping, HookSettings, RapierWorld, WarmStartHooks};

/// Kinetic energy under which a pile counts as at rest (J).
const REST: f64 = 0.01;

struct Args {
    steps: usize,
    seeds: Vec<u64>,
    scenes: Vec<String>,
    providers: Vec<String>,
    budgets: Vec<(usize, usize)>,
}

fn parse() -> Result<Args, String> {
    let mut args = Args {
        steps: 300,
        seeds: vec![12345, 12346],
        scenes: [
            "box-pile:bodies=100",
            "pile:bodies=100",
            "pyramid:base=10",
            "stack:count=10",
        ]
        .map(String::from)
        .to_vec(),
        providers: [
            "native",
            "none",
            "builtin",
            "sor",
            "learned-sor",
            "sor@island",
            "learned-sor@island",
            "sor@island+passes",
            "learned-sor@island+passes",
        ]
        .map(String::from)
        .to_vec(),
        budgets: vec![(1, 1), (1, 2), (1, 4), (1, 8), (4, 1)],
    };
    let mut it = std::env::args().skip(1);
    let list = |v: Option<String>| -> Result<Vec<String>, String> {
        let v = v.ok_or("missing value")?;
        // Scene specs hold commas inside their parameters: split on ';' when given.
        let sep = if v.contains(';') { ';' } else { ',' };
        Ok(v.split(sep).map(str::to_string).collect())
    };
    while let Some(flag) = it.next() {
        match flag.as_str() {
            "--steps" => {
                args.steps = it
                    .next()
                    .ok_or("--steps N")?
                    .parse()
                    .map_err(|e| format!("{e}"))?
            }
            "--seeds" => {
                args.seeds = list(it.next())?
                    .iter()
                    .map(|s| s.parse().map_err(|e| format!("seed {s}: {e}")))
                    .collect::<Result<_, _>>()?
            }
            "--scenes" => args.scenes = list(it.next())?,
            "--providers" => args.providers = list(it.next())?,
            "--budgets" => {
                args.budgets = list(it.next())?
                    .iter()
                    .map(|b| {
                        let (s, k) = b.split_once('x').ok_or(format!("budget {b}: SxK"))?;
                        Ok((
                            s.parse().map_err(|e| format!("{b}: {e}"))?,
                            k.parse().map_err(|e| format!("{b}: {e}"))?,
                        ))
                    })
                    .collect::<Result<_, String>>()?
            }
            other => return Err(format!("unknown argument {other}")),
        }
    }
    Ok(args)
}

#[derive(Default)]
struct Row {
    runs: usize,
    pen_mean: f64,
    pen_max: f64,
    nve_mean: f64,
    ke_last: f64,
    settle_steps: f64,
    unsettled: usize,
    ms_per_step: f64,
    provider_ms: f64,
    fallbacks: usize,
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = parse()?;
    let registry = deepcontact_experiments::full_registry();
    println!(
        "| scene | budget | provider | pen. mean (mm) | pen. max (mm) | vn err. mean (mm/s) | KE end (J) | rest step (KE < {REST} J) | ms/step | provider ms/step | fallbacks |"
    );
    println!("|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|");
    for scene_spec in &args.scenes {
        for &(substeps, passes) in &args.budgets {
            for provider in &args.providers {
                let mut row = Row::default();
                for &seed in &args.seeds {
                    let scene = registry.build_scene(scene_spec, seed)?;
                    let mut world = RapierWorld::from_scene(&scene)?;
                    world.params.dt = 0.01;
                    world.params.num_solver_iterations = substeps;
                    world.params.num_internal_pgs_iterations = passes;
                    let hooks = if provider == "native" {
                        None
                    } else {
                        let (spec, capped) = match provider.strip_suffix("+passes") {
                            Some(spec) => (spec, true),
                            None => (provider.as_str(), false),
                        };
                        let (spec, grouping) = match spec.strip_suffix("@island") {
                            Some(spec) => (spec, Grouping::Island),
                            None => (spec, Grouping::Manifold),
                        };
                        let settings = HookSettings {
                            grouping,
                            pass_budget: capped.then_some((substeps * passes) as u32),
                            ..HookSettings::default()
                        };
                        Some(WarmStartHooks::with_settings(
                            registry.build_provider(spec)?,
                            settings,
                        ))
                    };
                    let (mut pen_sum, mut nve_sum, mut ke, mut last_moving) = (0.0, 0.0, 0.0, 0);
                    let (mut seconds, mut provider_s) = (0.0, 0.0);
                    for step in 0..args.steps {
                        let t = Instant::now();
                        match &hooks {
                            None => world.step_native(),
                            Some(h) => {
                                let stats = world.step(h)?;
                                provider_s += stats.provider_seconds;
                                row.fallbacks += stats.fallbacks;
                            }
                        }
                        seconds += t.elapsed().as_secs_f64();
                        let m = world.measures();
                        pen_sum += m.penetration_mean;
                        nve_sum += m.normal_velocity_error_mean;
                        row.pen_max = row.pen_max.max(m.penetration_max);
                        ke = m.kinetic_energy;
                        if ke >= REST {
                            last_moving = step + 1;
                        }
                    }
                    let n = args.steps as f64;
                    row.runs += 1;
                    row.pen_mean += pen_sum / n;
                    row.nve_mean += nve_sum / n;
                    row.ke_last += ke;
                    row.settle_steps += last_moving as f64;
                    row.unsettled += usize::from(last_moving == args.steps);
                    row.ms_per_step += 1e3 * seconds / n;
                    row.provider_ms += 1e3 * provider_s / n;
                }
                let r = row.runs as f64;
                println!(
                    "| {scene_spec} | {substeps}x{passes} | {provider} | {:.3} | {:.3} | {:.2} | {:.4} | {}{:.0} | {:.3} | {:.3} | {} |",
                    1e3 * row.pen_mean / r,
                    1e3 * row.pen_max,
                    1e3 * row.nve_mean / r,
                    row.ke_last / r,
                    if row.unsettled > 0 {
                        format!("{}/{} never; mean ", row.unsettled, row.runs)
                    } else {
                        String::new()
                    },
                    row.settle_steps / r,
                    row.ms_per_step / r,
                    row.provider_ms / r,
                    row.fallbacks,
                );
            }
        }
    }
    Ok(())
}
