//! The domain plan of a large island, on one thread or several.
//!
//! The island's bodies (renumbered in Z-order by the solver) are cut into `n` runs holding
//! about as many manifolds each: the domains. A manifold whose movable bodies all lie in one
//! domain belongs to it; the others (across a cut) form one part more, the cut. Each part is
//! an island of its own for the sweep — its rows, its bodies (renumbered in order), its
//! colours and batches — so a domain is swept by the ordinary one-thread loop on memory no
//! other thread touches. An iteration sweeps the domains (side by side on threads: they share
//! no movable body, and immovable bodies are only read), then the cut on one thread, between
//! copies of its movable bodies' velocities from and back to their domains. That is one
//! Gauss-Seidel order of all manifolds, the same whatever the threads, and the parts' measures
//! are folded in part order, so the result is bit-identical for any thread count.

use std::ops::Range;
use std::sync::{Mutex, MutexGuard, PoisonError};

use deepcontact_core::{ResidualNorm, SolveReport, SolverSettings};

use crate::sync::{Cell3, phase_starts, run_phased};
use crate::velocity::{Manifold, PgsSettings, PgsSolver, Row, Sweep, Vel, Verdict, judge, movable};
use crate::velocity_chunked::{publish, read};

/// The parts of the domain plan, rebuilt for every solve (buffers reused).
#[derive(Debug, Clone, Default)]
pub(crate) struct Domains {
    /// Domains `0..n`, then the cut, each a one-thread solver holding its part.
    pub(crate) parts: Vec<PgsSolver>,
    /// Per part, the island's row of each of its rows.
    pub(crate) rows_of: Vec<Vec<u32>>,
    /// Per part, the island's body of each of its bodies.
    pub(crate) bodies_of: Vec<Vec<u32>>,
    /// The cut's movable bodies, domain by domain: (slot in the cut, slot in the domain).
    pub(crate) links: Vec<(u32, u32)>,
    /// Per domain, its run of `links`.
    pub(crate) link_ranges: Vec<Range<usize>>,
    /// Scratch: each island body's slot in the part being built (`u32::MAX`: none).
    slot: Vec<u32>,
    /// Scratch: the part of each manifold.
    part_of: Vec<u32>,
    /// Scratch: the parts of each island body, as bits.
    used: Vec<u64>,
}

/// The most domains of the plan: a body's parts are bits of a `u64`, the cut's included.
pub const MAX_DOMAINS: usize = 63;

/// The part index of a manifold's movable bodies: their domain, or `n` (the cut) when they
/// lie in two domains. A manifold without a movable body (not swept in effect) goes to
/// domain 0.
fn part_of(m: &Manifold, domain: &impl Fn(u32) -> u32, n: u32) -> u32 {
    let a = movable(m.ma, m.ia).then(|| domain(m.a));
    let b = movable(m.mb, m.ib).then(|| domain(m.b));
    match (a, b) {
        (Some(a), Some(b)) if a != b => n,
        (Some(d), _) | (None, Some(d)) => d,
        (None, None) => 0,
    }
}

