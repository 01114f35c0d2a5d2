//! What threads that share one island's sweep synchronise with: three `f64`s in atomics (a
//! velocity, a pose, a set of measures) and a queue of phased work items.

use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering as Mem};

/// Three `f64`s that threads share, as bits in relaxed atomics (plain loads and stores on
/// x86-64 and AArch64): each is written by one thread within a phase, and [`run_phased`]'s
/// completion count (release on completing, acquire before the next phase) orders the writes
/// before the next phase's reads.
#[derive(Debug, Default)]
pub(crate) struct Cell3([AtomicU64; 3]);

impl Cell3 {
    /// A cell holding `v`.
    pub(crate) fn new(v: [f64; 3]) -> Self {
        Self(v.map(|x| AtomicU64::new(x.to_bits())))
    }

    /// The three values.
    #[inline(always)]
    pub(crate) fn load(&self) -> [f64; 3] {
        [0, 1, 2].map(|i| f64::from_bits(self.0[i].load(Mem::Relaxed)))
    }

    /// Sets the three values.
    #[inline(always)]
    pub(crate) fn store(&self, v: [f64; 3]) {
        for (cell, x) in self.0.iter().zip(v) {
            cell.store(x.to_bits(), Mem::Relaxed);
        }
    }
}

pub(crate) use deepcontact_core::threads::{
    AbortOnPanic, effective_threads, lock, on_threads, wait_unless_aborted,
};

/// Runs iterations of phased work on `threads` threads (≥ 1; the caller is one of them).
///
/// An iteration is `phase_starts.last()` items in phases (`phase_starts`: the first item of
/// each phase, ascending from 0, then the item count). Every thread walks the phases in
/// order; each phase is split into one contiguous home segment per thread, and a thread
/// claims the items of its own segment first, then helps with the others' (each segment has
/// its own counter), counts the items it did, and waits until every item of the phase is
/// done. The thread whose count completes an iteration calls `judge(iteration, parity)`
/// (0-based; `parity` = iteration mod 2, which `process(item, parity)` also gets); `true`
/// stops the run. A thread that loses its core holds up at most the one item it claimed and
/// the count of those it did before. What an item computes must
/// not depend on which thread runs it. A panic in `process` or `judge` ends every thread's
/// waits and reaches the caller. Returns the iterations run.
pub(crate) fn run_phased(
    threads: usize,
    max_iterations: u32,
    phase_starts: &[usize],
    process: &(dyn Fn(usize, usize) + Sync),
    judge: &(dyn Fn(u32, usize) -> bool + Sync),
) -> u32 {
    let total = phase_starts.last().copied().unwrap_or(0);
    if total == 0 {
        return 0;
    }
    let phases = phase_starts.len() - 1;
    // Thread t's home segment of phase p: [home(p, t), home(p, t + 1)).
    let home = |p: usize, t: usize| {
        phase_starts[p] + (phase_starts[p + 1] - phase_starts[p]) * t / threads
    };
    // Per thread: where each phase's segment starts in its counter's count of one iteration,
    // and the count of a whole iteration.
    let offsets: Vec<Vec<usize>> = (0..threads)
        .map(|t| {
            let mut acc = 0;
            let mut v: Vec<usize> = (0..phases)
                .map(|p| {
                    let at = acc;
                    acc += home(p, t + 1) - home(p, t);
                    at
                })
                .collect();
            v.push(acc);
            v
        })
        .collect();
    let cursors: Vec<Padded<AtomicUsize>> =
        (0..threads).map(|_| Padded(AtomicUsize::new(0))).collect();
    let (done, judged) = (Padded(AtomicUsize::new(0)), Padded(AtomicUsize::new(0)));
    let stopped = AtomicBool::new(false);
    let aborted = AtomicBool::new(false);
    // Claims one item of segment t in phase p of iteration it, if one is left.
    let claim = |t: usize, it: usize, p: usize| -> Option<usize> {
        let first = it * offsets[t][phases] + offsets[t][p];
        let end = first + home(p, t + 1) - home(p, t);
        let cursor = &cursors[t].0;
        let mut c = cursor.load(Mem::Relaxed);
        while c < end {
            match cursor.compare_exchange_weak(c, c + 1, Mem::Relaxed, Mem::Relaxed) {
                Ok(_) => return Some(home(p, t) + (c - first)),
                Err(now) => c = now,
            }
        }
        None
    };
    let work = |me: usize| {
        let _guard = AbortOnPanic(&aborted);
        for it in 0..max_iterations as usize {
            if it > 0
                && (!wait_unless_aborted(&aborted, || judged.0.load(Mem::Acquire) >= it)
                    || stopped.load(Mem::Relaxed))
            {
                return;
            }
            for (p, &start) in phase_starts[..phases].iter().enumerate() {
                // Every item of the earlier phases done before this phase's first.
                let need = it * total + start;
                if !wait_unless_aborted(&aborted, || done.0.load(Mem::Acquire) >= need) {
                    return;
                }
                let mut mine = 0;
                for k in 0..threads {
                    let t = (me + k) % threads;
                    while let Some(item) = claim(t, it, p) {
                        process(item, it % 2);
                        mine += 1;
                    }
                }
                // A thread's items of the phase counted at once, when none is left to claim:
                // the count's cache line crosses the cores once a thread, not once an item.
                if mine > 0 && done.0.fetch_add(mine, Mem::AcqRel) + mine == (it + 1) * total {
                    if judge(it as u32, it % 2) {
                        stopped.store(true, Mem::Relaxed);
                    }
                    judged.0.store(it + 1, Mem::Release);
                }
            }
        }
    };
    on_threads(0..threads, work);
    judged.0.load(Mem::Acquire) as u32
}

