//! What threads that share a stage synchronise with: short spin waits, a flag that a panicking
//! thread raises so that the others stop waiting, locks that outlive a panic, and the core
//! count. The collide stage ([`World`](crate::world::World) on a large world) and the solver
//! crates' shared sweeps use them.

use std::sync::atomic::{AtomicBool, Ordering as Mem};
use std::sync::{
    Mutex, MutexGuard, OnceLock, PoisonError, RwLock, RwLockReadGuard, RwLockWriteGuard,
};

/// Spins before a waiting thread yields its core: a `pause` costs tens of cycles on current
/// x86 cores, so this is a microsecond or so, what a partner finishing its item needs; one
/// that lost its core is not waited for by spinning.
const SPINS: u32 = 64;

/// Waits until `ready()` holds: spins briefly, then yields.
#[inline]
pub fn wait_until(ready: impl Fn() -> bool) {
    let mut spins = 0;
    while !ready() {
        if spins < SPINS {
            spins += 1;
            std::hint::spin_loop();
        } else {
            std::thread::yield_now();
        }
    }
}

/// Marks a run aborted when the thread holding it unwinds from a panic, so that the threads
/// waiting on it stop waiting and the scope passes the panic on instead of hanging.
#[derive(Debug)]
pub struct AbortOnPanic<'a>(pub &'a AtomicBool);

impl Drop for AbortOnPanic<'_> {
    fn drop(&mut self) {
        if std::thread::panicking() {
            self.0.store(true, Mem::Release);
        }
    }
}

/// Waits until `ready()` holds or the run is `aborted`; `false` when it was aborted.
#[inline]
pub fn wait_unless_aborted(aborted: &AtomicBool, ready: impl Fn() -> bool) -> bool {
    wait_until(|| aborted.load(Mem::Acquire) || ready());
    !aborted.load(Mem::Acquire)
}

/// The value behind `m`, also after a thread panicked holding it: that panic already fails the
/// run (it reaches the caller), and the value is only read to finish it.
pub fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// [`lock`] for reading an [`RwLock`].
pub fn read<T>(m: &RwLock<T>) -> RwLockReadGuard<'_, T> {
    m.read().unwrap_or_else(PoisonError::into_inner)
}

/// [`lock`] for writing an [`RwLock`].
pub fn write<T>(m: &RwLock<T>) -> RwLockWriteGuard<'_, T> {
    m.write().unwrap_or_else(PoisonError::into_inner)
}

/// The cores this process may use, read once: the standard library reads the CPU affinity
/// and the cgroup quota files at every call (about ten system calls), and a world asks for
/// every island of every step.
pub fn cores() -> usize {
    static CORES: OnceLock<usize> = OnceLock::new();
    *CORES.get_or_init(|| std::thread::available_parallelism().map_or(1, std::num::NonZero::get))
}

/// Threads to run for a request of `requested`: no more than [`cores`]. What a shared stage
/// computes never depends on it.
pub fn effective_threads(requested: usize) -> usize {
    if requested <= 1 {
        return 1;
    }
    requested.min(cores())
}
