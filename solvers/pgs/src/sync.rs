//! What threads that share one island's sweep synchronise with: three `f64`s in atomics (a
//! velocity, a pose, a set of measures) and a spinning barrier between colours.

use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering as Mem};

/// Three `f64`s that threads share, as bits in relaxed atomics (plain loads and stores on
/// x86-64 and AArch64): each is written by one thread within a colour, and the barrier
/// between colours orders the writes before the next colour's reads.
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

/// Spins (about a millisecond) before a waiting thread starts yielding its core, when every
/// thread can have a core of its own: a yield hands the core to any other runnable process
/// for a whole time slice, so it is only for a partner that has lost its core, never for one
/// still sweeping its part of a colour.
const SPINS: u32 = 1 << 16;

/// Spins before yielding when there are more threads than cores: a partner without a core
/// only runs once the waiting threads give theirs up.
const SPINS_OVERSUBSCRIBED: u32 = 1 << 6;

/// A reusable barrier for a fixed number of threads: spins, then yields.
#[derive(Debug)]
pub(crate) struct SpinBarrier {
    threads: usize,
    spins: u32,
    arrived: AtomicUsize,
    epoch: AtomicUsize,
}

impl SpinBarrier {
    /// A barrier for `threads` threads (≥ 1).
    pub(crate) fn new(threads: usize) -> Self {
        Self {
            threads,
            spins: if threads <= cores() {
                SPINS
            } else {
                SPINS_OVERSUBSCRIBED
            },
            arrived: AtomicUsize::new(0),
            epoch: AtomicUsize::new(0),
        }
    }

    /// Waits for every thread; `epoch` is the caller's count of barriers passed. The last
    /// thread to arrive resets the count before it publishes the new epoch (release), so a
    /// thread that sees the epoch (acquire) also sees the reset and every write made before
    /// the barrier.
    pub(crate) fn wait(&self, epoch: &mut usize) {
        *epoch += 1;
        if self.arrived.fetch_add(1, Mem::AcqRel) + 1 == self.threads {
            self.arrived.store(0, Mem::Relaxed);
            self.epoch.store(*epoch, Mem::Release);
            return;
        }
        let mut spins = 0;
        while self.epoch.load(Mem::Acquire) != *epoch {
            if spins < self.spins {
                spins += 1;
                std::hint::spin_loop();
            } else {
                std::thread::yield_now();
            }
        }
    }
}

/// Threads to run for a request of `requested`: no more than the cores this process may
/// use (more would wait at every barrier for a partner without a core). The result never
/// depends on it.
pub(crate) fn effective_threads(requested: usize) -> usize {
    requested.clamp(1, cores())
}

/// The cores this process may use.
fn cores() -> usize {
    std::thread::available_parallelism().map_or(1, std::num::NonZero::get)
}

/// The owner of chunk `j` of `n` among `threads` threads: contiguous runs, thread
/// `⌊j · threads / n⌋`.
pub(crate) fn owner(j: usize, n: usize, threads: usize) -> usize {
    j * threads / n
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_barrier_orders_every_write_before_it() {
        // Four threads, 200 rounds: in round r each writes r into its own cell, waits, then
        // reads every cell; all must read r everywhere (no thread runs a round ahead).
        let cells: Vec<Cell3> = (0..4).map(|_| Cell3::default()).collect();
        let barrier = SpinBarrier::new(4);
        std::thread::scope(|s| {
            for t in 0..4 {
                let (cells, barrier) = (&cells, &barrier);
                s.spawn(move || {
                    let mut epoch = 0;
                    for r in 0..200 {
                        cells[t].store([r as f64; 3]);
                        barrier.wait(&mut epoch);
                        for c in cells {
                            assert_eq!(c.load(), [r as f64; 3]);
                        }
                        barrier.wait(&mut epoch);
                    }
                });
            }
        });
    }

    #[test]
    fn owners_are_contiguous_and_cover_every_thread_that_has_work() {
        for n in 1..40 {
            for threads in 1..6 {
                let owners: Vec<usize> = (0..n).map(|j| owner(j, n, threads)).collect();
                assert!(owners.windows(2).all(|w| w[0] <= w[1]));
                assert_eq!(owners[0], 0);
                assert!(*owners.last().unwrap() < threads);
                if n >= threads {
                    assert_eq!(*owners.last().unwrap(), threads - 1);
                }
            }
        }
    }
}
