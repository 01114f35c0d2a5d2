//! One big island on several threads: the settled pile (`--seed`, default 12345) of `--bodies`
//! circles (default 10 000) stepped under the thesis stop rule (cap 1 000, ∞-norm < 1e-4, position
//! cap 250) from the same snapshot, alternately for `--rounds` rounds: the plain one-thread solvers
//! (unchunked sweep, position pass in problem order), and the planned sweeps on 1 thread and on
//! `--threads` threads (islands side by side; the velocity sweep in the domain plan of at most
//! `--domains` domains of at least `--domain-points` points each (defaults 16 and 1 100;
//! `--domain-points 0`: exactly `--domains`), or with `--domains 0` in the chunked plan; the
//! position pass likewise in domains or, with `--domains 0`, in shared colours), as `simulate
//! --threads` runs. The pile is settled with the chunked plans (the snapshot of the earlier
//! measurements). Prints ms per step (whole step, velocity solve, the rest) per thread count and
//! the ratio T threads / 1 thread (of the medians, of each round's pair, and of the fastest
//! rounds), and checks that every run ends in the same bits (positions, velocities) whatever the
//! thread count.
//!
//! ```sh
//! cargo run --release -p deepcontact-benches --example threads
//! cargo run --release -p deepcontact-benches --example threads -- --bodies 1000 --threads 2 --steps 10
//! ```
//!
//! Timings are wall-clock; compare rows of one run only.

use std::time::Instant;

use deepcontact_benches::{FNV_OFFSET, SEED, fnv1a, median, settle_world};
use deepcontact_core::{CarriedWarmStart, World, WorldSettings, scene};
use deepcontact_pgs::{PgsPositionSettings, PgsPositionSolver, PgsSettings, PgsSolver};

/// Command-line options.
struct Options {
    bodies: usize,
    threads: usize,
    steps: u64,
    settle: u64,
    rounds: usize,
    domains: usize,
    domain_points: usize,
    seed: u64,
}

fn parse() -> Result<Option<Options>, String> {
    let mut o = Options {
        bodies: 10_000,
        threads: 2,
        steps: 5,
        settle: 0,
        rounds: 3,
        domains: PgsSettings::default().domains,
        domain_points: PgsSettings::default().domain_points,
        seed: SEED,
    };
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        if a == "--help" || a == "-h" {
            println!(
                "usage: threads [--bodies 10000] [--threads 2] [--steps 5] [--settle STEPS] \
                 [--rounds 3] [--domains 16] [--domain-points 1100] [--seed 12345]  \
                 (--settle default: 250 × (bodies / 100)^¼)"
            );
            return Ok(None);
        }
        let value = args.next().ok_or(format!("{a} needs a value"))?;
        let number = |v: &str| v.parse::<u64>().map_err(|e| format!("{a} {v}: {e}"));
        match a.as_str() {
            "--bodies" => o.bodies = number(&value)? as usize,
            "--threads" => o.threads = number(&value)? as usize,
            "--steps" => o.steps = number(&value)?,
            "--settle" => o.settle = number(&value)?,
            "--rounds" => o.rounds = number(&value)? as usize,
            "--domains" => o.domains = number(&value)? as usize,
            "--domain-points" => o.domain_points = number(&value)? as usize,
            "--seed" => o.seed = number(&value)?,
            _ => return Err(format!("unknown option {a} (see --help)")),
        }
    }
    if o.settle == 0 {
        o.settle = (250.0 * (o.bodies as f64 / 100.0).powf(0.25)).round() as u64;
    }
    if !(1..=64).contains(&o.threads) || o.steps == 0 || o.rounds == 0 {
        return Err("--threads must be 1 to 64, --steps and --rounds at least 1".into());
    }
    Ok(Some(o))
}

/// One measured run: per-step sums and the final state's bits.
#[derive(Default)]
struct Run {
    wall: f64,
    solve: f64,
    iterations: u64,
    position_iterations: u64,
    contacts: u64,
    islands: u64,
    bits: Vec<u64>,
}

/// A configuration: the plain one-thread solvers (problem-order position pass, unchunked
/// sweep), or the chunked plan on a number of threads.
#[derive(Clone, Copy)]
enum Config {
    Plain,
    /// Threads, most domains, points a domain.
    Chunked(usize, usize, usize),
}

impl Config {
    fn label(self) -> String {
        match self {
            Config::Plain => "1, unchunked".into(),
            Config::Chunked(t, _, _) => format!("{t}"),
        }
    }

    fn solvers(self) -> (PgsSolver, PgsPositionSolver) {
        let (threads, from, domains, domain_points) = match self {
            Config::Plain => (1, usize::MAX, 0, 0),
            Config::Chunked(t, d, p) => (t, PgsSettings::default().parallel_min_points, d, p),
        };
        let solver = PgsSolver::with_settings(PgsSettings {
            threads,
            parallel_min_points: from,
            domains,
            domain_points,
            ..PgsSettings::default()
        });
        let position = PgsPositionSolver::with_settings(PgsPositionSettings {
            threads,
            parallel_min_points: from,
            domains,
            domain_points,
        });
        (solver, position)
    }
}

