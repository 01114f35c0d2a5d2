//! The collide stage of a large world shared out over threads: the broad phase's bounds,
//! binning and cell pairs and the narrow phase's manifolds, in chunks that any thread takes.
//!
//! Starting a thread costs 30–130 µs on the machines measured (more when its core sat idle and
//! halted; docs/PERFORMANCE.md), about what the narrow phase of a 10 000-body pile hands to it. So the helpers are
//! started first, before the bounds, and stay through the stage: each phase is a list of
//! chunks that the stepping thread and the helpers claim from one counter, a helper that
//! arrives late takes fewer, and between phases the stepping thread does the serial part
//! (the pairs' radix sort) while the helpers spin. The stages in order:
//!
//! 1. **Bounds**: chunks of bodies, each body's AABB and parry2d pose, binned into the grid of
//!    the previous call's cell size (the pairs do not depend on the cell size).
//! 2. **Join**: two items, each reading every bounds chunk in body order: the bodies' AABBs,
//!    kinds, first cells and poses copied into one array each; and the entries and large
//!    bodies joined, the entries sorted by cell, the cells cut into chunks of whole cells. The
//!    two write nothing the other reads, so they run side by side.
//! 3. **Cell pairs**: chunks of whole cells, the large bodies against chunks of bodies, and one
//!    chunk for the next call's cell size (twice the median extent).
//! 4. *Serial*: the pairs joined, sorted and deduplicated: the broad phase's pairs.
//! 5. **Manifolds**: chunks of pairs, each chunk's contacts and manifold ranges its own.
//! 6. *Serial*: the chunks' contacts joined in pair order.
//!
//! What a chunk computes does not depend on the thread that takes it, and every join is in
//! chunk order, so the pairs and the contacts are those of [`BroadPhase::find_pairs`] and
//! [`NarrowPhase::collide`], bit for bit, for any thread count.
//!
//! [`BroadPhase::find_pairs`]: crate::broad_phase::BroadPhase::find_pairs

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering as Mem};
use std::sync::{Mutex, RwLock};

use parry2d::math::Pose;
use parry2d::query::ContactManifold;

use crate::body::{Body, BodyKind};
use crate::broad_phase::{
    Aabb, CellBody, CellBox, bin_body, bound, cell_body, cell_cuts, cell_pairs, cell_size,
    large_pairs, sort_entries, sort_pairs,
};
use crate::math::Real;
use crate::narrow_phase::{NarrowPhase, RawContact, collide_pairs};
use crate::threads::{AbortOnPanic, lock, on_threads, read, wait_unless_aborted, write};

/// Bodies a bounds chunk takes.
const BODY_CHUNK: usize = 512;
/// Entries a cell-pairs chunk takes at least (then up to the end of its last cell).
const ENTRY_CHUNK: usize = 2048;
/// Pairs a manifolds chunk takes at least.
const PAIR_CHUNK: usize = 256;
/// Bodies a chunk of the large bodies' tests takes at least.
const LARGE_CHUNK: usize = 2048;

/// Bodies from which [`World`](crate::world::World) shares its collide stage out this way
/// when it has more than one collide thread (`WorldSettings::collide_threads`); smaller
/// worlds share the narrow phase alone ([`NarrowPhase::collide_on`]). Chosen, not tuned: at
/// 4 200 and 5 000 bodies this stage is no slower than the narrow phase shared alone
/// (docs/PERFORMANCE.md).
pub(crate) const SHARED_COLLIDE_MIN_BODIES: usize = 4096;

/// The bounds of a run of bodies, in body order: per body its AABB, kind, first cell and
/// parry2d pose; the `(cell, body)` entries and the large bodies.
#[derive(Debug, Default)]
struct Bounds {
    aabbs: Vec<Aabb>,
    kinds: Vec<BodyKind>,
    first: Vec<(i64, i64)>,
    poses: Vec<Pose>,
    entries: Vec<(u64, u32)>,
    large: Vec<u32>,
}

impl Bounds {
    fn clear(&mut self) {
        self.aabbs.clear();
        self.kinds.clear();
        self.first.clear();
        self.poses.clear();
        self.entries.clear();
        self.large.clear();
    }
}

