//! Which threads run a call's work, seen from outside the library.
//!
//! A call made on a thread that is not a rayon worker (as a test's thread
//! is) can reach rayon's current pool only by handing it jobs: a parallel
//! iterator, `join` or `scope` started there injects its job into rayon's
//! global pool, and the caller blocks until a worker of that pool has run
//! it. [`watch`] runs a call so while every worker of the global pool runs
//! a *thief*: a loop that asks rayon for a job (`rayon::yield_now`, which
//! takes injected jobs and steals from the other workers' deques) and
//! records its own thread id whenever rayon hands it one. The thieves are
//! then the only threads that can run such a job, so every job the call
//! hands to rayon's current pool runs on a thief and is recorded, whatever
//! the library's code path: no hook in the library and no timing.
//!
//! The call ran on the calling thread alone (as far as rayon's current pool
//! goes) exactly when no thief ran a job: [`Watched::threads`] is then the
//! calling thread alone. Work on a pool the library builds for itself (a
//! BSDF's `threads(n)`, n > 1) has no tie to the global pool and is not
//! seen: a call on such a pool leaves the thieves idle, which is what a
//! test of a pool of `n` asserts.
//!
//! The global pool is process-wide, and a test binary runs its tests on
//! several threads at once, so a thief would also take other tests' jobs:
//! a watching test runs in a process of its own ([`in_own_process`]: the
//! test binary again, with that one test selected), where nothing else uses
//! rayon's global pool.
#![allow(dead_code)]

use std::process::Command;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::{self, ThreadId};
use std::time::{Duration, Instant};

/// The variable that marks the child process of [`in_own_process`]: the
/// name of the test it runs.
const CHILD: &str = "STRATA_WATCH_THREADS_TEST";

/// Runs `body` in a process of its own: this test binary again, running
/// only the test `test` (its path in the binary, as `cargo test` prints it,
/// e.g. `threads::one_thread`), which must be the test that calls this.
/// In that process `body` runs; here, the child's output is shown if it
/// fails.
pub fn in_own_process(test: &str, body: impl FnOnce()) {
    if std::env::var(CHILD).as_deref() == Ok(test) {
        body();
        return;
    }
    let exe = std::env::current_exe().expect("the test binary's path");
    let out = Command::new(exe)
        .args([test, "--exact", "--nocapture", "--test-threads=1"])
        .env(CHILD, test)
        .output()
        .expect("the test binary runs again");
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(out.status.success(), "{test} in its own process:\n{text}");
    assert!(
        text.contains("test result: ok. 1 passed"),
        "{test} in its own process ran no test:\n{text}"
    );
}

/// A call's result and the threads that ran its work.
#[derive(Debug)]
pub struct Watched<R> {
    pub value: R,
    /// The thread the call was made on.
    pub caller: ThreadId,
    /// The other threads that ran jobs of the call, and how many each.
    pub others: Vec<(ThreadId, usize)>,
}

impl<R> Watched<R> {
    /// Every thread seen running the call's work (the caller first).
    pub fn threads(&self) -> Vec<ThreadId> {
        std::iter::once(self.caller)
            .chain(self.others.iter().map(|&(t, _)| t))
            .collect()
    }

    /// The call ran on the calling thread alone.
    pub fn on_caller_only(&self) -> bool {
        self.threads() == [self.caller]
    }

    /// Jobs of the call that ran on another thread.
    pub fn jobs_elsewhere(&self) -> usize {
        self.others.iter().map(|&(_, n)| n).sum()
    }
}

/// Runs `call` on this thread while every worker of rayon's global pool
/// runs a thief (see the module's doc), and reports which threads ran it.
/// Must run on a thread that is not a rayon worker, in a process of its
/// own ([`in_own_process`]).
pub fn watch<R>(call: impl FnOnce() -> R) -> Watched<R> {
    assert!(
        rayon::current_thread_index().is_none(),
        "watch runs a call from outside rayon's pools"
    );
    assert!(
        std::env::var_os(CHILD).is_some(),
        "watch runs in a process of its own (in_own_process)"
    );
    let workers = rayon::current_num_threads();
    let started = Arc::new(AtomicUsize::new(0));
    let finished = Arc::new(AtomicUsize::new(0));
    let stop = Arc::new(AtomicBool::new(false));
    let stolen: Arc<Mutex<Vec<ThreadId>>> = Arc::default();
    {
        let (started, finished) = (started.clone(), finished.clone());
        let (stop, stolen) = (stop.clone(), stolen.clone());
        // A broadcast runs once on every worker of the pool.
        rayon::spawn_broadcast(move |_| {
            started.fetch_add(1, Ordering::SeqCst);
            while !stop.load(Ordering::SeqCst) {
                match rayon::yield_now() {
                    Some(rayon::Yield::Executed) => {
                        stolen.lock().unwrap().push(thread::current().id())
                    }
                    // The caller waits for an injected job until a thief
                    // takes it: a pause changes only how soon.
                    _ => thread::sleep(Duration::from_micros(50)),
                }
            }
            finished.fetch_add(1, Ordering::SeqCst);
        });
    }
    let until = |what: &str, n: &AtomicUsize| {
        let t0 = Instant::now();
        while n.load(Ordering::SeqCst) < workers {
            assert!(
                t0.elapsed() < Duration::from_secs(60),
                "the global pool's workers never {what}"
            );
            thread::sleep(Duration::from_micros(100));
        }
    };
    until("started their thieves", &started);
    let value = call();
    stop.store(true, Ordering::SeqCst);
    until("stopped their thieves", &finished);
    let mut others: Vec<(ThreadId, usize)> = Vec::new();
    for t in stolen.lock().unwrap().drain(..) {
        match others.iter_mut().find(|(u, _)| *u == t) {
            Some((_, n)) => *n += 1,
            None => others.push((t, 1)),
        }
    }
    Watched {
        value,
        caller: thread::current().id(),
        others,
    }
}
