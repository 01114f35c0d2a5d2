//! Broad phase: a sorted uniform grid for bodies of ordinary size plus a list of large
//! bodies (walls) tested against everything. Linear in the number of bodies for piles.

use crate::body::{Body, BodyKind};
use crate::math::{Real, Vector, from_parry, parry_pose};

/// Axis-aligned bounding box in world coordinates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aabb {
    /// Lower corner.
    pub min: Vector,
    /// Upper corner.
    pub max: Vector,
}

impl Aabb {
    /// Whether the boxes overlap (touching counts).
    #[inline]
    pub fn overlaps(&self, o: &Aabb) -> bool {
        self.min.x <= o.max.x
            && o.min.x <= self.max.x
            && self.min.y <= o.max.y
            && o.min.y <= self.max.y
    }
}

/// What the pair tests of a cell read of one of its bodies.
#[derive(Debug, Clone, Copy)]
pub(crate) struct CellBody {
    pub(crate) aabb: Aabb,
    pub(crate) first: (i64, i64),
    pub(crate) id: u32,
    pub(crate) dynamic: bool,
}

/// The box of occupied cells, `lo..=hi` (empty: `lo` above `hi`).
#[derive(Debug, Clone, Copy)]
pub(crate) struct CellBox {
    lo: (i64, i64),
    hi: (i64, i64),
}

impl Default for CellBox {
    fn default() -> Self {
        Self {
            lo: (i64::MAX, i64::MAX),
            hi: (i64::MIN, i64::MIN),
        }
    }
}

impl CellBox {
    /// The box covering both.
    pub(crate) fn merge(&mut self, o: &CellBox) {
        self.lo = (self.lo.0.min(o.lo.0), self.lo.1.min(o.lo.1));
        self.hi = (self.hi.0.max(o.hi.0), self.hi.1.max(o.hi.1));
    }
}

/// Reusable broad-phase state: all buffers persist between steps.
#[derive(Debug, Default, Clone)]
pub struct BroadPhase {
    aabbs: Vec<Aabb>,
    /// Body kinds, packed: the pair tests read them for random bodies, and the `Body`
    /// structs of a large world do not fit in the cache.
    kinds: Vec<BodyKind>,
    extents: Vec<Real>,
    entries: Vec<(u64, u32)>,
    /// Per body, the cell of its AABB's lower corner (`(x, y)` cell indices).
    first: Vec<(i64, i64)>,
    /// The bodies of the cell [`cell_pairs`] is at (scratch).
    cell: Vec<CellBody>,
    large: Vec<u32>,
    pairs: Vec<(u32, u32)>,
    /// Counting-sort scratch: bucket offsets and the sorted copy.
    counts: Vec<u32>,
    sorted_entries: Vec<(u64, u32)>,
    sorted_pairs: Vec<(u32, u32)>,
}

/// `x.floor() as i64` (saturating; NaN gives 0) without a call: x86-64's baseline has no
/// rounding instruction, so `f64::floor` calls the C library, four times a body here.
/// Truncation toward zero is one below the floor exactly for negative non-integers.
#[inline(always)]
fn floor_i64(x: Real) -> i64 {
    let t = x as i64;
    t.saturating_sub(i64::from((t as Real) > x))
}

#[inline]
fn cell_key(ix: i64, iy: i64) -> u64 {
    // Offset so the key order is the (ix, iy) order for any signed cell.
    (((ix + (1 << 31)) as u64) << 32) | ((iy + (1 << 31)) as u64 & 0xffff_ffff)
}

/// Body `b`'s world AABB grown by `margin`, and the parry2d pose it was computed at.
#[inline]
pub(crate) fn bound(b: &Body, margin: Real) -> (Aabb, parry2d::math::Pose) {
    let pose = parry_pose(&b.origin(), b.angle);
    let aabb = b.shape.compute_aabb(&pose);
    let m = Vector::new(margin, margin);
    (
        Aabb {
            min: from_parry(aabb.mins) - m,
            max: from_parry(aabb.maxs) + m,
        },
        pose,
    )
}

/// Cell size for `aabbs`: twice the median extent, so a typical body covers 1-4 cells
/// (`extents`: scratch).
pub(crate) fn cell_size(extents: &mut Vec<Real>, aabbs: impl Iterator<Item = Aabb>) -> Real {
    extents.clear();
    extents.extend(aabbs.map(|a| (a.max - a.min).max()));
    if extents.is_empty() {
        return 1e-3;
    }
    let mid = extents.len() / 2;
    extents.select_nth_unstable_by(mid, |a, b| a.total_cmp(b));
    (2.0 * extents[mid]).max(1e-3)
}