/// Every body's bounds in body order, joined from the bounds chunks (the join's first item).
#[derive(Debug, Default)]
struct BodyBounds {
    aabbs: Vec<Aabb>,
    kinds: Vec<BodyKind>,
    first: Vec<(i64, i64)>,
    poses: Vec<Pose>,
}

/// What the threads read in a phase besides [`BodyBounds`]: the join's second item and the
/// serial part's outputs.
#[derive(Debug, Default)]
struct Joined {
    /// The `(cell, body)` entries sorted by cell, and the large bodies.
    entries: Vec<(u64, u32)>,
    large: Vec<u32>,
    /// Where the cell-pairs chunks cut the entries (from 0 to their count).
    cuts: Vec<usize>,
    /// Chunks of whole cells, then chunks of the large bodies' tests.
    cell_chunks: usize,
    large_chunks: usize,
    /// The broad phase's pairs, sorted, once joined.
    pairs: Vec<(u32, u32)>,
    /// Pairs a manifolds chunk takes.
    pair_chunk: usize,
}

/// One chunk's outputs (and its scratch), kept from call to call. Aligned to two cache lines
/// (adjacent-line prefetch): every push writes a buffer's length here, and two threads filling
/// neighbouring chunks would otherwise write one line (the bounds phase on two threads 1.3 × as
/// long, docs/PERFORMANCE.md).
#[derive(Debug, Default)]
#[repr(align(128))]
struct Chunk {
    /// A bounds chunk's bodies, and the box of the cells they cover.
    bounds: Bounds,
    cells: CellBox,
    cell: Vec<CellBody>,
    pairs: Vec<(u32, u32)>,
    manifolds: Vec<ContactManifold<(), ()>>,
    contacts: Vec<RawContact>,
    ranges: Vec<(u32, u32)>,
    /// The cell size's chunk: the AABBs' extents (scratch) and `1 / cell size`.
    extents: Vec<Real>,
    inv: Real,
}

/// The serial parts' scratch.
#[derive(Debug, Default)]
struct Scratch {
    extents: Vec<Real>,
    counts: Vec<u32>,
    sorted_entries: Vec<(u64, u32)>,
    sorted_pairs: Vec<(u32, u32)>,
}

/// The shared collide stage's buffers, kept between steps.
#[derive(Debug, Default)]
pub(crate) struct SharedCollide {
    bodies: BodyBounds,
    joined: Joined,
    chunks: Vec<Chunk>,
    scratch: Scratch,
    /// `1 / cell size` of the last call (`None` before the first).
    inv: Option<Real>,
    /// Chunks the helpers took in the last call, per phase.
    helped: [usize; 4],
    /// The leading thread leaves the join's items to the helpers (tests: the join on a helper
    /// is otherwise a matter of scheduling).
    #[cfg(test)]
    leave_join: bool,
}

impl Clone for SharedCollide {
    /// A fresh one: the buffers are scratch, and the pairs and contacts of a call come from
    /// the bodies alone (the cell size too, from the first call on).
    fn clone(&self) -> Self {
        Self::default()
    }
}

/// `narrow`'s contacts and manifold ranges: the pair chunks', in chunk order.
fn gather_contacts(narrow: &mut NarrowPhase, chunks: &[Chunk]) {
    narrow.contacts.clear();
    narrow.manifolds_ranges.clear();
    for chunk in chunks {
        let offset = narrow.contacts.len() as u32;
        narrow.contacts.extend_from_slice(&chunk.contacts);
        narrow
            .manifolds_ranges
            .extend(chunk.ranges.iter().map(|&(s, e)| (s + offset, e + offset)));
    }
}

/// The phases the threads share.
const BOUNDS: usize = 0;
const JOIN: usize = 1;
const CELL_PAIRS: usize = 2;
const MANIFOLDS: usize = 3;
/// The phases, in order.
const PHASES: [usize; 4] = [BOUNDS, JOIN, CELL_PAIRS, MANIFOLDS];
/// The join's items: the bodies' bounds ([`join_bodies`]), then the entries ([`join_entries`]).
const JOIN_BODIES: usize = 0;
const JOIN_ITEMS: usize = 2;

