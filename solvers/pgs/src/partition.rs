//! An island cut into domains along the Z-order of its bodies: the partition that the domain
//! plans of the velocity sweep ([`crate::velocity_domains`]) and of the position pass
//! ([`crate::position_domains`]) sweep side by side.
//!
//! The bodies (renumbered in Z-order by the solver, so a run of indices is a patch of space)
//! are cut into `n` runs holding about as many constraints each: the domains. A constraint
//! whose movable bodies all lie in one domain belongs to it; the others, across a cut, make
//! part `n`, the cut. Immovable bodies belong to no domain: every part that reads one gets a
//! copy (they are never written).

use std::ops::Range;

/// A constraint's two bodies as the partition sees them: index and whether it can move.
pub(crate) type Ends = [(u32, bool); 2];

/// The most domains: a body's parts are bits of a `u64`, the cut's included.
pub const MAX_DOMAINS: usize = 63;

/// The parts of an island (buffers reused from one build to the next).
#[derive(Debug, Clone, Default)]
pub(crate) struct Partition {
    /// The number of domains; the cut is part `n`.
    pub(crate) n: usize,
    /// The part of each constraint.
    pub(crate) part_of: Vec<u32>,
    /// Per part, its bodies in ascending island order: the bodies of its constraints, and
    /// for a domain also its movable bodies that only the cut touches (so that a domain owns
    /// every movable body of its run).
    pub(crate) bodies_of: Vec<Vec<u32>>,
    /// The cut's movable bodies, domain by domain: (slot in the cut, slot in the domain).
    pub(crate) links: Vec<(u32, u32)>,
    /// Per domain, its run of `links`.
    pub(crate) link_ranges: Vec<Range<usize>>,
    /// The number of the island's bodies.
    bodies: usize,
    /// The first body of each domain.
    starts: Vec<u32>,
    /// Scratch: the parts of each body, as bits.
    used: Vec<u64>,
}

impl Partition {
    /// Cuts `bodies` bodies into `n` domains (1 to [`MAX_DOMAINS`], clamped) for the
    /// constraints `0..count` with the given ends.
    pub(crate) fn build(
        &mut self,
        n: usize,
        bodies: usize,
        count: usize,
        ends: impl Fn(usize) -> Ends,
    ) {
        let n = n.clamp(1, MAX_DOMAINS);
        self.n = n;
        self.bodies = bodies;
        // Cut where the constraints counted at their first movable body reach k / n of all.
        let key = |[(a, ma), (b, mb)]: Ends| match (ma, mb) {
            (true, true) => a.min(b),
            (true, false) => a,
            (false, true) => b,
            (false, false) => 0,
        };
        self.used.clear();
        self.used.resize(bodies + 1, 0);
        for c in 0..count {
            self.used[key(ends(c)) as usize] += 1;
        }
        self.starts.clear();
        let mut seen = 0usize;
        for (b, &k) in self.used.iter().enumerate() {
            while self.starts.len() < n && seen >= self.starts.len() * count / n {
                self.starts.push(b as u32);
            }
            seen += k as usize;
        }
        self.starts.resize(n, bodies as u32);
        let mut part_of = std::mem::take(&mut self.part_of);
        part_of.clear();
        part_of.extend((0..count).map(|c| self.part(ends(c))));
        self.part_of = part_of;
        // The parts each body belongs to, as bits.
        self.used.clear();
        self.used.resize(bodies, 0);
        for (c, &q) in self.part_of.iter().enumerate() {
            for (b, moves) in ends(c) {
                self.used[b as usize] |= 1 << q;
                if moves && q as usize == n {
                    self.used[b as usize] |= 1 << self.domain(b);
                }
            }
        }
        self.bodies_of.resize_with(n + 1, Vec::new);
        for (p, list) in self.bodies_of.iter_mut().enumerate() {
            list.clear();
            let bit = 1u64 << p;
            list.extend((0..bodies as u32).filter(|&b| self.used[b as usize] & bit != 0));
        }
        self.link_cut(count, &ends);
    }