/// Bins body `i` (AABB `a`, cells of size `1 / inv`): its first cell to `first`, one
/// `(cell, body)` entry per cell it covers to `entries` and those cells into `cells`, or,
/// covering more than 16 cells, the body to `large` instead.
#[inline]
pub(crate) fn bin_body(
    i: u32,
    a: &Aabb,
    inv: Real,
    first: &mut Vec<(i64, i64)>,
    entries: &mut Vec<(u64, u32)>,
    large: &mut Vec<u32>,
    cells: &mut CellBox,
) {
    let (x0, y0) = (floor_i64(a.min.x * inv), floor_i64(a.min.y * inv));
    let (x1, y1) = (floor_i64(a.max.x * inv), floor_i64(a.max.y * inv));
    first.push((x0, y0));
    if (x1 - x0 + 1) * (y1 - y0 + 1) > 16 {
        large.push(i);
        return;
    }
    cells.merge(&CellBox {
        lo: (x0, y0),
        hi: (x1, y1),
    });
    for ix in x0..=x1 {
        for iy in y0..=y1 {
            entries.push((cell_key(ix, iy), i));
        }
    }
}

/// Reads body `id` for [`cell_pairs`] from per-body AABBs, first cells and kinds.
#[inline]
pub(crate) fn cell_body<'a>(
    aabbs: &'a [Aabb],
    first: &'a [(i64, i64)],
    kinds: &'a [BodyKind],
) -> impl Fn(u32) -> CellBody + 'a {
    |id| CellBody {
        aabb: aabbs[id as usize],
        first: first[id as usize],
        id,
        dynamic: kinds[id as usize] == BodyKind::Dynamic,
    }
}

/// Overlapping pairs sharing a cell, of the sorted `entries` (whole cells), appended to
/// `pairs`; `body(id)` reads a body, `cell` is scratch. Each pair is reported once: in the
/// cell holding the overlap's lower corner. That cell is `(max(xa, xb), max(ya, yb))` of
/// the two bodies' first cells: `⌊max(u, v) · inv⌋ = max(⌊u · inv⌋, ⌊v · inv⌋)` for
/// `inv > 0`, as a rounded product is monotone in `u`.
pub(crate) fn cell_pairs(
    entries: &[(u64, u32)],
    body: impl Fn(u32) -> CellBody,
    cell: &mut Vec<CellBody>,
    pairs: &mut Vec<(u32, u32)>,
) {
    let mut start = 0;
    while start < entries.len() {
        let key = entries[start].0;
        let mut end = start + 1;
        while end < entries.len() && entries[end].0 == key {
            end += 1;
        }
        // The cell's bodies gathered once (each is read by every pair of the cell).
        cell.clear();
        cell.extend(entries[start..end].iter().map(|&(_, id)| body(id)));
        // Every candidate written, the count advanced by the test's outcome: the test is
        // true for a quarter of the candidates or so, too often to predict.
        let k = cell.len();
        let mut n = pairs.len();
        pairs.resize(n + k * (k - 1) / 2, (0, 0));
        for (i, a) in cell.iter().enumerate() {
            for b in &cell[i + 1..] {
                let hit = (a.dynamic | b.dynamic)
                    & (a.aabb.min.x <= b.aabb.max.x)
                    & (b.aabb.min.x <= a.aabb.max.x)
                    & (a.aabb.min.y <= b.aabb.max.y)
                    & (b.aabb.min.y <= a.aabb.max.y)
                    & (cell_key(a.first.0.max(b.first.0), a.first.1.max(b.first.1)) == key);
                pairs[n] = (a.id.min(b.id), a.id.max(b.id));
                n += usize::from(hit);
            }
        }
        pairs.truncate(n);
        start = end;
    }
}

/// Where `entries` (sorted) can be cut near every `size` entries without splitting a cell:
/// the cuts, ascending, from 0 to `entries.len()`, into `cuts`.
pub(crate) fn cell_cuts(entries: &[(u64, u32)], size: usize, cuts: &mut Vec<usize>) {
    cuts.clear();
    cuts.push(0);
    let mut at = 0;
    while at < entries.len() {
        let mut end = (at + size.max(1)).min(entries.len());
        while end < entries.len() && entries[end].0 == entries[end - 1].0 {
            end += 1;
        }
        cuts.push(end);
        at = end;
    }
}