/// A value on cache lines of its own (two lines: adjacent-line prefetch), so that threads
/// that write neighbouring values (counters, locks, measures) do not contend for one line.
#[repr(align(128))]
#[derive(Debug, Default)]
pub(crate) struct Padded<T>(pub(crate) T);

/// The first items of each phase, from each phase's item count: `[0, n0, n0 + n1, …]`.
pub(crate) fn phase_starts(counts: impl IntoIterator<Item = usize>) -> Vec<usize> {
    let mut starts = vec![0];
    for n in counts {
        starts.push(starts.last().copied().unwrap_or(0) + n);
    }
    starts
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Mutex;

    #[test]
    fn phased_items_run_in_phase_order_and_the_judge_stops_the_run() {
        // Three phases of 5, 1 and 7 items. An item of phase p finds its iteration i from the
        // items of p started before it, then checks that every earlier phase of i is
        // finished and no later phase of i has started, and that it got i's parity.
        let starts = phase_starts([5, 1, 7]);
        let sizes = [5, 1, 7];
        for threads in 1..=4 {
            let started: Vec<AtomicUsize> = (0..3).map(|_| AtomicUsize::new(0)).collect();
            let finished: Vec<AtomicUsize> = (0..3).map(|_| AtomicUsize::new(0)).collect();
            let judged = Mutex::new(Vec::new());
            let process = |item: usize, parity: usize| {
                let p = starts.partition_point(|&s| s <= item) - 1;
                let i = started[p].fetch_add(1, Mem::SeqCst) / sizes[p];
                assert_eq!(parity, i % 2);
                // Long enough that another thread could run ahead if the queue let it.
                std::thread::yield_now();
                for q in 0..3 {
                    if q < p {
                        assert_eq!(finished[q].load(Mem::SeqCst), (i + 1) * sizes[q]);
                    } else if q > p {
                        assert_eq!(started[q].load(Mem::SeqCst), i * sizes[q]);
                    }
                }
                finished[p].fetch_add(1, Mem::SeqCst);
            };
            let judge = |it: u32, parity: usize| {
                assert_eq!(it as usize % 2, parity);
                judged.lock().unwrap().push(it);
                it == 6
            };
            let ran = run_phased(threads, 100, &starts, &process, &judge);
            assert_eq!(ran, 7, "{threads} threads");
            assert_eq!(*judged.lock().unwrap(), (0..7).collect::<Vec<_>>());
            for (f, n) in finished.iter().zip(sizes) {
                assert_eq!(f.load(Mem::SeqCst), 7 * n, "every item once per iteration");
            }
            // The cap ends a run that the judge never stops.
            assert_eq!(
                run_phased(threads, 3, &starts, &|_, _| {}, &|_, _| false),
                3
            );
        }
    }

    #[test]
    fn a_panicking_item_fails_the_run_instead_of_hanging_it() {
        for threads in 1..=3 {
            let run = std::panic::catch_unwind(|| {
                run_phased(
                    threads,
                    10,
                    &phase_starts([3, 4]),
                    &|item, _| assert_ne!(item, 5, "item 5 fails"),
                    &|_, _| false,
                )
            });
            assert!(run.is_err(), "{threads} threads");
        }
    }

    #[test]
    fn a_slow_thread_leaves_the_rest_of_its_segment_to_a_faster_one() {
        // One phase of 8 items on 2 threads. In every iteration the caller's first item
        // waits until the spawned thread has started an item, and the spawned thread's item
        // waits until the caller has run 7: so the spawned thread holds its first item (4)
        // while the caller runs its own 4 and the 3 left of the spawned thread's segment.
        // Nothing here depends on timing; the deadlines only end a wait that the queue
        // would never end (a caller that does not help), and the test then fails.
        let caller = std::thread::current().id();
        let deadline = std::time::Duration::from_secs(2);
        let wait = |ready: &dyn Fn() -> bool| {
            let t0 = std::time::Instant::now();
            while !ready() && t0.elapsed() < deadline {
                std::thread::yield_now();
            }
        };
        let ran_by_caller: Vec<Vec<AtomicBool>> = (0..3)
            .map(|_| (0..8).map(|_| AtomicBool::new(false)).collect())
            .collect();
        let (caller_ran, spawned_started): (Vec<AtomicUsize>, Vec<AtomicBool>) = (
            (0..3).map(|_| AtomicUsize::new(0)).collect(),
            (0..3).map(|_| AtomicBool::new(false)).collect(),
        );
        let iteration = AtomicUsize::new(0);
        let process = |item: usize, _: usize| {
            let it = iteration.load(Mem::SeqCst);
            let mine = std::thread::current().id() == caller;
            if mine {
                wait(&|| spawned_started[it].load(Mem::SeqCst));
                caller_ran[it].fetch_add(1, Mem::SeqCst);
            } else {
                spawned_started[it].store(true, Mem::SeqCst);
                wait(&|| caller_ran[it].load(Mem::SeqCst) >= 7);
            }
            ran_by_caller[it][item].store(mine, Mem::SeqCst);
        };
        let judge = |it: u32, _: usize| {
            iteration.store(it as usize + 1, Mem::SeqCst);
            false
        };
        assert_eq!(run_phased(2, 3, &[0, 8], &process, &judge), 3);
        for (it, items) in ran_by_caller.iter().enumerate() {
            let by: Vec<bool> = items.iter().map(|b| b.load(Mem::SeqCst)).collect();
            let expected = [true, true, true, true, false, true, true, true];
            assert_eq!(
                by, expected,
                "iteration {it}: who ran each item (true: the caller)"
            );
        }
    }
}
