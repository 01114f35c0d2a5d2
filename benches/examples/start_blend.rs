//! How close to the solution a start must be before the solver stops early: the scene of each
//! seed (`--scene`, default the circle pile; a registered spec such as `box-pile:bodies=1000`,
//! or a bare name with `--bodies`) is stepped with `--drive` (default `builtin`) and, at each
//! listed step, that step is
//! run on copies of the world from starts between the carried impulses and an oracle's
//! (`--oracle`, default the `copy` oracle solved to 1e-5): `carried + w (oracle − carried)` for
//! each blend `w` of `--blends`, on the rows `--rows` names (`both`, `normal`: the tangent rows
//! keep the carried impulses, or `tangent`). Each run's velocity iterations, capped islands and
//! natural residual are printed, then the totals per blend. Providers named with `--starts` run
//! the same steps from their own start. Every start's distance to the oracle's (over every row,
//! `‖start − oracle‖`) is printed as a fraction of the carried impulses' distance to it (1 − w for
//! a blend `w` on every row).
//!
//! ```sh
//! cargo run --release -p deepcontact-benches --example start_blend -- \
//!     --bodies 1000 --seeds 100..104 --steps 160,180,200,220,240 --blends 0.5,0.9,0.99,0.999
//! ```

use deepcontact_core::{
    Impulse, StepReport, WarmStart, WarmStartContext, WarmStartError, WorldSettings,
};
use deepcontact_experiments::scene_for;
use deepcontact_experiments::seeds::parse_seeds;
use deepcontact_pgs::PgsPositionSolver;

const USAGE: &str = "usage: start_blend [--scene pile] [--bodies 1000] [--seeds 100..104] \
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

/// A start that the example runs a step from.
enum Kind {
    /// The carried impulses moved a fraction `w` of the way to the oracle's, on `rows`.
    Blend { w: f64, rows: Rows },
    /// A provider's own start, its distance to the oracle's summed in [`Start::sums`].
    Provider(Box<dyn WarmStart>),
}

/// A start beside the two it is measured against: the carried impulses' and the oracle's.
struct Start {
    kind: Kind,
    carried: Box<dyn WarmStart>,
    oracle: Box<dyn WarmStart>,
    /// `Σ ‖start − oracle‖²` and `Σ ‖carried − oracle‖²` over the rows seen.
    sums: [f64; 2],
    scratch: [Vec<Impulse>; 2],
}

impl WarmStart for Start {
    fn name(&self) -> &str {
        "start_blend"
    }

    fn warm_start(
        &mut self,
        ctx: &WarmStartContext<'_>,
        out: &mut [Impulse],
    ) -> Result<(), WarmStartError> {
        let [c, o] = &mut self.scratch;
        for (v, provider) in [(&mut *c, &mut self.carried), (&mut *o, &mut self.oracle)] {
            v.clear();
            v.resize(out.len(), Impulse::ZERO);
            provider.warm_start(ctx, v)?;
        }
        match &mut self.kind {
            Kind::Blend { w, rows } => {
                let towards = |x: f64, y: f64, on: bool| if on { x + *w * (y - x) } else { x };
                for ((s, x), y) in out.iter_mut().zip(c.iter()).zip(o.iter()) {
                    *s = Impulse::new(
                        towards(x.normal, y.normal, *rows != Rows::Tangent),
                        towards(x.tangent, y.tangent, *rows != Rows::Normal),
                    );
                }
            }
            Kind::Provider(p) => p.warm_start(ctx, out)?,
        }
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
        match &self.kind {
            Kind::Blend { .. } => 0,
            Kind::Provider(p) => p.passes_spent(),
        }
    }
}

/// What the runs from one start add up to: steps, capped islands, velocity iterations, and
/// each step's distance to the oracle's start as a fraction of the carried impulses'.
#[derive(Default)]
struct Totals {
    runs: usize,
    capped: usize,
    iterations: u64,
    distances: Vec<f64>,
}

impl Totals {
    /// Adds one step run from the start, `distance` its start's distance to the oracle's.
    fn add(&mut self, r: &StepReport, distance: f64) {
        self.runs += 1;
        self.capped += r.capped_islands;
        self.iterations += u64::from(r.velocity_iterations);
        self.distances.push(distance);
    }

    /// The runs summed up: capped islands, iterations a step, the median distance.
    fn summary(&mut self) -> String {
        self.distances.sort_by(f64::total_cmp);
        let median = self.distances.get(self.distances.len() / 2);
        format!(
            "{} capped islands over {} steps, {:.0} velocity iterations a step, distance to the \
             oracle {:.3} of the carried impulses' (median over the steps)",
            self.capped,
            self.runs,
            self.iterations as f64 / self.runs.max(1) as f64,
            median.copied().unwrap_or(f64::NAN)
        )
    }
}

