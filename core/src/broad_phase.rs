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

/// Reusable broad-phase state: all buffers persist between steps.
#[derive(Debug, Default, Clone)]
pub struct BroadPhase {
    aabbs: Vec<Aabb>,
    entries: Vec<(u64, u32)>,
    large: Vec<u32>,
    pairs: Vec<(u32, u32)>,
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
        self.aabbs.clear();
        for b in bodies {
            let aabb = b.shape.compute_aabb(&parry_pose(&b.origin(), b.angle));
            let m = Vector::new(margin, margin);
            self.aabbs.push(Aabb {
                min: from_parry(aabb.mins) - m,
                max: from_parry(aabb.maxs) + m,
            });
        }
        self.pairs.clear();
        if bodies.len() < 2 {
            return &self.pairs;
        }
        // Cell size: twice the median extent, so a typical body covers 1-4 cells.
        let mut extents: Vec<Real> = self.aabbs.iter().map(|a| (a.max - a.min).max()).collect();
        let mid = extents.len() / 2;
        extents.select_nth_unstable_by(mid, |a, b| a.total_cmp(b));
        let cell = (2.0 * extents[mid]).max(1e-3);
        let inv = 1.0 / cell;

        self.entries.clear();
        self.large.clear();
        for (i, a) in self.aabbs.iter().enumerate() {
            let (x0, y0) = (
                (a.min.x * inv).floor() as i64,
                (a.min.y * inv).floor() as i64,
            );
            let (x1, y1) = (
                (a.max.x * inv).floor() as i64,
                (a.max.y * inv).floor() as i64,
            );
            if (x1 - x0 + 1) * (y1 - y0 + 1) > 16 {
                self.large.push(i as u32);
                continue;
            }
            for ix in x0..=x1 {
                for iy in y0..=y1 {
                    self.entries.push((cell_key(ix, iy), i as u32));
                }
            }
        }
        self.entries.sort_unstable();

        let movable = |i: u32| bodies[i as usize].kind != BodyKind::Static;
        let dynamic_pair = |a: u32, b: u32| {
            bodies[a as usize].kind == BodyKind::Dynamic
                || bodies[b as usize].kind == BodyKind::Dynamic
        };
        let mut start = 0;
        while start < self.entries.len() {
            let key = self.entries[start].0;
            let mut end = start + 1;
            while end < self.entries.len() && self.entries[end].0 == key {
                end += 1;
            }
            for i in start..end {
                let a = self.entries[i].1;
                for j in i + 1..end {
                    let b = self.entries[j].1;
                    if !dynamic_pair(a, b) {
                        continue;
                    }
                    let (aa, bb) = (&self.aabbs[a as usize], &self.aabbs[b as usize]);
                    if !aa.overlaps(bb) {
                        continue;
                    }
                    // Report the pair only in the cell holding the overlap's lower corner,
                    // so pairs sharing several cells are found once.
                    let cx = (aa.min.x.max(bb.min.x) * inv).floor() as i64;
                    let cy = (aa.min.y.max(bb.min.y) * inv).floor() as i64;
                    if cell_key(cx, cy) == key {
                        self.pairs.push((a.min(b), a.max(b)));
                    }
                }
            }
            start = end;
        }
        for (k, &l) in self.large.iter().enumerate() {
            for i in 0..bodies.len() as u32 {
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
        self.pairs.sort_unstable();
        self.pairs.dedup();
        &self.pairs
    }
}
