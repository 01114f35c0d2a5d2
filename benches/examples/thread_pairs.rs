//! Whole runs on two thread counts, as processes in turns: `deepcontact simulate --json` with
//! `--threads A` and `--threads B` (default 1 and 2), `--pairs` times (default 12), which one
//! first alternating from pair to pair, so that a slow spell of the machine touches both. Each
//! process is timed from its start to its exit (start-up and the report's output included), and
//! its step reports are hashed without their timing fields (`*_seconds`): every pair must give one
//! hash on both thread counts, or the run fails. Prints each pair and the medians (smallest–
//! largest) of B / A: the processes' wall times and the summed `step_seconds`.
//!
//! ```sh
//! cargo build --release --bin deepcontact --example thread_pairs -p deepcontact-benches
//! target/release/examples/thread_pairs --bodies 10000 --steps 250 --pairs 12
//! ```
//!
//! `--bin PATH` names the binary (default: `deepcontact` beside this example's directory, as
//! cargo builds both into `target/release`); `--scene`, `--seed` and `--solver` are passed on.
//! Last, a table of the stages' seconds (`collide_seconds`, `islands_seconds`,
//! `solve_seconds`, `position_seconds` and `step_seconds` of the reports) summed over the steps
//! of each phase, medians over the pairs, for both thread counts; `--phases 150,205` cuts the
//! run into phases at those steps (default: one phase, the whole run).

use std::path::PathBuf;
use std::process::Command;
use std::time::Instant;

use deepcontact_benches::{FNV_OFFSET, fnv1a, median};

/// Command-line options.
struct Options {
    bin: PathBuf,
    bodies: usize,
    steps: u64,
    seed: Option<u64>,
    scene: Option<String>,
    solver: Option<String>,
    threads: [usize; 2],
    pairs: usize,
    /// The first step of each phase after the first (ascending, under `steps`).
    phases: Vec<u64>,
}

/// The timed stages of a step report, as the table names them, and their fields.
const STAGES: [(&str, &str); 5] = [
    ("collide", "collide_seconds"),
    ("islands", "islands_seconds"),
    ("velocity solves", "solve_seconds"),
    ("position passes", "position_seconds"),
    ("whole steps", "step_seconds"),
];

/// One process's run: its wall time, the sum of its steps' `step_seconds`, its report hash,
/// and per phase the stages' seconds summed over its steps.
struct Run {
    wall: f64,
    steps: f64,
    hash: u64,
    stages: Vec<[f64; STAGES.len()]>,
}

const USAGE: &str = "usage: thread_pairs [--bin PATH] [--bodies 10000] [--steps 250] \
                     [--seed S] [--scene NAME] [--solver SPEC] [--threads 1,2] [--pairs 12] \
                     [--phases STEP,STEP,...]";

