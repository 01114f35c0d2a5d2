//! What threads that share a stage synchronise with: short spin waits, a flag that a panicking
//! thread raises so that the others stop waiting, locks that outlive a panic, and the core
//! count, and [`on_threads`], which runs a stage's shares on threads kept for the process. The
//! collide stage ([`World`](crate::world::World) on a large world) and the solver crates'
//! shared sweeps use them.

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

/// The helper threads kept for the process (`cores() − 1` of them, built at the first shared
/// stage that wants one); `None` on one core, when the OS refuses the threads, and in a child
/// forked after they were built (a fork copies the pool's state but not its threads, so a
/// share handed to them would never run).
fn kept_pool() -> Option<&'static rayon::ThreadPool> {
    static POOL: OnceLock<Option<(u32, rayon::ThreadPool)>> = OnceLock::new();
    let (pid, pool) = POOL
        .get_or_init(|| {
            let helpers = cores().saturating_sub(1);
            if helpers == 0 {
                return None;
            }
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(helpers)
                .thread_name(|i| format!("deepcontact-helper-{i}"))
                .build()
                .ok()?;
            Some((std::process::id(), pool))
        })
        .as_ref()?;
    (*pid == std::process::id()).then_some(pool)
}

/// Set while a stage runs on the kept helpers: a second stage at the same time (another
/// world's, on another thread, or one started inside a share) starts threads of its own.
static KEPT_IN_USE: AtomicBool = AtomicBool::new(false);

/// Runs `work` on each share, the first on the calling thread and each other on a thread of
/// its own, all at once, and returns when every share is done; a panic in any share reaches
/// the caller once all have ended.
///
/// The shares run on helper threads kept for the process while they are free and enough:
/// starting a thread for every stage costs the caller tens of µs (≈ 3 stages a step on a
/// large world), and the thread starts later than a kept one wakes (docs/PERFORMANCE.md,
/// "Threads kept for the process"). Otherwise (the helpers busy with another stage, a share
/// that starts a stage, more shares than cores) each share gets a thread started for it. Either way every share runs at
/// the same time as the others, so shares may wait for one another (a barrier), and what a
/// share computes must not depend on which thread runs it.
pub fn on_threads<T: Send>(shares: impl IntoIterator<Item = T>, work: impl Fn(T) + Sync) {
    let mut shares = shares.into_iter();
    let Some(first) = shares.next() else {
        return;
    };
    let rest: Vec<T> = shares.collect();
    if rest.is_empty() {
        work(first);
        return;
    }
    let work = &work;
    let pool = kept_pool().filter(|pool| rest.len() <= pool.current_num_threads());
    if let Some(pool) = pool
        && !KEPT_IN_USE.swap(true, Mem::Acquire)
    {
        // Clears the flag also when a share's panic unwinds through here.
        struct Release;
        impl Drop for Release {
            fn drop(&mut self) {
                KEPT_IN_USE.store(false, Mem::Release);
            }
        }
        let _release = Release;
        pool.in_place_scope(|scope| {
            for share in rest {
                scope.spawn(move |_| work(share));
            }
            work(first);
        });
        return;
    }
    std::thread::scope(|scope| {
        for share in rest {
            scope.spawn(move || work(share));
        }
        work(first);
    });
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::AtomicUsize;
    use std::time::{Duration, Instant};

    /// Waits until `ready()` or two seconds have passed; whether it became ready.
    fn within_deadline(ready: impl Fn() -> bool) -> bool {
        let t0 = Instant::now();
        while !ready() {
            if t0.elapsed() > Duration::from_secs(2) {
                return false;
            }
            std::thread::yield_now();
        }
        true
    }

    /// Whether the calling thread is one of the kept helpers.
    fn on_a_kept_helper() -> bool {
        std::thread::current()
            .name()
            .is_some_and(|n| n.starts_with("deepcontact-helper"))
    }

    /// Runs a stage of `shares` shares that each wait for all the others (a barrier, which
    /// only passes when they run at the same time); returns how many of the shares the
    /// caller does not run themselves ran on kept helpers.
    fn barrier_stage(shares: usize) -> usize {
        let arrived = AtomicUsize::new(0);
        let (met, kept) = (AtomicUsize::new(0), AtomicUsize::new(0));
        on_threads(0..shares, |t| {
            arrived.fetch_add(1, Mem::SeqCst);
            if within_deadline(|| arrived.load(Mem::SeqCst) == shares) {
                met.fetch_add(1, Mem::SeqCst);
            }
            if t > 0 && on_a_kept_helper() {
                kept.fetch_add(1, Mem::SeqCst);
            }
        });
        assert_eq!(met.load(Mem::SeqCst), shares, "every share met the others");
        kept.load(Mem::SeqCst)
    }

    #[test]
    fn shares_run_at_the_same_time_and_on_the_kept_helpers_when_free() {
        if cores() < 2 {
            // One core: no helpers are kept; the shares still run at the same time.
            assert_eq!(barrier_stage(2), 0);
            return;
        }
        // Other tests of this crate may hold the helpers for a moment: then a stage starts
        // threads of its own, which the barrier checks too.
        assert!(
            within_deadline(|| barrier_stage(2) > 0),
            "no stage ran on the kept helpers"
        );
        // More shares than helpers: threads started for the stage.
        assert_eq!(barrier_stage(cores() + 1), 0);
    }

    #[test]
    fn a_stage_started_inside_a_share_gets_threads_of_its_own() {
        // An inner stage started by a share that runs on a kept helper: the outer stage holds
        // the helpers, so the inner one starts threads of its own (waiting for a helper would
        // wait for a share that its own thread runs). (An outer stage that found the helpers
        // busy with another test's stage runs on threads of its own, and its inner stages may
        // take the helpers: only the shares on a helper are checked.)
        let (checked, inner_kept) = (AtomicUsize::new(0), AtomicUsize::new(0));
        let ran = within_deadline(|| {
            on_threads(0..2, |_| {
                let kept = barrier_stage(2);
                if on_a_kept_helper() {
                    checked.fetch_add(1, Mem::SeqCst);
                    inner_kept.fetch_add(kept, Mem::SeqCst);
                }
            });
            checked.load(Mem::SeqCst) >= 3 || cores() < 2
        });
        assert!(ran, "no share ran on a kept helper");
        assert_eq!(inner_kept.load(Mem::SeqCst), 0);
    }

    #[test]
    fn a_panicking_share_reaches_the_caller_and_frees_the_helpers() {
        let run = std::panic::catch_unwind(|| {
            on_threads(0..2, |t| assert_ne!(t, 1, "share 1 fails"));
        });
        assert!(run.is_err());
        assert!(
            !KEPT_IN_USE.load(Mem::SeqCst) || cores() < 2 || {
                // Another test's stage may hold them now; then it frees them.
                within_deadline(|| !KEPT_IN_USE.load(Mem::SeqCst))
            }
        );
    }
}
