//! The chunked sweep of a large island, on one thread or several.
//!
//! Each colour's batches are cut into chunks of [`CHUNK`] batches, and its one-at-a-time
//! manifolds make one item more: the work items of a phase ([`crate::threads::sync::run_phased`]).
//! Threads claim items (each its own contiguous run of a colour first); manifolds of one
//! colour share no movable body, so the items of a colour never write the same velocity, and
//! an item starts only once the earlier colours are done (still Gauss-Seidel: every row sees the latest velocities). Each item's
//! impulse-change measures go to a slot of their own, folded in slot order once the sweep is
//! done, so the result is the same bits for any thread count and any assignment of items to
//! threads (one thread runs the same items in the same order).

use deepcontact_core::{ResidualNorm, SolveReport, SolverSettings};

use std::sync::Mutex;

use crate::threads::sync::{Cell3, lock, phase_starts, run_phased};
use crate::velocity::{
    Batch, LaneSweep, Manifold, Row, Segment, Sweep, Vel, Velocities, Verdict, judge, sweep_batch,
    sweep_manifold,
};

/// Batches per chunk: the unit a thread takes, and the unit of the measures' summation order.
pub(crate) const CHUNK: usize = 16;

/// The solver's buffers that the chunked sweep works on.
pub(crate) struct Sweepable<'a> {
    /// Single-point manifolds in batches, colour by colour.
    pub(crate) batches: &'a mut [Batch],
    /// One segment per colour: its batches and its one-at-a-time manifolds.
    pub(crate) segments: &'a [Segment],
    /// The one-at-a-time manifolds, indexed by the segments.
    pub(crate) serial: &'a [Manifold],
    /// The rows of the one-at-a-time manifolds (and of all others).
    pub(crate) rows: &'a mut [Row],
    /// Body velocities (in, out).
    pub(crate) vel: &'a mut [Vel],
}

/// The shared velocities as a sweep sees them. The last cell is the batches' sink
/// ([`Batch`]'s `wa`, `wb`): nothing reads it, so stores to it are dropped (threads would
/// otherwise all write that one cache line).
struct Shared<'a>(&'a [Cell3]);

impl Velocities for Shared<'_> {
    #[inline(always)]
    fn get(&self, i: u32) -> Vel {
        let [vx, vy, w] = self.0[i as usize].load();
        Vel { vx, vy, w }
    }

    #[inline(always)]
    fn set(&mut self, i: u32, v: Vel) {
        if i as usize + 1 < self.0.len() {
            self.0[i as usize].store([v.vx, v.vy, v.w]);
        }
    }
}

/// A slot's measures: `max`, `sum_sq`, `contact_sq`.
fn publish(slot: &Cell3, s: &Sweep) {
    slot.store([s.max, s.sum_sq, s.contact_sq]);
}

/// The measures of a slot.
fn read(slot: &Cell3) -> Sweep {
    let [max, sum_sq, contact_sq] = slot.load();
    Sweep {
        max,
        sum_sq,
        contact_sq,
    }
}

/// One work item: a chunk of a colour's batches, or a colour's one-at-a-time manifolds.
enum Item<'a> {
    Batches(Mutex<&'a mut [Batch]>),
    Serial(std::ops::Range<usize>),
}