fn parse() -> Result<Option<Options>, String> {
    let beside = std::env::current_exe()
        .ok()
        .and_then(|exe| Some(exe.parent()?.parent()?.join("deepcontact")))
        .unwrap_or_else(|| PathBuf::from("target/release/deepcontact"));
    let mut o = Options {
        bin: beside,
        bodies: 10_000,
        steps: 250,
        seed: None,
        scene: None,
        solver: None,
        threads: [1, 2],
        pairs: 12,
        phases: Vec::new(),
    };
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        if a == "--help" || a == "-h" {
            println!("{USAGE}");
            return Ok(None);
        }
        let value = args.next().ok_or(format!("{a} needs a value\n{USAGE}"))?;
        let number = |v: &str| {
            v.parse::<u64>()
                .map_err(|e| format!("{a} {v}: {e}\n{USAGE}"))
        };
        match a.as_str() {
            "--bin" => o.bin = PathBuf::from(value),
            "--bodies" => o.bodies = number(&value)? as usize,
            "--steps" => o.steps = number(&value)?,
            "--seed" => o.seed = Some(number(&value)?),
            "--scene" => o.scene = Some(value),
            "--solver" => o.solver = Some(value),
            "--pairs" => o.pairs = number(&value)? as usize,
            "--phases" => {
                o.phases = value
                    .split(',')
                    .map(number)
                    .collect::<Result<Vec<_>, _>>()?;
            }
            "--threads" => {
                let counts = value
                    .split(',')
                    .map(|t| number(t).map(|t| t as usize))
                    .collect::<Result<Vec<_>, _>>()?;
                o.threads = match counts[..] {
                    [a, b] if a >= 1 && b >= 1 && a != b => [a, b],
                    _ => return Err(format!("--threads wants two counts A,B: {value}")),
                };
            }
            _ => return Err(format!("unknown option {a}\n{USAGE}")),
        }
    }
    if o.pairs == 0 {
        return Err("--pairs must be at least 1".into());
    }
    let ascending = o.phases.windows(2).all(|w| w[0] < w[1]);
    if !ascending || o.phases.first() == Some(&0) || o.phases.last() >= Some(&o.steps) {
        return Err(format!(
            "--phases wants ascending steps between 1 and {}: {:?}",
            o.steps.saturating_sub(1),
            o.phases
        ));
    }
    if !o.bin.is_file() {
        return Err(format!(
            "no binary at {} (build it: cargo build --release --bin deepcontact; or --bin PATH)",
            o.bin.display()
        ));
    }
    Ok(Some(o))
}

/// Runs one process on `threads` threads and reads its step reports.
fn run(o: &Options, threads: usize) -> Result<Run, String> {
    let mut cmd = Command::new(&o.bin);
    cmd.arg("simulate")
        .args(["--bodies", &o.bodies.to_string()])
        .args(["--steps", &o.steps.to_string()])
        .args(["--threads", &threads.to_string(), "--json"]);
    if let Some(seed) = o.seed {
        cmd.args(["--seed", &seed.to_string()]);
    }
    if let Some(scene) = &o.scene {
        cmd.args(["--scene", scene]);
    }
    if let Some(solver) = &o.solver {
        cmd.args(["--solver", solver]);
    }
    let t0 = Instant::now();
    let out = cmd
        .output()
        .map_err(|e| format!("{}: {e}", o.bin.display()))?;
    let wall = t0.elapsed().as_secs_f64();
    if !out.status.success() {
        return Err(format!(
            "{:?} failed ({}): {}",
            cmd,
            out.status,
            String::from_utf8_lossy(&out.stderr)
        ));
    }
    let text = String::from_utf8(out.stdout).map_err(|e| format!("report not UTF-8: {e}"))?;
    let (mut steps, mut hash, mut lines) = (0.0, FNV_OFFSET, 0);
    let mut stages = vec![[0.0; STAGES.len()]; o.phases.len() + 1];
    for line in text.lines().filter(|l| !l.trim().is_empty()) {
        let mut report: serde_json::Map<String, serde_json::Value> =
            serde_json::from_str(line).map_err(|e| format!("step report {lines}: {e}"))?;
        let seconds = |field: &str| {
            report
                .get(field)
                .and_then(serde_json::Value::as_f64)
                .ok_or(format!("step report {lines} has no {field}"))
        };
        steps += seconds("step_seconds")?;
        let phase = o.phases.partition_point(|&first| first <= lines as u64);
        for (sum, (_, field)) in stages[phase].iter_mut().zip(STAGES) {
            *sum += seconds(field)?;
        }
        report.retain(|key, _| !key.ends_with("_seconds"));
        let canonical = serde_json::to_string(&report).map_err(|e| e.to_string())?;
        hash = fnv1a(hash, canonical.as_bytes());
        lines += 1;
    }
    if lines as u64 != o.steps {
        return Err(format!("{lines} step reports for {} steps", o.steps));
    }
    Ok(Run {
        wall,
        steps,
        hash,
        stages,
    })
}

/// Median, smallest and largest of `v` (not empty).
fn spread(v: &[f64]) -> (f64, f64, f64) {
    let (lo, hi) = v
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &x| {
            (lo.min(x), hi.max(x))
        });
    (median(v), lo, hi)
}

