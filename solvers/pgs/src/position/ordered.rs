//! The plain plan's pass (points in problem order) on several threads, with the bits of one.
//!
//! The island's movable bodies are cut into slabs, one a thread; a point belongs to
//! the slab of its first movable body, and each thread visits its own points on a copy of the
//! poses in the island's wave order ([`Waves`]: waves of points that share no movable body,
//! which keeps every body's corrections in problem order), four at a time where a point moves
//! no body of another thread. A movable body that points of two threads move (a seam
//! body) lives in a shared cell with a count of the corrections applied to it. Before a
//! point corrects a seam body it waits until the count equals the number of points that
//! correct that body before it in problem order (this iteration's, plus every earlier
//! iteration's), reads the pose from the cell, corrects it, writes it back and counts one
//! more. So every body sees the corrections of the one-thread order in that order, and every
//! point reads the poses that order gives it: the same bits for any thread count.
//!
//! No thread waits forever: all threads follow one order (the waves of the whole island, a
//! wave's points in any order), and the unfinished point earliest in it waits for nothing
//! (every point that shares a body with it and comes before it in problem order is in an
//! earlier wave, done), so some thread can always go on. The threads meet once an iteration,
//! where the last to arrive folds the measures and judges the stop rule.

use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering as Mem};
use std::sync::{Mutex, PoisonError};

use deepcontact_core::math::{Pose, Vector};
use deepcontact_core::{PositionReport, PositionSettings};

use crate::position::waves::{Waves, levels};
use crate::position::{CachedRotations, PassMeasures, PosRow, Rotation, correct_point};
use crate::threads::sync::{AbortOnPanic, Cell3, Padded, lock, on_threads, wait_unless_aborted};

/// Islands of at least this many points run the ordered plan when more than one thread is
/// asked for and the island is below the domain plan's size; below it a thread's share is
/// too short to pay for the waits (docs/PERFORMANCE.md: from 64 or 128 points the 100-body
/// pile's pass got slower on two threads).
pub(crate) const ORDERED_MIN_POINTS: usize = 256;

/// The thread of each movable body (`u32::MAX` for an immovable one): slabs holding about as
/// many movable bodies each, ties broken by body index.
fn slabs(rows: &[PosRow], poses: &[Pose], threads: usize) -> Vec<u32> {
    let mut movable = vec![false; poses.len()];
    for row in rows {
        for (b, moves) in row.ends() {
            movable[b as usize] |= moves;
        }
    }
    let mut order: Vec<u32> = (0..poses.len() as u32)
        .filter(|&b| movable[b as usize])
        .collect();
    // Slabs across the longer side of the bodies' bounds, so that the seams run along the
    // shorter one: fewer seam bodies to hand over (docs/PERFORMANCE.md measures both cuts).
    let (lo, hi) = order.iter().fold(
        (
            Vector::repeat(f64::INFINITY),
            Vector::repeat(f64::NEG_INFINITY),
        ),
        |(lo, hi), &b| {
            let c = poses[b as usize].position;
            (lo.inf(&c), hi.sup(&c))
        },
    );
    let along_x = hi.x - lo.x >= hi.y - lo.y;
    let key = |p: &Pose| if along_x { p.position.x } else { p.position.y };
    order.sort_by(|&a, &b| {
        key(&poses[a as usize])
            .total_cmp(&key(&poses[b as usize]))
            .then(a.cmp(&b))
    });
    let mut owner = vec![u32::MAX; poses.len()];
    for (k, &b) in order.iter().enumerate() {
        owner[b as usize] = (k * threads / order.len()) as u32;
    }
    owner
}

/// A seam body's cell: its pose and the count of corrections applied to it.
#[derive(Debug, Default)]
struct Seam {
    pose: Cell3,
    count: AtomicU64,
}

/// What a point needs to know of one of its bodies that is a seam body.
#[derive(Debug, Clone, Copy)]
struct SeamUse {
    /// The body (island index).
    body: u32,
    /// Its seam cell.
    cell: u32,
    /// Corrections of this body before this point in one iteration of problem order.
    before: u64,
}

/// The ordered plan of one island: each thread's points and their seam bodies.
#[derive(Debug, Default)]
struct Plan {
    /// Per thread, its points (indices into the rows), in problem order.
    points: Vec<Vec<u32>>,
    /// Per thread, its points in the island's waves ([`Waves`]), those with a seam body one
    /// at a time.
    waves: Vec<Waves>,
    /// Per point, the seam uses of its bodies (up to two).
    uses: Vec<[Option<SeamUse>; 2]>,
    /// Per seam cell, its body and how many points correct it in one iteration.
    seams: Vec<(u32, u64)>,
    /// Per body, the one thread that moves it (`u32::MAX`: none, or a seam body).
    mover: Vec<u32>,
}