/// Runs stage 3's loop in the chunked plan, `chunk` batches a chunk ([`CHUNK`] in the
/// solver), on up to `threads` threads (≥ 1; no more than the cores, nor than the widest
/// colour has chunks). Returns the iterations run and the last verdict, as the one-thread
/// loop does, and the threads it ran on; `report` gets the residual of every iteration. The sweeps run compiled for
/// `arch`: on one thread the whole loop, on several each work item (a chunk of batches or a
/// colour's one-at-a-time manifolds).
pub(crate) fn solve_chunked(
    s: &mut Sweepable<'_>,
    chunk: usize,
    threads: usize,
    arch: pulp::Arch,
    settings: &SolverSettings,
    report: &mut SolveReport,
) -> (u32, Verdict, usize) {
    // No more threads than the widest colour has chunks: the others would only wait.
    let widest = s
        .segments
        .iter()
        .map(|seg| seg.batches.len().div_ceil(chunk));
    let threads = threads.min(widest.max().unwrap_or(1)).max(1);
    let (mut items, counts) = work_items(s.batches, s.segments, chunk);
    if threads == 1 {
        let (it, verdict) = arch.dispatch(OneThread {
            items: &mut items,
            serial: s.serial,
            rows: s.rows,
            vel: s.vel,
            settings,
            report,
        });
        return (it, verdict, 1);
    }
    let starts = phase_starts(counts);
    let slots: [Vec<Cell3>; 2] =
        [0, 1].map(|_| (0..items.len()).map(|_| Cell3::default()).collect());
    let vel: Vec<Cell3> = s
        .vel
        .iter()
        .map(|v| Cell3::new([v.vx, v.vy, v.w]))
        .collect();
    let rows = Mutex::new(&mut *s.rows);
    let serial = s.serial;
    let sweeps = Mutex::new(Vec::new());
    let contact = settings.norm == ResidualNorm::Contact;
    let process = |item: usize, parity: usize| {
        let sweep = arch.dispatch(SharedItem {
            item: &items[item],
            serial,
            rows: &rows,
            vel: &vel,
            contact,
        });
        publish(&slots[parity][item], &sweep);
    };
    let judge_iteration = |it: u32, parity: usize| {
        let mut sweep = Sweep::default();
        for slot in &slots[parity] {
            sweep.add(&read(slot));
        }
        lock(&sweeps).push(sweep);
        judge(settings, it + 1, &sweep, None) != Verdict::Continue
    };
    run_phased(
        threads,
        settings.max_iterations,
        &starts,
        &process,
        &judge_iteration,
    );
    for (v, shared) in s.vel.iter_mut().zip(&vel) {
        let [vx, vy, w] = shared.load();
        *v = Vel { vx, vy, w };
    }
    // The iterations' residuals into the report, and the verdict, as the judge saw them.
    let mut last = (0, Verdict::Continue);
    for (k, sweep) in sweeps
        .into_inner()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
        .iter()
        .enumerate()
    {
        last = (
            k as u32 + 1,
            judge(settings, k as u32 + 1, sweep, Some(report)),
        );
    }
    (last.0, last.1, threads)
}

/// The work items colour by colour — each colour's batches in chunks of `chunk`, then its
/// one-at-a-time manifolds if any — and the number of items of each colour (a phase).
fn work_items<'b>(
    batches: &'b mut [Batch],
    segments: &[Segment],
    chunk: usize,
) -> (Vec<Item<'b>>, Vec<usize>) {
    let mut items = Vec::new();
    let mut counts = Vec::with_capacity(segments.len());
    let mut rest = batches;
    for seg in segments {
        let (colour, tail) = std::mem::take(&mut rest).split_at_mut(seg.batches.len());
        rest = tail;
        let before = items.len();
        items.extend(
            colour
                .chunks_mut(chunk)
                .map(|b| Item::Batches(Mutex::new(b))),
        );
        if !seg.manifolds.is_empty() {
            items.push(Item::Serial(seg.manifolds.clone()));
        }
        counts.push(items.len() - before);
    }
    (items, counts)
}

/// [`solve_one_thread`] as an operation of [`pulp::Arch::dispatch`]: the whole loop compiled
/// for the instruction set chosen at run time (same bits on every one).
struct OneThread<'a, 'i> {
    items: &'a mut [Item<'i>],
    serial: &'a [Manifold],
    rows: &'a mut [Row],
    vel: &'a mut [Vel],
    settings: &'a SolverSettings,
    report: &'a mut SolveReport,
}

