//! Sweeping the domains of a [`Partition`], on one thread or several: the loop that the domain
//! plans of the velocity sweep and of the position pass share.
//!
//! An iteration sweeps the even domains, then the odd ones. Two domains of one parity share no
//! movable body, so the domains of a phase are swept side by side on threads, each on memory of
//! its own, and threads take them from a queue (a thread that runs slower takes fewer). A
//! body of a seam between two domains has one shared value, which a domain takes before its sweep
//! and leaves after it; the phases order those hand-overs. That is one Gauss-Seidel order of
//! all constraints whatever the threads, and the domains' measures are folded in sweep order,
//! so the result is bit-identical for any thread count. One thread runs the same order in a
//! plain loop ([`alone`]).

use std::sync::{Mutex, PoisonError};

use crate::threads::partition::Partition;
use crate::threads::sync::{Cell3, Padded, lock, phase_starts, run_phased};

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

/// The domains of `n` in sweep order: the even ones, then the odd ones.
pub(crate) fn sweep_order(n: usize) -> impl Iterator<Item = usize> {
    (0..n).step_by(2).chain((1..n).step_by(2))
}

/// Threads that can work on `n` domains side by side: no more than the even domains.
pub(crate) fn useful_threads(threads: usize, n: usize) -> usize {
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
    let seams = seam_values(parts, partition);
    let order: Vec<usize> = sweep_order(n).collect();
    let threads = useful_threads(threads, n);
    if threads == 1 {
        return (
            alone(parts, partition, seams, &order, max_iterations, stop),
            1,
        );
    }
    let shared: Vec<Cell3> = seams.into_iter().map(Cell3::new).collect();
    // Each domain's lock and measures on cache lines of their own: the threads that sweep
    // neighbouring domains do not pass lines back and forth.
    let parts: Vec<Padded<Mutex<&mut P>>> =
        parts.iter_mut().map(|p| Padded(Mutex::new(p))).collect();
    let slots: [Vec<Padded<Mutex<P::Measures>>>; 2] =
        [0, 1].map(|_| (0..n).map(|_| Padded::default()).collect());
    let done = Mutex::new(Vec::with_capacity(max_iterations.min(4096) as usize));
    let process = |item: usize, parity: usize| {
        let p = order[item];
        let mut part = lock(&parts[p].0);
        let links = &links[ranges[p].clone()];
        for &(s, k) in links {
            part.set(s, shared[k as usize].load());
        }
        let m = part.sweep();
        for &(s, k) in links {
            shared[k as usize].store(part.get(s));
        }
        *lock(&slots[parity][item].0) = m;
    };
    let judge = |it: u32, parity: usize| {
        let mut all = P::Measures::default();
        for slot in &slots[parity] {
            P::fold(&mut all, &lock(&slot.0));
        }
        lock(&done).push(all);
        stop(it, &all)
    };
    run_phased(
        threads,
        max_iterations,
        &phase_starts([n.div_ceil(2), n / 2]),
        &process,
        &judge,
    );
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

/// [`sweep_parts`] on the calling thread alone: the same sweeps, hand-overs and folds in the
/// same order, so the same bits, without the queue, the locks and the atomics that a second
/// thread needs. Those cost about as much an iteration whatever the domains hold (a claim, two
/// locks and the seams' cells a domain, a fold of every domain's measures a phase), so they
/// weigh most on small domains. (The velocity sweep's plan on one thread does without the
/// hand-overs too: its domains sweep the island's own velocities, `velocity::domains`.)
fn alone<P: Part>(
    parts: &mut [P],
    partition: &Partition,
    mut shared: Vec<[f64; 3]>,
    order: &[usize],
    max_iterations: u32,
    stop: &(dyn Fn(u32, &P::Measures) -> bool + Sync),
) -> Vec<P::Measures> {
    let (links, ranges) = (&partition.links, &partition.link_ranges);
    let mut done = Vec::with_capacity(max_iterations.min(4096) as usize);
    for it in 0..max_iterations {
        let mut all = P::Measures::default();
        for &p in order {
            let part = &mut parts[p];
            let links = &links[ranges[p].clone()];
            for &(s, k) in links {
                part.set(s, shared[k as usize]);
            }
            let m = part.sweep();
            for &(s, k) in links {
                shared[k as usize] = part.get(s);
            }
            P::fold(&mut all, &m);
        }
        done.push(all);
        if stop(it, &all) {
            break;
        }
    }
    for (part, range) in parts.iter_mut().zip(ranges) {
        for &(s, k) in &links[range.clone()] {
            part.set(s, shared[k as usize]);
        }
    }
    done
}

/// The seams' values, from the domains that hold them (both hold the island's value).
fn seam_values<P: Part>(parts: &[P], partition: &Partition) -> Vec<[f64; 3]> {
    let mut values = vec![[0.0; 3]; partition.shared.len()];
    for (part, range) in parts.iter().zip(&partition.link_ranges) {
        for &(s, k) in &partition.links[range.clone()] {
            values[k as usize] = part.get(s);
        }
    }
    values
}
