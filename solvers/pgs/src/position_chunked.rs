//! The coloured position pass of a large island, on one thread or several.
//!
//! Points are coloured greedily in problem order so that no two points of a colour move the
//! same body (immovable bodies never conflict: they are not written), then visited colour by
//! colour; each colour's points are cut into chunks of [`CHUNK`] points and thread `t` of
//! `T` takes a contiguous run of them. A barrier after each colour makes its corrections
//! visible to the next. The pass's measures are minima and maxima, which do not depend on
//! the order they are folded in, so every thread reaches the same stop decision and the
//! result is the same bits for any `T`.

use deepcontact_core::math::{Pose, Vector};
use deepcontact_core::{ContactProblem, PositionReport, PositionSettings};

use crate::position::{PassMeasures, PosRow, Poses, correct_point, immovable};
use crate::sync::{Cell3, SpinBarrier, owner};

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
    pub(crate) fn build(&mut self, problem: &ContactProblem) {
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

/// What every thread shares.
struct Common<'a> {
    settings: &'a PositionSettings,
    /// Per colour, per thread: the rows it corrects, in order.
    work: Vec<Vec<&'a [PosRow]>>,
    poses: Vec<Cell3>,
    /// Per iteration parity, per thread: its measures (min separation, max correction, max
    /// impulse).
    slots: [Vec<Cell3>; 2],
    barrier: SpinBarrier,
}

/// Runs the pass over `rows` (laid out in the order of `plan`, its chunks of `plan.chunk`
/// points) on `threads`
/// threads (≥ 1; fewer when no colour has that many chunks), as the one-thread loop
/// of [`crate::PgsPositionSolver`] does in problem order: same corrections, same stop rule,
/// same report.
pub(crate) fn solve(
    rows: &[PosRow],
    plan: &Plan,
    threads: usize,
    settings: &PositionSettings,
    poses: &mut [Pose],
    report: &mut PositionReport,
) {
    let chunk = plan.chunk;
    // No more threads than the widest colour has chunks: the others would only wait.
    let widest = plan
        .colours
        .iter()
        .map(|(range, _)| range.len().div_ceil(chunk));
    let threads = threads.min(widest.max().unwrap_or(1)).max(1);
    let work = plan
        .colours
        .iter()
        .map(|(range, overflow)| {
            let points = &rows[range.clone()];
            let mut per_thread = vec![&points[..0]; threads];
            if *overflow {
                per_thread[0] = points;
            } else {
                // Contiguous runs of whole chunks per thread.
                let n_chunks = points.len().div_ceil(chunk);
                let first = |t: usize| {
                    (0..n_chunks)
                        .find(|&j| owner(j, n_chunks, threads) >= t)
                        .map_or(points.len(), |j| j * chunk)
                };
                for (t, run) in per_thread.iter_mut().enumerate() {
                    *run = &points[first(t)..first(t + 1)];
                }
            }
            per_thread
        })
        .collect();
    let common = Common {
        settings,
        work,
        poses: poses
            .iter()
            .map(|p| Cell3::new([p.position.x, p.position.y, p.angle]))
            .collect(),
        slots: [
            (0..threads).map(|_| Cell3::default()).collect(),
            (0..threads).map(|_| Cell3::default()).collect(),
        ],
        barrier: SpinBarrier::new(threads),
    };
    std::thread::scope(|scope| {
        for t in 1..threads {
            let common = &common;
            scope.spawn(move || worker(common, t, &mut PositionReport::default()));
        }
        worker(&common, 0, report);
    });
    for (i, pose) in poses.iter_mut().enumerate() {
        *pose = Shared(&common.poses).get(i);
    }
}

/// One thread's loop: per iteration, per colour its points then a barrier (its measures
/// published before the last), then the fold of every thread's measures and the verdict.
fn worker(common: &Common<'_>, t: usize, report: &mut PositionReport) {
    let mut poses = Shared(&common.poses);
    let mut epoch = 0;
    for it in 0..common.settings.max_iterations {
        let slots = &common.slots[it as usize % 2];
        let mut mine = PassMeasures::default();
        let last = common.work.len().saturating_sub(1);
        for (c, per_thread) in common.work.iter().enumerate() {
            for row in per_thread[t] {
                mine.add(&correct_point(row, common.settings, &mut poses, true));
            }
            if c == last {
                slots[t].store([mine.min_separation, mine.max_correction, mine.max_impulse]);
            }
            common.barrier.wait(&mut epoch);
        }
        let mut all = PassMeasures::default();
        for slot in slots {
            let [min_separation, max_correction, max_impulse] = slot.load();
            all.merge(&PassMeasures {
                min_separation,
                max_correction,
                max_impulse,
            });
        }
        if all.judge(it, common.settings, report) {
            return;
        }
    }
}
