//! The chunked sweep of a large island, on one thread or several.
//!
//! Each colour's batches are cut into chunks of [`CHUNK`] batches; thread `t` of `T` takes a
//! contiguous run of every colour's chunks, and thread 0 also the colour's one-at-a-time
//! manifolds. Manifolds of one colour share no movable body, so the threads never write the
//! same velocity; a barrier after each colour makes its writes visible to the next colour
//! (still Gauss-Seidel: every row sees the latest velocities). Each chunk's impulse-change
//! measures go to a slot of their own and every thread folds the slots in slot order, so all
//! threads reach the same stop decision and the result is the same bits for any `T`
//! (`T = 1` runs the same plan on the calling thread).

use deepcontact_core::{ResidualNorm, SolveReport, SolverSettings};

use crate::sync::{Cell3, SpinBarrier, owner};
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

/// The shared velocities as a sweep sees them.
struct Shared<'a>(&'a [Cell3]);

impl Velocities for Shared<'_> {
    #[inline(always)]
    fn get(&self, i: u32) -> Vel {
        let [vx, vy, w] = self.0[i as usize].load();
        Vel { vx, vy, w }
    }

    #[inline(always)]
    fn set(&mut self, i: u32, v: Vel) {
        self.0[i as usize].store([v.vx, v.vy, v.w]);
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

/// What every thread shares during the loop.
struct Common<'a> {
    segments: &'a [Segment],
    /// Per segment: the slot of its one-at-a-time manifolds.
    serial_slot: Vec<usize>,
    /// Two sets of slots, used by odd and even iterations: a thread may start the next
    /// iteration while another still folds this one's slots.
    slots: [Vec<Cell3>; 2],
    vel: Vec<Cell3>,
    barrier: SpinBarrier,
    settings: &'a SolverSettings,
}

/// One thread's part: per segment its chunks `(slot, batches)`, and for thread 0 the
/// one-at-a-time manifolds with their rows.
struct Part<'a> {
    chunks: Vec<Vec<(usize, &'a mut [Batch])>>,
    serial: Option<(&'a mut [Row], &'a [Manifold])>,
}

/// Runs stage 3's loop in the chunked plan, `chunk` batches a chunk ([`CHUNK`] in the
/// solver), on `threads` threads (≥ 1; fewer when no colour has that many chunks). Returns the
/// iterations run and the last verdict, as the one-thread loop does; `report` gets the
/// residual of every iteration.
pub(crate) fn solve_chunked(
    s: &mut Sweepable<'_>,
    chunk: usize,
    threads: usize,
    settings: &SolverSettings,
    report: &mut SolveReport,
) -> (u32, Verdict) {
    // No more threads than the widest colour has chunks: the others would only wait.
    let widest = s
        .segments
        .iter()
        .map(|seg| seg.batches.len().div_ceil(chunk));
    let threads = threads.min(widest.max().unwrap_or(1)).max(1);
    let mut parts: Vec<Part<'_>> = (0..threads)
        .map(|_| Part {
            chunks: (0..s.segments.len()).map(|_| Vec::new()).collect(),
            serial: None,
        })
        .collect();
    // Slots in (colour, chunk) order, each colour's one-at-a-time slot after its chunks.
    let mut serial_slot = Vec::with_capacity(s.segments.len());
    let mut slot = 0;
    let mut rest: &mut [Batch] = s.batches;
    for (c, seg) in s.segments.iter().enumerate() {
        let (colour, tail) = std::mem::take(&mut rest).split_at_mut(seg.batches.len());
        rest = tail;
        let n_chunks = colour.len().div_ceil(chunk);
        for (j, batches) in colour.chunks_mut(chunk).enumerate() {
            parts[owner(j, n_chunks, threads)].chunks[c].push((slot, batches));
            slot += 1;
        }
        serial_slot.push(slot);
        slot += 1;
    }
    parts[0].serial = Some((&mut *s.rows, s.serial));
    let common = Common {
        segments: s.segments,
        serial_slot,
        slots: [
            (0..slot).map(|_| Cell3::default()).collect(),
            (0..slot).map(|_| Cell3::default()).collect(),
        ],
        vel: s
            .vel
            .iter()
            .map(|v| Cell3::new([v.vx, v.vy, v.w]))
            .collect(),
        barrier: SpinBarrier::new(threads),
        settings,
    };
    let contact = settings.norm == ResidualNorm::Contact;
    let run = |part: Part<'_>, report: Option<&mut SolveReport>| {
        if contact {
            worker::<true>(&common, part, report)
        } else {
            worker::<false>(&common, part, report)
        }
    };
    let mut parts = parts.into_iter();
    let first = parts.next().expect("at least one thread");
    let outcome = std::thread::scope(|scope| {
        for part in parts {
            scope.spawn(|| run(part, None));
        }
        run(first, Some(report))
    });
    for (v, shared) in s.vel.iter_mut().zip(&common.vel) {
        let [vx, vy, w] = shared.load();
        *v = Vel { vx, vy, w };
    }
    outcome
}

/// One thread's loop: per iteration, per colour its chunks (and thread 0 the colour's
/// one-at-a-time manifolds), a barrier, then the fold of all slots and the verdict.
fn worker<const CONTACT: bool>(
    common: &Common<'_>,
    mut part: Part<'_>,
    mut report: Option<&mut SolveReport>,
) -> (u32, Verdict) {
    let mut vel = Shared(&common.vel);
    let mut epoch = 0;
    let mut it = 0;
    while it < common.settings.max_iterations {
        let slots = &common.slots[it as usize % 2];
        for (c, seg) in common.segments.iter().enumerate() {
            for (slot, chunk) in &mut part.chunks[c] {
                let mut lanes = LaneSweep::default();
                for batch in chunk.iter_mut() {
                    sweep_batch::<CONTACT, _>(batch, &mut vel, &mut lanes);
                }
                let mut sweep = Sweep::default();
                sweep.add_lanes(&lanes);
                publish(&slots[*slot], &sweep);
            }
            if let Some((rows, serial)) = &mut part.serial {
                let mut sweep = Sweep::default();
                for m in &serial[seg.manifolds.clone()] {
                    sweep_manifold::<CONTACT, _>(m, rows, &mut vel, &mut sweep);
                }
                publish(&slots[common.serial_slot[c]], &sweep);
            }
            common.barrier.wait(&mut epoch);
        }
        let mut sweep = Sweep::default();
        for slot in slots {
            sweep.add(&read(slot));
        }
        it += 1;
        match judge(common.settings, it, &sweep, report.as_deref_mut()) {
            Verdict::Continue => {}
            end => return (it, end),
        }
    }
    (it, Verdict::Continue)
}
