//! One-point islands packed into the lanes of one sweep ([`VelocitySolver::solve_many`]).
//!
//! An island of one contact point is one manifold: alone, its sweep is one batch of which
//! three lanes are padding, and an iteration is that manifold's dependent chain. Up to
//! [`PACK`] such islands (they share no body) fill the lanes of two batches instead, swept
//! side by side, so that one iteration advances them all. Each island is prepared and
//! finished by a solver of its own, as alone. Its lane's measures are judged as its own
//! batch's would be (padding lanes measure exactly zero), and its impulses and velocities
//! are taken back when its stop rule, a divergence or the cap ends it (the lane is swept on
//! with the others and its later values dropped), so each ends with the bits of its own
//! solve.
//!
//! [`VelocitySolver::solve_many`]: deepcontact_core::VelocitySolver::solve_many

use std::time::Instant;

use deepcontact_core::{IslandSolve, ResidualNorm, SolverSettings};

use crate::velocity::{
    Batch, BatchKernel, Island, KernelOp, LANES, LaneSweep, PgsSolver, Sweep, Vel, dispatch,
};
use crate::velocity_many::Progress;

/// One-point islands swept together: the lanes of two batches.
pub(crate) const PACK: usize = 2 * LANES;

impl PgsSolver {
    /// Solves the one-point islands `islands[k]`, `k` in `group` (at most [`PACK`]), packed
    /// into the lanes of one sweep; an island that is not swept as one batch (other options)
    /// is solved alone. The group's time is shared out between the reports in proportion to
    /// their iterations.
    pub(crate) fn solve_packed(
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
        // Which of the group are packed, in lane order.
        let mut packed = [0usize; PACK];
        let mut count = 0;
        for (j, &k) in group.iter().enumerate() {
            let (solver, i) = (&mut solvers[j], &mut islands[k]);
            // The options as they are now (a caller may have changed them since).
            (solver.settings, solver.arch) = (self.settings, self.arch);
            let points = i.problem.len();
            if let Err(e) = solver.begin(i.problem, settings, i.impulses, i.velocities, i.report) {
                i.result = Err(e);
            } else if solver.batches_only(points) && solver.batches.len() == 1 {
                packed[count] = j;
                count += 1;
            } else {
                let (it, verdict) = solver.run(points, settings, i.report);
                i.result = solver.end(it, verdict, i.impulses, i.velocities, i.report);
            }
        }
        let packed = &packed[..count];
        let halves = self.pack(&solvers, packed);
        let outcomes = dispatch(
            self.arch,
            PackLoop {
                pack: self,
                halves,
                solvers: &mut solvers,
                packed,
                islands,
                group,
                settings,
            },
        );
        for (&j, (it, verdict)) in packed.iter().zip(outcomes) {
            let i = &mut islands[group[j]];
            i.result = solvers[j].end(it, verdict, i.impulses, i.velocities, i.report);
        }
        let seconds = t0.elapsed().as_secs_f64();
        let total: f64 = group
            .iter()
            .map(|&k| f64::from(islands[k].report.iterations.max(1)))
            .sum();
        for &k in group {
            let report = &mut *islands[k].report;
            report.seconds = seconds * f64::from(report.iterations.max(1)) / total;
        }
        self.lane_solvers = solvers;
    }

    /// Lays the `packed` solvers' batches and velocities out in this solver's buffers: lanes
    /// `0..LANES` in batch 0 on the first half of `vel`, the rest in batch 1 on the second,
    /// each half ending with a dummy body and a sink for its padding lanes. Returns the
    /// length of the first half.
    fn pack(&mut self, solvers: &[PgsSolver], packed: &[usize]) -> usize {
        self.batches.clear();
        self.vel.clear();
        let mut first_half = 0;
        for half in packed.chunks(LANES) {
            let start = self.vel.len();
            let mut batch = Batch::default();
            for (lane, &j) in half.iter().enumerate() {
                let offset = (self.vel.len() - start) as u32;
                batch.set_lane(lane, &solvers[j].batches[0], 0, offset);
                self.vel.extend_from_slice(&solvers[j].vel);
            }
            let dummy = (self.vel.len() - start) as u32;
            let padding = Batch::empty(dummy, dummy + 1);
            for lane in half.len()..LANES {
                batch.set_lane(lane, &padding, lane, 0);
            }
            self.vel.extend([Vel::default(); 2]);
            self.batches.push(batch);
            if first_half == 0 {
                first_half = self.vel.len();
            }
        }
        first_half
    }
}

