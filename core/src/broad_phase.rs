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
struct CellBody {
    aabb: Aabb,
    first: (i64, i64),
    id: u32,
    dynamic: bool,
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
    /// The bodies of the cell [`Self::cell_pairs`] is at (scratch).
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
        self.compute_bounds(bodies, margin);
        self.pairs.clear();
        if bodies.len() < 2 {
            return &self.pairs;
        }
        let inv = 1.0 / self.cell_size();
        self.bin_bodies(inv);
        self.cell_pairs();
        self.large_pairs(bodies.len() as u32);
        self.sort_pairs(bodies.len());
        self.pairs.dedup();
        &self.pairs
    }

    /// Every body's AABB grown by `margin`, and its kind.
    fn compute_bounds(&mut self, bodies: &[Body], margin: Real) {
        self.aabbs.clear();
        self.kinds.clear();
        self.kinds.extend(bodies.iter().map(|b| b.kind));
        for b in bodies {
            let aabb = b.shape.compute_aabb(&parry_pose(&b.origin(), b.angle));
            let m = Vector::new(margin, margin);
            self.aabbs.push(Aabb {
                min: from_parry(aabb.mins) - m,
                max: from_parry(aabb.maxs) + m,
            });
        }
    }

    /// Cell size: twice the median extent, so a typical body covers 1-4 cells.
    fn cell_size(&mut self) -> Real {
        let extents = &mut self.extents;
        extents.clear();
        extents.extend(self.aabbs.iter().map(|a| (a.max - a.min).max()));
        let mid = extents.len() / 2;
        extents.select_nth_unstable_by(mid, |a, b| a.total_cmp(b));
        (2.0 * extents[mid]).max(1e-3)
    }

    /// One entry per (cell, body) sorted by cell; bodies covering more than 16 cells go to
    /// the large list instead.
    fn bin_bodies(&mut self, inv: Real) {
        self.entries.clear();
        self.large.clear();
        self.first.clear();
        // Bounding box of the occupied cells, for the counting sort.
        let (mut cx0, mut cy0, mut cx1, mut cy1) = (i64::MAX, i64::MAX, i64::MIN, i64::MIN);
        for (i, a) in self.aabbs.iter().enumerate() {
            let (x0, y0) = (floor_i64(a.min.x * inv), floor_i64(a.min.y * inv));
            let (x1, y1) = (floor_i64(a.max.x * inv), floor_i64(a.max.y * inv));
            self.first.push((x0, y0));
            if (x1 - x0 + 1) * (y1 - y0 + 1) > 16 {
                self.large.push(i as u32);
                continue;
            }
            (cx0, cy0, cx1, cy1) = (cx0.min(x0), cy0.min(y0), cx1.max(x1), cy1.max(y1));
            for ix in x0..=x1 {
                for iy in y0..=y1 {
                    self.entries.push((cell_key(ix, iy), i as u32));
                }
            }
        }
        self.sort_entries((cx0, cy0), (cx1, cy1));
    }

    /// Overlapping pairs sharing a cell, each reported once: in the cell holding the
    /// overlap's lower corner. That cell is `(max(xa, xb), max(ya, yb))` of the two bodies'
    /// [`first`](Self::first) cells: `⌊max(u, v) · inv⌋ = max(⌊u · inv⌋, ⌊v · inv⌋)` for
    /// `inv > 0`, as a rounded product is monotone in `u`.
    fn cell_pairs(&mut self) {
        let (kinds, first) = (&self.kinds, &self.first);
        let mut start = 0;
        while start < self.entries.len() {
            let key = self.entries[start].0;
            let mut end = start + 1;
            while end < self.entries.len() && self.entries[end].0 == key {
                end += 1;
            }
            // The cell's bodies gathered once (each is read by every pair of the cell).
            self.cell.clear();
            self.cell
                .extend(self.entries[start..end].iter().map(|&(_, id)| CellBody {
                    aabb: self.aabbs[id as usize],
                    first: first[id as usize],
                    id,
                    dynamic: kinds[id as usize] == BodyKind::Dynamic,
                }));
            // Every candidate written, the count advanced by the test's outcome: the test is
            // true for a quarter of the candidates or so, too often to predict.
            let k = self.cell.len();
            let mut n = self.pairs.len();
            self.pairs.resize(n + k * (k - 1) / 2, (0, 0));
            for (i, a) in self.cell.iter().enumerate() {
                for b in &self.cell[i + 1..] {
                    let hit = (a.dynamic | b.dynamic)
                        & (a.aabb.min.x <= b.aabb.max.x)
                        & (b.aabb.min.x <= a.aabb.max.x)
                        & (a.aabb.min.y <= b.aabb.max.y)
                        & (b.aabb.min.y <= a.aabb.max.y)
                        & (cell_key(a.first.0.max(b.first.0), a.first.1.max(b.first.1)) == key);
                    self.pairs[n] = (a.id.min(b.id), a.id.max(b.id));
                    n += usize::from(hit);
                }
            }
            self.pairs.truncate(n);
            start = end;
        }
    }

    /// Pairs of a large body with every other body (large ones once per pair).
    fn large_pairs(&mut self, n: u32) {
        let kinds = &self.kinds;
        let movable = |i: u32| kinds[i as usize] != BodyKind::Static;
        let dynamic_pair = |a: u32, b: u32| dynamic_pair(kinds, a, b);
        for (k, &l) in self.large.iter().enumerate() {
            for i in 0..n {
                if i == l || (self.large[..k].contains(&i)) {
                    continue;
                }
                if (movable(l) || movable(i))
                    && dynamic_pair(l, i)
                    && self.aabbs[l as usize].overlaps(&self.aabbs[i as usize])
                {
                    self.pairs.push((l.min(i), l.max(i)));
                }
            }
        }
    }

    /// Sorts the `(cell key, body)` entries into the order `sort_unstable` gives (key, then
    /// body), in linear time: a counting sort over the bounding box `lo..=hi` of the occupied
    /// cells, stable, and the entries were pushed in body order. Falls back to
    /// `sort_unstable` when that box is much larger than the entries (a body far away).
    fn sort_entries(&mut self, lo: (i64, i64), hi: (i64, i64)) {
        let n = self.entries.len();
        let side = |a: i64, b: i64| {
            b.checked_sub(a)
                .and_then(|d| d.checked_add(1))
                .and_then(|d| usize::try_from(d).ok())
        };
        let cells = match (side(lo.0, hi.0), side(lo.1, hi.1)) {
            (Some(w), Some(h)) => w.checked_mul(h).map(|c| (c, h)),
            _ => None,
        };
        let Some((cells, h)) = cells.filter(|&(c, _)| n > 0 && c <= 4 * n + 1024) else {
            self.entries.sort_unstable();
            return;
        };
        // Inverse of `cell_key`, then the cell's index in the box (row-major in x, as the key).
        let dense = |key: u64| {
            let ix = (key >> 32) as i64 - (1 << 31);
            let iy = (key & 0xffff_ffff) as i64 - (1 << 31);
            (ix - lo.0) as usize * h + (iy - lo.1) as usize
        };
        let counts = &mut self.counts;
        counts.clear();
        counts.resize(cells + 1, 0);
        for &(key, _) in &self.entries {
            counts[dense(key) + 1] += 1;
        }
        for c in 1..counts.len() {
            counts[c] += counts[c - 1];
        }
        self.sorted_entries.clear();
        self.sorted_entries.resize(n, (0, 0));
        for &e in &self.entries {
            let d = dense(e.0);
            self.sorted_entries[counts[d] as usize] = e;
            counts[d] += 1;
        }
        std::mem::swap(&mut self.entries, &mut self.sorted_entries);
    }

    /// Sorts the pairs (bodies `< bodies`) lexicographically in linear time: a stable
    /// counting sort by the second body, then by the first (LSD radix). Same order as
    /// `sort_unstable` (equal pairs are indistinguishable).
    fn sort_pairs(&mut self, bodies: usize) {
        if self.pairs.len() < 64 {
            self.pairs.sort_unstable();
            return;
        }
        let counts = &mut self.counts;
        let (src, dst) = (&mut self.pairs, &mut self.sorted_pairs);
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
            for p in src.iter() {
                counts[key(p) + 1] += 1;
            }
            for c in 1..counts.len() {
                counts[c] += counts[c - 1];
            }
            dst.clear();
            dst.resize(src.len(), (0, 0));
            for &p in src.iter() {
                let k = key(&p);
                dst[counts[k] as usize] = p;
                counts[k] += 1;
            }
            std::mem::swap(src, dst);
        }
    }
}

/// Whether a pair can collide at all: at least one of the two bodies is dynamic.
fn dynamic_pair(kinds: &[BodyKind], a: u32, b: u32) -> bool {
    kinds[a as usize] == BodyKind::Dynamic || kinds[b as usize] == BodyKind::Dynamic
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
