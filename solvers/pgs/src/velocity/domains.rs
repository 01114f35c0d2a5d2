//! The domain plan of the velocity sweep of a large island, on one thread or several.
//!
//! The island is cut into domains ([`Partition`]); each domain is an island of its own for the
//! sweep — its rows, its bodies (renumbered in order), its colours and batches — so a domain is
//! swept by the ordinary one-thread loop (lanes and all) on memory no other thread touches
//! while it runs, and [`sweep_parts`] runs the iterations.
//!
//! On one thread no other thread touches anything, so the domains' plans are pointed at the
//! island's own velocities instead ([`repoint`]) and swept in the same order in one loop
//! ([`OnIsland`]): a seam body's value is then where the last domain to sweep it left it,
//! which is what the hand-overs give, so the bits are the same without the hand-overs
//! (docs/PERFORMANCE.md, "The domain plan on one thread, per pass").

use deepcontact_core::{ResidualNorm, SolveReport, SolverSettings};

use crate::threads::domain_sweep::{Part, sweep_order, sweep_parts, useful_threads};
use crate::threads::partition::Partition;
use crate::velocity::{
    BatchKernel, LANES, Manifold, PgsSettings, PgsSolver, Row, SolveLoop, Sweep, Sweeps, Vel,
    Verdict, judge, movable,
};

/// The domains of the domain plan, rebuilt for every solve (buffers reused).
#[derive(Debug, Clone, Default)]
pub(crate) struct Domains {
    /// Which manifolds and bodies each domain holds, and the seams between them.
    pub(crate) partition: Partition,
    /// The domains, each a one-thread solver holding its manifolds.
    pub(crate) parts: Vec<PgsSolver>,
    /// Per domain, the island's row of each of its rows.
    pub(crate) rows_of: Vec<Vec<u32>>,
    /// Per building thread, each island body's slot in the domain it builds (scratch).
    slots: Vec<Vec<u32>>,
    /// Whether the domains are swept on one thread, their plans pointed at the island's
    /// velocities ([`repoint`]).
    on_island: bool,
}

impl Domains {
    /// Cuts the island (`manifolds`, `rows`, `vel`: the solver's, after the warm start, bodies
    /// in Z-order) into `n` domains (1 to [`MAX_DOMAINS`](crate::MAX_DOMAINS), clamped) and
    /// builds each domain's sweep plan, the domains side by side on up to `threads` threads (≥ 1;
    /// a domain's plan does not depend on the thread). When the solve will run on one thread
    /// ([`useful_threads`]), the plans are pointed at the island's velocities `vel`.
    pub(crate) fn build(
        &mut self,
        n: usize,
        threads: usize,
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
        self.parts.resize_with(n, PgsSolver::default);
        self.rows_of.resize_with(n, Vec::new);
        let partition = &self.partition;
        let items: Vec<_> = self.parts.iter_mut().zip(&mut self.rows_of).collect();
        let island = Island {
            manifolds,
            rows,
            vel,
            settings,
        };
        partition.build_parts(
            items,
            &mut self.slots,
            threads,
            &|p, (part, rows_of), slot| {
                build_part(p, part, rows_of, partition, slot, &island);
            },
        );
        self.on_island = useful_threads(threads, n) == 1;
        if self.on_island {
            for (part, bodies) in self.parts.iter_mut().zip(&self.partition.bodies_of) {
                repoint(part, bodies, vel.len());
            }
        }
    }

    /// Copies the domains' impulses back into the island's rows and their velocities into the
    /// island's (a seam body's are the same in both its domains after a solve; an immovable
    /// body's are never written; swept on the island's velocities, there is nothing to copy).
    pub(crate) fn write_back(&mut self, rows: &mut [Row], vel: &mut [Vel]) {
        for (p, part) in self.parts.iter_mut().enumerate() {
            part.sync_rows();
            for (r, &g) in part.rows.iter().zip(&self.rows_of[p]) {
                rows[g as usize] = *r;
            }
            if self.on_island {
                continue;
            }
            for (v, &g) in part.vel.iter().zip(&self.partition.bodies_of[p]) {
                vel[g as usize] = *v;
            }
        }
    }

    /// Stage 3's loop in the domain plan on up to `threads` threads (≥ 1; no more than half
    /// the domains, rounded up; `vel`: the island's velocities). Returns the iterations run and
    /// the last verdict, as the one-thread loop does, and the threads it ran on; `report` gets
    /// the residual of every iteration.
    pub(crate) fn solve(
        &mut self,
        threads: usize,
        arch: pulp::Arch,
        settings: &SolverSettings,
        report: &mut SolveReport,
        vel: &mut Vec<Vel>,
    ) -> (u32, Verdict, usize) {
        if self.on_island {
            // The padding lanes' dummy body and the sink after the island's bodies, as a
            // domain's own velocities have them ([`repoint`]).
            let bodies = vel.len();
            vel.extend([Vel::default(); 2]);
            let order: Vec<usize> = sweep_order(self.parts.len()).collect();
            let (it, verdict) = crate::velocity::dispatch(
                arch,
                SolveLoop {
                    sweeps: &mut OnIsland {
                        parts: &mut self.parts,
                        order: &order,
                        vel,
                    },
                    settings,
                    report,
                },
            );
            vel.truncate(bodies);
            return (it, verdict, 1);
        }
        let contact = settings.norm == ResidualNorm::Contact;
        let mut parts: Vec<VelocityPart<'_>> = self
            .parts
            .iter_mut()
            .map(|solver| VelocityPart {
                solver,
                arch,
                contact,
            })
            .collect();
        let stop =
            |it: u32, sweep: &Sweep| judge(settings, it + 1, sweep, None) != Verdict::Continue;
        let (sweeps, threads) = sweep_parts(
            &mut parts,
            &self.partition,
            threads,
            settings.max_iterations,
            &stop,
        );
        // The iterations' residuals into the report, and the verdict, as the loop saw them.
        let mut last = (0, Verdict::Continue);
        for (k, sweep) in sweeps.iter().enumerate() {
            last = (
                k as u32 + 1,
                judge(settings, k as u32 + 1, sweep, Some(report)),
            );
        }
        (last.0, last.1, threads)
    }
}

