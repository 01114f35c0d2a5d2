//! Sweeping the domains of a [`Partition`], on one thread or several: the loop that the domain
//! plans of the velocity sweep and of the position pass share.
//!
//! An iteration sweeps the even domains, then the odd ones. Two domains of one parity share no
//! movable body, so the domains of a parity are swept side by side on threads, each on memory
//! of its own; each thread takes a band of neighbouring domains. A body of a seam between two
//! domains has one shared value, which a domain takes before its sweep and leaves after it. An
//! odd domain waits for its two even neighbours of the same iteration (the domains it shares
//! seams with), and the next iteration waits for the stop rule, so the hand-overs happen in the
//! order of all even domains, then all odd ones. That is one Gauss-Seidel order of all
//! constraints whatever the threads, and the domains' measures are folded in sweep order, so the
//! result is bit-identical for any thread count.

use std::sync::atomic::{AtomicBool, AtomicU32, AtomicUsize, Ordering as Mem};
use std::sync::{Mutex, MutexGuard, PoisonError};

use crate::threads::partition::Partition;
use crate::threads::sync::{AbortOnPanic, Cell3, Padded, wait_until};

/// One domain of a partition as the loop sweeps it.
pub(crate) trait Part: Send {
    /// What a sweep measures, folded over the domains in sweep order.
    type Measures: Copy + Default + Send;
    /// The value of the body in `slot` (a velocity `[vx, vy, ω]`, a pose `[x, y, angle]`).
    fn get(&self, slot: u32) -> [f64; 3];
    /// Sets the value of the body in `slot`.
    fn set(&mut self, slot: u32, value: [f64; 3]);
    /// One sweep over the domain's constraints.
    fn sweep(&mut self) -> Self::Measures;
    /// Folds `m` (of a domain swept after those of `into`) into `into`.
    fn fold(into: &mut Self::Measures, m: &Self::Measures);
}

/// The value behind `m` (a panicked sweep has already made the solve fail).
fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// The domains of `n` in sweep order: the even ones, then the odd ones.
fn sweep_order(n: usize) -> impl Iterator<Item = usize> {
    (0..n).step_by(2).chain((1..n).step_by(2))
}

/// Threads that can work on `n` domains side by side: no more than the even domains.
fn useful_threads(threads: usize, n: usize) -> usize {
    threads.clamp(1, n.div_ceil(2).max(1))
}

/// Sweeps `parts` (the domains of `partition`) on up to `threads` threads (≥ 1; no more than
/// [`useful_threads`]) until `stop(iteration, measures)` (0-based) holds or `max_iterations`
/// have run. Returns every iteration's measures, folded in sweep order, and the threads it
/// ran on; the parts end with the seams' last values.
pub(crate) fn sweep_parts<P: Part>(
    parts: &mut [P],
    partition: &Partition,
    threads: usize,
    max_iterations: u32,
    stop: &(dyn Fn(u32, &P::Measures) -> bool + Sync),
) -> (Vec<P::Measures>, usize) {
    let n = parts.len();
    let (links, ranges) = (&partition.links, &partition.link_ranges);
    // The seams' values, from the domains that hold them (both hold the island's value).
    let shared: Vec<Cell3> = (0..partition.shared.len())
        .map(|_| Cell3::default())
        .collect();
    for (part, range) in parts.iter().zip(ranges) {
        for &(s, k) in &links[range.clone()] {
            shared[k as usize].store(part.get(s));
        }
    }
    let order: Vec<usize> = sweep_order(n).collect();
    // Each domain's lock and measures on cache lines of their own: the threads that sweep
    // neighbouring domains do not pass lines back and forth.
    let parts: Vec<Padded<Mutex<&mut P>>> =
        parts.iter_mut().map(|p| Padded(Mutex::new(p))).collect();
    let slots: [Vec<Padded<Mutex<P::Measures>>>; 2] =
        [0, 1].map(|_| (0..n).map(|_| Padded::default()).collect());
    let done = Mutex::new(Vec::with_capacity(max_iterations.min(4096) as usize));
    // Each domain's place in the sweep order: its measures' slot.
    let mut item_of = vec![0; n];
    for (item, &p) in order.iter().enumerate() {
        item_of[p] = item;
    }
    let process = |p: usize, parity: usize| {
        let mut part = lock(&parts[p].0);
        let links = &links[ranges[p].clone()];
        for &(s, k) in links {
            part.set(s, shared[k as usize].load());
        }
        let m = part.sweep();
        for &(s, k) in links {
            shared[k as usize].store(part.get(s));
        }
        *lock(&slots[parity][item_of[p]].0) = m;
    };
    let judge = |it: u32, parity: usize| {
        let mut all = P::Measures::default();
        for slot in &slots[parity] {
            P::fold(&mut all, &lock(&slot.0));
        }
        lock(&done).push(all);
        stop(it, &all)
    };
    let threads = useful_threads(threads, n);
    run_banded(threads, n, max_iterations, &process, &judge);
    // The seams' last values into every domain that holds them.
    for (part, range) in parts.iter().zip(ranges) {
        let mut part = lock(&part.0);
        for &(s, k) in &links[range.clone()] {
            part.set(s, shared[k as usize].load());
        }
    }
    (
        done.into_inner().unwrap_or_else(PoisonError::into_inner),
        threads,
    )
}