/// The chunk queue of one call: per phase, its chunk count once published, the next chunk to
/// claim and the chunks done.
#[derive(Default)]
struct Queue {
    published: AtomicUsize,
    count: [AtomicUsize; 4],
    next: [AtomicUsize; 4],
    done: [AtomicUsize; 4],
    /// Chunks the helpers took, per phase.
    helped: [AtomicUsize; 4],
    aborted: AtomicBool,
}

impl Queue {
    /// Makes `phase` of `count` chunks claimable.
    fn publish(&self, phase: usize, count: usize) {
        self.count[phase].store(count, Mem::Relaxed);
        self.published.store(phase + 1, Mem::Release);
    }

    /// Runs `work` on chunks of `phase` until none is left to claim, then counts them done;
    /// returns how many it ran.
    fn take(&self, phase: usize, work: &impl Fn(usize, usize)) -> usize {
        let count = self.count[phase].load(Mem::Relaxed);
        let mut mine = 0;
        loop {
            let c = self.next[phase].fetch_add(1, Mem::Relaxed);
            if c >= count {
                break;
            }
            work(phase, c);
            mine += 1;
        }
        self.done[phase].fetch_add(mine, Mem::AcqRel);
        mine
    }

    /// Waits until every chunk of `phase` is done; `false` when a thread panicked.
    fn finished(&self, phase: usize) -> bool {
        let count = self.count[phase].load(Mem::Relaxed);
        wait_unless_aborted(&self.aborted, || {
            self.done[phase].load(Mem::Acquire) >= count
        })
    }

    /// A helper: every phase, as it is published.
    fn help(&self, work: &impl Fn(usize, usize)) {
        let _abort = AbortOnPanic(&self.aborted);
        for phase in PHASES {
            if !wait_unless_aborted(&self.aborted, || self.published.load(Mem::Acquire) > phase) {
                return;
            }
            let mine = self.take(phase, work);
            self.helped[phase].fetch_add(mine, Mem::Relaxed);
        }
    }
}

impl SharedCollide {
    /// Whether the leading thread takes the join's items too (always, but in the tests that
    /// leave them to the helpers).
    #[cfg(not(test))]
    fn lead_takes_join(&self, _threads: usize) -> bool {
        true
    }

    /// Whether the leading thread takes the join's items too (not when a test leaves them to
    /// the `threads − 1` helpers).
    #[cfg(test)]
    fn lead_takes_join(&self, threads: usize) -> bool {
        !(self.leave_join && threads > 1)
    }