fn main() {
    let o = match parse() {
        Ok(Some(o)) => o,
        Ok(None) => return,
        Err(e) => {
            eprintln!("{e}");
            std::process::exit(2);
        }
    };
    let [a, b] = o.threads;
    println!(
        "{} simulate --bodies {} --steps {} --json, {a} and {b} threads in turns, {} pairs",
        o.bin.display(),
        o.bodies,
        o.steps,
        o.pairs
    );
    let (mut walls, mut sums, mut hashes) = (Vec::new(), Vec::new(), Vec::<u64>::new());
    // Per thread count (A, B): every pair's stage sums.
    let mut stages: [Vec<Vec<[f64; STAGES.len()]>>; 2] = [Vec::new(), Vec::new()];
    for pair in 0..o.pairs {
        let order = if pair % 2 == 0 { [a, b] } else { [b, a] };
        let [first, second] = order.map(|threads| {
            run(&o, threads).unwrap_or_else(|e| {
                eprintln!("pair {pair}: {e}");
                std::process::exit(1);
            })
        });
        let (ra, rb) = if order[0] == a {
            (&first, &second)
        } else {
            (&second, &first)
        };
        walls.push(rb.wall / ra.wall);
        sums.push(rb.steps / ra.steps);
        println!(
            "pair {pair:2}: {a} thread(s) {:.3} s, {b} thread(s) {:.3} s, wall {b}/{a} {:.3}, \
             summed steps {b}/{a} {:.3}, reports {:016x} / {:016x}",
            ra.wall, rb.wall, walls[pair], sums[pair], ra.hash, rb.hash
        );
        if ra.hash != rb.hash {
            eprintln!(
                "pair {pair}: the reports differ between {a} and {b} threads (every field but the \
                 timings should be the same bits)"
            );
            std::process::exit(1);
        }
        if hashes.first().is_some_and(|&h| h != ra.hash) {
            eprintln!(
                "pair {pair}: the reports differ from the first pair's (same seed, same run)"
            );
            std::process::exit(1);
        }
        hashes.push(ra.hash);
        stages[0].push(ra.stages.clone());
        stages[1].push(rb.stages.clone());
    }
    let (wm, wl, wh) = spread(&walls);
    let (sm, sl, sh) = spread(&sums);
    println!(
        "{b} / {a} threads over {} pairs: wall median {wm:.3} ({wl:.3}–{wh:.3}), summed steps \
         median {sm:.3} ({sl:.3}–{sh:.3}); every report the same bits ({:016x})",
        o.pairs, hashes[0]
    );
    print_stages(&o, &stages);
}

/// The stages' seconds per phase, medians over the pairs, `A / B` threads, as a table.
fn print_stages(o: &Options, stages: &[Vec<Vec<[f64; STAGES.len()]>>; 2]) {
    let [a, b] = o.threads;
    let bounds: Vec<u64> = std::iter::once(0)
        .chain(o.phases.iter().copied())
        .chain(std::iter::once(o.steps))
        .collect();
    println!(
        "\nseconds summed over each phase's steps, medians of {} pairs, {a} / {b} threads:\n",
        o.pairs
    );
    let heads: Vec<String> = bounds
        .windows(2)
        .map(|w| format!("steps {}–{}", w[0], w[1] - 1))
        .collect();
    println!("| stage | {} |", heads.join(" | "));
    println!("|---|{}", "---|".repeat(heads.len()));
    for (s, (name, _)) in STAGES.iter().enumerate() {
        let cells: Vec<String> = (0..heads.len())
            .map(|phase| {
                let [ma, mb] = [0, 1].map(|t| {
                    let v: Vec<f64> = stages[t].iter().map(|run| run[phase][s]).collect();
                    median(&v)
                });
                format!("{ma:.3} / {mb:.3}")
            })
            .collect();
        println!("| {name} | {} |", cells.join(" | "));
    }
}
