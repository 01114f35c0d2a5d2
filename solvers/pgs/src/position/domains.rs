//! The domain plan of the position pass of a large island, on one thread or several.
//!
//! The island is cut into domains ([`Partition`]), as the velocity sweep's; each domain visits its
//! points in the island's order (no colours: one thread sweeps a domain; in [`Waves`], which
//! keep that order's bits) on poses of its own, and [`sweep_parts`] runs the iterations. The pass's measures are minima
//! and maxima, so only the order of the corrections decides the bits, and that order is the
//! same for every thread count.

use deepcontact_core::math::Pose;
use deepcontact_core::{PositionReport, PositionSettings};

use crate::position::waves::Waves;
use crate::position::{CachedRotations, PassMeasures, PosRow, Rotation, correct_point};
use crate::threads::domain_sweep::{Part, sweep_parts};
use crate::threads::partition::Partition;

/// The domains of the position pass's domain plan (buffers reused from one island to the next).
#[derive(Debug, Clone, Default)]
pub(crate) struct PositionDomains {
    /// Which points and bodies each domain holds, and the seams between them.
    partition: Partition,
    /// Per domain, its rows (bodies renumbered to the domain's slots), in the island's order.
    rows: Vec<Vec<PosRow>>,
    /// Per domain, its bodies' poses.
    poses: Vec<Vec<Pose>>,
    /// Per domain, its bodies' last rotations (one per pose).
    rotations: Vec<Vec<Rotation>>,
    /// Per domain, its points in waves, and whether [`Waves::build`] planned them.
    waves: Vec<(Waves, bool)>,
    /// Per building thread, each island body's slot in the domain it builds (scratch).
    slots: Vec<Vec<u32>>,
}

impl PositionDomains {
    /// Cuts the island (`rows` and `poses`, bodies in Z-order) into `n` domains (1 to
    /// [`MAX_DOMAINS`](crate::MAX_DOMAINS), clamped), the domains built side by side on up to
    /// `threads` threads (≥ 1).
    pub(crate) fn build(&mut self, n: usize, threads: usize, rows: &[PosRow], poses: &[Pose]) {
        self.partition
            .build(n, poses.len(), rows.len(), |k| rows[k].ends());
        let n = self.partition.n;
        self.rows.resize_with(n, Vec::new);
        self.poses.resize_with(n, Vec::new);
        self.waves.resize_with(n, Default::default);
        let partition = &self.partition;
        let items: Vec<_> = self
            .rows
            .iter_mut()
            .zip(&mut self.poses)
            .zip(&mut self.waves)
            .collect();
        let build = |p: usize, ((list, own), waves): Item<'_>, slot: &[u32]| {
            own.clear();
            own.extend(partition.bodies_of[p].iter().map(|&b| poses[b as usize]));
            list.clear();
            list.extend(
                rows.iter()
                    .zip(&partition.part_of)
                    .filter(|&(_, &q)| q as usize == p)
                    .map(|(row, _)| row.renumbered(slot)),
            );
            waves.1 = waves.0.build(list, own);
        };
        partition.build_parts(items, &mut self.slots, threads, &build);
    }

    /// Runs the pass on up to `threads` threads (≥ 1; no more than half the domains, rounded up)
    /// under the stop
    /// rule of `settings`, and writes the poses back (`poses`: the island's, as given to
    /// [`Self::build`]). Returns the threads it ran on.
    pub(crate) fn solve(
        &mut self,
        threads: usize,
        settings: &PositionSettings,
        poses: &mut [Pose],
        report: &mut PositionReport,
    ) -> usize {
        self.rotations.resize_with(self.poses.len(), Vec::new);
        let mut parts: Vec<PositionPart<'_>> = self
            .rows
            .iter()
            .zip(self.poses.iter_mut())
            .zip(self.rotations.iter_mut())
            .zip(&self.waves)
            .map(|(((rows, poses), rotations), (waves, planned))| {
                rotations.clear();
                rotations.resize(poses.len(), Rotation::default());
                PositionPart {
                    rows,
                    waves: planned.then_some(waves),
                    poses: CachedRotations { poses, rotations },
                    settings,
                }
            })
            .collect();
        let stop =
            |it: u32, m: &PassMeasures| m.judge(it, settings, &mut PositionReport::default());
        let (passes, ran_on) = sweep_parts(
            &mut parts,
            &self.partition,
            threads,
            settings.max_iterations,
            &stop,
        );
        // The report as the last iteration left it.
        if let Some((it, last)) = passes.iter().enumerate().next_back() {
            last.judge(it as u32, settings, report);
        }
        // Each body from its domains (a seam body's poses are the same in both after the pass;
        // an immovable body's are never written).
        for (own, bodies) in self.poses.iter().zip(&self.partition.bodies_of) {
            for (pose, &b) in own.iter().zip(bodies) {
                poses[b as usize] = *pose;
            }
        }
        ran_on
    }
}

/// What [`PositionDomains::build`] fills for one domain: its rows, its poses, its waves.
type Item<'a> = (
    (&'a mut Vec<PosRow>, &'a mut Vec<Pose>),
    &'a mut (Waves, bool),
);

/// A domain of the pass: its rows and its poses (with their last rotations: a seam body's
/// pose written by [`Part::set`] keeps the cache right, since it is keyed by the angle).
struct PositionPart<'a> {
    rows: &'a [PosRow],
    /// The rows in waves ([`Waves::build`] accepted them).
    waves: Option<&'a Waves>,
    poses: CachedRotations<'a>,
    settings: &'a PositionSettings,
}

impl Part for PositionPart<'_> {
    type Measures = PassMeasures;

    #[inline]
    fn get(&self, slot: u32) -> [f64; 3] {
        let p = self.poses.poses[slot as usize];
        [p.position.x, p.position.y, p.angle]
    }

    #[inline]
    fn set(&mut self, slot: u32, [x, y, angle]: [f64; 3]) {
        self.poses.poses[slot as usize] =
            Pose::new(deepcontact_core::math::Vector::new(x, y), angle);
    }

    fn sweep(&mut self) -> PassMeasures {
        if let Some(waves) = self.waves {
            return waves.iterate(self.rows, self.settings, &mut self.poses);
        }
        let mut m = PassMeasures::default();
        for row in self.rows {
            m.merge(&correct_point(row, self.settings, &mut self.poses, true));
        }
        m
    }

    fn fold(into: &mut PassMeasures, m: &PassMeasures) {
        into.merge(m);
    }
}
