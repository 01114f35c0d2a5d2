//! The coloured position pass of a large island, on one thread or several.
//!
//! Points are coloured greedily in problem order so that no two points of a colour move the
//! same body (immovable bodies never conflict: they are not written), then visited colour by
//! colour; each colour's points are cut into chunks of [`CHUNK`] points, the work items of a
//! phase ([`crate::threads::sync::run_phased`]): an item starts once the earlier colours are done. The
//! pass's measures are minima and maxima, which do not depend on the order they are folded
//! in, so the result is the same bits for any thread count.

use deepcontact_core::math::{Pose, Vector};
use deepcontact_core::{ContactProblem, PositionReport, PositionSettings};

use crate::position::{PassMeasures, PosRow, Poses, correct_point, immovable};
use std::sync::Mutex;

use crate::threads::sync::{Cell3, lock, phase_starts, run_phased};
use crate::threads::z_order::ZOrder;

/// Points per chunk: the unit a thread takes.
pub(crate) const CHUNK: usize = 64;

/// Colours a point may take; points that find none go to one last colour, visited by
/// thread 0 alone in problem order.
const COLOURS: usize = 64;

/// The coloured order of an island's points.
#[derive(Debug, Clone)]
pub(crate) struct Plan {
    /// Points per chunk ([`CHUNK`]).
    pub(crate) chunk: usize,
    /// Point indices, colour by colour (problem order within a colour); the pass's rows are
    /// laid out in this order.
    order: Vec<u32>,
    /// Per non-empty colour: its range in `order`, and whether it is the overflow colour.
    colours: Vec<(std::ops::Range<usize>, bool)>,
    /// Scratch: colour bit mask per body, colour per point.
    body_colours: Vec<u64>,
    point_colours: Vec<u8>,
}

impl Default for Plan {
    fn default() -> Self {
        Self {
            chunk: CHUNK,
            order: Vec::new(),
            colours: Vec::new(),
            body_colours: Vec::new(),
            point_colours: Vec::new(),
        }
    }
}

impl Plan {
    /// Point indices, colour by colour.
    pub(crate) fn order(&self) -> &[u32] {
        &self.order
    }

    /// Colours the points of `problem` (buffers reused).
    pub(crate) fn build(&mut self, problem: &ContactProblem, z: &ZOrder) {
        self.body_colours.clear();
        self.body_colours.resize(problem.bodies.len(), 0);
        self.point_colours.clear();
        let mut counts = [0usize; COLOURS + 1];
        for p in &problem.points {
            let (a, b) = (p.body_a as usize, p.body_b as usize);
            let movable = |i: usize| !immovable(&problem.bodies[i]);
            let used = |i: usize| {
                if movable(i) { self.body_colours[i] } else { 0 }
            };
            let free = !(used(a) | used(b));
            let c = if free == 0 {
                COLOURS
            } else {
                free.trailing_zeros() as usize
            };
            if c != COLOURS {
                for i in [a, b] {
                    if movable(i) {
                        self.body_colours[i] |= 1 << c;
                    }
                }
            }
            counts[c] += 1;
            self.point_colours.push(c as u8);
        }
        // Counting sort by colour, stable.
        let mut offsets = [0usize; COLOURS + 1];
        let mut acc = 0;
        self.colours.clear();
        for (c, (o, n)) in offsets.iter_mut().zip(counts).enumerate() {
            *o = acc;
            if n > 0 {
                self.colours.push((acc..acc + n, c == COLOURS));
            }
            acc += n;
        }
        self.order.clear();
        self.order.resize(problem.points.len(), 0);
        for (k, &c) in self.point_colours.iter().enumerate() {
            self.order[offsets[c as usize]] = k as u32;
            offsets[c as usize] += 1;
        }
        // Each colour (but the overflow, whose order matters) in Z-order of its points, so
        // that a chunk holds neighbours: the points of a colour are independent, their order
        // changes nothing.
        for (range, overflow) in &self.colours {
            if !overflow {
                self.order[range.clone()]
                    .sort_by_cached_key(|&k| z.key(&problem.points[k as usize].point));
            }
        }
    }
}