/// `steps` thesis-rule steps of a copy of `snapshot` in configuration `config`.
fn run(snapshot: &World, config: Config, steps: u64) -> Result<Run, String> {
    let mut world = snapshot.clone();
    let island_threads = match config {
        Config::Plain => 1,
        Config::Chunked(t, _, _) => t,
    };
    world
        .set_settings(WorldSettings {
            island_threads,
            collide_threads: island_threads,
            ..WorldSettings::default()
        })
        .map_err(|e| e.to_string())?;
    let (mut solver, mut position) = config.solvers();
    let mut r = Run::default();
    for _ in 0..steps {
        let t0 = Instant::now();
        let s = world
            .step(&mut CarriedWarmStart, &mut solver, &mut position)
            .map_err(|e| e.to_string())?;
        r.wall += t0.elapsed().as_secs_f64();
        r.solve += s.solve_seconds;
        r.iterations += u64::from(s.velocity_iterations);
        r.position_iterations += u64::from(s.position_iterations);
        r.contacts += s.contacts as u64;
        r.islands += s.islands as u64;
    }
    r.bits = world
        .bodies()
        .iter()
        .flat_map(|b| b.state().map(f64::to_bits))
        .collect();
    Ok(r)
}

/// The pile of `o.bodies` circles settled for `o.settle` steps.
fn settled_pile(o: &Options) -> Result<World, String> {
    let t0 = Instant::now();
    let scene = scene::pile(o.seed, o.bodies).map_err(|e| e.to_string())?;
    let mut world = scene.build(settle_world(50)).map_err(|e| e.to_string())?;
    // Settled with the chunked plans, which the earlier measurements (docs/BENCHMARKS.md)
    // settled with: the same snapshot for every version since.
    let (mut solver, mut position) = (
        PgsSolver::with_settings(PgsSettings {
            domains: 0,
            ..PgsSettings::default()
        }),
        PgsPositionSolver::with_settings(PgsPositionSettings {
            domains: 0,
            ..PgsPositionSettings::default()
        }),
    );
    for _ in 0..o.settle {
        world
            .step(&mut CarriedWarmStart, &mut solver, &mut position)
            .map_err(|e| e.to_string())?;
    }
    eprintln!(
        "pile of {} circles (seed {}) settled for {} steps in {:.1} s",
        o.bodies,
        o.seed,
        o.settle,
        t0.elapsed().as_secs_f64()
    );
    Ok(world)
}

/// The ratio of `many` (runs on `threads` threads) to `one` (one thread) round by round, and
/// of their fastest rounds: the runs of a round follow each other within a second, so they
/// share the machine's state more often than the medians of whole columns do.
fn print_rounds(threads: usize, many: &[Run], one: &[Run]) {
    let paired: Vec<f64> = many.iter().zip(one).map(|(m, o)| m.wall / o.wall).collect();
    let fastest = |rs: &[Run]| rs.iter().map(|r| r.wall).fold(f64::INFINITY, f64::min);
    let (lo, hi) = paired
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &r| {
            (lo.min(r), hi.max(r))
        });
    println!(
        "\n{threads} threads / 1 thread, round by round: median {:.3} ({lo:.3}–{hi:.3}, {} \
         rounds); fastest round / fastest round: {:.3}",
        median(&paired),
        paired.len(),
        fastest(many) / fastest(one),
    );
}

fn main() -> Result<(), String> {
    let Some(o) = parse()? else {
        return Ok(());
    };
    let world = settled_pile(&o)?;
    let configs = [
        Config::Plain,
        Config::Chunked(1, o.domains, o.domain_points),
        Config::Chunked(o.threads, o.domains, o.domain_points),
    ];
    let mut runs: [Vec<Run>; 3] = [Vec::new(), Vec::new(), Vec::new()];
    for round in 0..o.rounds {
        for (k, &config) in configs.iter().enumerate() {
            let r = run(&world, config, o.steps)?;
            eprintln!(
                "round {round}, {} thread(s): {:.2} ms/step",
                config.label(),
                r.wall / o.steps as f64 * 1e3
            );
            runs[k].push(r);
        }
    }
    // The chunked runs against each other: the same bits whatever the thread count.
    let reference = &runs[1][0];
    for r in runs[1..].iter().flatten() {
        if r.bits != reference.bits || r.iterations != reference.iterations {
            return Err("runs with different thread counts ended in different states".into());
        }
    }
    let per_step = |rs: &[Run], f: fn(&Run) -> f64| {
        median(
            &rs.iter()
                .map(|r| f(r) / o.steps as f64 * 1e3)
                .collect::<Vec<_>>(),
        )
    };
    println!(
        "Pile of {} circles (seed {}) settled {} steps, then {} steps under the thesis stop \
         rule, {} rounds; {:.0} contact points in {:.1} islands, {:.0} velocity iterations \
         (slowest island) and {:.0} position iterations per step; the chunked runs bit-identical for every thread \
         count (the unchunked run's position pass visits the points in another order), their \
         final state's hash {:#018x} (to compare builds).\n",
        o.bodies,
        o.seed,
        o.settle,
        o.steps,
        o.rounds,
        reference.contacts as f64 / o.steps as f64,
        reference.islands as f64 / o.steps as f64,
        reference.iterations as f64 / o.steps as f64,
        reference.position_iterations as f64 / o.steps as f64,
        reference
            .bits
            .iter()
            .fold(FNV_OFFSET, |h, w| fnv1a(h, &w.to_le_bytes())),
    );
    println!(
        "| threads | step ms (median) | velocity solve ms | rest ms | step / chunked 1 thread | \
         step / unchunked |"
    );
    println!("|---|---:|---:|---:|---:|---:|");
    let plain = per_step(&runs[0], |r| r.wall);
    let one = per_step(&runs[1], |r| r.wall);
    for (k, &config) in configs.iter().enumerate() {
        let step = per_step(&runs[k], |r| r.wall);
        let solve = per_step(&runs[k], |r| r.solve);
        println!(
            "| {} | {step:.1} | {solve:.1} | {:.1} | {:.3} | {:.3} |",
            config.label(),
            step - solve,
            step / one,
            step / plain
        );
    }
    print_rounds(o.threads, &runs[2], &runs[1]);
    Ok(())
}
