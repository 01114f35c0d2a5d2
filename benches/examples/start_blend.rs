//! How close to the solution a start must be before the solver stops early: the pile of each
//! seed is stepped with `--drive` (default `builtin`) and, at each listed step, that step is
//! run on copies of the world from starts between the carried impulses and an oracle's
//! (`--oracle`, default the `copy` oracle solved to 1e-5): `carried + w (oracle − carried)` for
//! each blend `w` of `--blends`, on the rows `--rows` names (`both`, `normal`: the tangent rows
//! keep the carried impulses, or `tangent`). Each run's velocity iterations, capped islands and
//! natural residual are printed, then the totals per blend. Providers named with `--starts` run
//! the same steps from their own start, and their start's distance to the oracle's (over every
//! row, `‖start − oracle‖`) is printed as a fraction of the carried impulses' distance to it:
//! 1 − w for a blend `w`.
//!
//! ```sh
//! cargo run --release -p deepcontact-benches --example start_blend -- \
//!     --bodies 1000 --seeds 100..104 --steps 160,180,200,220,240 --blends 0.5,0.9,0.99,0.999
//! ```

use deepcontact_core::{
    Impulse, WarmStart, WarmStartContext, WarmStartError, WorldSettings, scene,
};
use deepcontact_experiments::seeds::parse_seeds;
use deepcontact_pgs::PgsPositionSolver;

const USAGE: &str = "usage: start_blend [--bodies 1000] [--seeds 100..104] \
[--steps 160,180,200,220,240] [--blends 0.5,0.9,0.99,0.999] [--rows both|normal|tangent] \
[--drive builtin] [--oracle copy:max_iterations=100000,tolerance=1e-5] [--solver pgs] \
[--starts PROVIDER,...]";

/// Which rows of the start the oracle moves.
#[derive(Clone, Copy, PartialEq)]
enum Rows {
    Both,
    Normal,
    Tangent,
}

/// The carried impulses moved a fraction `blend` of the way to the oracle's, on `rows`.
struct Blend {
    carried: Box<dyn WarmStart>,
    oracle: Box<dyn WarmStart>,
    blend: f64,
    rows: Rows,
    scratch: [Vec<Impulse>; 2],
}

impl WarmStart for Blend {
    fn name(&self) -> &str {
        "blend"
    }

    fn warm_start(
        &mut self,
        ctx: &WarmStartContext<'_>,
        out: &mut [Impulse],
    ) -> Result<(), WarmStartError> {
        let [a, b] = &mut self.scratch;
        a.clear();
        a.resize(out.len(), Impulse::ZERO);
        b.clear();
        b.resize(out.len(), Impulse::ZERO);
        self.carried.warm_start(ctx, a)?;
        self.oracle.warm_start(ctx, b)?;
        let w = self.blend;
        let towards = |x: f64, y: f64, on: bool| if on { x + w * (y - x) } else { x };
        for ((o, x), y) in out.iter_mut().zip(a.iter()).zip(b.iter()) {
            *o = Impulse::new(
                towards(x.normal, y.normal, self.rows != Rows::Tangent),
                towards(x.tangent, y.tangent, self.rows != Rows::Normal),
            );
        }
        Ok(())
    }
}

/// A provider's start, measured against the carried impulses' and an oracle's.
struct Measured {
    start: Box<dyn WarmStart>,
    carried: Box<dyn WarmStart>,
    oracle: Box<dyn WarmStart>,
    /// `Σ ‖start − oracle‖²` and `Σ ‖carried − oracle‖²` over the rows seen.
    sums: [f64; 2],
    scratch: [Vec<Impulse>; 2],
}

impl WarmStart for Measured {
    fn name(&self) -> &str {
        "measured"
    }

    fn warm_start(
        &mut self,
        ctx: &WarmStartContext<'_>,
        out: &mut [Impulse],
    ) -> Result<(), WarmStartError> {
        let [c, o] = &mut self.scratch;
        c.clear();
        c.resize(out.len(), Impulse::ZERO);
        o.clear();
        o.resize(out.len(), Impulse::ZERO);
        self.carried.warm_start(ctx, c)?;
        self.oracle.warm_start(ctx, o)?;
        self.start.warm_start(ctx, out)?;
        let d2 = |a: &Impulse, b: &Impulse| {
            (a.normal - b.normal).powi(2) + (a.tangent - b.tangent).powi(2)
        };
        for ((s, c), o) in out.iter().zip(c.iter()).zip(o.iter()) {
            self.sums[0] += d2(s, o);
            self.sums[1] += d2(c, o);
        }
        Ok(())
    }

    fn passes_spent(&self) -> u32 {
        self.start.passes_spent()
    }
}

fn main() {
    if let Err(e) = run() {
        eprintln!("start_blend: {e}\n{USAGE}");
        std::process::exit(2);
    }
}