    /// The domain of movable body `b`.
    pub(crate) fn domain(&self, b: u32) -> u32 {
        (self.starts.partition_point(|&s| s <= b) - 1) as u32
    }

    /// The part of a constraint: the domain of its movable bodies, or the cut when they lie
    /// in two domains (one without a movable body, which a sweep leaves as it is, goes to
    /// domain 0).
    fn part(&self, [(a, ma), (b, mb)]: Ends) -> u32 {
        let (da, db) = (ma.then(|| self.domain(a)), mb.then(|| self.domain(b)));
        match (da, db) {
            (Some(x), Some(y)) if x != y => self.n as u32,
            (Some(d), _) | (None, Some(d)) => d,
            (None, None) => 0,
        }
    }

    /// Runs `build(p, item, slot)` for the `p`-th item of `items` (one per part) on up to
    /// `threads` threads (≥ 1), part `p` on thread `p mod threads`. `slot` gives each island
    /// body's slot in part `p` (`u32::MAX` for the bodies it does not hold); each thread
    /// keeps it in a buffer of `scratch` of its own, set and reset part by part. What `build`
    /// makes of an item must not depend on the thread that runs it.
    pub(crate) fn build_parts<T: Send>(
        &self,
        items: Vec<T>,
        scratch: &mut Vec<Vec<u32>>,
        threads: usize,
        build: &(dyn Fn(usize, T, &[u32]) + Sync),
    ) {
        let threads = threads.clamp(1, items.len().max(1));
        let mut shares: Vec<Vec<(usize, T)>> = (0..threads).map(|_| Vec::new()).collect();
        for (p, item) in items.into_iter().enumerate() {
            shares[p % threads].push((p, item));
        }
        if scratch.len() < threads {
            scratch.resize_with(threads, Vec::new);
        }
        let run = |share: Vec<(usize, T)>, slot: &mut Vec<u32>| {
            slot.clear();
            slot.resize(self.bodies, u32::MAX);
            for (p, item) in share {
                for (s, &b) in self.bodies_of[p].iter().enumerate() {
                    slot[b as usize] = s as u32;
                }
                build(p, item, slot);
                for &b in &self.bodies_of[p] {
                    slot[b as usize] = u32::MAX;
                }
            }
        };
        let mut work = shares.into_iter().zip(scratch.iter_mut());
        let first = work.next();
        std::thread::scope(|scope| {
            for (share, slot) in work {
                scope.spawn(move || run(share, slot));
            }
            if let Some((share, slot)) = first {
                run(share, slot);
            }
        });
    }