impl pulp::WithSimd for OneThread<'_, '_> {
    type Output = (u32, Verdict);

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _simd: S) -> Self::Output {
        let Self {
            items,
            serial,
            rows,
            vel,
            settings,
            report,
        } = self;
        if settings.norm == ResidualNorm::Contact {
            solve_one_thread::<true>(items, serial, rows, vel, settings, report)
        } else {
            solve_one_thread::<false>(items, serial, rows, vel, settings, report)
        }
    }
}

/// [`sweep_item`] as an operation of [`pulp::Arch::dispatch`], one work item at a time.
struct SharedItem<'a, 'i> {
    item: &'a Item<'i>,
    serial: &'a [Manifold],
    rows: &'a Mutex<&'i mut [Row]>,
    vel: &'a [Cell3],
    contact: bool,
}

impl pulp::WithSimd for SharedItem<'_, '_> {
    type Output = Sweep;

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _simd: S) -> Self::Output {
        if self.contact {
            sweep_item::<true>(self.item, self.serial, self.rows, self.vel)
        } else {
            sweep_item::<false>(self.item, self.serial, self.rows, self.vel)
        }
    }
}

/// The chunked plan on the calling thread: the same items in the same order, each item's
/// measures folded in item order (so the same bits as on any number of threads), without the
/// shared cells and the queue.
#[inline(always)]
fn solve_one_thread<const CONTACT: bool>(
    items: &mut [Item<'_>],
    serial: &[Manifold],
    rows: &mut [Row],
    vel: &mut [Vel],
    settings: &SolverSettings,
    report: &mut SolveReport,
) -> (u32, Verdict) {
    let mut it = 0;
    while it < settings.max_iterations {
        let mut sweep = Sweep::default();
        for item in items.iter_mut() {
            sweep.add(&match item {
                Item::Batches(batches) => sweep_batches::<CONTACT>(
                    batches
                        .get_mut()
                        .unwrap_or_else(std::sync::PoisonError::into_inner),
                    vel,
                ),
                Item::Serial(range) => {
                    sweep_serial::<CONTACT, _>(&serial[range.clone()], rows, vel)
                }
            });
        }
        it += 1;
        match judge(settings, it, &sweep, Some(report)) {
            Verdict::Continue => {}
            end => return (it, end),
        }
    }
    (it, Verdict::Continue)
}

/// Sweeps a chunk of batches and returns its measures (lanes folded in lane order).
#[inline(always)]
fn sweep_batches<const CONTACT: bool>(
    batches: &mut [Batch],
    vel: &mut (impl Velocities + ?Sized),
) -> Sweep {
    let mut lanes = LaneSweep::default();
    for batch in batches.iter_mut() {
        sweep_batch::<CONTACT, _>(batch, vel, &mut lanes);
    }
    let mut sweep = Sweep::default();
    sweep.add_lanes(&lanes);
    sweep
}

/// Sweeps one-at-a-time manifolds in order and returns their measures.
#[inline(always)]
fn sweep_serial<const CONTACT: bool, V: Velocities + ?Sized>(
    manifolds: &[Manifold],
    rows: &mut [Row],
    vel: &mut V,
) -> Sweep {
    let mut sweep = Sweep::default();
    for m in manifolds {
        sweep_manifold::<CONTACT, _>(m, rows, vel, &mut sweep);
    }
    sweep
}

/// Sweeps one shared item on the shared velocities and returns its measures.
#[inline(always)]
fn sweep_item<const CONTACT: bool>(
    item: &Item<'_>,
    serial: &[Manifold],
    rows: &Mutex<&mut [Row]>,
    vel: &[Cell3],
) -> Sweep {
    let mut vel = Shared(vel);
    match item {
        Item::Batches(batches) => sweep_batches::<CONTACT>(&mut lock(batches), &mut vel),
        Item::Serial(range) => {
            sweep_serial::<CONTACT, _>(&serial[range.clone()], &mut lock(rows), &mut vel)
        }
    }
}
