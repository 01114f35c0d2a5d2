//! How long one thread takes to see what another stored, on this machine: two threads pass a
//! counter back and forth (each stores the next value with release ordering, then spins until
//! the other has stored its own), `--runs` runs (default 8) of `--trips` round trips each
//! (default 1 000 000), `--pause-ms` apart (default 500; a host may move the virtual cores
//! between runs). Prints each run's nanoseconds per round trip and their median (smallest–
//! largest).
//!
//! A round trip is two cache lines crossing between the cores and back: the least a sweep
//! shared by two threads pays each time they meet. A sweep that meets k times an iteration
//! needs iterations much longer than k round trips to gain from its second thread
//! (docs/PERFORMANCE.md, "Routes measured and left out").
//!
//! ```sh
//! cargo run --release -p deepcontact-benches --example handover -- --runs 8
//! ```

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use deepcontact_benches::median;

/// Command-line options.
struct Options {
    runs: usize,
    trips: u64,
    pause_ms: u64,
}

fn parse() -> Result<Option<Options>, String> {
    let mut o = Options {
        runs: 8,
        trips: 1_000_000,
        pause_ms: 500,
    };
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        if a == "--help" || a == "-h" {
            println!("usage: handover [--runs 8] [--trips 1000000] [--pause-ms 500]");
            return Ok(None);
        }
        let value = args.next().ok_or(format!("{a} needs a value"))?;
        let number = |v: &str| v.parse::<u64>().map_err(|e| format!("{a} {v}: {e}"));
        match a.as_str() {
            "--runs" => o.runs = number(&value)? as usize,
            "--trips" => o.trips = number(&value)?,
            "--pause-ms" => o.pause_ms = number(&value)?,
            _ => return Err(format!("unknown option {a} (see --help)")),
        }
    }
    if o.runs == 0 || o.trips < 2 {
        return Err("--runs must be at least 1, --trips at least 2".into());
    }
    Ok(Some(o))
}

/// A counter on cache lines of its own, so that the two counters do not share one.
#[repr(align(128))]
struct Counter(AtomicU64);

/// Spins until `counter` reaches `value`.
fn wait_for(counter: &Counter, value: u64) {
    while counter.0.load(Ordering::Acquire) < value {
        std::hint::spin_loop();
    }
}

/// One run: `trips` (≥ 2) round trips between the calling thread and a second one, the first
/// untimed; seconds a timed trip.
fn run(trips: u64) -> f64 {
    let (ping, pong) = (Counter(AtomicU64::new(0)), Counter(AtomicU64::new(0)));
    let mut seconds = 0.0;
    std::thread::scope(|scope| {
        scope.spawn(|| {
            for i in 1..=trips {
                wait_for(&ping, i);
                pong.0.store(i, Ordering::Release);
            }
        });
        // One trip first, so that the second thread is running when the clock starts.
        ping.0.store(1, Ordering::Release);
        wait_for(&pong, 1);
        let t0 = Instant::now();
        for i in 2..=trips {
            ping.0.store(i, Ordering::Release);
            wait_for(&pong, i);
        }
        seconds = t0.elapsed().as_secs_f64() / (trips - 1) as f64;
    });
    seconds
}

fn main() {
    let o = match parse() {
        Ok(Some(o)) => o,
        Ok(None) => return,
        Err(e) => {
            eprintln!("handover: {e}");
            std::process::exit(2);
        }
    };
    // On one core each trip would wait for the scheduler to switch threads: no figure, hours.
    let cores = std::thread::available_parallelism().map_or(1, std::num::NonZero::get);
    if cores < 2 {
        eprintln!("handover: needs two cores, this process may use {cores}");
        std::process::exit(2);
    }
    let mut ns = Vec::with_capacity(o.runs);
    for k in 0..o.runs {
        if k > 0 {
            std::thread::sleep(Duration::from_millis(o.pause_ms));
        }
        let trip = run(o.trips) * 1e9;
        println!("run {}: {trip:.1} ns a round trip", k + 1);
        ns.push(trip);
    }
    let (lo, hi) = ns.iter().fold((f64::INFINITY, 0.0_f64), |(lo, hi), &x| {
        (lo.min(x), hi.max(x))
    });
    println!(
        "median {:.1} ns a round trip ({lo:.1}–{hi:.1}), {} runs of {} trips",
        median(&ns),
        o.runs,
        o.trips
    );
}
