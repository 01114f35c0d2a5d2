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
//! `--ceiling` adds to each pair a third run: B / A copies of the A-thread process started side by
//! side (B a multiple of A), timed from their start to the last one's exit. That run does B / A
//! times the work of one A-thread process with every core B threads use busy and nothing shared,
//! so its wall time over B / A times the A-thread process's is the B / A ratio a run with no
//! serial part and no waits would reach on this machine: the ceiling that the host's cores,
//! caches and neighbours leave. Each pair then runs the three in turns (the order rotates), and the
//! summary gives the ceiling's median beside the ratio.
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
    /// Whether each pair also times B / A copies of the A-thread process side by side.
    ceiling: bool,
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
                     [--phases STEP,STEP,...] [--ceiling]";

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
        ceiling: false,
    };
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        if a == "--help" || a == "-h" {
            println!("{USAGE}");
            return Ok(None);
        }
        if a == "--ceiling" {
            o.ceiling = true;
            continue;
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
    if o.ceiling && o.threads[1] % o.threads[0] != 0 {
        return Err(format!(
            "--ceiling wants B a multiple of A (B / A copies of the A-thread run): {:?}",
            o.threads
        ));
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

/// The `simulate` command of one process on `threads` threads.
fn command(o: &Options, threads: usize) -> Command {
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
    cmd
}

/// Runs one process on `threads` threads and reads its step reports.
fn run(o: &Options, threads: usize) -> Result<Run, String> {
    let mut cmd = command(o, threads);
    let t0 = Instant::now();
    let out = cmd
        .output()
        .map_err(|e| format!("{}: {e}", o.bin.display()))?;
    let wall = t0.elapsed().as_secs_f64();
    read(o, &cmd, out, wall)
}

/// Runs `copies` processes on `threads` threads each, started side by side; the wall time from
/// their start to the last one's exit, and the first one's run (every copy must give its hash).
fn side_by_side(o: &Options, threads: usize, copies: usize) -> Result<(f64, Run), String> {
    let t0 = Instant::now();
    let children = (0..copies)
        .map(|_| {
            let mut cmd = command(o, threads);
            cmd.stdout(std::process::Stdio::piped())
                .stderr(std::process::Stdio::piped());
            let child = cmd
                .spawn()
                .map_err(|e| format!("{}: {e}", o.bin.display()))?;
            Ok((cmd, child))
        })
        .collect::<Result<Vec<_>, String>>()?;
    // Each child's output read on a thread of its own: a report is megabytes, more than a
    // pipe holds, so a child whose output nobody reads would wait for the others to end.
    let outs = std::thread::scope(|scope| {
        let readers: Vec<_> = children
            .into_iter()
            .map(|(cmd, child)| scope.spawn(move || (cmd, child.wait_with_output())))
            .collect();
        readers
            .into_iter()
            .map(|reader| {
                let (cmd, out) = reader
                    .join()
                    .map_err(|_| "a reader thread panicked".to_string())?;
                let out = out.map_err(|e| format!("{}: {e}", o.bin.display()))?;
                Ok((cmd, out))
            })
            .collect::<Result<Vec<_>, String>>()
    })?;
    let wall = t0.elapsed().as_secs_f64();
    let mut runs = outs
        .into_iter()
        .map(|(cmd, out)| read(o, &cmd, out, wall))
        .collect::<Result<Vec<_>, String>>()?;
    if runs.iter().any(|r| r.hash != runs[0].hash) {
        return Err("copies of one run side by side gave different reports".into());
    }
    Ok((wall, runs.swap_remove(0)))
}

/// Reads the step reports of a finished process (`cmd`, which took `wall` seconds).
fn read(o: &Options, cmd: &Command, out: std::process::Output, wall: f64) -> Result<Run, String> {
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

/// One pair's runs: the A-thread run, the B-thread run, and with `--ceiling` the wall time of
/// B / A copies of the A-thread run side by side.
struct Pair {
    a: Run,
    b: Run,
    ceiling_wall: Option<f64>,
}

/// Runs pair `pair`: A and B alternating first; with the ceiling's run, the three in an order
/// that rotates. Every run must report the same bits.
fn run_pair(o: &Options, pair: usize) -> Result<Pair, String> {
    let [a, b] = o.threads;
    let order: Vec<usize> = if o.ceiling {
        [0, 1, 2]
            .into_iter()
            .cycle()
            .skip(pair % 3)
            .take(3)
            .collect()
    } else if pair % 2 == 0 {
        vec![0, 1]
    } else {
        vec![1, 0]
    };
    let (mut ra, mut rb, mut side) = (None, None, None);
    for which in order {
        match which {
            0 => ra = Some(run(o, a)?),
            1 => rb = Some(run(o, b)?),
            _ => side = Some(side_by_side(o, a, b / a)?),
        }
    }
    let (Some(ra), Some(rb)) = (ra, rb) else {
        return Err("a run of the pair did not happen".into());
    };
    if ra.hash != rb.hash {
        return Err(format!(
            "the reports differ between {a} and {b} threads (every field but the timings \
             should be the same bits)"
        ));
    }
    if side.as_ref().is_some_and(|(_, copy)| copy.hash != ra.hash) {
        return Err("the copies side by side gave other reports than the run alone".into());
    }
    Ok(Pair {
        a: ra,
        b: rb,
        ceiling_wall: side.map(|(wall, _)| wall),
    })
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
    let (mut walls, mut sums, mut ceilings) = (Vec::new(), Vec::new(), Vec::new());
    let mut hash = None;
    // Per thread count (A, B): every pair's stage sums.
    let mut stages: [Vec<Vec<[f64; STAGES.len()]>>; 2] = [Vec::new(), Vec::new()];
    for pair in 0..o.pairs {
        let p = run_pair(&o, pair).unwrap_or_else(|e| {
            eprintln!("pair {pair}: {e}");
            std::process::exit(1);
        });
        walls.push(p.b.wall / p.a.wall);
        sums.push(p.b.steps / p.a.steps);
        println!(
            "pair {pair:2}: {a} thread(s) {:.3} s, {b} thread(s) {:.3} s, wall {b}/{a} {:.3}, \
             summed steps {b}/{a} {:.3}, reports {:016x} / {:016x}",
            p.a.wall, p.b.wall, walls[pair], sums[pair], p.a.hash, p.b.hash
        );
        if let Some(wall) = p.ceiling_wall {
            ceilings.push(wall / ((b / a) as f64 * p.a.wall));
            println!(
                "         {} copies of the {a}-thread run side by side {wall:.3} s, ceiling {:.3}",
                b / a,
                ceilings[pair]
            );
        }
        if *hash.get_or_insert(p.a.hash) != p.a.hash {
            eprintln!(
                "pair {pair}: the reports differ from the first pair's (same seed, same run)"
            );
            std::process::exit(1);
        }
        stages[0].push(p.a.stages);
        stages[1].push(p.b.stages);
    }
    print_ratios(&o, &walls, &sums, &ceilings, hash.unwrap_or_default());
    print_stages(&o, &stages);
}

/// The medians (smallest–largest) of B / A over the pairs, and of the ceiling when measured.
fn print_ratios(o: &Options, walls: &[f64], sums: &[f64], ceilings: &[f64], hash: u64) {
    let [a, b] = o.threads;
    let (wm, wl, wh) = spread(walls);
    let (sm, sl, sh) = spread(sums);
    println!(
        "{b} / {a} threads over {} pairs: wall median {wm:.3} ({wl:.3}–{wh:.3}), summed steps \
         median {sm:.3} ({sl:.3}–{sh:.3}); every report the same bits ({hash:016x})",
        o.pairs
    );
    if ceilings.is_empty() {
        return;
    }
    let (cm, cl, ch) = spread(ceilings);
    let over: Vec<f64> = walls.iter().zip(ceilings).map(|(w, c)| w / c).collect();
    let (om, ol, oh) = spread(&over);
    println!(
        "ceiling ({} copies of the {a}-thread run side by side over {} × its time alone): median \
         {cm:.3} ({cl:.3}–{ch:.3}); wall {b}/{a} over the pair's ceiling: median {om:.3} \
         ({ol:.3}–{oh:.3})",
        b / a,
        b / a
    );
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
