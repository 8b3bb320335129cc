//! Thread pools that survive `fork()`.
//!
//! Threads do not survive `fork`: a forked child inherits a rayon pool's
//! queues but none of its workers, so a job handed to a pool built in the
//! parent (rayon's global one included) waits forever. strata never enters a
//! pool built in another process. Each pool it uses is stamped with the id of
//! the process that built it (rayon's global pool with that of the process
//! where strata first used it); a call that finds itself in another process,
//! a forked child, runs on a pool of the same size built for its own process
//! ([`process_pool`]: built on first use, one per process and size, never
//! dropped), or, if no thread can be started, on the calling thread. Results
//! do not depend on the pool, so the child computes the parent's numbers.
//! The price is a `getpid` per parallel section.
//!
//! A section that must not leave the calling thread (a BSDF of
//! `threads(1)`, a batch too small to repay a hand-over) runs in
//! [`on_calling_thread`]: there [`par_map`] maps in order on the calling
//! thread and [`current_threads`] is 1, whichever engine path the section
//! takes.

use std::cell::Cell;
use std::ptr;
use std::sync::atomic::{AtomicPtr, AtomicU32, Ordering};
use std::thread::LocalKey;

use rayon::prelude::*;
use rayon::{ThreadPool, ThreadPoolBuildError, ThreadPoolBuilder};

/// The id of this process.
fn pid() -> u32 {
    std::process::id()
}

/// The process in which strata first used rayon's global pool (0: none yet).
static GLOBAL_PID: AtomicU32 = AtomicU32::new(0);

/// Whether a parallel iterator started here runs on live threads: on a
/// pool's worker (the pool is this thread's, so of this process), or on
/// rayon's global pool, which strata then first used in this process.
///
/// A process that used rayon's global pool before its first strata call and
/// then forked leaves its child a global pool that this cannot tell from a
/// fresh one; strata's own uses (every batch call, and [`current_threads`])
/// stamp it before they create it.
fn current_is_live() -> bool {
    if rayon::current_thread_index().is_some() {
        return true;
    }
    let me = pid();
    let first = GLOBAL_PID.load(Ordering::Acquire);
    if first != 0 {
        return first == me;
    }
    match GLOBAL_PID.compare_exchange(0, me, Ordering::AcqRel, Ordering::Acquire) {
        Ok(_) => true,
        Err(first) => first == me,
    }
}

thread_local! {
    /// This thread is inside [`on_calling_thread`].
    static CALLING_ONLY: Cell<bool> = const { Cell::new(false) };
}

/// Runs `f` with every parallel section it starts on this thread run on
/// this thread: [`par_map`] maps in order here, [`current_threads`] is 1.
/// Nests; the setting ends with `f`, also when it unwinds.
pub(crate) fn on_calling_thread<R>(f: impl FnOnce() -> R) -> R {
    with_set(&CALLING_ONLY, true, f)
}

/// Runs `f` with this thread's `cell` set to `value`, restored after `f`,
/// also when it unwinds.
fn with_set<T: Copy + 'static, R>(
    cell: &'static LocalKey<Cell<T>>,
    value: T,
    f: impl FnOnce() -> R,
) -> R {
    struct Restore<T: Copy + 'static>(&'static LocalKey<Cell<T>>, T);
    impl<T: Copy + 'static> Drop for Restore<T> {
        fn drop(&mut self) {
            self.0.with(|c| c.set(self.1));
        }
    }
    let _restore = Restore(cell, cell.with(|c| c.replace(value)));
    f()
}

/// Whether this thread is inside [`on_calling_thread`].
fn calling_only() -> bool {
    CALLING_ONLY.with(Cell::get)
}

thread_local! {
    /// The threads of the call running on this thread ([`with_budget`]; 0:
    /// none set).
    static BUDGET: Cell<usize> = const { Cell::new(0) };
}

/// Runs `f` as part of a call allowed `threads` threads: what
/// [`build_threads`] says on this thread outside a pool. Nests; the setting
/// ends with `f`, also when it unwinds.
pub(crate) fn with_budget<R>(threads: usize, f: impl FnOnce() -> R) -> R {
    with_set(&BUDGET, threads, f)
}

/// How many threads a one-off build started here (a table that later
/// calls share) may run on, its own threads rather than a pool's: 1 inside
/// [`on_calling_thread`], a pool's size on its worker, the call's budget
/// ([`with_budget`]) on the thread that made it, else rayon's current
/// pool's size.
pub(crate) fn build_threads() -> usize {
    if calling_only() {
        return 1;
    }
    if rayon::current_thread_index().is_some() {
        return rayon::current_num_threads();
    }
    match BUDGET.with(Cell::get) {
        0 => current_threads(),
        n => n,
    }
}