/// The command line's settings.
struct Options {
    scene: String,
    bodies: usize,
    seeds: Vec<u64>,
    steps: Vec<u64>,
    blends: Vec<f64>,
    rows: Rows,
    drive: String,
    oracle: String,
    solver: String,
    starts: Vec<String>,
}

fn main() {
    match parse() {
        Ok(None) => println!("{USAGE}"),
        Ok(Some(o)) => {
            if let Err(e) = run(&o) {
                eprintln!("start_blend: {e}");
                std::process::exit(1);
            }
        }
        Err(e) => {
            eprintln!("start_blend: {e}\n{USAGE}");
            std::process::exit(2);
        }
    }
}

/// The options from the command line (`None`: help was asked for).
fn parse() -> Result<Option<Options>, Box<dyn std::error::Error>> {
    let mut o = Options {
        scene: "pile".into(),
        bodies: 1000,
        seeds: parse_seeds("100..104")?,
        steps: vec![160, 180, 200, 220, 240],
        blends: vec![0.5, 0.9, 0.99, 0.999],
        rows: Rows::Both,
        drive: "builtin".into(),
        oracle: "copy:max_iterations=100000,tolerance=1e-5".into(),
        solver: "pgs".into(),
        starts: Vec::new(),
    };
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        let mut value = || args.next().ok_or(format!("{a} needs a value"));
        match a.as_str() {
            "--scene" => o.scene = value()?,
            "--bodies" => o.bodies = value()?.parse()?,
            "--seeds" => o.seeds = parse_seeds(&value()?)?,
            "--steps" => o.steps = list(&value()?)?,
            "--blends" => o.blends = list(&value()?)?,
            "--rows" => {
                o.rows = match value()?.as_str() {
                    "both" => Rows::Both,
                    "normal" => Rows::Normal,
                    "tangent" => Rows::Tangent,
                    other => return Err(format!("--rows {other}: both, normal or tangent").into()),
                }
            }
            "--drive" => o.drive = value()?,
            "--oracle" => o.oracle = value()?,
            "--solver" => o.solver = value()?,
            "--starts" => o.starts = list(&value()?)?,
            "-h" | "--help" => return Ok(None),
            other => return Err(format!("unknown argument `{other}`").into()),
        }
    }
    o.steps.sort_unstable();
    o.steps.dedup();
    if o.steps.is_empty() || o.blends.len() + o.starts.len() == 0 {
        return Err("name at least one step, and a blend or a start".into());
    }
    Ok(Some(o))
}

fn run(o: &Options) -> Result<(), Box<dyn std::error::Error>> {
    let registry = deepcontact_experiments::full_registry();
    // The starts: the blends, then the named providers.
    let labels: Vec<String> = o
        .blends
        .iter()
        .map(|w| format!("w {w}"))
        .chain(o.starts.iter().cloned())
        .collect();
    let mut totals: Vec<Totals> = labels.iter().map(|_| Totals::default()).collect();
    for &seed in &o.seeds {
        let mut driver = registry.build_provider(&o.drive)?;
        let mut solver = registry.build_solver(&o.solver)?;
        let mut position = PgsPositionSolver::new();
        let mut world =
            scene_for(&registry, &o.scene, seed, o.bodies)?.build(WorldSettings::default())?;
        let mut at = 0;
        for &step in &o.steps {
            while at < step {
                world.step(driver.as_mut(), solver.as_mut(), &mut position)?;
                at += 1;
            }
            let mut line = format!("seed {seed} step {step}:");
            for (k, (total, label)) in totals.iter_mut().zip(&labels).enumerate() {
                let kind = match o.blends.get(k) {
                    Some(&w) => Kind::Blend { w, rows: o.rows },
                    None => Kind::Provider(registry.build_provider(&o.starts[k - o.blends.len()])?),
                };
                let mut start = Start {
                    kind,
                    carried: registry.build_provider(&o.drive)?,
                    oracle: registry.build_provider(&o.oracle)?,
                    sums: [0.0; 2],
                    scratch: Default::default(),
                };
                let mut resolver = registry.build_solver(&o.solver)?;
                let r = world.clone().step(
                    &mut start,
                    resolver.as_mut(),
                    &mut PgsPositionSolver::new(),
                )?;
                let distance = (start.sums[0] / start.sums[1]).sqrt();
                total.add(&r, distance);
                line += &format!(
                    "  {label}: {} it, {} capped, {:.2e}, distance {distance:.3}",
                    r.velocity_iterations, r.capped_islands, r.natural_residual
                );
            }
            println!("{line}");
        }
    }
    for (total, label) in totals.iter_mut().zip(&labels) {
        println!("{label}: {}", total.summary());
    }
    Ok(())
}

/// A comma-separated list of numbers (empty items skipped).
fn list<T: std::str::FromStr>(text: &str) -> Result<Vec<T>, String>
where
    T::Err: std::fmt::Display,
{
    text.split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| s.parse().map_err(|e| format!("`{s}`: {e}")))
        .collect()
}