impl Plan {
    fn build(rows: &[PosRow], poses: &[Pose], threads: usize) -> Self {
        let owner = slabs(rows, poses, threads);
        let row_owner = |row: &PosRow| {
            row.ends()
                .iter()
                .find(|&&(_, moves)| moves)
                .map_or(0, |&(b, _)| owner[b as usize])
        };
        // A body is a seam body when points of two threads move it.
        const NONE: u32 = u32::MAX;
        let mut first_thread = vec![NONE; poses.len()];
        let mut seam = vec![false; poses.len()];
        for row in rows {
            let t = row_owner(row);
            for (b, moves) in row.ends() {
                let f = &mut first_thread[b as usize];
                if !moves {
                    continue;
                }
                if *f == NONE {
                    *f = t;
                } else if *f != t {
                    seam[b as usize] = true;
                }
            }
        }
        let mut cell_of = vec![NONE; poses.len()];
        let mut plan = Plan {
            points: vec![Vec::new(); threads],
            waves: Vec::with_capacity(threads),
            uses: Vec::with_capacity(rows.len()),
            seams: Vec::new(),
            mover: first_thread
                .iter()
                .zip(&seam)
                .map(|(&t, &s)| if s { NONE } else { t })
                .collect(),
        };
        for (k, row) in rows.iter().enumerate() {
            plan.points[row_owner(row) as usize].push(k as u32);
            let mut uses = [None, None];
            for (slot, (b, moves)) in uses.iter_mut().zip(row.ends()) {
                if !(moves && seam[b as usize]) {
                    continue;
                }
                if cell_of[b as usize] == NONE {
                    cell_of[b as usize] = plan.seams.len() as u32;
                    plan.seams.push((b, 0));
                }
                let cell = cell_of[b as usize];
                let count = &mut plan.seams[cell as usize].1;
                *slot = Some(SeamUse {
                    body: b,
                    cell,
                    before: *count,
                });
                *count += 1;
            }
            plan.uses.push(uses);
        }
        // The waves of the whole island, so that every thread visits its points in one order
        // that all threads share: the unfinished point earliest in it waits for nothing. With
        // a negative zero on an immovable body, problem order (a wave a point), one at a time.
        let (mut latest, mut wave_of) = (Vec::new(), Vec::new());
        let in_waves = levels(rows, poses, &mut latest, &mut wave_of);
        if !in_waves {
            wave_of = (1..=rows.len() as u32).collect();
        }
        for points in &plan.points {
            let mut waves = Waves::default();
            waves.group(rows, &wave_of, points.iter().copied(), |k| {
                !in_waves
                    || rows[k as usize].remeasure
                    || plan.uses[k as usize].iter().any(Option::is_some)
            });
            plan.waves.push(waves);
        }
        plan
    }
}

/// Runs the pass over `rows` (problem order) on `threads` threads (≥ 2) under the stop rule
/// of `settings`, writing the poses and the report as the one-thread loop would. Returns the
/// threads it ran on.
pub(crate) fn solve(
    rows: &[PosRow],
    threads: usize,
    settings: &PositionSettings,
    poses: &mut [Pose],
    report: &mut PositionReport,
) -> usize {
    let plan = Plan::build(rows, poses, threads);
    let seams: Vec<Padded<Seam>> = plan
        .seams
        .iter()
        .map(|&(b, _)| {
            let p = poses[b as usize];
            Padded(Seam {
                pose: Cell3::new([p.position.x, p.position.y, p.angle]),
                count: AtomicU64::new(0),
            })
        })
        .collect();
    let measures: Vec<Mutex<PassMeasures>> = (0..threads)
        .map(|_| Mutex::new(PassMeasures::default()))
        .collect();
    let shared_report = Mutex::new(PositionReport::default());
    let (arrived, released) = (Padded(AtomicUsize::new(0)), Padded(AtomicUsize::new(0)));
    let stopped = AtomicBool::new(false);
    // Set when a thread panics: the others stop waiting, and the scope passes the panic on.
    let aborted = AtomicBool::new(false);
    let start: &[Pose] = poses;
    let work = |t: usize| -> Vec<Pose> {
        let _guard = AbortOnPanic(&aborted);
        let mut local = start.to_vec();
        let mut rotations = vec![Rotation::default(); local.len()];
        let mut own = CachedRotations {
            poses: &mut local,
            rotations: &mut rotations,
        };
        for it in 0..settings.max_iterations as usize {
            let single = |k: u32, own: &mut CachedRotations<'_>| {
                let uses = &plan.uses[k as usize];
                for u in uses.iter().flatten() {
                    let cell = &seams[u.cell as usize].0;
                    let want = it as u64 * plan.seams[u.cell as usize].1 + u.before;
                    if !wait_unless_aborted(&aborted, || cell.count.load(Mem::Acquire) == want) {
                        return None;
                    }
                    let [x, y, angle] = cell.pose.load();
                    own.poses[u.body as usize] = Pose::new(Vector::new(x, y), angle);
                }
                let m = correct_point(&rows[k as usize], settings, own, true);
                for u in uses.iter().flatten() {
                    let cell = &seams[u.cell as usize].0;
                    let p = own.poses[u.body as usize];
                    cell.pose.store([p.position.x, p.position.y, p.angle]);
                    cell.count.fetch_add(1, Mem::Release);
                }
                Some(m)
            };
            let Some(m) = plan.waves[t].iterate_with(settings, &mut own, single) else {
                return local;
            };
            *lock(&measures[t]) = m;
            if arrived.0.fetch_add(1, Mem::AcqRel) + 1 == (it + 1) * threads {
                if judge(&measures, it as u32, settings, &mut lock(&shared_report)) {
                    stopped.store(true, Mem::Relaxed);
                }
                released.0.store(it + 1, Mem::Release);
            } else if !wait_unless_aborted(&aborted, || released.0.load(Mem::Acquire) > it) {
                return local;
            }
            if stopped.load(Mem::Relaxed) {
                break;
            }
        }
        local
    };
    let mut locals: Vec<Vec<Pose>> = vec![Vec::new(); threads];
    on_threads(locals.iter_mut().enumerate(), |(t, local)| *local = work(t));
    write_back(&plan, &seams, &locals, poses);
    *report = shared_report
        .into_inner()
        .unwrap_or_else(PoisonError::into_inner);
    threads
}

