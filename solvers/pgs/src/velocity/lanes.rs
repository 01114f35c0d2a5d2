//! Small islands packed into the lanes of shared batches ([`VelocitySolver::solve_many`]).
//!
//! A small island swept alone leaves lanes of its batches empty (padding), and an iteration
//! is its manifolds' dependent chain. Small islands share no body, so several fill the lanes
//! of shared batches instead: an island whose batches use at most `w` lanes takes `w`
//! adjacent lanes of every batch of a half of the pack, its k-th batch in the half's k-th;
//! the two halves of a pack ([`PACK`] lanes in all) are swept side by side. One iteration
//! advances every island of the pack, each through its own sequence of batches, in its own
//! order. Each island is prepared and finished by a solver of its own, as alone. Its lanes'
//! measures are folded as its own batches' would be (padding lanes measure exactly zero),
//! and its impulses and velocities are taken back when its stop rule, a divergence or the cap
//! ends it (its lanes are swept on with the others and their later values dropped), so each
//! ends with the bits of its own solve. Under an over-relaxation schedule every lane's
//! effective masses change at the same sweeps, as each island's own would. Islands not swept
//! as batches only (two-point manifolds, other options) are solved alone.
//!
//! [`VelocitySolver::solve_many`]: deepcontact_core::VelocitySolver::solve_many

use std::time::Instant;

use deepcontact_core::{IslandSolve, SolveReport, SolverSettings};

use crate::velocity::many::Progress;
use crate::velocity::over_relaxation::scale_lanes;
use crate::velocity::{
    Batch, BatchKernel, Island, KernelOp, LANES, LaneSweep, PgsSolver, Real, Sweep, Vel, Verdict,
    dispatch,
};

/// Lanes of a pack: two halves of [`LANES`].
pub(crate) const PACK: usize = 2 * LANES;

/// How a prepared small island is swept.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Kind {
    /// Already finished (alone, or its preparation failed).
    Done,
    /// Batches only, this many lanes wide (at most [`LANES`]): in a pack.
    Pack(usize),
}

/// One island of a pack: its index in the group, half, first lane and width.
#[derive(Debug, Clone, Copy, Default)]
struct Member {
    island: usize,
    half: usize,
    lane: usize,
    width: usize,
}

/// The islands of one pack, lanes taken first fit.
#[derive(Debug, Clone, Copy, Default)]
struct Pack {
    members: [Member; PACK],
    count: usize,
    used: [usize; 2],
}

impl Pack {
    /// Adds island `island` of `width` lanes to the first half with room; false if neither
    /// has room.
    fn add(&mut self, island: usize, width: usize) -> bool {
        let Some(half) = (0..2).find(|&h| self.used[h] + width <= LANES) else {
            return false;
        };
        self.members[self.count] = Member {
            island,
            half,
            lane: self.used[half],
            width,
        };
        self.count += 1;
        self.used[half] += width;
        true
    }

    fn members(&self) -> &[Member] {
        &self.members[..self.count]
    }
}

/// The time of a group shared out between its islands, in proportion to their
/// point-iterations (an island without points or iterations counts as one of each, so the
/// shares are finite).
fn share_time(seconds: f64, islands: &mut [IslandSolve<'_>], group: &[usize]) {
    let weight = |i: &IslandSolve<'_>| {
        (i.problem.len().max(1) as f64) * f64::from(i.report.iterations.max(1))
    };
    let total: f64 = group.iter().map(|&k| weight(&islands[k])).sum();
    for &k in group {
        let w = weight(&islands[k]);
        islands[k].report.seconds = seconds * w / total;
    }
}