    /// The broad phase's pairs of `bodies` (AABBs grown by `margin`) and their manifolds
    /// (points with separation ≤ `margin`) into `narrow`'s contacts and ranges, on the
    /// calling thread and `threads − 1` helpers (`threads` ≥ 1). Returns the pairs.
    pub(crate) fn collide(
        &mut self,
        bodies: &[Body],
        margin: Real,
        threads: usize,
        narrow: &mut NarrowPhase,
    ) -> &[(u32, u32)] {
        let take_join = self.lead_takes_join(threads);
        let n = bodies.len();
        let bound_chunks = n.div_ceil(BODY_CHUNK);
        let inv = self.prepare(bodies, margin, bound_chunks);
        let buffers = self.chunks.len();
        let (per_body, joined) = (RwLock::new(&mut self.bodies), RwLock::new(&mut self.joined));
        let scratch = Mutex::new(&mut self.scratch);
        let chunks: Vec<Mutex<&mut Chunk>> = self.chunks.iter_mut().map(Mutex::new).collect();
        let work = |phase: usize, c: usize| match phase {
            BOUNDS => bounds_chunk(bodies, c, margin, inv, &mut lock(&chunks[c])),
            JOIN if c == JOIN_BODIES => {
                join_bodies(&mut write(&per_body), &chunks[..bound_chunks], n);
            }
            JOIN => {
                let mut joined = write(&joined);
                join_entries(&mut joined, &mut lock(&scratch), &chunks[..bound_chunks]);
                joined.plan_cell_pairs(buffers - 1, n);
            }
            CELL_PAIRS => {
                cell_pairs_chunk(&read(&per_body), &read(&joined), c, &mut lock(&chunks[c]))
            }
            _ => manifolds_chunk(
                bodies,
                &read(&per_body),
                &read(&joined),
                c,
                margin,
                &mut lock(&chunks[c]),
            ),
        };
        let queue = Queue::default();
        let mut next_inv = inv;
        let mut pair_chunks = 0;
        let lead = || {
            let _abort = AbortOnPanic(&queue.aborted);
            queue.publish(BOUNDS, bound_chunks);
            queue.take(BOUNDS, &work);
            if !queue.finished(BOUNDS) {
                return;
            }
            queue.publish(JOIN, JOIN_ITEMS);
            if take_join {
                queue.take(JOIN, &work);
            }
            if !queue.finished(JOIN) {
                return;
            }
            let cell_chunks = {
                let joined = read(&joined);
                // And one for the next call's cell size.
                joined.cell_chunks + joined.large_chunks + 1
            };
            queue.publish(CELL_PAIRS, cell_chunks);
            queue.take(CELL_PAIRS, &work);
            if !queue.finished(CELL_PAIRS) {
                return;
            }
            pair_chunks = {
                let mut joined = write(&joined);
                join_pairs(
                    &mut joined,
                    &mut lock(&scratch),
                    &chunks[..cell_chunks - 1],
                    n,
                );
                next_inv = lock(&chunks[cell_chunks - 1]).inv;
                joined.pair_chunk = PAIR_CHUNK.max(joined.pairs.len().div_ceil(buffers));
                joined.pairs.len().div_ceil(joined.pair_chunk)
            };
            queue.publish(MANIFOLDS, pair_chunks);
            queue.take(MANIFOLDS, &work);
            queue.finished(MANIFOLDS);
        };
        // The stepping thread leads (it publishes the phases, and joins and sorts the pairs
        // between two of them); the others help.
        let roles = std::iter::once(Some(lead)).chain((1..threads.max(1)).map(|_| None));
        on_threads(roles, |role| match role {
            Some(mut lead) => lead(),
            None => queue.help(&work),
        });
        drop(chunks);
        self.inv = Some(next_inv);
        self.helped = PHASES.map(|p| queue.helped[p].load(Mem::Relaxed));
        gather_contacts(narrow, &self.chunks[..pair_chunks]);
        &self.joined.pairs
    }

    /// Before a call on `bodies` (`bound_chunks` bounds chunks): the cell size to bin them in
    /// (the last call's, or from their bounds on the first call), returned as `1 / size`; and
    /// enough chunk buffers for every bounds chunk and, at the last call's count, every
    /// manifolds chunk (the later phases' chunks grow to fit the buffers), at least four: two
    /// for the large bodies' tests, two for the cells.
    fn prepare(&mut self, bodies: &[Body], margin: Real, bound_chunks: usize) -> Real {
        let wanted = bound_chunks
            .max(self.joined.pairs.len().div_ceil(PAIR_CHUNK))
            .max(4);
        if self.chunks.len() < wanted {
            self.chunks.resize_with(wanted, Chunk::default);
        }
        match self.inv {
            Some(inv) => inv,
            None => {
                let aabbs = bodies.iter().map(|b| bound(b, margin).0);
                1.0 / cell_size(&mut self.scratch.extents, aabbs)
            }
        }
    }
}

#[cfg(test)]
impl SharedCollide {
    /// Whether [`Self::collide`] ran since this was made.
    pub(crate) fn called(&self) -> bool {
        self.inv.is_some()
    }
}

impl Joined {
    /// Cuts the sorted entries into chunks of whole cells and the large bodies' tests into
    /// chunks of the bodies, `buffers` chunks at most in all (`n` bodies).
    fn plan_cell_pairs(&mut self, buffers: usize, n: usize) {
        self.large_chunks = if self.large.is_empty() {
            0
        } else {
            n.div_ceil(LARGE_CHUNK).min(buffers / 2).max(1)
        };
        let room = (buffers - self.large_chunks).max(1);
        let size = ENTRY_CHUNK.max(self.entries.len().div_ceil(room));
        cell_cuts(&self.entries, size, &mut self.cuts);
        // Whole cells may overrun a chunk's size: cuts beyond the room are merged into the
        // last chunk.
        if self.cuts.len() - 1 > room {
            let end = *self.cuts.last().unwrap_or(&0);
            self.cuts.truncate(room);
            self.cuts.push(end);
        }
        self.cell_chunks = self.cuts.len() - 1;
    }
}