/// Pairs of each large body with the bodies `others` (large ones once per pair), appended
/// to `pairs`; `aabb(i)` and `kind(i)` read body `i`.
pub(crate) fn large_pairs(
    large: &[u32],
    others: std::ops::Range<u32>,
    aabb: impl Fn(u32) -> Aabb,
    kind: impl Fn(u32) -> BodyKind,
    pairs: &mut Vec<(u32, u32)>,
) {
    let dynamic = |i: u32| kind(i) == BodyKind::Dynamic;
    for (k, &l) in large.iter().enumerate() {
        let bound = aabb(l);
        for i in others.clone() {
            if i == l || large[..k].contains(&i) {
                continue;
            }
            if (dynamic(l) || dynamic(i)) && bound.overlaps(&aabb(i)) {
                pairs.push((l.min(i), l.max(i)));
            }
        }
    }
}

/// Sorts the `(cell key, body)` entries into the order `sort_unstable` gives (key, then
/// body), in linear time: a counting sort over the box `cells` of the occupied cells,
/// stable, and the entries were pushed in body order. Falls back to `sort_unstable` when
/// that box is much larger than the entries (a body far away). `sorted` and `counts`:
/// scratch.
pub(crate) fn sort_entries(
    entries: &mut Vec<(u64, u32)>,
    sorted: &mut Vec<(u64, u32)>,
    counts: &mut Vec<u32>,
    cells: &CellBox,
) {
    let (lo, hi) = (cells.lo, cells.hi);
    let n = entries.len();
    let side = |a: i64, b: i64| {
        b.checked_sub(a)
            .and_then(|d| d.checked_add(1))
            .and_then(|d| usize::try_from(d).ok())
    };
    let size = match (side(lo.0, hi.0), side(lo.1, hi.1)) {
        (Some(w), Some(h)) => w.checked_mul(h).map(|c| (c, h)),
        _ => None,
    };
    let Some((size, h)) = size.filter(|&(c, _)| n > 0 && c <= 4 * n + 1024) else {
        entries.sort_unstable();
        return;
    };
    // Inverse of `cell_key`, then the cell's index in the box (row-major in x, as the key).
    let dense = |key: u64| {
        let ix = (key >> 32) as i64 - (1 << 31);
        let iy = (key & 0xffff_ffff) as i64 - (1 << 31);
        (ix - lo.0) as usize * h + (iy - lo.1) as usize
    };
    counts.clear();
    counts.resize(size + 1, 0);
    for &(key, _) in entries.iter() {
        counts[dense(key) + 1] += 1;
    }
    for c in 1..counts.len() {
        counts[c] += counts[c - 1];
    }
    sorted.clear();
    sorted.resize(n, (0, 0));
    for &e in entries.iter() {
        let d = dense(e.0);
        sorted[counts[d] as usize] = e;
        counts[d] += 1;
    }
    std::mem::swap(entries, sorted);
}

/// Sorts the pairs (bodies `< bodies`) lexicographically in linear time and drops repeats:
/// a stable counting sort by the second body, then by the first (LSD radix). Same order as
/// `sort_unstable` (equal pairs are indistinguishable). `sorted` and `counts`: scratch.
pub(crate) fn sort_pairs(
    pairs: &mut Vec<(u32, u32)>,
    sorted: &mut Vec<(u32, u32)>,
    counts: &mut Vec<u32>,
    bodies: usize,
) {
    if pairs.len() < 64 {
        pairs.sort_unstable();
        pairs.dedup();
        return;
    }
    for pass in 0..2 {
        let key = |p: &(u32, u32)| {
            if pass == 0 {
                p.1 as usize
            } else {
                p.0 as usize
            }
        };
        counts.clear();
        counts.resize(bodies + 1, 0);
        for p in pairs.iter() {
            counts[key(p) + 1] += 1;
        }
        for c in 1..counts.len() {
            counts[c] += counts[c - 1];
        }
        sorted.clear();
        sorted.resize(pairs.len(), (0, 0));
        for &p in pairs.iter() {
            let k = key(&p);
            sorted[counts[k] as usize] = p;
            counts[k] += 1;
        }
        std::mem::swap(pairs, sorted);
    }
    pairs.dedup();
}

impl BroadPhase {
    /// An empty broad phase.
    pub fn new() -> Self {
        Self::default()
    }

    /// World AABBs computed by the last [`Self::find_pairs`].
    pub fn aabbs(&self) -> &[Aabb] {
        &self.aabbs
    }