impl PgsSolver {
    /// Solves the small islands `islands[k]`, `k` in `group`: each prepared on a solver of its
    /// own, then packed if it is swept as batches only (at most [`LANES`] wide, as every
    /// batch is), else alone; the group's time is shared out between the reports in
    /// proportion to their point-iterations.
    pub(crate) fn solve_small(
        &mut self,
        settings: &SolverSettings,
        islands: &mut [IslandSolve<'_>],
        group: &[usize],
    ) {
        let t0 = Instant::now();
        let mut solvers = std::mem::take(&mut self.lane_solvers);
        if solvers.len() < group.len() {
            solvers.resize_with(group.len(), PgsSolver::default);
        }
        let mut kinds = std::mem::take(&mut self.small_kinds);
        kinds.clear();
        for (solver, &k) in solvers.iter_mut().zip(group) {
            let i = &mut islands[k];
            // The options as they are now (a caller may have changed them since).
            (solver.settings, solver.arch) = (self.settings, self.arch);
            let points = i.problem.len();
            let kind = match solver.begin(i.problem, settings, i.impulses, i.velocities, i.report) {
                Err(e) => {
                    i.result = Err(e);
                    Kind::Done
                }
                Ok(()) if solver.batches_only(points) => {
                    Kind::Pack(solver.batches.iter().map(Batch::width).max().unwrap_or(0))
                }
                Ok(()) => {
                    let (it, verdict) = solver.run_scheduled(i.problem, settings, i.report);
                    i.result = solver.end(it, verdict, i.impulses, i.velocities, i.report);
                    Kind::Done
                }
            };
            kinds.push(kind);
        }
        // In packs, lanes taken first fit in order.
        let mut pack = Pack::default();
        for (j, &kind) in kinds.iter().enumerate() {
            let Kind::Pack(width) = kind else {
                continue;
            };
            if !pack.add(j, width) {
                self.run_pack(settings, islands, group, &mut solvers, &pack);
                pack = Pack::default();
                pack.add(j, width);
            }
        }
        if pack.count > 0 {
            self.run_pack(settings, islands, group, &mut solvers, &pack);
        }
        share_time(t0.elapsed().as_secs_f64(), islands, group);
        self.lane_solvers = solvers;
        self.small_kinds = kinds;
    }

    /// Sweeps the islands of `pack` together in this solver's buffers until each has ended,
    /// then finishes each on its own solver.
    fn run_pack(
        &mut self,
        settings: &SolverSettings,
        islands: &mut [IslandSolve<'_>],
        group: &[usize],
        solvers: &mut [PgsSolver],
        pack: &Pack,
    ) {
        let (split, offsets) = self.lay_out(solvers, pack);
        // Under a schedule the packed lanes' masses are scaled share by share from a copy.
        if self.settings.over_relaxation.is_none() {
            self.batch_masses.clear();
        } else {
            self.save_batch_masses();
        }
        let masses = std::mem::take(&mut self.batch_masses);
        let outcomes = dispatch(
            self.arch,
            PackLoop {
                pack: self,
                split,
                offsets,
                members: pack.members(),
                solvers,
                islands,
                group,
                settings,
                masses: &masses,
            },
        );
        self.batch_masses = masses;
        for (m, (it, verdict)) in pack.members().iter().zip(outcomes) {
            let i = &mut islands[group[m.island]];
            let solver = &mut solvers[m.island];
            i.result = solver.end(it, verdict, i.impulses, i.velocities, i.report);
        }
    }

    /// Lays `pack` out in this solver's buffers: each half's batches (as many as its longest
    /// island has) on its own velocities (its islands' in member order, then a dummy body and
    /// a sink for the padding lanes); the first half's batches and velocities come first.
    /// Returns where the second half's batches and velocities start, and each member's offset
    /// into its half's velocities.
    fn lay_out(&mut self, solvers: &[PgsSolver], pack: &Pack) -> ((usize, usize), [usize; PACK]) {
        self.planned_bodies = None;
        self.batches.clear();
        self.vel.clear();
        let mut offsets = [0; PACK];
        let mut split = (0, 0);
        for half in 0..2 {
            let batch_start = self.batches.len();
            let mut length = 0;
            let mut bodies = 0;
            for (k, m) in pack.members().iter().enumerate() {
                if m.half == half {
                    offsets[k] = bodies;
                    bodies += solvers[m.island].vel.len();
                    length = length.max(solvers[m.island].batches.len());
                }
            }
            let dummy = bodies as u32;
            self.batches
                .resize(batch_start + length, Batch::empty(dummy, dummy + 1));
            for (k, m) in pack.members().iter().enumerate() {
                if m.half != half {
                    continue;
                }
                let solver = &solvers[m.island];
                for (to, from) in self.batches[batch_start..].iter_mut().zip(&solver.batches) {
                    for lane in 0..m.width {
                        to.set_lane(m.lane + lane, from, lane, offsets[k] as u32);
                    }
                }
                self.vel.extend_from_slice(&solver.vel);
            }
            self.vel.extend([Vel::default(); 2]);
            if half == 0 {
                split = (self.batches.len(), self.vel.len());
            }
        }
        (split, offsets)
    }
}

/// The iterations of a pack, compiled for the solver's instruction set: the iterations run
/// and the verdict of each member, in member order.
struct PackLoop<'a, 'i> {
    /// The solver whose buffers hold the pack ([`PgsSolver::lay_out`]).
    pack: &'a mut PgsSolver,
    /// Where the second half's batches and velocities start.
    split: (usize, usize),
    /// Each member's offset into its half's velocities.
    offsets: [usize; PACK],
    members: &'a [Member],
    solvers: &'a mut [PgsSolver],
    islands: &'a mut [IslandSolve<'i>],
    group: &'a [usize],
    settings: &'a SolverSettings,
    /// The packed batches' own effective masses ([`PgsSolver::save_batch_masses`]), scaled
    /// into them share by share under the solver's [`crate::OverRelaxation`].
    masses: &'a [[Real; 2 * LANES]],
}

impl KernelOp for PackLoop<'_, '_> {
    type Output = [(u32, Verdict); PACK];

