//! Quick timing of the transfers on the thesis pile (100 circles settled for 200 steps,
//! thesis grid 61 × 61 at 0.25 m, poly6, h = 0.5). Run in release:
//!
//! ```text
//! cargo run --release -p deepcontact-grid --example transfer_timing
//! ```
//!
//! Each figure is the best over 31 batches of the mean on-CPU time of one call (the least
//! disturbed by other work on a shared machine), with the wall-clock median beside it.

use std::hint::black_box;
use std::time::Instant;

use deepcontact_core::{
    CarriedWarmStart, Impulse, Vector, WarmStart, WarmStartContext, WorldSettings, scene,
};
use deepcontact_grid::{
    G2pMethod, GridEncoder, GridFilterConfig, GridFiltered, GridLayout, GridSpec, Kernel,
    NeighbourSearch, Transfer,
};
use deepcontact_pgs::{PgsPositionSolver, PgsSolver};

/// Nanoseconds this thread has spent on a CPU (Linux `schedstat`), so that time spent
/// waiting for a core while other jobs run is not counted; `None` elsewhere.
fn cpu_ns() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/thread-self/schedstat").ok()?;
    text.split_whitespace().next()?.parse().ok()
}

/// Best over 31 batches of the mean on-CPU time of one call (wall time where the
/// on-CPU clock is missing), and the median of the wall-clock batches.
fn time(label: &str, reps: usize, mut f: impl FnMut()) -> f64 {
    for _ in 0..reps {
        f();
    }
    let mut cpu = Vec::new();
    let mut wall = Vec::new();
    for _ in 0..31 {
        let (c0, t) = (cpu_ns(), Instant::now());
        for _ in 0..reps {
            f();
        }
        wall.push(t.elapsed().as_secs_f64() / reps as f64);
        if let (Some(a), Some(b)) = (c0, cpu_ns()) {
            cpu.push((b - a) as f64 * 1e-9 / reps as f64);
        }
    }
    wall.sort_by(|a, b| a.total_cmp(b));
    cpu.sort_by(|a, b| a.total_cmp(b));
    let best = cpu.first().copied().unwrap_or(wall[0]) * 1e6;
    println!(
        "{label:<64} {best:>8.2} µs (wall median {:.2})",
        wall[15] * 1e6
    );
    best
}

/// Replays fixed impulses (stands in for `copy` so only the grid filter is timed).
struct Fixed(Vec<Impulse>);

impl WarmStart for Fixed {
    fn name(&self) -> &str {
        "fixed"
    }
    fn warm_start(
        &mut self,
        _: &WarmStartContext<'_>,
        out: &mut [Impulse],
    ) -> Result<(), deepcontact_core::WarmStartError> {
        out.copy_from_slice(&self.0[..out.len()]);
        Ok(())
    }
}

/// Calls timed per batch (2 000: each call takes microseconds).
const REPS: usize = 2000;

fn main() {
    let world = settled_pile();
    let (contacts, values) = contact_values(&world);
    println!(
        "pile seed 0 after 200 steps: {} bodies, {} contacts, {} islands",
        world.bodies().len() - 4,
        contacts.len(),
        world.last_problems().len()
    );
    let grid = time_transfers(&contacts, &values);
    time_cnn_transfers(&world, &grid, &contacts);
    time_grid_filter(&world);
}

/// The thesis pile of seed 0 stepped 200 times with carried impulses.
fn settled_pile() -> deepcontact_core::World {
    let mut world = scene::pile(0, 100)
        .unwrap()
        .build(WorldSettings::default())
        .unwrap();
    let (mut v, mut p) = (PgsSolver::new(), PgsPositionSolver::new());
    for _ in 0..200 {
        world.step(&mut CarriedWarmStart, &mut v, &mut p).unwrap();
    }
    world
}

/// The world's contact points and their solved impulses, two channels a point (normal,
/// tangent).
fn contact_values(world: &deepcontact_core::World) -> (Vec<Vector>, Vec<f64>) {
    let contacts: Vec<Vector> = world.raw_contacts().iter().map(|c| c.point).collect();
    let solved = world.contacts();
    let values: Vec<f64> = world
        .raw_contacts()
        .iter()
        .flat_map(|c| {
            let i = solved
                .binary_search_by(|(id, _)| id.cmp(&c.id))
                .map(|i| solved[i].1)
                .unwrap_or_default();
            [i.normal, i.tangent]
        })
        .collect();
    (contacts, values)
}

