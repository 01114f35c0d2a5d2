//! The benchmark groups and their shared fixtures.

pub mod grid;
pub mod onnx;
pub mod peer;
pub mod providers;
pub mod rapier_pile;
pub mod slope;
pub mod solvers;

use std::sync::OnceLock;

use deepcontact_benches::{RECORD_STEPS, SEED, SIZES, Snapshot, record_step, settle_world};
use deepcontact_core::WorldSettings;

/// Top-level group names, as the first segment of every benchmark id.
const GROUPS: [&str; 5] = ["providers", "solvers", "grid", "onnx", "peer"];

/// Whether `group` may be selected by the command line's criterion filter: a command-line
/// word naming a group (e.g. `cargo bench -- peer`, `-- solvers/iteration`) selects only the
/// groups it names, so the others skip their setup (settling a 10 000-body pile takes ~20 s);
/// without such a word every group runs.
pub fn wanted(group: &str) -> bool {
    let named: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with('-') && GROUPS.iter().any(|g| a.contains(g)))
        .collect();
    named.is_empty() || named.iter().any(|a| a.contains(group))
}

/// The 100-body thesis pile (seed 12345, thesis settings) recorded at [`RECORD_STEPS`].
pub fn thesis_snapshots() -> &'static [Snapshot] {
    static CELL: OnceLock<Vec<Snapshot>> = OnceLock::new();
    CELL.get_or_init(|| {
        RECORD_STEPS
            .iter()
            .map(|&s| {
                record_step(SEED, 100, s, WorldSettings::default()).expect("record the thesis pile")
            })
            .collect()
    })
}

/// Pile sizes to run (`DEEPCONTACT_BENCH_SIZES`, default 100, 1 000, 10 000).
pub fn sizes() -> Vec<usize> {
    match std::env::var("DEEPCONTACT_BENCH_SIZES") {
        Ok(v) if !v.trim().is_empty() => {
            v.split(',').filter_map(|s| s.trim().parse().ok()).collect()
        }
        _ => SIZES.to_vec(),
    }
}

/// Pile sizes of the `peer` group: `DEEPCONTACT_BENCH_SIZES` if set, else 100 and 1 000 (the
/// 10 000-body comparison is in `examples/scaling.rs`: settling both engines takes a minute).
pub fn peer_sizes() -> Vec<usize> {
    match std::env::var("DEEPCONTACT_BENCH_SIZES") {
        Ok(v) if !v.trim().is_empty() => sizes(),
        _ => vec![100, 1_000],
    }
}

/// Steps to settle a pile of `n` bodies before recording it for the solver benchmarks:
/// the thesis's 250 steps for 100 bodies, 250 × (n / 100)^¼ beyond (a taller pile falls longer).
pub fn settle_steps(n: usize) -> u64 {
    (250.0 * (n as f64 / 100.0).max(1.0).powf(0.25)).round() as u64
}

/// A settled pile of `n` bodies (seed 12345, settled with [`settle_world`]`(50)`), its last
/// step recorded; computed once per size and process.
pub fn settled(n: usize) -> &'static Snapshot {
    static CELL: OnceLock<std::sync::Mutex<Vec<(usize, &'static Snapshot)>>> = OnceLock::new();
    let cell = CELL.get_or_init(Default::default);
    let mut list = cell.lock().expect("settled piles");
    if let Some((_, s)) = list.iter().find(|(k, _)| *k == n) {
        return s;
    }
    let t = std::time::Instant::now();
    let snap =
        record_step(SEED, n, settle_steps(n) - 1, settle_world(50)).expect("settle the pile");
    eprintln!(
        "settled {n} bodies: {} steps, {} contacts, {} islands in {:.1} s",
        settle_steps(n),
        snap.contacts(),
        snap.islands.len(),
        t.elapsed().as_secs_f64()
    );
    let snap: &'static Snapshot = Box::leak(Box::new(snap));
    list.push((n, snap));
    snap
}
