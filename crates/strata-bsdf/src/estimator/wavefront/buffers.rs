//! What a thread keeps between the engine's calls (waves, query columns,
//! reducers, task buffers), so that a warm thread's calls allocate nothing.

use super::engine::{Queries, Unit, WalkOut};
use super::stages::{PdfScratch, TaskBuffers};
use super::walks::Walks;
use crate::estimator::accumulate::BlockReducer;
use std::cell::RefCell;
use std::thread::LocalKey;

thread_local! {
    /// Waves kept for reuse by this thread (a few: one per call or task it
    /// runs at once, which work stealing can nest).
    pub(super) static WAVES: RefCell<Vec<Walks>> = const { RefCell::new(Vec::new()) };
    /// The buffers of this thread's calls (query columns, reducers).
    pub(super) static CALLS: RefCell<Option<CallBuffers>> = const { RefCell::new(None) };
    /// The buffers of the tasks this thread runs (units, walk outputs, queues).
    pub(super) static TASKS: RefCell<Option<TaskScratch>> = const { RefCell::new(None) };
}

/// What a call keeps between calls on its thread.
#[derive(Default)]
pub(super) struct CallBuffers {
    pub(super) queries: Queries,
    pub(super) valid: Vec<u32>,
    /// Sample: each query's sample index.
    pub(super) index: Vec<u64>,
    pub(super) red: Vec<BlockReducer>,
    pub(super) red2: Vec<(BlockReducer, BlockReducer)>,
    /// Pdf: each query's sums of density walks, and a round's jobs.
    pub(super) pdf: PdfScratch,
}

/// What a task keeps between tasks on its thread.
#[derive(Default)]
pub(super) struct TaskScratch {
    pub(super) ids: Vec<usize>,
    pub(super) units: Vec<Unit>,
    pub(super) out: Vec<WalkOut>,
    pub(super) bufs: TaskBuffers,
}

/// Runs `f` on the buffers this thread keeps in `key`, taken out while `f`
/// runs: a call nested in `f` (work stealing, or a sink that calls the
/// engine) finds none and starts from empty ones, which it then keeps. A
/// call made while the thread's locals are torn down (from a thread-local's
/// destructor) runs on fresh buffers and keeps nothing.
pub(crate) fn with_kept<T: Default + 'static, R>(
    key: &'static LocalKey<RefCell<Option<T>>>,
    f: impl FnOnce(&mut T) -> R,
) -> R {
    let kept = key.try_with(|c| c.borrow_mut().take()).ok().flatten();
    let mut b = kept.unwrap_or_default();
    let r = f(&mut b);
    let _ = key.try_with(|c| *c.borrow_mut() = Some(b));
    r
}

/// Runs `f` on this thread's call buffers ([`with_kept`] of [`CALLS`]),
/// letting go of the call's parameter sets when it ends so that their
/// owner can reuse their memory.
pub(super) fn with_calls<R>(f: impl FnOnce(&mut CallBuffers) -> R) -> R {
    with_kept(&CALLS, |c| {
        let r = f(c);
        c.queries.release();
        r
    })
}

/// Runs `f` on a wave of `slots` slots, reusing one this thread kept: the
/// smallest that holds `slots` without growing, else the largest (which
/// grows), so that a warm thread serves any batch up to its largest so far
/// without allocating. (Results do not depend on the wave.)
pub(super) fn with_wave<R>(slots: usize, f: impl FnOnce(&mut Walks) -> R) -> R {
    // (`try_with`: from a thread-local's destructor, a fresh wave.)
    let kept = WAVES.try_with(|w| {
        let mut w = w.borrow_mut();
        let cap = |i: &usize| w[*i].capacity();
        let i = (0..w.len())
            .filter(|i| cap(i) >= slots)
            .min_by_key(cap)
            .or_else(|| (0..w.len()).max_by_key(cap))?;
        Some(w.swap_remove(i))
    });
    let mut ws = kept.ok().flatten().unwrap_or_else(|| Walks::new(slots));
    ws.set_slots(slots);
    let r = f(&mut ws);
    let _ = WAVES.try_with(|w| {
        let mut w = w.borrow_mut();
        if w.len() >= 4 {
            w.remove(0);
        }
        w.push(ws);
    });
    r
}