impl Domains {
    /// Cuts the island (`manifolds`, `rows`, `vel`: the solver's, after the warm start, bodies
    /// in Z-order) into `n` domains (1 to [`MAX_DOMAINS`], clamped) and the cut, and builds
    /// each part's sweep plan.
    pub(crate) fn build(
        &mut self,
        n: usize,
        manifolds: &[Manifold],
        rows: &[Row],
        vel: &[Vel],
        settings: PgsSettings,
    ) {
        let n = n.clamp(1, MAX_DOMAINS);
        let bodies = vel.len();
        // Where each domain's run of bodies starts: cut where the manifolds counted at their
        // first movable body reach k / n of the total.
        let key = |m: &Manifold| match (movable(m.ma, m.ia), movable(m.mb, m.ib)) {
            (true, true) => m.a.min(m.b),
            (true, false) => m.a,
            (false, true) => m.b,
            (false, false) => 0,
        };
        let mut per_body = vec![0u32; bodies + 1];
        for m in manifolds {
            per_body[key(m) as usize] += 1;
        }
        let mut starts = Vec::with_capacity(n);
        let mut seen = 0usize;
        for (b, &count) in per_body.iter().enumerate() {
            while starts.len() < n && seen >= starts.len() * manifolds.len() / n {
                starts.push(b as u32);
            }
            seen += count as usize;
        }
        starts.resize(n, bodies as u32);
        let domain = |b: u32| (starts.partition_point(|&s| s <= b) - 1) as u32;
        self.part_of.clear();
        self.part_of
            .extend(manifolds.iter().map(|m| part_of(m, &domain, n as u32)));
        // The parts each body belongs to, as bits: a part's bodies are those of its manifolds,
        // and a domain holds as well its movable bodies that only the cut touches.
        self.used.clear();
        self.used.resize(bodies, 0);
        for (m, &q) in manifolds.iter().zip(&self.part_of) {
            for (b, moves) in [(m.a, movable(m.ma, m.ia)), (m.b, movable(m.mb, m.ib))] {
                self.used[b as usize] |= 1 << q;
                if moves && q as usize == n {
                    self.used[b as usize] |= 1 << domain(b);
                }
            }
        }
        self.parts.resize_with(n + 1, PgsSolver::default);
        self.rows_of.resize_with(n + 1, Vec::new);
        self.bodies_of.resize_with(n + 1, Vec::new);
        self.slot.clear();
        self.slot.resize(bodies, u32::MAX);
        for p in 0..=n {
            self.build_part(p, manifolds, rows, vel, settings);
        }
        self.link_cut(n, &domain);
    }

    /// Builds part `p`: its bodies in island order (a domain also holds its movable bodies
    /// that only the cut touches, so that it owns every one of them), its rows, its manifolds
    /// renumbered, then its colours and batches.
    fn build_part(
        &mut self,
        p: usize,
        manifolds: &[Manifold],
        rows: &[Row],
        vel: &[Vel],
        settings: PgsSettings,
    ) {
        let bodies_of = &mut self.bodies_of[p];
        bodies_of.clear();
        let bit = 1u64 << p;
        bodies_of.extend((0..vel.len() as u32).filter(|&b| self.used[b as usize] & bit != 0));
        for (s, &b) in bodies_of.iter().enumerate() {
            self.slot[b as usize] = s as u32;
        }
        let part = &mut self.parts[p];
        part.settings = PgsSettings {
            threads: 1,
            parallel_min_points: usize::MAX,
            ..settings
        };
        part.vel.clear();
        part.vel.extend(bodies_of.iter().map(|&b| vel[b as usize]));
        let rows_of = &mut self.rows_of[p];
        rows_of.clear();
        part.rows.clear();
        part.manifolds.clear();
        for (m, &q) in manifolds.iter().zip(&self.part_of) {
            if q as usize != p {
                continue;
            }
            let local = Manifold {
                a: self.slot[m.a as usize],
                b: self.slot[m.b as usize],
                start: part.rows.len() as u32,
                ..*m
            };
            let range = m.start as usize..(m.start + m.count) as usize;
            rows_of.extend(range.clone().map(|r| r as u32));
            part.rows.extend_from_slice(&rows[range]);
            part.manifolds.push(local);
        }
        // Neighbours next to each other within a colour: the bodies are in Z-order. (The
        // start makes the key unique, so the unstable sort is deterministic.)
        part.manifolds
            .sort_unstable_by_key(|m| (m.a.min(m.b), m.a.max(m.b), m.start));
        part.reset_plan();
        part.colour(bodies_of.len(), None);
        for &b in bodies_of.iter() {
            self.slot[b as usize] = u32::MAX;
        }
    }