fn run() -> Result<(), Box<dyn std::error::Error>> {
    let mut bodies = 1000;
    let mut seeds = parse_seeds("100..104")?;
    let mut steps: Vec<u64> = vec![160, 180, 200, 220, 240];
    let mut blends: Vec<f64> = vec![0.5, 0.9, 0.99, 0.999];
    let mut rows = Rows::Both;
    let (mut drive, mut solver_spec) = ("builtin".to_string(), "pgs".to_string());
    let mut oracle = "copy:max_iterations=100000,tolerance=1e-5".to_string();
    let mut starts: Vec<String> = Vec::new();
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        let mut value = || args.next().ok_or(format!("{a} needs a value"));
        match a.as_str() {
            "--bodies" => bodies = value()?.parse()?,
            "--seeds" => seeds = parse_seeds(&value()?)?,
            "--steps" => steps = list(&value()?)?,
            "--blends" => blends = list(&value()?)?,
            "--rows" => {
                rows = match value()?.as_str() {
                    "both" => Rows::Both,
                    "normal" => Rows::Normal,
                    "tangent" => Rows::Tangent,
                    other => return Err(format!("--rows {other}: both, normal or tangent").into()),
                }
            }
            "--drive" => drive = value()?,
            "--oracle" => oracle = value()?,
            "--solver" => solver_spec = value()?,
            "--starts" => starts = value()?.split(',').map(str::to_string).collect(),
            "-h" | "--help" => {
                println!("{USAGE}");
                return Ok(());
            }
            other => return Err(format!("unknown argument `{other}`").into()),
        }
    }
    steps.sort_unstable();
    steps.dedup();
    if steps.is_empty() || blends.is_empty() {
        return Err("name at least one step and one blend".into());
    }
    let registry = deepcontact_experiments::full_registry();
    // Per blend: runs, capped islands, velocity iterations.
    let mut totals = vec![(0usize, 0usize, 0u64); blends.len()];
    // Per named start: the same, and each step's distance to the oracle (fraction of carried's).
    let mut measured = vec![((0usize, 0usize, 0u64), Vec::new()); starts.len()];
    for &seed in &seeds {
        let mut driver = registry.build_provider(&drive)?;
        let mut solver = registry.build_solver(&solver_spec)?;
        let mut position = PgsPositionSolver::new();
        let mut world = scene::by_name("pile", seed, bodies)?.build(WorldSettings::default())?;
        let mut at = 0;
        for &step in &steps {
            while at < step {
                world.step(driver.as_mut(), solver.as_mut(), &mut position)?;
                at += 1;
            }
            let mut line = format!("seed {seed} step {step}:");
            for (total, &blend) in totals.iter_mut().zip(&blends) {
                let mut start = Blend {
                    carried: registry.build_provider(&drive)?,
                    oracle: registry.build_provider(&oracle)?,
                    blend,
                    rows,
                    scratch: Default::default(),
                };
                let mut resolver = registry.build_solver(&solver_spec)?;
                let r = world.clone().step(
                    &mut start,
                    resolver.as_mut(),
                    &mut PgsPositionSolver::new(),
                )?;
                *total = (
                    total.0 + 1,
                    total.1 + r.capped_islands,
                    total.2 + u64::from(r.velocity_iterations),
                );
                line += &format!(
                    "  w {blend}: {} it, {} capped, {:.2e}",
                    r.velocity_iterations, r.capped_islands, r.natural_residual
                );
            }
            for ((total, distances), spec) in measured.iter_mut().zip(&starts) {
                let mut start = Measured {
                    start: registry.build_provider(spec)?,
                    carried: registry.build_provider(&drive)?,
                    oracle: registry.build_provider(&oracle)?,
                    sums: [0.0; 2],
                    scratch: Default::default(),
                };
                let mut resolver = registry.build_solver(&solver_spec)?;
                let r = world.clone().step(
                    &mut start,
                    resolver.as_mut(),
                    &mut PgsPositionSolver::new(),
                )?;
                *total = (
                    total.0 + 1,
                    total.1 + r.capped_islands,
                    total.2 + u64::from(r.velocity_iterations),
                );
                let distance = (start.sums[0] / start.sums[1]).sqrt();
                distances.push(distance);
                line += &format!(
                    "  {spec}: {} it, {} capped, {:.2e}, distance {distance:.3}",
                    r.velocity_iterations, r.capped_islands, r.natural_residual
                );
            }
            println!("{line}");
        }
    }
    for ((runs, capped, iterations), blend) in totals.iter().zip(&blends) {
        println!(
            "w {blend}: {capped} capped islands over {runs} steps, {:.0} velocity iterations a step",
            *iterations as f64 / (*runs).max(1) as f64
        );
    }
    for (((runs, capped, iterations), distances), spec) in measured.iter_mut().zip(&starts) {
        distances.sort_by(f64::total_cmp);
        println!(
            "{spec}: {capped} capped islands over {runs} steps, {:.0} velocity iterations a step, \
             distance to the oracle {:.3} of the carried impulses' (median over the steps)",
            *iterations as f64 / (*runs).max(1) as f64,
            distances
                .get(distances.len() / 2)
                .copied()
                .unwrap_or(f64::NAN)
        );
    }
    Ok(())
}

/// A comma-separated list of numbers.
fn list<T: std::str::FromStr>(text: &str) -> Result<Vec<T>, String>
where
    T::Err: std::fmt::Display,
{
    text.split(',')
        .map(|s| s.trim().parse().map_err(|e| format!("`{}`: {e}", s.trim())))
        .collect()
}
