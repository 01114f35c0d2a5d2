//! Particles ↔ grid transfer (deepcontact-grid) on the recorded thesis pile: the contact
//! points and their impulses of step 240 (161 points), on the thesis grid (61 × 61 at 0.25 m,
//! poly6, h = 0.5), with the exact lookup and with kiddo k-d trees; and the world encoder (6
//! input channels from bodies, contacts and walls).

use criterion::{BenchmarkId, Criterion, Throughput};
use deepcontact_core::Vector;
use deepcontact_grid::{GridEncoder, GridLayout, GridSpec, Kernel, NeighbourSearch, Transfer};

use super::thesis_snapshots;

/// The `grid` group.
pub fn bench(c: &mut Criterion) {
    if !super::wanted("grid") {
        return;
    }
    let snap = thesis_snapshots().last().expect("recorded steps");
    let mut positions: Vec<Vector> = Vec::new();
    let mut values: Vec<f64> = Vec::new();
    for island in &snap.islands {
        for (p, imp) in island
            .problem
            .points
            .iter()
            .zip(island.carried.iter().flatten())
        {
            positions.push(p.point);
            values.extend([imp.normal, imp.tangent]);
        }
    }
    let mut group = c.benchmark_group("grid");
    group.throughput(Throughput::Elements(positions.len() as u64));
    for search in [NeighbourSearch::Exact, NeighbourSearch::KdTree] {
        let label = format!("{search:?}").to_lowercase();
        let mut t = Transfer::new(GridSpec::thesis(), Kernel::Poly6, 0.5)
            .expect("thesis grid")
            .with_search(search);
        let mut grid = vec![0.0; 2 * t.spec().len()];
        let mut back = vec![0.0; values.len()];
        group.bench_function(BenchmarkId::new("p2g", &label), |b| {
            b.iter(|| {
                grid.fill(0.0);
                t.particles_to_grid(&positions, &values, 2, &mut grid)
                    .expect("p2g")
            })
        });
        group.bench_function(BenchmarkId::new("g2p", &label), |b| {
            b.iter(|| {
                t.grid_to_particles(&grid, 2, &positions, &mut back)
                    .expect("g2p")
            })
        });
        group.bench_function(BenchmarkId::new("p2g+g2p", &label), |b| {
            b.iter(|| {
                grid.fill(0.0);
                t.particles_to_grid(&positions, &values, 2, &mut grid)
                    .expect("p2g");
                t.grid_to_particles(&grid, 2, &positions, &mut back)
                    .expect("g2p")
            })
        });
    }
    let mut encoder = GridEncoder::new(GridLayout::thesis()).expect("thesis layout");
    let mut input = vec![0.0; encoder.layout().input_len()];
    group.throughput(Throughput::Elements(snap.dynamic_bodies() as u64));
    group.bench_function("encode_world", |b| {
        b.iter(|| {
            encoder
                .encode_world(&snap.world, &mut input)
                .expect("encode")
        })
    });
    group.finish();
}