/// The island that [`Domains::build`] cuts into parts.
struct Island<'a> {
    manifolds: &'a [Manifold],
    rows: &'a [Row],
    vel: &'a [Vel],
    settings: PgsSettings,
}

/// Builds domain `p` of `partition` of `island` into `part` (`slot`: each island body's slot
/// in it): its bodies' velocities, its rows (`rows_of`: the island's row of each), its
/// manifolds renumbered, then its colours and batches.
fn build_part(
    p: usize,
    part: &mut PgsSolver,
    rows_of: &mut Vec<u32>,
    partition: &Partition,
    slot: &[u32],
    island: &Island<'_>,
) {
    let Island {
        manifolds,
        rows,
        vel,
        settings,
    } = *island;
    part.settings = PgsSettings {
        threads: 1,
        parallel_min_points: usize::MAX,
        ..settings
    };
    let bodies = &partition.bodies_of[p];
    part.vel.clear();
    part.vel.extend(bodies.iter().map(|&b| vel[b as usize]));
    rows_of.clear();
    part.rows.clear();
    part.manifolds.clear();
    for (m, &q) in manifolds.iter().zip(&partition.part_of) {
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
    // Neighbours next to each other within a colour: the bodies are in Z-order. (The start
    // makes the key unique, so the unstable sort is deterministic.)
    part.manifolds
        .sort_unstable_by_key(|m| (m.a.min(m.b), m.a.max(m.b), m.start));
    part.reset_plan();
    part.colour(bodies.len(), None);
}

/// Points domain `part`'s plan (its batches' lanes and its one-at-a-time manifolds) at the
/// island's velocities: its slot `s` becomes island body `bodies[s]`, and the padding lanes'
/// dummy and the sink after its bodies become those after the island's `island` bodies.
fn repoint(part: &mut PgsSolver, bodies: &[u32], island: usize) {
    let own = bodies.len() as u32;
    let at = |s: u32| match s.checked_sub(own) {
        None => bodies[s as usize],
        Some(k) => island as u32 + k,
    };
    for batch in &mut part.batches {
        for lane in 0..LANES {
            batch.a[lane] = at(batch.a[lane]);
            batch.b[lane] = at(batch.b[lane]);
            batch.wa[lane] = at(batch.wa[lane]);
            batch.wb[lane] = at(batch.wb[lane]);
        }
    }
    for m in &mut part.scratch {
        (m.a, m.b) = (at(m.a), at(m.b));
    }
}

/// The domains swept one after another on the island's velocities, in the phased loop's order
/// (even domains, then odd), each sweep's measures folded in that order: [`sweep_parts`] on one
/// thread without the hand-overs.
struct OnIsland<'a> {
    parts: &'a mut [PgsSolver],
    order: &'a [usize],
    vel: &'a mut [Vel],
}

impl Sweeps for OnIsland<'_> {
    #[inline(always)]
    fn sweep_once<const CONTACT: bool, K: BatchKernel>(&mut self, kernel: K) -> Sweep {
        let mut all = Sweep::default();
        for &p in self.order {
            all.add(&self.parts[p].iterate_on::<CONTACT, K>(kernel, self.vel));
        }
        all
    }
}

/// A domain of the velocity sweep: its solver, swept in the instruction set chosen at run time.
struct VelocityPart<'a> {
    solver: &'a mut PgsSolver,
    arch: pulp::Arch,
    contact: bool,
}

impl Part for VelocityPart<'_> {
    type Measures = Sweep;

    #[inline]
    fn get(&self, slot: u32) -> [f64; 3] {
        let v = self.solver.vel[slot as usize];
        [v.vx, v.vy, v.w]
    }

    #[inline]
    fn set(&mut self, slot: u32, [vx, vy, w]: [f64; 3]) {
        self.solver.vel[slot as usize] = Vel { vx, vy, w };
    }

    fn sweep(&mut self) -> Sweep {
        let (solver, contact) = (&mut *self.solver, self.contact);
        crate::velocity::dispatch(self.arch, SweepOnce { solver, contact })
    }

    fn fold(into: &mut Sweep, m: &Sweep) {
        into.add(m);
    }
}

/// One sweep of one domain, compiled for the instruction set chosen at run time.
struct SweepOnce<'a> {
    solver: &'a mut PgsSolver,
    contact: bool,
}

impl crate::velocity::KernelOp for SweepOnce<'_> {
    type Output = Sweep;

    #[inline(always)]
    fn run<K: crate::velocity::BatchKernel>(self, kernel: K) -> Self::Output {
        if self.contact {
            self.solver.iterate::<true, K>(kernel)
        } else {
            self.solver.iterate::<false, K>(kernel)
        }
    }
}
