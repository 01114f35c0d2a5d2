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

use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering as Mem};

use deepcontact_core::{ResidualNorm, SolveReport, SolverSettings};

use crate::velocity::{
    Batch, LaneSweep, Manifold, Row, Segment, Sweep, Vel, Velocities, Verdict, judge, sweep_batch,
    sweep_manifold,
};

/// Batches per chunk: the unit a thread takes, and the unit of the measures' summation order.
pub(crate) const CHUNK: usize = 16;

/// Spins before a waiting thread starts yielding its core (a core shared with other work
/// must not be burnt).
const SPINS: u32 = 1 << 12;

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

/// A body velocity that threads share: the `f64` bits in relaxed atomics (plain loads and
/// stores on x86-64 and AArch64); the barrier between colours orders them.
#[derive(Debug, Default)]
struct SharedVel {
    vx: AtomicU64,
    vy: AtomicU64,
    w: AtomicU64,
}

impl SharedVel {
    fn new(v: &Vel) -> Self {
        Self {
            vx: AtomicU64::new(v.vx.to_bits()),
            vy: AtomicU64::new(v.vy.to_bits()),
            w: AtomicU64::new(v.w.to_bits()),
        }
    }

    #[inline(always)]
    fn load(&self) -> Vel {
        Vel {
            vx: f64::from_bits(self.vx.load(Mem::Relaxed)),
            vy: f64::from_bits(self.vy.load(Mem::Relaxed)),
            w: f64::from_bits(self.w.load(Mem::Relaxed)),
        }
    }

    #[inline(always)]
    fn store(&self, v: Vel) {
        self.vx.store(v.vx.to_bits(), Mem::Relaxed);
        self.vy.store(v.vy.to_bits(), Mem::Relaxed);
        self.w.store(v.w.to_bits(), Mem::Relaxed);
    }
}

/// The shared velocities as a sweep sees them.
struct Shared<'a>(&'a [SharedVel]);

impl Velocities for Shared<'_> {
    #[inline(always)]
    fn get(&self, i: u32) -> Vel {
        self.0[i as usize].load()
    }

    #[inline(always)]
    fn set(&mut self, i: u32, v: Vel) {
        self.0[i as usize].store(v);
    }
}

/// One slot of measures, shared: `max`, `sum_sq`, `contact_sq` as `f64` bits.
#[derive(Debug, Default)]
struct Slot([AtomicU64; 3]);

impl Slot {
    fn publish(&self, s: &Sweep) {
        self.0[0].store(s.max.to_bits(), Mem::Relaxed);
        self.0[1].store(s.sum_sq.to_bits(), Mem::Relaxed);
        self.0[2].store(s.contact_sq.to_bits(), Mem::Relaxed);
    }

    fn read(&self) -> Sweep {
        Sweep {
            max: f64::from_bits(self.0[0].load(Mem::Relaxed)),
            sum_sq: f64::from_bits(self.0[1].load(Mem::Relaxed)),
            contact_sq: f64::from_bits(self.0[2].load(Mem::Relaxed)),
        }
    }
}

/// A reusable barrier for a fixed number of threads: spins, then yields.
#[derive(Debug)]
struct SpinBarrier {
    threads: usize,
    arrived: AtomicUsize,
    epoch: AtomicUsize,
}

impl SpinBarrier {
    fn new(threads: usize) -> Self {
        Self {
            threads,
            arrived: AtomicUsize::new(0),
            epoch: AtomicUsize::new(0),
        }
    }

    /// Waits for every thread; `epoch` is the caller's count of barriers passed. The last
    /// thread to arrive resets the count before it publishes the new epoch (release), so a
    /// thread that sees the epoch (acquire) also sees the reset and every write made before
    /// the barrier.
    fn wait(&self, epoch: &mut usize) {
        *epoch += 1;
        if self.arrived.fetch_add(1, Mem::AcqRel) + 1 == self.threads {
            self.arrived.store(0, Mem::Relaxed);
            self.epoch.store(*epoch, Mem::Release);
            return;
        }
        let mut spins = 0;
        while self.epoch.load(Mem::Acquire) != *epoch {
            if spins < SPINS {
                spins += 1;
                std::hint::spin_loop();
            } else {
                std::thread::yield_now();
            }
        }
    }
}

/// What every thread shares during the loop.
struct Common<'a> {
    segments: &'a [Segment],
    /// Per segment: the slot of its one-at-a-time manifolds.
    serial_slot: Vec<usize>,
    /// Two sets of slots, used by odd and even iterations: a thread may start the next
    /// iteration while another still folds this one's slots.
    slots: [Vec<Slot>; 2],
    vel: Vec<SharedVel>,
    barrier: SpinBarrier,
    settings: &'a SolverSettings,
}

/// One thread's part: per segment its chunks `(slot, batches)`, and for thread 0 the
/// one-at-a-time manifolds with their rows.
struct Part<'a> {
    chunks: Vec<Vec<(usize, &'a mut [Batch])>>,
    serial: Option<(&'a mut [Row], &'a [Manifold])>,
}

/// Runs stage 3's loop in the chunked plan on `threads` threads (≥ 1). Returns the
/// iterations run and the last verdict, as the one-thread loop does; `report` gets the
/// residual of every iteration.
pub(crate) fn solve_chunked(
    s: &mut Sweepable<'_>,
    threads: usize,
    settings: &SolverSettings,
    report: &mut SolveReport,
) -> (u32, Verdict) {
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
        let n_chunks = colour.len().div_ceil(CHUNK);
        for (j, chunk) in colour.chunks_mut(CHUNK).enumerate() {
            // Contiguous runs: chunk j of n goes to thread ⌊j T / n⌋.
            parts[j * threads / n_chunks].chunks[c].push((slot, chunk));
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
            (0..slot).map(|_| Slot::default()).collect(),
            (0..slot).map(|_| Slot::default()).collect(),
        ],
        vel: s.vel.iter().map(SharedVel::new).collect(),
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
        *v = shared.load();
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
                slots[*slot].publish(&sweep);
            }
            if let Some((rows, serial)) = &mut part.serial {
                let mut sweep = Sweep::default();
                for m in &serial[seg.manifolds.clone()] {
                    sweep_manifold::<CONTACT, _>(m, rows, &mut vel, &mut sweep);
                }
                slots[common.serial_slot[c]].publish(&sweep);
            }
            common.barrier.wait(&mut epoch);
        }
        let mut sweep = Sweep::default();
        for slot in slots {
            sweep.add(&slot.read());
        }
        it += 1;
        match judge(common.settings, it, &sweep, report.as_deref_mut()) {
            Verdict::Continue => {}
            end => return (it, end),
        }
    }
    (it, Verdict::Continue)
}