    #[inline(always)]
    fn run<K: BatchKernel>(self, kernel: K) -> Self::Output {
        let mut progress: [Progress; PACK] = Default::default();
        // Islands not ended, per half.
        let mut live = [0usize; 2];
        for m in self.members {
            live[m.half] += 1;
        }
        let (batches, vel) = (&mut self.pack.batches, &mut self.pack.vel);
        let (batches_a, batches_b) = batches.split_at_mut(self.split.0);
        let (vel_a, vel_b) = vel.split_at_mut(self.split.1);
        let contact = self.settings.norm == deepcontact_core::ResidualNorm::Contact;
        // As `run_scheduled`: every live island of the pack has run the same sweeps, so the
        // shares of the first `max_iterations − 1` change the masses of all lanes at once.
        let schedule = self.pack.settings.over_relaxation;
        let cap = self.settings.max_iterations;
        let scheduled = !schedule.is_none() && cap >= 2;
        let (masses_a, masses_b) = if scheduled {
            self.masses.split_at(self.split.0)
        } else {
            (&[][..], &[][..])
        };
        let mut shares = schedule.shares(if scheduled { cap - 1 } else { 0 });
        let (mut left, mut relaxed) = (0u32, scheduled);
        loop {
            let (live_a, live_b) = (live[0] > 0, live[1] > 0);
            if !(live_a || live_b) {
                break;
            }
            while relaxed && left == 0 {
                let (omega, sweeps) = shares.next().unwrap_or((1.0, 0));
                scale_lanes(batches_a, masses_a, omega);
                scale_lanes(batches_b, masses_b, omega);
                (left, relaxed) = (sweeps, sweeps > 0);
            }
            left = left.saturating_sub(1);
            let (mut la, mut lb) = (LaneSweep::default(), LaneSweep::default());
            let (a, b) = (
                island(live_a, &mut *batches_a, &mut *vel_a, &mut la),
                island(live_b, &mut *batches_b, &mut *vel_b, &mut lb),
            );
            if contact {
                kernel.sweep_two::<true>(a, b);
            } else {
                kernel.sweep_two::<false>(a, b);
            }
            for (k, m) in self.members.iter().enumerate() {
                if progress[k].ended.is_some() {
                    continue;
                }
                let lanes = if m.half == 0 { &la } else { &lb };
                // As `iterate` folds an island swept as batches only.
                let mut sweep = Sweep::default();
                sweep.add_span(lanes, m.lane, m.width);
                let report: &mut SolveReport = self.islands[self.group[m.island]].report;
                progress[k].judge(self.settings, &sweep, report);
                if progress[k].ended.is_some() {
                    live[m.half] -= 1;
                    let (batches, vel) = if m.half == 0 {
                        (&*batches_a, &*vel_a)
                    } else {
                        (&*batches_b, &*vel_b)
                    };
                    take_back(
                        &mut self.solvers[m.island],
                        m,
                        batches,
                        vel,
                        self.offsets[k],
                    );
                }
            }
        }
        progress.map(|p| p.outcome())
    }
}

/// A half of the pack as an island of [`BatchKernel::sweep_two`]: no batches once all its
/// islands have ended.
#[inline(always)]
fn island<'x>(
    live: bool,
    batches: &'x mut [Batch],
    vel: &'x mut [Vel],
    lanes: &'x mut LaneSweep,
) -> Island<'x> {
    Island {
        batches: if live { batches } else { &mut [] },
        vel,
        lanes,
    }
}

/// Member `m`'s impulses and its bodies' velocities as they are now in its half of the pack
/// (`batches`, `vel`; its velocities from `offset`), back into its own solver (whose dummy
/// and sink keep their own values).
fn take_back(solver: &mut PgsSolver, m: &Member, batches: &[Batch], vel: &[Vel], offset: usize) {
    for (own, packed) in solver.batches.iter_mut().zip(batches) {
        for lane in 0..m.width {
            own.set_impulses(lane, packed, m.lane + lane);
        }
    }
    let bodies = solver.vel.len() - 2;
    solver.vel[..bodies].copy_from_slice(&vel[offset..offset + bodies]);
}