    /// The cut's movable bodies, linked to their slots in their domains.
    fn link_cut(&mut self, count: usize, ends: &impl Fn(usize) -> Ends) {
        let n = self.n;
        self.links.clear();
        self.link_ranges.clear();
        // (domain, body) of every movable body of the cut, in domain order.
        let mut movers: Vec<(u32, u32)> = (0..count)
            .filter(|&c| self.part_of[c] as usize == n)
            .flat_map(|c| ends(c).into_iter().filter(|&(_, moves)| moves))
            .map(|(b, _)| (self.domain(b), b))
            .collect();
        movers.sort_unstable();
        movers.dedup();
        let slot_in = |list: &[u32], b: u32| {
            list.binary_search(&b)
                .expect("a part holds the bodies it is linked by") as u32
        };
        let mut at = 0;
        for d in 0..n as u32 {
            let first = self.links.len();
            while at < movers.len() && movers[at].0 == d {
                let b = movers[at].1;
                self.links.push((
                    slot_in(&self.bodies_of[n], b),
                    slot_in(&self.bodies_of[d as usize], b),
                ));
                at += 1;
            }
            self.link_ranges.push(first..self.links.len());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_chain_is_cut_into_balanced_domains_and_a_cut_between_them() {
        // Bodies 0..=10 in a chain (constraint c joins c and c + 1), body 5 immovable: 3
        // domains of about 10 / 3 constraints, the constraints across the cuts in the cut.
        let moves = |b: u32| b != 5;
        let ends = |c: usize| {
            [
                (c as u32, moves(c as u32)),
                (c as u32 + 1, moves(c as u32 + 1)),
            ]
        };
        let mut p = Partition::default();
        p.build(3, 11, 10, ends);
        assert_eq!(p.n, 3);
        let mut counts = [0; 4];
        for (c, &q) in p.part_of.iter().enumerate() {
            counts[q as usize] += 1;
            let [(a, ma), (b, mb)] = ends(c);
            if q == 3 {
                assert!(ma && mb && p.domain(a) != p.domain(b), "constraint {c}");
            } else {
                for (body, m) in [(a, ma), (b, mb)] {
                    assert!(!m || p.domain(body) == q, "constraint {c}");
                }
            }
        }
        assert_eq!(counts.iter().sum::<usize>(), 10);
        assert!(
            counts[..3].iter().all(|&k| (2..=4).contains(&k)),
            "{counts:?}"
        );
        // Each movable body in exactly one domain's list; the immovable body 5 in the lists
        // of the parts that read it.
        for b in (0..11u32).filter(|&b| moves(b)) {
            let holders = (0..3).filter(|&d| p.bodies_of[d].contains(&b)).count();
            assert_eq!(holders, 1, "body {b}");
        }
        // Every link joins the same body in the cut and in its domain.
        for (d, range) in p.link_ranges.iter().enumerate() {
            for &(s, l) in &p.links[range.clone()] {
                assert_eq!(p.bodies_of[3][s as usize], p.bodies_of[d][l as usize]);
            }
        }
        let mut made = vec![Vec::new(); 4];
        p.build_parts(
            made.iter_mut().collect(),
            &mut Vec::new(),
            1,
            &|_, item, slot| {
                *item = slot.to_vec();
            },
        );
        let slots = &made[1];
        for (s, &b) in p.bodies_of[1].iter().enumerate() {
            assert_eq!(slots[b as usize], s as u32);
        }
        assert_eq!(
            slots.iter().filter(|&&s| s != u32::MAX).count(),
            p.bodies_of[1].len()
        );
    }

    #[test]
    fn build_parts_visits_every_part_once_with_its_own_item_and_slots_on_any_thread_count() {
        // 7 parts of a chain cut into 6 domains, built on 1 to 9 threads with one scratch kept
        // throughout (so a buffer left dirty by a part would show in a later one): each part
        // gets its own item, and exactly its own bodies' slots.
        let ends = |c: usize| [(c as u32, true), (c as u32 + 1, true)];
        let mut p = Partition::default();
        p.build(6, 20, 19, ends);
        let mut scratch = Vec::new();
        for threads in 1..=9 {
            let mut made: Vec<(usize, Vec<u32>)> = vec![(usize::MAX, Vec::new()); 7];
            let items: Vec<_> = made.iter_mut().collect();
            p.build_parts(items, &mut scratch, threads, &|q, item, slot| {
                *item = (q, slot.to_vec());
            });
            for (q, (seen, slots)) in made.iter().enumerate() {
                assert_eq!(*seen, q, "{threads} threads");
                let mut expected = vec![u32::MAX; 20];
                for (s, &b) in p.bodies_of[q].iter().enumerate() {
                    expected[b as usize] = s as u32;
                }
                assert_eq!(slots, &expected, "part {q}, {threads} threads");
            }
        }
    }

    #[test]
    fn one_domain_leaves_an_empty_cut() {
        let ends = |c: usize| [(c as u32, true), (c as u32 + 1, true)];
        let mut p = Partition::default();
        p.build(1, 6, 5, ends);
        assert!(p.part_of.iter().all(|&q| q == 0));
        assert!(p.bodies_of[1].is_empty() && p.links.is_empty());
        // More domains than constraints: some stay empty, nothing is lost.
        p.build(9, 6, 5, ends);
        assert_eq!(p.part_of.len(), 5);
        assert_eq!(p.link_ranges.len(), 9);
    }
}