/// Bounds chunk `c`: bodies `c · BODY_CHUNK ..`, their AABBs, kinds and poses, binned into
/// cells of size `1 / inv`.
fn bounds_chunk(bodies: &[Body], c: usize, margin: Real, inv: Real, chunk: &mut Chunk) {
    let start = c * BODY_CHUNK;
    let end = (start + BODY_CHUNK).min(bodies.len());
    let own = &mut chunk.bounds;
    own.clear();
    chunk.cells = CellBox::default();
    // Bounds first, then the binning, as `BroadPhase::find_pairs` does: the shape's AABB is a
    // virtual call, across which one loop would keep the binning's state live (one loop: the
    // bounds phase ≈ 1.3 × as long, docs/PERFORMANCE.md).
    for b in &bodies[start..end] {
        let (aabb, pose) = bound(b, margin);
        own.aabbs.push(aabb);
        own.poses.push(pose);
        own.kinds.push(b.kind);
    }
    for (i, aabb) in own.aabbs.iter().enumerate() {
        bin_body(
            (start + i) as u32,
            aabb,
            inv,
            &mut own.first,
            &mut own.entries,
            &mut own.large,
            &mut chunk.cells,
        );
    }
}

/// The join's first item: the `n` bodies' bounds, from the bounds `chunks` in body order. (Read
/// from the last chunk down: the second item reads them from the first up, so the two seldom
/// want one chunk's lock at once.)
fn join_bodies(into: &mut BodyBounds, chunks: &[Mutex<&mut Chunk>], n: usize) {
    let zero = crate::math::Vector::zeros();
    into.aabbs.resize(
        n,
        Aabb {
            min: zero,
            max: zero,
        },
    );
    into.kinds.resize(n, BodyKind::Static);
    into.first.resize(n, (0, 0));
    into.poses.resize(n, Pose::identity());
    for (c, chunk) in chunks.iter().enumerate().rev() {
        let b = &lock(chunk).bounds;
        let range = c * BODY_CHUNK..c * BODY_CHUNK + b.aabbs.len();
        into.aabbs[range.clone()].copy_from_slice(&b.aabbs);
        into.kinds[range.clone()].copy_from_slice(&b.kinds);
        into.first[range.clone()].copy_from_slice(&b.first);
        into.poses[range].copy_from_slice(&b.poses);
    }
}

/// The join's second item: the bounds `chunks`' entries and large bodies joined in body order,
/// the entries sorted by cell.
fn join_entries(joined: &mut Joined, scratch: &mut Scratch, chunks: &[Mutex<&mut Chunk>]) {
    joined.entries.clear();
    joined.large.clear();
    let mut cells = CellBox::default();
    for chunk in chunks {
        let chunk = lock(chunk);
        joined.entries.extend_from_slice(&chunk.bounds.entries);
        joined.large.extend_from_slice(&chunk.bounds.large);
        cells.merge(&chunk.cells);
    }
    sort_entries(
        &mut joined.entries,
        &mut scratch.sorted_entries,
        &mut scratch.counts,
        &cells,
    );
}

/// Cell-pairs chunk `c`: the pairs of its cells, or, past the cells' chunks, of the large
/// bodies with its share of the bodies, or, last, the next call's cell size.
fn cell_pairs_chunk(b: &BodyBounds, joined: &Joined, c: usize, chunk: &mut Chunk) {
    chunk.pairs.clear();
    let (aabbs, kinds) = (&b.aabbs, &b.kinds);
    if c == joined.cell_chunks + joined.large_chunks {
        chunk.inv = 1.0 / cell_size(&mut chunk.extents, aabbs.iter().copied());
    } else if c < joined.cell_chunks {
        cell_pairs(
            &joined.entries[joined.cuts[c]..joined.cuts[c + 1]],
            cell_body(aabbs, &b.first, kinds),
            &mut chunk.cell,
            &mut chunk.pairs,
        );
    } else {
        let n = aabbs.len();
        let k = c - joined.cell_chunks;
        let per = n.div_ceil(joined.large_chunks);
        let (start, end) = ((k * per).min(n), ((k + 1) * per).min(n));
        large_pairs(
            &joined.large,
            start as u32..end as u32,
            |i| aabbs[i as usize],
            |i| kinds[i as usize],
            &mut chunk.pairs,
        );
    }
}

