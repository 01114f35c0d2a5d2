//! Islands: connected components of dynamic bodies linked by contacts (union-find).
//! Static and kinematic bodies never join islands; they appear in every island they touch.

/// Union-find with path halving and union by size.
#[derive(Debug, Default, Clone)]
pub struct UnionFind {
    parent: Vec<u32>,
    size: Vec<u32>,
}

impl UnionFind {
    /// Resets to `n` singletons, keeping allocations.
    pub fn reset(&mut self, n: usize) {
        self.parent.clear();
        self.parent.extend(0..n as u32);
        self.size.clear();
        self.size.resize(n, 1);
    }

    /// Representative of `x`'s set.
    pub fn find(&mut self, mut x: u32) -> u32 {
        while self.parent[x as usize] != x {
            let p = self.parent[x as usize];
            self.parent[x as usize] = self.parent[p as usize];
            x = self.parent[x as usize];
        }
        x
    }

    /// Merges the sets of `a` and `b`.
    pub fn union(&mut self, a: u32, b: u32) {
        let (mut ra, mut rb) = (self.find(a), self.find(b));
        if ra == rb {
            return;
        }
        if self.size[ra as usize] < self.size[rb as usize] {
            std::mem::swap(&mut ra, &mut rb);
        }
        self.parent[rb as usize] = ra;
        self.size[ra as usize] += self.size[rb as usize];
    }
}

/// Island partition of a step's manifolds.
#[derive(Debug, Default, Clone)]
pub struct Islands {
    uf: UnionFind,
    island_of_root: Vec<u32>,
    has_contact: Vec<bool>,
    counts: Vec<u32>,
    /// Manifold indices grouped by island (see `ranges`).
    pub manifolds: Vec<u32>,
    /// `[start, end)` into `manifolds`, one per island, islands ordered by smallest body.
    pub ranges: Vec<(u32, u32)>,
}

impl Islands {
    /// Groups manifolds (given as `(body_a, body_b)` per manifold) into islands.
    /// `dynamic[i]` says whether body `i` is dynamic.
    pub fn build(&mut self, dynamic: &[bool], manifold_bodies: &[(u32, u32)]) {
        let n = dynamic.len();
        self.uf.reset(n);
        for &(a, b) in manifold_bodies {
            if dynamic[a as usize] && dynamic[b as usize] {
                self.uf.union(a, b);
            }
        }
        // Island ids in order of the smallest dynamic body with a contact.
        self.island_of_root.clear();
        self.island_of_root.resize(n, u32::MAX);
        let has_contact = &mut self.has_contact;
        has_contact.clear();
        has_contact.resize(n, false);
        for &(a, b) in manifold_bodies {
            has_contact[a as usize] = true;
            has_contact[b as usize] = true;
        }
        let mut count = 0u32;
        for i in 0..n as u32 {
            if dynamic[i as usize] && has_contact[i as usize] {
                let r = self.uf.find(i);
                if self.island_of_root[r as usize] == u32::MAX {
                    self.island_of_root[r as usize] = count;
                    count += 1;
                }
            }
        }
        // Counting sort of manifolds by island, stable in manifold order.
        let island_of = |uf: &mut UnionFind, ior: &[u32], (a, b): (u32, u32)| {
            let d = if dynamic[a as usize] { a } else { b };
            ior[uf.find(d) as usize]
        };
        let counts = &mut self.counts;
        counts.clear();
        counts.resize(count as usize + 1, 0);
        for &mb in manifold_bodies {
            let k = island_of(&mut self.uf, &self.island_of_root, mb);
            self.counts[k as usize + 1] += 1;
        }
        for k in 0..count as usize {
            self.counts[k + 1] += self.counts[k];
        }
        self.ranges.clear();
        for k in 0..count as usize {
            self.ranges.push((self.counts[k], self.counts[k + 1]));
        }
        self.manifolds.clear();
        self.manifolds.resize(manifold_bodies.len(), 0);
        for (m, &mb) in manifold_bodies.iter().enumerate() {
            let k = island_of(&mut self.uf, &self.island_of_root, mb) as usize;
            self.manifolds[self.counts[k] as usize] = m as u32;
            self.counts[k] += 1;
        }
    }

    /// Number of islands.
    pub fn len(&self) -> usize {
        self.ranges.len()
    }

    /// Whether there are no islands.
    pub fn is_empty(&self) -> bool {
        self.ranges.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn statics_do_not_join_islands() {
        // bodies 0 (static), 1, 2, 3 dynamic; 1-2 touch, 3 touches only the ground.
        let dynamic = [false, true, true, true];
        let manifolds = [(0, 1), (1, 2), (0, 3)];
        let mut isl = Islands::default();
        isl.build(&dynamic, &manifolds);
        assert_eq!(isl.len(), 2);
        let (s, e) = isl.ranges[0];
        assert_eq!(&isl.manifolds[s as usize..e as usize], &[0, 1]);
        let (s, e) = isl.ranges[1];
        assert_eq!(&isl.manifolds[s as usize..e as usize], &[2]);
    }
}
