//! An island cut into domains, bands of its contact graph: the partition that the domain plans
//! of the velocity sweep ([`crate::velocity::domains`]) and of the position pass
//! ([`crate::position::domains`]) sweep side by side.
//!
//! The movable bodies are layered by a breadth-first walk of the constraints between them
//! (from the lowest-numbered body; the solver numbers bodies in Z-order, so that is a corner
//! of the island), and runs of layers holding about as many constraints each make `n` domains.
//! A constraint belongs to the domain of its later movable body. A breadth-first walk puts the
//! two bodies of a constraint in the same layer or in neighbouring ones, so a domain's
//! constraints move bodies of that domain and of the one before it only: two domains of the same
//! parity share no movable body, and an iteration sweeps the even domains side by side, then
//! the odd ones. A body that two domains move (a body of the seam between them) has one shared
//! value that each domain takes before its sweep and leaves after it. Immovable bodies belong
//! to no domain: every part that reads one gets a copy (they are never written).

use std::ops::Range;

/// A constraint's two bodies as the partition sees them: index and whether it can move.
pub(crate) type Ends = [(u32, bool); 2];

/// The most domains: a body's parts are bits of a `u64`.
pub const MAX_DOMAINS: usize = 63;

/// The contact points a domain holds at least by default
/// ([`PgsSettings::domain_points`](crate::PgsSettings::domain_points)).
pub const DOMAIN_POINTS: usize = 1100;

/// The domains of an island of `points` contact points: `points / domain_points`, at least 4
/// (two side by side in each phase of an iteration) and at most `most`; `most` itself for
/// `domain_points` 0. The count depends on the island alone, never on the threads.
pub(crate) fn domains_for(points: usize, most: usize, domain_points: usize) -> usize {
    match domain_points {
        0 => most,
        per => (points / per).max(4).min(most),
    }
}