/// The iterations of a pack, compiled for the solver's instruction set: the iterations run
/// and the verdict of each packed island, in lane order.
struct PackLoop<'a, 'i> {
    /// The solver whose buffers hold the pack ([`PgsSolver::pack`]).
    pack: &'a mut PgsSolver,
    /// The length of the first half of the pack's velocities.
    halves: usize,
    solvers: &'a mut [PgsSolver],
    packed: &'a [usize],
    islands: &'a mut [IslandSolve<'i>],
    group: &'a [usize],
    settings: &'a SolverSettings,
}

impl KernelOp for PackLoop<'_, '_> {
    type Output = [(u32, crate::velocity::Verdict); PACK];

    #[inline(always)]
    fn run<K: BatchKernel>(self, kernel: K) -> Self::Output {
        let mut progress: [Progress; PACK] = Default::default();
        let n = self.packed.len();
        let (batches, vel) = (&mut self.pack.batches, &mut self.pack.vel);
        let (vel_a, vel_b) = vel.split_at_mut(self.halves);
        // The lanes' offsets into their half of the velocities.
        let mut offsets = [0usize; PACK];
        for lane in 1..n {
            if lane % LANES != 0 {
                offsets[lane] = offsets[lane - 1] + self.solvers[self.packed[lane - 1]].vel.len();
            }
        }
        loop {
            let live = |range: std::ops::Range<usize>| {
                progress[range.start.min(n)..range.end.min(n)]
                    .iter()
                    .any(|p| p.ended.is_none())
            };
            let (live_a, live_b) = (live(0..LANES), live(LANES..PACK));
            if !(live_a || live_b) {
                break;
            }
            let (mut la, mut lb) = (LaneSweep::default(), LaneSweep::default());
            let contact = self.settings.norm == ResidualNorm::Contact;
            let halves = batches.len().min(1);
            let (first, second) = batches.split_at_mut(halves);
            match (live_a, live_b) {
                (true, true) => {
                    let (a, b) = (
                        Island {
                            batches: first,
                            vel: vel_a,
                            lanes: &mut la,
                        },
                        Island {
                            batches: second,
                            vel: vel_b,
                            lanes: &mut lb,
                        },
                    );
                    if contact {
                        kernel.sweep_two::<true>(a, b);
                    } else {
                        kernel.sweep_two::<false>(a, b);
                    }
                }
                (true, false) => sweep::<K>(kernel, contact, first, vel_a, &mut la),
                _ => sweep::<K>(kernel, contact, second, vel_b, &mut lb),
            }
            for (lane, &j) in self.packed.iter().enumerate() {
                if progress[lane].ended.is_some() {
                    continue;
                }
                let (lanes, batch, half) = if lane < LANES {
                    (&la, &first[0], &*vel_a)
                } else {
                    (&lb, &second[0], &*vel_b)
                };
                // As `iterate` folds an island swept as one batch.
                let mut sweep = Sweep::default();
                sweep.add_lanes(&lanes.only(lane % LANES));
                let report = &mut *self.islands[self.group[j]].report;
                progress[lane].judge(self.settings, &sweep, report);
                if progress[lane].ended.is_some() {
                    // Its impulses and its bodies' velocities as they are now (its dummy
                    // and sink are its own solver's).
                    let solver = &mut self.solvers[j];
                    solver.batches[0].set_impulses(0, batch, lane % LANES);
                    let bodies = solver.vel.len() - 2;
                    let at = offsets[lane];
                    solver.vel[..bodies].copy_from_slice(&half[at..at + bodies]);
                }
            }
        }
        progress.map(|p| p.outcome())
    }
}

/// One sweep of the batches of one half of a pack.
#[inline(always)]
fn sweep<K: BatchKernel>(
    kernel: K,
    contact: bool,
    batches: &mut [Batch],
    vel: &mut [Vel],
    lanes: &mut LaneSweep,
) {
    if contact {
        kernel.sweep::<true>(batches, vel, lanes);
    } else {
        kernel.sweep::<false>(batches, vel, lanes);
    }
}