/// The cell-pairs chunks' pairs joined, sorted and deduplicated (`n` bodies).
fn join_pairs(joined: &mut Joined, scratch: &mut Scratch, chunks: &[Mutex<&mut Chunk>], n: usize) {
    joined.pairs.clear();
    for chunk in chunks {
        joined.pairs.extend_from_slice(&lock(chunk).pairs);
    }
    sort_pairs(
        &mut joined.pairs,
        &mut scratch.sorted_pairs,
        &mut scratch.counts,
        n,
    );
}

/// Manifolds chunk `c`: the contacts of its pairs.
fn manifolds_chunk(
    bodies: &[Body],
    b: &BodyBounds,
    joined: &Joined,
    c: usize,
    margin: Real,
    chunk: &mut Chunk,
) {
    let start = (c * joined.pair_chunk).min(joined.pairs.len());
    let end = (start + joined.pair_chunk).min(joined.pairs.len());
    chunk.contacts.clear();
    chunk.ranges.clear();
    collide_pairs(
        bodies,
        &b.poses,
        &joined.pairs[start..end],
        margin,
        &mut chunk.manifolds,
        &mut chunk.contacts,
        &mut chunk.ranges,
    );
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::body::BodyDesc;
    use crate::broad_phase::BroadPhase;
    use crate::math::Vector;
    use crate::rng::PortableRng;
    use crate::scene;
    use crate::shape::ShapeDesc;
    use crate::world::{World, WorldSettings};

    /// A pile's walls and balls with boxes and balls strewn over it at random angles, some
    /// overlapping (two-point manifolds, pairs of every kind).
    pub(crate) fn strewn_world(
        balls: usize,
        strewn: usize,
        side: Real,
        seed: u64,
        settings: WorldSettings,
    ) -> World {
        let mut descs = scene::pile(seed, balls).unwrap().bodies;
        let mut rng = PortableRng::new(seed);
        for k in 0..strewn {
            let p = Vector::new(
                rng.uniform_range(1.0, side - 1.0),
                rng.uniform_range(1.0, side - 1.0),
            );
            let shape = if k % 2 == 0 {
                ShapeDesc::Ball {
                    radius: rng.uniform_range(0.2, 0.9),
                }
            } else {
                ShapeDesc::Cuboid {
                    half_width: rng.uniform_range(0.2, 0.8),
                    half_height: rng.uniform_range(0.2, 0.8),
                }
            };
            let mut d = BodyDesc::dynamic(shape, p);
            d.angle = rng.uniform_range(-3.0, 3.0);
            descs.push(d);
        }
        World::with_bodies(settings, &descs).unwrap()
    }

    /// The contacts' ids and value bits, and the manifold ranges.
    pub(crate) type Bits = (Vec<(crate::contact::ContactId, [u64; 5])>, Vec<(u32, u32)>);

    pub(crate) fn bits(n: &NarrowPhase) -> Bits {
        let c = n
            .contacts
            .iter()
            .map(|c| {
                (
                    c.id,
                    [c.point.x, c.point.y, c.normal.x, c.normal.y, c.separation].map(f64::to_bits),
                )
            })
            .collect();
        (c, n.manifolds_ranges.clone())
    }

    #[test]
    fn shared_pairs_and_contacts_are_the_serial_bits_for_any_thread_count() {
        let margin = 0.02;
        for (balls, strewn, seed) in [(3000, 1500, 3), (800, 1400, 8)] {
            let world = strewn_world(balls, strewn, 60.0, seed, WorldSettings::default());
            let bodies = world.bodies();
            let mut broad = BroadPhase::new();
            let pairs = broad.find_pairs(bodies, margin).to_vec();
            let mut serial = NarrowPhase::new();
            serial.collide(bodies, &pairs, margin);
            let expected = bits(&serial);
            // Every phase has several chunks and the walls are large bodies.
            assert!(bodies.len() > 4 * BODY_CHUNK, "{} bodies", bodies.len());
            assert!(pairs.len() > 4 * PAIR_CHUNK, "{} pairs", pairs.len());
            assert!(expected.1.len() > 1000, "{} manifolds", expected.1.len());
            // One shared collide reused (its cell size from the call before, after the
            // first), on 1 to 4 threads, twice each.
            let mut shared = SharedCollide::default();
            // Chunks the helpers took.
            let mut helped = 0;
            for threads in [1, 2, 3, 4, 2, 1, 4, 3] {
                let mut narrow = NarrowPhase::new();
                let got = shared
                    .collide(bodies, margin, threads, &mut narrow)
                    .to_vec();
                assert_eq!(got, pairs, "{threads} threads");
                assert!(bits(&narrow) == expected, "{threads} threads");
                let joined = &shared.joined;
                assert!(!joined.large.is_empty() && joined.cell_chunks > 1);
                assert_eq!(shared.bodies.poses.len(), bodies.len());
                assert!(joined.pairs.len().div_ceil(joined.pair_chunk) > 1);
                if threads == 1 {
                    assert_eq!(shared.helped, [0; 4]);
                }
                helped += shared.helped.iter().sum::<usize>();
            }
            // A helper that starts late finds no chunk left (a busy machine, a small world),
            // and the join's two items go to a helper only when it is already waiting as they
            // are published: with the lead leaving them, the helpers take both, with the
            // serial bits.
            shared.leave_join = true;
            for threads in [2, 3] {
                let mut narrow = NarrowPhase::new();
                assert_eq!(
                    shared.collide(bodies, margin, threads, &mut narrow),
                    &pairs[..]
                );
                assert!(bits(&narrow) == expected, "{threads} threads");
                assert_eq!(shared.helped[JOIN], JOIN_ITEMS, "{threads} threads");
                helped += shared.helped.iter().sum::<usize>();
            }
            shared.leave_join = false;
            assert!(helped > 0);
        }
    }

    #[test]
    fn more_pairs_than_chunk_buffers_grow_the_chunks_and_lose_no_contact() {
        // 4 200 balls heaped into a small box: many more pairs than the buffers' count times
        // the least chunk, at the first call (no earlier call to size the buffers).
        let mut descs = scene::pile(2, 100).unwrap().bodies;
        let mut rng = PortableRng::new(5);
        for _ in 0..4200 {
            let p = Vector::new(rng.uniform_range(1.0, 9.0), rng.uniform_range(1.0, 9.0));
            descs.push(BodyDesc::dynamic(ShapeDesc::Ball { radius: 0.3 }, p));
        }
        let world = World::with_bodies(WorldSettings::default(), &descs).unwrap();
        let bodies = world.bodies();
        let mut broad = BroadPhase::new();
        let pairs = broad.find_pairs(bodies, 0.0).to_vec();
        let mut serial = NarrowPhase::new();
        serial.collide(bodies, &pairs, 0.0);
        let mut shared = SharedCollide::default();
        let mut narrow = NarrowPhase::new();
        let got = shared.collide(bodies, 0.0, 2, &mut narrow).to_vec();
        assert!(
            pairs.len() > bodies.len().div_ceil(BODY_CHUNK) * PAIR_CHUNK,
            "{} pairs",
            pairs.len()
        );
        assert!(shared.joined.pair_chunk > PAIR_CHUNK);
        assert_eq!(got, pairs);
        assert!(bits(&narrow) == bits(&serial));
    }

    #[test]
    fn cell_cuts_never_split_a_cell_and_cover_every_entry() {
        let mut rng = PortableRng::new(11);
        let mut entries: Vec<(u64, u32)> = (0..5000)
            .map(|i| ((rng.uniform_range(0.0, 300.0) as u64), i))
            .collect();
        entries.sort_unstable();
        let mut cuts = Vec::new();
        for size in [1, 7, 64, 2048, 10_000] {
            cell_cuts(&entries, size, &mut cuts);
            assert_eq!((cuts[0], *cuts.last().unwrap()), (0, entries.len()));
            for w in cuts.windows(2) {
                assert!(w[1] > w[0] && w[1] - w[0] >= size.min(entries.len() - w[0]));
            }
            for &c in &cuts[1..cuts.len() - 1] {
                assert_ne!(entries[c].0, entries[c - 1].0, "cut {c} splits a cell");
            }
        }
    }
}