    /// The cut's movable bodies, linked to their slots in their domains.
    fn link_cut(&mut self, n: usize, domain: &impl Fn(u32) -> u32) {
        self.links.clear();
        self.link_ranges.clear();
        let cut = &self.bodies_of[n];
        // (domain, slot in the cut) of every movable body of the cut.
        let mut movers: Vec<(u32, u32)> = Vec::new();
        for m in &self.parts[n].manifolds {
            if movable(m.ma, m.ia) {
                movers.push((domain(cut[m.a as usize]), m.a));
            }
            if movable(m.mb, m.ib) {
                movers.push((domain(cut[m.b as usize]), m.b));
            }
        }
        movers.sort_unstable();
        movers.dedup();
        let mut at = 0;
        for d in 0..n as u32 {
            let first = self.links.len();
            while at < movers.len() && movers[at].0 == d {
                let slot = movers[at].1;
                let body = cut[slot as usize];
                let local = self.bodies_of[d as usize]
                    .binary_search(&body)
                    .expect("a domain holds its bodies that the cut moves");
                self.links.push((slot, local as u32));
                at += 1;
            }
            self.link_ranges.push(first..self.links.len());
        }
    }

    /// Copies the parts' impulses back into the island's rows and the domains' velocities
    /// into the island's (the cut's movable bodies are their domains').
    pub(crate) fn write_back(&mut self, rows: &mut [Row], vel: &mut [Vel]) {
        let n = self.parts.len() - 1;
        for (p, part) in self.parts.iter_mut().enumerate() {
            part.sync_rows();
            for (r, &g) in part.rows.iter().zip(&self.rows_of[p]) {
                rows[g as usize] = *r;
            }
            if p < n {
                for (v, &g) in part.vel.iter().zip(&self.bodies_of[p]) {
                    vel[g as usize] = *v;
                }
            }
        }
    }

    /// Stage 3's loop in the domain plan on up to `threads` threads (≥ 1; no more than the
    /// domains). Returns the iterations run and the last verdict, as the one-thread loop
    /// does; `report` gets the residual of every iteration.
    pub(crate) fn solve(
        &mut self,
        threads: usize,
        arch: pulp::Arch,
        settings: &SolverSettings,
        report: &mut SolveReport,
    ) -> (u32, Verdict) {
        let n = self.parts.len() - 1;
        let contact = settings.norm == ResidualNorm::Contact;
        let threads = threads.min(n).max(1);
        if threads == 1 {
            return arch.dispatch(OneThread {
                domains: self,
                settings,
                report,
                contact,
            });
        }
        let (links, ranges) = (&self.links, &self.link_ranges);
        // Each domain's bodies that the cut moves, passed through a mailbox of its own in
        // link order, so that a domain's velocities are only ever touched by the thread that
        // sweeps it (no cache line of theirs moves between cores): a domain takes the cut's
        // last values before its sweep and leaves its own after it; the cut takes the
        // domains' values before its sweep and leaves its own after it.
        let mail: Vec<Mutex<Vec<Vel>>> = ranges
            .iter()
            .zip(&self.parts)
            .map(|(range, part)| {
                let own = links[range.clone()]
                    .iter()
                    .map(|&(_, l)| part.vel[l as usize]);
                Mutex::new(own.collect())
            })
            .collect();
        let parts: Vec<Mutex<&mut PgsSolver>> = self.parts.iter_mut().map(Mutex::new).collect();
        let slots: [Vec<Cell3>; 2] = [0, 1].map(|_| (0..=n).map(|_| Cell3::default()).collect());
        let sweeps = Mutex::new(Vec::new());
        let process = |item: usize, parity: usize| {
            let sweep = if item < n {
                let (mut part, mut mail) = (lock(&parts[item]), lock(&mail[item]));
                let links = &links[ranges[item].clone()];
                for (v, &(_, l)) in mail.iter().zip(links) {
                    part.vel[l as usize] = *v;
                }
                let sweep = arch.dispatch(Part {
                    part: &mut part,
                    contact,
                });
                for (v, &(_, l)) in mail.iter_mut().zip(links) {
                    *v = part.vel[l as usize];
                }
                sweep
            } else {
                let mut cut = lock(&parts[n]);
                for (range, mail) in ranges.iter().zip(&mail) {
                    for (v, &(s, _)) in lock(mail).iter().zip(&links[range.clone()]) {
                        cut.vel[s as usize] = *v;
                    }
                }
                let sweep = arch.dispatch(Part {
                    part: &mut cut,
                    contact,
                });
                for (range, mail) in ranges.iter().zip(&mail) {
                    for (v, &(s, _)) in lock(mail).iter_mut().zip(&links[range.clone()]) {
                        *v = cut.vel[s as usize];
                    }
                }
                sweep
            };
            publish(&slots[parity][item], &sweep);
        };
        let judge_iteration = |it: u32, parity: usize| {
            let mut sweep = Sweep::default();
            for slot in &slots[parity] {
                sweep.add(&read(slot));
            }
            let mut sweeps = sweeps.lock().unwrap_or_else(PoisonError::into_inner);
            sweeps.push(sweep);
            judge(settings, it + 1, &sweep, None) != Verdict::Continue
        };
        run_phased(
            threads,
            settings.max_iterations,
            &phase_starts([n, 1]),
            &process,
            &judge_iteration,
        );
        // The cut's last values into their domains.
        for ((part, mail), range) in parts.iter().zip(&mail).zip(ranges) {
            let mut part = lock(part);
            for (v, &(_, l)) in lock(mail).iter().zip(&links[range.clone()]) {
                part.vel[l as usize] = *v;
            }
        }
        // The iterations' residuals into the report, and the verdict, as the judge saw them.
        let mut last = (0, Verdict::Continue);
        for (k, sweep) in sweeps
            .into_inner()
            .unwrap_or_else(PoisonError::into_inner)
            .iter()
            .enumerate()
        {
            last = (
                k as u32 + 1,
                judge(settings, k as u32 + 1, sweep, Some(report)),
            );
        }
        last
    }
}