#[cfg(test)]
impl Plan {
    /// Whether every point appears once and no colour but the overflow moves a body twice.
    pub(crate) fn check(&self, problem: &ContactProblem) -> bool {
        let mut seen = vec![false; problem.points.len()];
        for (range, overflow) in &self.colours {
            let mut bodies = std::collections::HashSet::new();
            for &k in &self.order[range.clone()] {
                if std::mem::replace(&mut seen[k as usize], true) {
                    return false;
                }
                let p = &problem.points[k as usize];
                for i in [p.body_a as usize, p.body_b as usize] {
                    if !overflow && !immovable(&problem.bodies[i]) && !bodies.insert(i) {
                        return false;
                    }
                }
            }
        }
        seen.iter().all(|&s| s)
    }
}

/// The shared poses as the pass sees them.
struct Shared<'a>(&'a [Cell3]);

impl Poses for Shared<'_> {
    #[inline(always)]
    fn get(&self, i: usize) -> Pose {
        let [x, y, angle] = self.0[i].load();
        Pose::new(Vector::new(x, y), angle)
    }

    #[inline(always)]
    fn set(&mut self, i: usize, pose: Pose) {
        self.0[i].store([pose.position.x, pose.position.y, pose.angle]);
    }
}

/// Runs the pass over `rows` (laid out in the order of `plan`, its chunks of `plan.chunk`
/// points) on up to `threads` threads (≥ 1; no more than the widest colour has chunks), as
/// the one-thread loop of [`crate::PgsPositionSolver`] does in problem order: same
/// corrections, same stop rule, same report. Returns the threads it ran on.
pub(crate) fn solve(
    rows: &[PosRow],
    plan: &Plan,
    threads: usize,
    settings: &PositionSettings,
    poses: &mut [Pose],
    report: &mut PositionReport,
) -> usize {
    let chunk = plan.chunk;
    // No more threads than the widest colour has chunks: the others would only wait.
    let widest = plan
        .colours
        .iter()
        .map(|(range, _)| range.len().div_ceil(chunk));
    let threads = threads.min(widest.max().unwrap_or(1)).max(1);
    // Items colour by colour: chunks of points (the overflow colour, which may move a body
    // twice, as one item in order).
    let mut items: Vec<&[PosRow]> = Vec::new();
    let mut counts = Vec::with_capacity(plan.colours.len());
    for (range, overflow) in &plan.colours {
        let before = items.len();
        if *overflow {
            items.push(&rows[range.clone()]);
        } else {
            items.extend(rows[range.clone()].chunks(chunk));
        }
        counts.push(items.len() - before);
    }
    if threads == 1 {
        // The same items in the same order on the calling thread, without shared cells.
        for it in 0..settings.max_iterations {
            let mut all = PassMeasures::default();
            for item in &items {
                for row in *item {
                    all.merge(&correct_point(row, settings, poses, true));
                }
            }
            if all.judge(it, settings, report) {
                break;
            }
        }
        return 1;
    }
    let starts = phase_starts(counts);
    let slots: [Vec<Cell3>; 2] =
        [0, 1].map(|_| (0..items.len()).map(|_| Cell3::default()).collect());
    let shared: Vec<Cell3> = poses
        .iter()
        .map(|p| Cell3::new([p.position.x, p.position.y, p.angle]))
        .collect();
    let passes = Mutex::new(Vec::new());
    let process = |item: usize, parity: usize| {
        let mut poses = Shared(&shared);
        let mut m = PassMeasures::default();
        for row in items[item] {
            m.merge(&correct_point(row, settings, &mut poses, true));
        }
        slots[parity][item].store([m.min_separation, m.max_correction, m.max_impulse]);
    };
    let judge = |it: u32, parity: usize| {
        let mut all = PassMeasures::default();
        for slot in &slots[parity] {
            let [min_separation, max_correction, max_impulse] = slot.load();
            all.merge(&PassMeasures {
                min_separation,
                max_correction,
                max_impulse,
            });
        }
        lock(&passes).push(all);
        all.judge(it, settings, &mut PositionReport::default())
    };
    run_phased(threads, settings.max_iterations, &starts, &process, &judge);
    for (i, pose) in poses.iter_mut().enumerate() {
        *pose = Shared(&shared).get(i);
    }
    // The report as the last judged iteration left it.
    let passes = passes
        .into_inner()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    if let Some((it, last)) = passes.iter().enumerate().next_back() {
        last.judge(it as u32, settings, report);
    }
    threads
}