/// The particle ↔ grid transfers of two channels with each neighbour search, the k-d tree's
/// build and the bilinear G2P; returns the grid of the values.
fn time_transfers(contacts: &[Vector], values: &[f64]) -> Vec<f64> {
    let spec = GridSpec::thesis();
    let mut grid = vec![0.0; 2 * spec.len()];
    let mut out = vec![0.0; values.len()];
    let stats = Transfer::new(spec, Kernel::Poly6, 0.5)
        .unwrap()
        .particles_to_grid(contacts, values, 2, &mut grid);
    println!(
        "pairs (contact point, node) within h: {:?}",
        stats.map(|s| s.pairs)
    );
    for search in [NeighbourSearch::Exact, NeighbourSearch::KdTree] {
        let mut t = Transfer::new(spec, Kernel::Poly6, 0.5)
            .unwrap()
            .with_search(search);
        t.build_node_tree().unwrap();
        let name = format!("{search:?}");
        let points = contacts.len();
        time(
            &format!("[{name}] P2G 2 channels, {points} contact points (+ grid zeroing)"),
            REPS,
            || {
                grid.fill(0.0);
                t.particles_to_grid(black_box(contacts), values, 2, &mut grid)
                    .unwrap();
            },
        );
        time(
            &format!("[{name}] SPH G2P 2 channels, {points} contact points"),
            REPS,
            || {
                t.grid_to_particles(black_box(&grid), 2, contacts, &mut out)
                    .unwrap();
            },
        );
        time(
            &format!("[{name}] fused round trip (P2G + G2P), 2 channels"),
            REPS,
            || {
                t.round_trip(black_box(contacts), values, 2, &mut out)
                    .unwrap();
            },
        );
    }
    time("[KdTree] build the tree over the 3721 nodes", 200, || {
        let mut t = Transfer::new(spec, Kernel::Poly6, 0.5)
            .unwrap()
            .with_search(NeighbourSearch::KdTree);
        t.build_node_tree().unwrap();
        black_box(&t);
    });
    let mut b = Transfer::new(spec, Kernel::Poly6, 0.5)
        .unwrap()
        .with_g2p(G2pMethod::Bilinear);
    time("bilinear G2P 2 channels", REPS, || {
        b.grid_to_particles(black_box(&grid), 2, contacts, &mut out)
            .unwrap();
    });
    grid
}

/// What a CNN provider does around its model: 6 input channels of the world, then the 2
/// output channels (`grid`) back onto the contact points.
fn time_cnn_transfers(world: &deepcontact_core::World, grid: &[f64], contacts: &[Vector]) {
    let layout = GridLayout::thesis();
    let mut enc = GridEncoder::new(layout.clone()).unwrap();
    let mut input = vec![0.0; layout.input_len()];
    let mut imp = vec![Impulse::ZERO; contacts.len()];
    let e = time(
        "encode_world: P2G 6 channels (100 bodies + contacts + walls)",
        REPS,
        || {
            enc.encode_world(black_box(world), &mut input).unwrap();
        },
    );
    let d = time(
        "decode: SPH G2P 2 channels to the contact points",
        REPS,
        || {
            enc.decode(black_box(grid), contacts, &mut imp).unwrap();
        },
    );
    println!(
        "{:<64} {:>8.2} µs",
        "CNN provider transfer total (encode + decode)",
        e + d
    );
}

/// The grid provider's filter on every island of the last step (inner = fixed values).
fn time_grid_filter(world: &deepcontact_core::World) {
    let problems = world.last_problems();
    let mut filtered: Vec<GridFiltered> = problems
        .iter()
        .map(|pr| {
            let start = pr.points.iter().map(|_| Impulse::new(1.0, 0.1)).collect();
            GridFiltered::new(Box::new(Fixed(start)), GridFilterConfig::default()).unwrap()
        })
        .collect();
    let none: Vec<Vec<Option<Impulse>>> = problems
        .iter()
        .map(|pr| vec![None; pr.points.len()])
        .collect();
    let mut outs: Vec<Vec<Impulse>> = problems
        .iter()
        .map(|pr| vec![Impulse::ZERO; pr.points.len()])
        .collect();
    time(
        "grid provider filter, all islands of one step (inner excluded)",
        REPS,
        || {
            for (k, pr) in problems.iter().enumerate() {
                let ctx = WarmStartContext::new(pr, &none[k], 0, 0.01).with_world(
                    world,
                    k,
                    problems.len(),
                );
                filtered[k].warm_start(&ctx, &mut outs[k]).unwrap();
            }
        },
    );
}