/// The number of threads a parallel section started here runs on: 1 inside
/// [`on_calling_thread`], else rayon's current pool's (for a forked child
/// whose global pool is its parent's, the size of the pool [`par_map`]
/// runs on).
pub(crate) fn current_threads() -> usize {
    if calling_only() {
        return 1;
    }
    // Stamps the global pool with this process before rayon creates it.
    let _ = current_is_live();
    rayon::current_num_threads()
}

/// `f(0), ..., f(n - 1)` in order: on the calling thread inside
/// [`on_calling_thread`], else computed over rayon's current pool, or, if
/// that pool was built in another process (this is a forked child), over a
/// pool of the same size of this process (on the calling thread if none
/// can be built).
pub(crate) fn par_map<R: Send>(n: usize, f: impl Fn(usize) -> R + Sync + Send) -> Vec<R> {
    if calling_only() {
        return (0..n).map(f).collect();
    }
    if current_is_live() {
        return (0..n).into_par_iter().map(f).collect();
    }
    match process_pool(rayon::current_num_threads()) {
        Some(p) => p.install(|| (0..n).into_par_iter().map(f).collect()),
        None => (0..n).map(f).collect(),
    }
}

/// A pool built for one process.
struct Built {
    pid: u32,
    threads: usize,
    pool: ThreadPool,
    /// The pool built before it (in this process or an ancestor).
    next: *mut Built,
}

/// The pools [`process_pool`] built, newest first: a list that only grows
/// (its nodes are never freed), so that a forked child can walk the one it
/// inherits whatever the parent's threads were doing.
static BUILT: AtomicPtr<Built> = AtomicPtr::new(ptr::null_mut());

/// A pool of `threads` threads built in this process: the first call for a
/// size builds it, later calls get the same pool; it lives as long as the
/// process. `None` if it cannot be built.
fn process_pool(threads: usize) -> Option<&'static ThreadPool> {
    let me = pid();
    let find = |mut at: *mut Built| {
        while !at.is_null() {
            // SAFETY: nodes come from `Box::into_raw` below, are published
            // complete (Release/Acquire) and never freed or changed after.
            let b = unsafe { &*at };
            if b.pid == me && b.threads == threads {
                return Some(&b.pool);
            }
            at = b.next;
        }
        None
    };
    let mut head = BUILT.load(Ordering::Acquire);
    if let Some(p) = find(head) {
        return Some(p);
    }
    let pool = ThreadPoolBuilder::new().num_threads(threads).build().ok()?;
    let node = Box::into_raw(Box::new(Built {
        pid: me,
        threads,
        pool,
        next: head,
    }));
    loop {
        match BUILT.compare_exchange(head, node, Ordering::AcqRel, Ordering::Acquire) {
            // SAFETY: published, so never freed (see `find`).
            Ok(_) => return Some(unsafe { &(*node).pool }),
            Err(now) => {
                if let Some(p) = find(now) {
                    // Another thread of this process built one first: ours
                    // was never published, and its threads are of this
                    // process, so dropping it is safe.
                    // SAFETY: `node` is ours alone (from `Box::into_raw`).
                    drop(unsafe { Box::from_raw(node) });
                    return Some(p);
                }
                head = now;
                // SAFETY: `node` is not published yet: ours alone.
                unsafe { (*node).next = now };
            }
        }
    }
}

/// A BSDF's own pool, stamped with the process that built it.
#[derive(Debug)]
pub(crate) struct OwnPool {
    /// `None` only while dropped in another process.
    pool: Option<ThreadPool>,
    threads: usize,
    pid: u32,
}

impl OwnPool {
    /// A pool of `threads` threads (0: one per core) in this process.
    pub(crate) fn new(threads: usize) -> Result<Self, ThreadPoolBuildError> {
        let pool = ThreadPoolBuilder::new().num_threads(threads).build()?;
        Ok(OwnPool {
            threads: pool.current_num_threads(),
            pool: Some(pool),
            pid: pid(),
        })
    }

    /// Its number of threads.
    pub(crate) fn threads(&self) -> usize {
        self.threads
    }

    /// Runs `f` on the pool; in a forked child, on this process's pool of
    /// the same size (on the calling thread if none can be built).
    pub(crate) fn install<R: Send>(&self, f: impl FnOnce() -> R + Send) -> R {
        match &self.pool {
            Some(p) if self.pid == pid() => p.install(f),
            _ => match process_pool(self.threads) {
                Some(p) => p.install(f),
                None => f(),
            },
        }
    }
}

impl Drop for OwnPool {
    fn drop(&mut self) {
        if self.pid != pid() {
            // A forked child's copy of a pool whose threads stayed in the
            // parent: dropping it would wake workers that do not exist here
            // (and could wait on a lock that one of them held at the fork).
            std::mem::forget(self.pool.take());
        }
    }
}
