//! Once warmed up, the transfers, the encoder and the `grid` provider allocate nothing.
#![allow(unsafe_code)] // a counting global allocator needs `unsafe impl GlobalAlloc`

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

use deepcontact_core::{
    CarriedWarmStart, Impulse, Vector, WarmStart, WarmStartContext, WarmStartError, WorldSettings,
    scene,
};
use deepcontact_grid::{
    G2pMethod, GridEncoder, GridFilterConfig, GridFiltered, GridLayout, GridSpec, Kernel, Transfer,
};
use deepcontact_pgs::{PgsPositionSolver, PgsSolver};

struct Counting;

thread_local! {
    static COUNT: Cell<usize> = const { Cell::new(0) };
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        COUNT.with(|c| c.set(c.get() + 1));
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        COUNT.with(|c| c.set(c.get() + 1));
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// Allocations made by this thread while running `f`.
fn allocations(f: impl FnOnce()) -> usize {
    let before = COUNT.with(Cell::get);
    f();
    COUNT.with(Cell::get) - before
}

/// Replays fixed impulses (an inner provider that allocates nothing itself).
struct Fixed;

impl WarmStart for Fixed {
    fn name(&self) -> &str {
        "fixed"
    }
    fn warm_start(
        &mut self,
        _: &WarmStartContext<'_>,
        out: &mut [Impulse],
    ) -> Result<(), WarmStartError> {
        out.fill(Impulse::new(1.0, 0.1));
        Ok(())
    }
}

#[test]
fn warmed_up_calls_do_not_allocate() {
    let mut world = scene::pile(2, 100)
        .unwrap()
        .build(WorldSettings::default())
        .unwrap();
    let (mut v, mut p) = (PgsSolver::new(), PgsPositionSolver::new());
    for _ in 0..150 {
        world.step(&mut CarriedWarmStart, &mut v, &mut p).unwrap();
    }
    let points: Vec<Vector> = world.raw_contacts().iter().map(|c| c.point).collect();
    let values: Vec<f64> = (0..2 * points.len()).map(|i| i as f64 * 0.01).collect();
    let spec = GridSpec::thesis();
    let mut grid = vec![0.0; 2 * spec.len()];
    let mut out = vec![0.0; values.len()];

    // Transfers, exact search.
    for g2p in [G2pMethod::Sph, G2pMethod::Bilinear] {
        let mut t = Transfer::new(spec, Kernel::Poly6, 0.5)
            .unwrap()
            .with_g2p(g2p);
        let mut run = || {
            t.particles_to_grid(&points, &values, 2, &mut grid).unwrap();
            t.grid_to_particles(&grid, 2, &points, &mut out).unwrap();
            t.round_trip(&points, &values, 2, &mut out).unwrap();
        };
        run();
        assert_eq!(allocations(run), 0, "{g2p:?}");
    }

    // Encoder: the 6 input channels of the world, labels, decoding.
    let layout = GridLayout::thesis();
    let mut enc = GridEncoder::new(layout.clone()).unwrap();
    let mut input = vec![0.0; layout.input_len()];
    let mut labels = vec![0.0; layout.output_len()];
    let mut impulses = vec![Impulse::ZERO; points.len()];
    let mut run = || {
        enc.encode_world(&world, &mut input).unwrap();
        enc.encode_world_labels(&world, &mut labels).unwrap();
        enc.decode(&labels, &points, &mut impulses).unwrap();
    };
    run();
    assert_eq!(allocations(run), 0, "encoder");

    // The grid provider on every island of the last step.
    let problems = world.last_problems();
    let carried: Vec<Vec<Impulse>> = problems
        .iter()
        .map(|pr| vec![Impulse::ZERO; pr.points.len()])
        .collect();
    let none: Vec<Vec<Option<Impulse>>> = problems
        .iter()
        .map(|pr| vec![None; pr.points.len()])
        .collect();
    let mut outs = carried.clone();
    let mut provider = GridFiltered::new(Box::new(Fixed), GridFilterConfig::default()).unwrap();
    let mut run = || {
        for (k, pr) in problems.iter().enumerate() {
            let ctx =
                WarmStartContext::new(pr, &none[k], 0, 0.01).with_world(&world, k, problems.len());
            provider.warm_start(&ctx, &mut outs[k]).unwrap();
        }
    };
    run();
    assert_eq!(allocations(run), 0, "grid provider");
}