/// The threads' measures of iteration `it` (0-based) folded in thread order and judged into
/// `report`: whether the pass stops.
fn judge(
    measures: &[Mutex<PassMeasures>],
    it: u32,
    settings: &PositionSettings,
    report: &mut PositionReport,
) -> bool {
    let mut all = PassMeasures::default();
    for slot in measures {
        all.merge(&lock(slot));
    }
    all.judge(it, settings, report)
}

/// Each body's pose from the copy of the thread that moved it, a seam body's from its cell.
fn write_back(plan: &Plan, seams: &[Padded<Seam>], locals: &[Vec<Pose>], poses: &mut [Pose]) {
    for (b, pose) in poses.iter_mut().enumerate() {
        if let Some(local) = locals.get(plan.mover[b] as usize) {
            *pose = local[b];
        }
    }
    for (&(b, _), seam) in plan.seams.iter().zip(seams) {
        let [x, y, angle] = seam.0.pose.load();
        poses[b as usize] = Pose::new(Vector::new(x, y), angle);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::position::tests::pile_problem;

    #[test]
    fn ordered_plan_on_two_to_four_threads_has_the_bits_of_one_in_waves() {
        let (problem, start) = pile_problem();
        let settings = PositionSettings {
            max_iterations: 60,
            ..PositionSettings::default()
        };
        let rows: Vec<PosRow> = (0..problem.points.len())
            .map(|k| PosRow::new(&problem, k, &settings))
            .collect();
        // One thread: the plain plan's loop.
        let mut one = start.clone();
        let mut rotations = vec![Rotation::default(); one.len()];
        let mut want_report = PositionReport::default();
        {
            let mut poses = CachedRotations {
                poses: &mut one,
                rotations: &mut rotations,
            };
            for it in 0..settings.max_iterations {
                let mut m = PassMeasures::default();
                for row in &rows {
                    m.merge(&correct_point(row, &settings, &mut poses, false));
                }
                if m.judge(it, &settings, &mut want_report) {
                    break;
                }
            }
        }
        assert!(want_report.iterations > 3, "{want_report:?}");
        let bits = |poses: &[Pose]| -> Vec<u64> {
            poses
                .iter()
                .flat_map(|p| [p.position.x, p.position.y, p.angle].map(f64::to_bits))
                .collect()
        };
        for threads in 2..=4 {
            // Every thread has points and some bodies are seams: the waits are exercised.
            let plan = Plan::build(&rows, &start, threads);
            assert!(
                plan.points.iter().all(|p| p.len() > 10),
                "{:?}",
                plan.points
            );
            assert!(plan.seams.len() >= threads, "{} seams", plan.seams.len());
            // Every thread corrects points four at a time; on two, half its points or more.
            for (points, waves) in plan.points.iter().zip(&plan.waves) {
                assert!(
                    waves.batched() > 0 && (threads > 2 || 2 * waves.batched() >= points.len()),
                    "{} of {}",
                    waves.batched(),
                    points.len()
                );
            }
            let mut poses = start.clone();
            let mut report = PositionReport::default();
            solve(&rows, threads, &settings, &mut poses, &mut report);
            assert_eq!(bits(&poses), bits(&one), "{threads} threads");
            assert_eq!(report.iterations, want_report.iterations);
            assert_eq!(
                report.min_separation.to_bits(),
                want_report.min_separation.to_bits()
            );
            assert_eq!(
                report.max_correction.to_bits(),
                want_report.max_correction.to_bits()
            );
        }
    }
}
