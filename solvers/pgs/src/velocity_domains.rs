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

use crate::partition::Partition;
use crate::sync::{Cell3, phase_starts, run_phased};
use crate::velocity::{Manifold, PgsSettings, PgsSolver, Row, Sweep, Vel, Verdict, judge, movable};
use crate::velocity_chunked::{publish, read};

/// The parts of the domain plan, rebuilt for every solve (buffers reused).
#[derive(Debug, Clone, Default)]
pub(crate) struct Domains {
    /// Which manifolds and bodies each part holds, and the cut's links to the domains.
    pub(crate) partition: Partition,
    /// Domains `0..n`, then the cut, each a one-thread solver holding its part.
    pub(crate) parts: Vec<PgsSolver>,
    /// Per part, the island's row of each of its rows.
    pub(crate) rows_of: Vec<Vec<u32>>,
}

impl Domains {
    /// Cuts the island (`manifolds`, `rows`, `vel`: the solver's, after the warm start, bodies
    /// in Z-order) into `n` domains (1 to [`MAX_DOMAINS`](crate::MAX_DOMAINS), clamped) and the cut, and builds
    /// each part's sweep plan.
    pub(crate) fn build(
        &mut self,
        n: usize,
        manifolds: &[Manifold],
        rows: &[Row],
        vel: &[Vel],
        settings: PgsSettings,
    ) {
        self.partition.build(n, vel.len(), manifolds.len(), |k| {
            let m = &manifolds[k];
            [(m.a, movable(m.ma, m.ia)), (m.b, movable(m.mb, m.ib))]
        });
        let n = self.partition.n;
        self.parts.resize_with(n + 1, PgsSolver::default);
        self.rows_of.resize_with(n + 1, Vec::new);
        for p in 0..=n {
            self.build_part(p, manifolds, rows, vel, settings);
        }
    }

    /// Builds part `p`: its bodies' velocities, its rows, its manifolds renumbered, then its
    /// colours and batches.
    fn build_part(
        &mut self,
        p: usize,
        manifolds: &[Manifold],
        rows: &[Row],
        vel: &[Vel],
        settings: PgsSettings,
    ) {
        let part = &mut self.parts[p];
        part.settings = PgsSettings {
            threads: 1,
            parallel_min_points: usize::MAX,
            ..settings
        };
        let bodies = &self.partition.bodies_of[p];
        part.vel.clear();
        part.vel.extend(bodies.iter().map(|&b| vel[b as usize]));
        let body_count = bodies.len();
        let part_of = std::mem::take(&mut self.partition.part_of);
        let slot = self.partition.slots(p);
        let rows_of = &mut self.rows_of[p];
        rows_of.clear();
        part.rows.clear();
        part.manifolds.clear();
        for (m, &q) in manifolds.iter().zip(&part_of) {
            if q as usize != p {
                continue;
            }
            let local = Manifold {
                a: slot[m.a as usize],
                b: slot[m.b as usize],
                start: part.rows.len() as u32,
                ..*m
            };
            let range = m.start as usize..(m.start + m.count) as usize;
            rows_of.extend(range.clone().map(|r| r as u32));
            part.rows.extend_from_slice(&rows[range]);
            part.manifolds.push(local);
        }
        self.partition.part_of = part_of;
        // Neighbours next to each other within a colour: the bodies are in Z-order. (The
        // start makes the key unique, so the unstable sort is deterministic.)
        part.manifolds
            .sort_unstable_by_key(|m| (m.a.min(m.b), m.a.max(m.b), m.start));
        part.reset_plan();
        part.colour(body_count, None);
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
                for (v, &g) in part.vel.iter().zip(&self.partition.bodies_of[p]) {
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
        let (links, ranges) = (&self.partition.links, &self.partition.link_ranges);
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
            &d.partition.links,
            &d.partition.link_ranges,
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