/// The parts of an island (buffers reused from one build to the next).
#[derive(Debug, Clone, Default)]
pub(crate) struct Partition {
    /// The number of domains (parts); some may be empty.
    pub(crate) n: usize,
    /// The domain of each constraint.
    pub(crate) part_of: Vec<u32>,
    /// Per domain, its bodies in ascending island order: the bodies of its constraints.
    pub(crate) bodies_of: Vec<Vec<u32>>,
    /// The island bodies that two domains move, ascending: the shared values.
    pub(crate) shared: Vec<u32>,
    /// Per domain, in its run of `links`: (slot in the domain, index in `shared`).
    pub(crate) links: Vec<(u32, u32)>,
    /// Per domain, its run of `links`.
    pub(crate) link_ranges: Vec<Range<usize>>,
    /// The number of the island's bodies.
    bodies: usize,
    /// Scratch: whether each body can move (some constraint says so).
    moves: Vec<bool>,
    /// Scratch: the first neighbour of each body in `neighbours`, then the end.
    first: Vec<u32>,
    /// Scratch: the movable neighbours of every movable body, body by body.
    neighbours: Vec<u32>,
    /// Scratch: each body's fill cursor in `neighbours`, then its index in `shared`.
    at: Vec<u32>,
    /// Scratch: the breadth-first queue.
    queue: Vec<u32>,
    /// Scratch: each body's layer (`u32::MAX`: an immovable body, or one no constraint holds).
    layer: Vec<u32>,
    /// Scratch: the constraints of each layer, then its domain.
    per_layer: Vec<u32>,
    /// Scratch: each movable body's domain.
    domain: Vec<u32>,
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
        self.link_graph(count, &ends);
        self.layer_bodies();
        self.domain_layers(n, count, &ends);
        // A constraint's domain: its later movable body's (none movable: domain 0, which leaves
        // it as it is).
        let domain = &self.domain;
        let key = |[(a, ma), (b, mb)]: Ends| match (ma, mb) {
            (true, true) => domain[a as usize].max(domain[b as usize]),
            (true, false) => domain[a as usize],
            (false, true) => domain[b as usize],
            (false, false) => 0,
        };
        let mut part_of = std::mem::take(&mut self.part_of);
        part_of.clear();
        part_of.extend((0..count).map(|c| key(ends(c))));
        self.part_of = part_of;
        // The parts each body belongs to, as bits.
        self.used.clear();
        self.used.resize(bodies, 0);
        for (c, &q) in self.part_of.iter().enumerate() {
            for (b, _) in ends(c) {
                self.used[b as usize] |= 1 << q;
            }
        }
        // Each domain's bodies, ascending: one pass over the bodies.
        self.bodies_of.resize_with(n, Vec::new);
        self.bodies_of.iter_mut().for_each(Vec::clear);
        for (b, &bits) in self.used.iter().enumerate() {
            let mut rest = bits;
            while rest != 0 {
                self.bodies_of[rest.trailing_zeros() as usize].push(b as u32);
                rest &= rest - 1;
            }
        }
        self.link_seams();
    }

    /// Which bodies move (`moves`), and the movable neighbours of each (`first`,
    /// `neighbours`), in constraint order.
    fn link_graph(&mut self, count: usize, ends: &impl Fn(usize) -> Ends) {
        let bodies = self.bodies;
        self.moves.clear();
        self.moves.resize(bodies, false);
        self.first.clear();
        self.first.resize(bodies + 1, 0);
        for c in 0..count {
            let ends = ends(c);
            for (b, m) in ends {
                self.moves[b as usize] |= m;
            }
            if let [(a, true), (b, true)] = ends {
                self.first[a as usize + 1] += 1;
                self.first[b as usize + 1] += 1;
            }
        }
        for b in 0..bodies {
            self.first[b + 1] += self.first[b];
        }
        self.neighbours.clear();
        self.neighbours.resize(self.first[bodies] as usize, 0);
        self.at.clear();
        self.at.extend_from_slice(&self.first[..bodies]);
        for c in 0..count {
            if let [(a, true), (b, true)] = ends(c) {
                for (from, to) in [(a, b), (b, a)] {
                    let at = &mut self.at[from as usize];
                    self.neighbours[*at as usize] = to;
                    *at += 1;
                }
            }
        }
    }

    /// Each movable body's breadth-first layer (`layer`): walks started from the
    /// lowest-numbered movable body not yet reached, each walk's layers after the last one's.
    fn layer_bodies(&mut self) {
        self.layer.clear();
        self.layer.resize(self.bodies, u32::MAX);
        let mut layers = 0u32;
        for start in 0..self.bodies {
            if !self.moves[start] || self.layer[start] != u32::MAX {
                continue;
            }
            self.queue.clear();
            self.queue.push(start as u32);
            self.layer[start] = layers;
            let mut head = 0;
            while let Some(&b) = self.queue.get(head) {
                head += 1;
                let (b, next) = (b as usize, self.layer[b as usize] + 1);
                for &to in &self.neighbours[self.first[b] as usize..self.first[b + 1] as usize] {
                    if self.layer[to as usize] == u32::MAX {
                        self.layer[to as usize] = next;
                        self.queue.push(to);
                    }
                }
            }
            // A walk's last body is in its deepest layer.
            layers = self
                .queue
                .last()
                .map_or(layers, |&b| self.layer[b as usize])
                + 1;
        }
        self.per_layer.clear();
        self.per_layer.resize(layers as usize, 0);
    }

    /// Runs of layers holding about `count / n` constraints each (counted at their later
    /// movable body's layer) into domains; each movable body's domain into `domain`.
    /// Neighbouring layers get the same domain or neighbouring ones, so a constraint's movable
    /// bodies do too.
    fn domain_layers(&mut self, n: usize, count: usize, ends: &impl Fn(usize) -> Ends) {
        let layer = &self.layer;
        for c in 0..count {
            let at = match ends(c) {
                [(a, true), (b, true)] => layer[a as usize].max(layer[b as usize]),
                [(a, true), _] | [_, (a, true)] => layer[a as usize],
                _ => continue,
            };
            self.per_layer[at as usize] += 1;
        }
        // A layer opens the next domain once the constraints before it reach that domain's
        // share.
        let (mut seen, mut domain) = (0usize, 0usize);
        for k in &mut self.per_layer {
            if domain + 1 < n && seen > 0 && seen * n >= (domain + 1) * count {
                domain += 1;
            }
            seen += *k as usize;
            *k = domain as u32;
        }
        self.domain.clear();
        self.domain.extend(
            self.layer
                .iter()
                .map(|&l| self.per_layer.get(l as usize).copied().unwrap_or(0)),
        );
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
        crate::threads::sync::on_threads(
            shares.into_iter().zip(scratch.iter_mut()),
            |(share, slot)| run(share, slot),
        );
    }

    /// The movable bodies that two domains hold (`shared`), and each domain's links to them.
    fn link_seams(&mut self) {
        self.shared.clear();
        self.at.clear();
        self.at.resize(self.bodies, u32::MAX);
        for (b, (&bits, &m)) in self.used.iter().zip(&self.moves).enumerate() {
            if m && bits.count_ones() > 1 {
                self.at[b] = self.shared.len() as u32;
                self.shared.push(b as u32);
            }
        }
        self.links.clear();
        self.link_ranges.clear();
        for list in &self.bodies_of {
            let start = self.links.len();
            for (s, &b) in list.iter().enumerate() {
                let k = self.at[b as usize];
                if k != u32::MAX {
                    self.links.push((s as u32, k));
                }
            }
            self.link_ranges.push(start..self.links.len());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_island_gets_a_domain_per_domain_points_at_least_four_at_most_the_setting() {
        for (points, want) in [
            (0, 4),
            (2048, 4),
            (5260, 4),
            (8800, 8),
            (17_600, 16),
            (99_999, 16),
        ] {
            assert_eq!(domains_for(points, 16, 1100), want, "{points} points");
        }
        // Fewer than four asked for: that many; points a domain 0: always the setting.
        assert_eq!(domains_for(50_000, 2, 1100), 2);
        assert_eq!(domains_for(100, 16, 0), 16);
        assert_eq!(domains_for(100, 3, 0), 3);
    }

    #[test]
    fn a_chain_is_cut_into_balanced_domains_with_one_seam_body_between_neighbours() {
        // Bodies 0..=10 in a chain (constraint c joins c and c + 1), body 5 immovable: the
        // walk from body 0 stops at 5, the second from 6 goes on; 3 domains of about 10 / 3
        // constraints.
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
        let mut counts = [0; 3];
        for &q in &p.part_of {
            counts[q as usize] += 1;
        }
        assert_eq!(counts.iter().sum::<usize>(), 10);
        assert!(counts.iter().all(|&k| (2..=5).contains(&k)), "{counts:?}");
        // Domains follow the chain: a constraint's domain is that of its later body, no earlier
        // than the domain before.
        assert!(
            p.part_of
                .windows(2)
                .all(|w| w[0] <= w[1] && w[1] <= w[0] + 1)
        );
        // Every movable body in one domain's list or, at a seam, in two neighbouring ones; the
        // immovable body 5 in the lists of the domains that read it, never shared.
        for b in (0..11u32).filter(|&b| moves(b)) {
            let holders: Vec<usize> = (0..3).filter(|&d| p.bodies_of[d].contains(&b)).collect();
            match holders[..] {
                [_] => assert!(!p.shared.contains(&b), "body {b}"),
                [x, y] => assert!(y == x + 1 && p.shared.contains(&b), "body {b}"),
                _ => panic!("body {b} in domains {holders:?}"),
            }
        }
        // Layers 0–4, then 5 (body 5 alone), then 6–10; the first seam falls on the immovable
        // body, the second shares body 7.
        assert_eq!(p.shared, [7]);
        // Every link joins the same body in its domain and in the shared list.
        for (d, range) in p.link_ranges.iter().enumerate() {
            for &(s, k) in &p.links[range.clone()] {
                assert_eq!(p.bodies_of[d][s as usize], p.shared[k as usize]);
            }
        }
        let mut made = vec![Vec::new(); 3];
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
    fn a_grid_walked_from_its_corner_has_no_constraint_across_two_domains() {
        // A 12 × 9 grid of bodies (row-major) with constraints to the right and upward
        // neighbours, its bottom row immovable except for the corner: walks layer the bodies
        // by their distance from the corner, and a constraint's bodies lie in one domain or in
        // two neighbouring ones.
        let (w, h) = (12u32, 9u32);
        let moves = |b: u32| b == 0 || b >= w;
        let mut pairs = Vec::new();
        for y in 0..h {
            for x in 0..w {
                let b = y * w + x;
                if x + 1 < w {
                    pairs.push((b, b + 1));
                }
                if y + 1 < h {
                    pairs.push((b, b + w));
                }
            }
        }
        let ends = |c: usize| {
            let (a, b) = pairs[c];
            [(a, moves(a)), (b, moves(b))]
        };
        let mut p = Partition::default();
        for n in 1..=8 {
            p.build(n, (w * h) as usize, pairs.len(), ends);
            for (c, &q) in p.part_of.iter().enumerate() {
                for (b, m) in ends(c) {
                    if m {
                        let holders: Vec<u32> = (0..n as u32)
                            .filter(|&d| p.bodies_of[d as usize].binary_search(&b).is_ok())
                            .collect();
                        assert!(holders.contains(&q), "constraint {c}");
                        assert!(holders.len() <= 2, "body {b} in domains {holders:?}");
                        assert!(holders.iter().all(|&d| d.abs_diff(q) <= 1));
                    }
                }
            }
            let mut counts = vec![0usize; n];
            for &q in &p.part_of {
                counts[q as usize] += 1;
            }
            // A domain closes on the layer that reaches its share, so it misses the share by
            // less than a layer's constraints (a diagonal of the grid: under 3 h).
            let share = pairs.len() / n;
            assert!(
                counts
                    .iter()
                    .all(|&k| k > 0 && k.abs_diff(share) < 3 * h as usize),
                "{n} domains: {counts:?}"
            );
        }
    }

    #[test]
    fn build_parts_visits_every_part_once_with_its_own_item_and_slots_on_any_thread_count() {
        // 7 domains of a chain, built on 1 to 9 threads with one scratch kept throughout (so a
        // buffer left dirty by a domain would show in a later one): each domain gets its own item,
        // and exactly its own bodies' slots.
        let ends = |c: usize| [(c as u32, true), (c as u32 + 1, true)];
        let mut p = Partition::default();
        p.build(7, 20, 19, ends);
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
    fn one_domain_shares_nothing_and_empty_domains_lose_nothing() {
        let ends = |c: usize| [(c as u32, true), (c as u32 + 1, true)];
        let mut p = Partition::default();
        p.build(1, 6, 5, ends);
        assert!(p.part_of.iter().all(|&q| q == 0));
        assert!(p.shared.is_empty() && p.links.is_empty());
        // More domains than constraints: some stay empty, nothing is lost.
        p.build(9, 6, 5, ends);
        assert_eq!(p.part_of.len(), 5);
        assert_eq!(p.link_ranges.len(), 9);
        // No constraint at all.
        p.build(4, 3, 0, ends);
        assert!(p.part_of.is_empty() && p.bodies_of.iter().all(Vec::is_empty));
    }
}