    /// Candidate pairs `(a, b)`, `a < b`, sorted, with at least one dynamic body and
    /// overlapping AABBs (enlarged by `margin`).
    pub fn find_pairs(&mut self, bodies: &[Body], margin: Real) -> &[(u32, u32)] {
        self.aabbs.clear();
        self.aabbs.extend(bodies.iter().map(|b| bound(b, margin).0));
        self.kinds.clear();
        self.kinds.extend(bodies.iter().map(|b| b.kind));
        self.pairs.clear();
        if bodies.len() < 2 {
            return &self.pairs;
        }
        let inv = 1.0 / cell_size(&mut self.extents, self.aabbs.iter().copied());
        self.entries.clear();
        self.large.clear();
        self.first.clear();
        let mut cells = CellBox::default();
        for (i, a) in self.aabbs.iter().enumerate() {
            bin_body(
                i as u32,
                a,
                inv,
                &mut self.first,
                &mut self.entries,
                &mut self.large,
                &mut cells,
            );
        }
        sort_entries(
            &mut self.entries,
            &mut self.sorted_entries,
            &mut self.counts,
            &cells,
        );
        let (aabbs, kinds) = (&self.aabbs, &self.kinds);
        cell_pairs(
            &self.entries,
            cell_body(aabbs, &self.first, kinds),
            &mut self.cell,
            &mut self.pairs,
        );
        large_pairs(
            &self.large,
            0..bodies.len() as u32,
            |i| aabbs[i as usize],
            |i| kinds[i as usize],
            &mut self.pairs,
        );
        sort_pairs(
            &mut self.pairs,
            &mut self.sorted_pairs,
            &mut self.counts,
            bodies.len(),
        );
        &self.pairs
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::body::BodyDesc;
    use crate::rng::PortableRng;
    use crate::scene;
    use crate::shape::ShapeDesc;
    use crate::world::{World, WorldSettings};

    /// All overlapping pairs with a dynamic body, by brute force, sorted.
    fn brute_force(bp: &BroadPhase, bodies: &[Body]) -> Vec<(u32, u32)> {
        let mut pairs = Vec::new();
        for a in 0..bodies.len() {
            for b in a + 1..bodies.len() {
                let dynamic =
                    bodies[a].kind == BodyKind::Dynamic || bodies[b].kind == BodyKind::Dynamic;
                if dynamic && bp.aabbs()[a].overlaps(&bp.aabbs()[b]) {
                    pairs.push((a as u32, b as u32));
                }
            }
        }
        pairs
    }

    #[test]
    fn counting_sorts_find_every_pair_once_in_order() {
        // A pile (walls are large bodies), plus one far-away body that makes the cell box
        // huge (the entries fall back to `sort_unstable`).
        for far in [false, true] {
            let mut descs = scene::pile(3, 400).unwrap().bodies;
            let mut rng = PortableRng::new(9);
            for _ in 0..200 {
                let p = Vector::new(rng.uniform_range(1.0, 29.0), rng.uniform_range(1.0, 29.0));
                descs.push(BodyDesc::dynamic(
                    ShapeDesc::Ball {
                        radius: rng.uniform_range(0.2, 0.9),
                    },
                    p,
                ));
            }
            if far {
                descs.push(BodyDesc::dynamic(
                    ShapeDesc::Ball { radius: 0.5 },
                    Vector::new(1e7, -3e6),
                ));
            }
            let world = World::with_bodies(WorldSettings::default(), &descs).unwrap();
            let mut bp = BroadPhase::new();
            let pairs = bp.find_pairs(world.bodies(), 0.01).to_vec();
            assert!(pairs.len() > 500);
            assert_eq!(pairs, brute_force(&bp, world.bodies()));
        }
    }

    #[test]
    fn floor_without_a_call_is_the_library_floor() {
        let mut xs = vec![
            0.0,
            -0.0,
            0.5,
            -0.5,
            -1.0,
            -1.0 - Real::EPSILON,
            3.0,
            2.999_999_999_999_999_6,
            -2.999_999_999_999_999_6,
            9.007_199_254_740_993e15,
            -9.007_199_254_740_993e15,
            9.3e18,
            -9.3e18,
            Real::INFINITY,
            Real::NEG_INFINITY,
            Real::NAN,
            Real::MIN_POSITIVE,
            -Real::MIN_POSITIVE,
        ];
        let mut rng = PortableRng::new(4);
        xs.extend((0..10_000).map(|_| rng.uniform_range(-1e3, 1e3)));
        for x in xs {
            assert_eq!(floor_i64(x), x.floor() as i64, "x = {x:e}");
        }
    }
}
