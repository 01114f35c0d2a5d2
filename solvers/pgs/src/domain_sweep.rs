//! Sweeping the parts of a [`Partition`], on one thread or several: the loop that the domain
//! plans of the velocity sweep and of the position pass share.
//!
//! An iteration sweeps the domains (side by side on threads: they share no movable body, and
//! their copies of immovable bodies are only read), then the cut on one thread, between
//! copies of its movable bodies' values from and back to their domains. That is one
//! Gauss-Seidel order of all constraints whatever the threads, and the parts' measures are
//! folded in part order, so the result is bit-identical for any thread count.
//!
//! On several threads the values the cut shares with a domain pass through a mailbox of that
//! domain's, in link order: a domain's own memory is only ever touched by the thread that
//! sweeps it, so none of its cache lines moves between cores. A domain takes the cut's last
//! values before its sweep and leaves its own after it; the cut takes the domains' values
//! before its sweep and leaves its own after it.

use std::sync::{Mutex, MutexGuard, PoisonError};

use crate::partition::Partition;
use crate::sync::{Padded, phase_starts, run_phased};

/// One part of a partition as the loop sweeps it.
pub(crate) trait Part: Send {
    /// What the cut shares with a domain per body (a velocity, a pose).
    type Value: Copy + Send;
    /// What a sweep measures, folded over the parts in order.
    type Measures: Copy + Default + Send;
    /// The value of the body in `slot`.
    fn get(&self, slot: u32) -> Self::Value;
    /// Sets the value of the body in `slot`.
    fn set(&mut self, slot: u32, value: Self::Value);
    /// One sweep over the part's constraints.
    fn sweep(&mut self) -> Self::Measures;
    /// Folds `m` (of a part swept after those of `into`) into `into`.
    fn fold(into: &mut Self::Measures, m: &Self::Measures);
}

/// The value behind `m` (a panicked sweep has already made the solve fail).
fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// Sweeps `parts` (the domains of `partition`, then its cut) on up to `threads` threads (≥ 1;
/// no more than the domains) until `stop(iteration, measures)` (0-based) holds or
/// `max_iterations` have run. Returns every iteration's measures, folded in part order; the
/// parts end with the cut's last values in their domains.
pub(crate) fn sweep_parts<P: Part>(
    parts: &mut [P],
    partition: &Partition,
    threads: usize,
    max_iterations: u32,
    stop: &(dyn Fn(u32, &P::Measures) -> bool + Sync),
) -> Vec<P::Measures> {
    let n = partition.n;
    let (links, ranges) = (&partition.links, &partition.link_ranges);
    if threads.min(n) <= 1 {
        return sweep_on_this_thread(parts, partition, max_iterations, stop);
    }
    // Each part's lock, mailbox and measures on cache lines of their own: the threads that
    // sweep neighbouring parts do not pass lines back and forth.
    let mail: Vec<Padded<Mutex<Vec<P::Value>>>> = ranges
        .iter()
        .zip(parts.iter())
        .map(|(range, part)| {
            Padded(Mutex::new(
                links[range.clone()]
                    .iter()
                    .map(|&(_, l)| part.get(l))
                    .collect(),
            ))
        })
        .collect();
    let parts: Vec<Padded<Mutex<&mut P>>> =
        parts.iter_mut().map(|p| Padded(Mutex::new(p))).collect();
    let slots: [Vec<Padded<Mutex<P::Measures>>>; 2] =
        [0, 1].map(|_| (0..=n).map(|_| Padded::default()).collect());
    let done = Mutex::new(Vec::with_capacity(max_iterations.min(4096) as usize));
    let process = |item: usize, parity: usize| {
        let m = if item < n {
            let (mut part, mut mail) = (lock(&parts[item].0), lock(&mail[item].0));
            let links = &links[ranges[item].clone()];
            for (v, &(_, l)) in mail.iter().zip(links) {
                part.set(l, *v);
            }
            let m = part.sweep();
            for (v, &(_, l)) in mail.iter_mut().zip(links) {
                *v = part.get(l);
            }
            m
        } else {
            let mut cut = lock(&parts[n].0);
            for (range, mail) in ranges.iter().zip(&mail) {
                for (v, &(s, _)) in lock(&mail.0).iter().zip(&links[range.clone()]) {
                    cut.set(s, *v);
                }
            }
            let m = cut.sweep();
            for (range, mail) in ranges.iter().zip(&mail) {
                for (v, &(s, _)) in lock(&mail.0).iter_mut().zip(&links[range.clone()]) {
                    *v = cut.get(s);
                }
            }
            m
        };
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
        threads.min(n),
        max_iterations,
        &phase_starts([n, 1]),
        &process,
        &judge,
    );
    // The cut's last values into their domains.
    for ((part, mail), range) in parts.iter().zip(&mail).zip(ranges) {
        let mut part = lock(&part.0);
        for (v, &(_, l)) in lock(&mail.0).iter().zip(&links[range.clone()]) {
            part.set(l, *v);
        }
    }
    done.into_inner().unwrap_or_else(PoisonError::into_inner)
}

/// [`sweep_parts`] on the calling thread: the same sweeps in the same order, the cut's values
/// copied straight between the parts.
fn sweep_on_this_thread<P: Part>(
    parts: &mut [P],
    partition: &Partition,
    max_iterations: u32,
    stop: &(dyn Fn(u32, &P::Measures) -> bool + Sync),
) -> Vec<P::Measures> {
    let n = partition.n;
    let (links, ranges) = (&partition.links, &partition.link_ranges);
    let (domains, cut) = parts.split_at_mut(n);
    let cut = &mut cut[0];
    // Room for every iteration's measures up front: no growth inside the loop.
    let mut measures = Vec::with_capacity(max_iterations.min(4096) as usize);
    for it in 0..max_iterations {
        let mut all = P::Measures::default();
        for part in domains.iter_mut() {
            P::fold(&mut all, &part.sweep());
        }
        for (domain, range) in domains.iter().zip(ranges) {
            for &(s, l) in &links[range.clone()] {
                cut.set(s, domain.get(l));
            }
        }
        P::fold(&mut all, &cut.sweep());
        for (domain, range) in domains.iter_mut().zip(ranges) {
            for &(s, l) in &links[range.clone()] {
                domain.set(l, cut.get(s));
            }
        }
        measures.push(all);
        if stop(it, &all) {
            break;
        }
    }
    measures
}