/// The order in which a thread sweeps its band `lo..hi` of the `n` domains within an
/// iteration: its even domains, those next to another band's domain first (that band's odd
/// domain waits for them), then its odd ones, those next to another band's domain last (they
/// wait for that band's even domain).
fn band_order(lo: usize, hi: usize, n: usize) -> Vec<usize> {
    let next_to_another = |p: usize| (p >= 1 && p - 1 < lo) || (p + 1 < n && p + 1 >= hi);
    let mut even: Vec<usize> = (lo..hi).filter(|p| p % 2 == 0).collect();
    let mut odd: Vec<usize> = (lo..hi).filter(|p| p % 2 == 1).collect();
    even.sort_by_key(|&p| (!next_to_another(p), p));
    odd.sort_by_key(|&p| (next_to_another(p), p));
    even.extend(odd);
    even
}

/// Runs the iterations of `n` domains (a partition's: domain `p` shares bodies with `p − 1`
/// and `p + 1` only) on `threads` threads (≥ 1; the caller is one of them), each thread a band
/// of neighbouring domains. An iteration sweeps the even domains, then the odd ones; an odd
/// domain waits for its two neighbours (even) of the same iteration only, not for every even
/// domain, and the even domains of the next iteration wait for the stop rule. The thread that
/// completes an iteration's last domain calls `judge(iteration, parity)` (0-based; `parity` =
/// iteration mod 2, which `process(domain, parity)` also gets); `true` stops the run. That is
/// the order of sweeping all even domains, then all odd ones, so what `process` computes is the
/// same as in that order. Returns the iterations run.
fn run_banded(
    threads: usize,
    n: usize,
    max_iterations: u32,
    process: &(dyn Fn(usize, usize) + Sync),
    judge: &(dyn Fn(u32, usize) -> bool + Sync),
) -> u32 {
    if n == 0 {
        return 0;
    }
    let threads = threads.clamp(1, n);
    // Per domain, the iterations it has completed.
    let swept: Vec<Padded<AtomicU32>> = (0..n).map(|_| Padded::default()).collect();
    let (finished, judged) = (Padded(AtomicUsize::new(0)), Padded(AtomicUsize::new(0)));
    let stopped = AtomicBool::new(false);
    // Set when a thread panics: the others stop waiting, and the scope passes the panic on.
    let aborted = AtomicBool::new(false);
    let work = |t: usize| {
        let _guard = AbortOnPanic(&aborted);
        let order = band_order(n * t / threads, n * (t + 1) / threads, n);
        let wait = |ready: &dyn Fn() -> bool| {
            wait_until(|| aborted.load(Mem::Acquire) || ready());
            !aborted.load(Mem::Acquire)
        };
        for it in 0..max_iterations as usize {
            if it > 0 {
                if !wait(&|| judged.0.load(Mem::Acquire) >= it) {
                    return;
                }
                if stopped.load(Mem::Relaxed) {
                    return;
                }
            }
            for &p in &order {
                if p % 2 == 1 {
                    // The even neighbours of this iteration (an even domain of the next one
                    // waits for the stop rule, so for every domain of this one).
                    for q in [p - 1, p + 1] {
                        if let Some(q) = swept.get(q)
                            && !wait(&|| q.0.load(Mem::Acquire) as usize > it)
                        {
                            return;
                        }
                    }
                }
                process(p, it % 2);
                swept[p].0.store(it as u32 + 1, Mem::Release);
                if finished.0.fetch_add(1, Mem::AcqRel) + 1 == (it + 1) * n {
                    if judge(it as u32, it % 2) {
                        stopped.store(true, Mem::Relaxed);
                    }
                    judged.0.store(it + 1, Mem::Release);
                }
            }
        }
    };
    std::thread::scope(|scope| {
        for t in 1..threads {
            let work = &work;
            scope.spawn(move || work(t));
        }
        work(0);
    });
    judged.0.load(Mem::Acquire) as u32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn banded_domains_run_after_their_neighbours_and_the_judge_stops_the_run() {
        // Seven domains. An odd domain finds its even neighbours done with its iteration; an
        // even domain finds its odd neighbours done with the iteration before and not started
        // on its own; every domain once an iteration; the judge sees every domain done.
        let n = 7;
        for threads in 1..=4 {
            let done: Vec<AtomicUsize> = (0..n).map(|_| AtomicUsize::new(0)).collect();
            let judged = Mutex::new(Vec::new());
            let process = |p: usize, parity: usize| {
                let i = done[p].load(Mem::SeqCst);
                assert_eq!(parity, i % 2);
                // Long enough that another thread could run ahead if the waits let it.
                std::thread::yield_now();
                for q in [p.wrapping_sub(1), p + 1] {
                    let Some(q) = done.get(q) else { continue };
                    let want = if p % 2 == 1 { i + 1 } else { i };
                    assert_eq!(q.load(Mem::SeqCst), want, "domain {p}, iteration {i}");
                }
                done[p].fetch_add(1, Mem::SeqCst);
            };
            let judge = |it: u32, parity: usize| {
                assert_eq!(it as usize % 2, parity);
                for d in &done {
                    assert_eq!(d.load(Mem::SeqCst), it as usize + 1);
                }
                lock(&judged).push(it);
                it == 5
            };
            assert_eq!(run_banded(threads, n, 100, &process, &judge), 6);
            assert_eq!(*lock(&judged), (0..6).collect::<Vec<_>>());
            // The cap ends a run that the judge never stops.
            assert_eq!(run_banded(threads, n, 3, &|_, _| {}, &|_, _| false), 3);
        }
    }

    #[test]
    fn a_panicking_domain_fails_the_run_instead_of_hanging_it() {
        for threads in 1..=3 {
            let run = std::panic::catch_unwind(|| {
                run_banded(
                    threads,
                    6,
                    10,
                    &|p, _| assert_ne!(p, 3, "domain 3 fails"),
                    &|_, _| false,
                )
            });
            assert!(run.is_err(), "{threads} threads");
        }
    }

    #[test]
    fn a_band_sweeps_its_even_domains_first_those_at_its_ends_before_the_rest() {
        // Two bands of 16: odd 7 waits for even 8.
        assert_eq!(band_order(0, 8, 16), [0, 2, 4, 6, 1, 3, 5, 7]);
        assert_eq!(band_order(8, 16, 16), [8, 10, 12, 14, 9, 11, 13, 15]);
        // Three bands: odd 5 waits for even 4, even 10 is waited for by odd 9.
        assert_eq!(band_order(0, 5, 16), [4, 0, 2, 1, 3]);
        assert_eq!(band_order(5, 10, 16), [6, 8, 7, 5, 9]);
        assert_eq!(band_order(10, 16, 16), [10, 12, 14, 11, 13, 15]);
        // One band.
        assert_eq!(band_order(0, 5, 5), [0, 2, 4, 1, 3]);
    }
}