/// The value behind `m` (a panicked sweep left nothing half-written that matters: the solve
/// reports the panic).
fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// One sweep of the cut: its movable bodies' velocities from their domains, the sweep, the
/// velocities back.
#[inline(always)]
fn sweep_cut<const CONTACT: bool>(
    cut: &mut PgsSolver,
    domains: &mut [PgsSolver],
    links: &[(u32, u32)],
    ranges: &[Range<usize>],
) -> Sweep {
    for (domain, range) in domains.iter().zip(ranges) {
        for &(s, l) in &links[range.clone()] {
            cut.vel[s as usize] = domain.vel[l as usize];
        }
    }
    let sweep = cut.iterate::<CONTACT>();
    for (domain, range) in domains.iter_mut().zip(ranges) {
        for &(s, l) in &links[range.clone()] {
            domain.vel[l as usize] = cut.vel[s as usize];
        }
    }
    sweep
}

/// The whole loop on the calling thread, compiled for the instruction set chosen at run time.
struct OneThread<'a> {
    domains: &'a mut Domains,
    settings: &'a SolverSettings,
    report: &'a mut SolveReport,
    contact: bool,
}

impl pulp::WithSimd for OneThread<'_> {
    type Output = (u32, Verdict);

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _simd: S) -> Self::Output {
        if self.contact {
            one_thread::<true>(self.domains, self.settings, self.report)
        } else {
            one_thread::<false>(self.domains, self.settings, self.report)
        }
    }
}

/// The domain plan's loop on one thread: the same sweeps in the same order as on several.
#[inline(always)]
fn one_thread<const CONTACT: bool>(
    d: &mut Domains,
    settings: &SolverSettings,
    report: &mut SolveReport,
) -> (u32, Verdict) {
    let n = d.parts.len() - 1;
    let (domains, cut) = d.parts.split_at_mut(n);
    let mut it = 0;
    while it < settings.max_iterations {
        let mut sweep = Sweep::default();
        for part in domains.iter_mut() {
            sweep.add(&part.iterate::<CONTACT>());
        }
        sweep.add(&sweep_cut::<CONTACT>(
            &mut cut[0],
            domains,
            &d.links,
            &d.link_ranges,
        ));
        it += 1;
        match judge(settings, it, &sweep, Some(report)) {
            Verdict::Continue => {}
            end => return (it, end),
        }
    }
    (it, Verdict::Continue)
}

/// One sweep of one part, compiled for the instruction set chosen at run time.
struct Part<'a> {
    part: &'a mut PgsSolver,
    contact: bool,
}

impl pulp::WithSimd for Part<'_> {
    type Output = Sweep;

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _simd: S) -> Self::Output {
        if self.contact {
            self.part.iterate::<true>()
        } else {
            self.part.iterate::<false>()
        }
    }
}
