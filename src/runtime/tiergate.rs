//! The tier-up gate: while a tiered JIT's background compiler has a tier-1 compile pending,
//! a frame's parallel passes run on one thread fewer than the pool has.
//!
//! Why: a tiered JIT's first frame starts on tier-0 kernels and switches to tier-1 code the
//! moment the worker has compiled it (`jit` module doc). On a machine with as many render
//! threads as cores the worker competed with every render thread for a core, so its compile
//! landed late and a long frame ran most of its work on tier-0 code (2-4x slower), and a
//! short one lost a core to the worker for its whole length anyway. With one render thread
//! held back the worker gets a whole core and tier 1 lands about twice as soon; from then
//! on every thread renders.
//!
//! How: [`Gate::new`] opens a gate only when the kernel source has a compile pending and the
//! pool has more than one thread (otherwise the caller runs its usual parallel iterator).
//! [`Gate::run`] then starts one claiming loop per pool thread; a loop takes the next job
//! from a shared counter only while it holds one of `threads - 1` permits, or once the
//! gate is open (no compile pending any more). A loop waiting for a permit holds no job, so
//! nothing can deadlock: a permit holder always makes progress, the permits are handed out
//! to whichever loops start first, and a waiting loop leaves as soon as the jobs run out.
//! The wait is bounded ([`POLL`]): a waiting loop rechecks the compiler at that interval, so
//! tier 1 landing mid-pass puts every thread to work within it, and a worker that never
//! finishes (failed, detached) only leaves the pass on `threads - 1` threads.
//!
//! Invariant: the gate decides which thread runs a job and when, never what a job computes;
//! results come back in job order, so a frame is bit for bit the same gated or not.
//! Where it sits: `render::Renderer::render_into`, around the expansion and bound pass and
//! around the tiles.

use std::sync::{Condvar, Mutex};
use std::time::Duration;

use crate::abi::{TierUpActivity, TierUpWatch};

/// How long a loop waiting for a permit sleeps before it asks the compiler again.
pub(super) const POLL: Duration = Duration::from_millis(1);

/// What a background compiler is doing; the gate's only question.
pub trait Compiler: Sync {
    fn activity(&self) -> TierUpActivity;
}

impl Compiler for TierUpWatch {
    fn activity(&self) -> TierUpActivity {
        TierUpWatch::activity(self)
    }
}

/// What one gated pass did, for `RenderStats`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct GateStats {
    /// Jobs started while the gate was closed (a compile pending).
    pub gated_jobs: usize,
    /// Most loops that held a permit at once (at most `threads - 1`).
    pub peak_threads: usize,
}

/// Run `f` on items `0..items` on the current pool, at most `per_job` items per job, and
/// return the results in item order: under a [`Gate`] (jobs of exactly `per_job` items) when
/// `compiler` has a compile pending and the pool a thread to spare, otherwise as a plain
/// parallel iterator that splits down to single items as rayon sees fit.
pub(super) fn run_items<T: Send>(
    compiler: Option<&dyn Compiler>,
    items: usize,
    per_job: usize,
    f: impl Fn(usize) -> T + Sync,
) -> (Vec<T>, GateStats) {
    use rayon::prelude::*;
    match Gate::new(compiler) {
        Some(gate) => {
            let job = |j: usize| {
                (j * per_job..(j * per_job + per_job).min(items))
                    .map(&f)
                    .collect::<Vec<T>>()
            };
            let (jobs, stats) = gate.run(items.div_ceil(per_job), job);
            (jobs.into_iter().flatten().collect(), stats)
        }
        None => (
            (0..items).into_par_iter().with_max_len(per_job).map(&f).collect(),
            GateStats::default(),
        ),
    }
}

/// Whether a pass started now would run under a closed gate: `compiler` is compiling
/// and nothing holds it. Work nested in a pass's jobs stays on its thread then.
pub(super) fn closed(compiler: Option<&dyn Compiler>) -> bool {
    compiler.is_some_and(|c| c.activity() == TierUpActivity::Compiling)
}

/// A closed gate for one pass of a frame (see the module doc).
pub struct Gate<'w> {
    compiler: &'w dyn Compiler,
    threads: usize,
    permits: usize,
}

struct State {
    /// The next job to hand out.
    next: usize,
    /// Loops holding a permit.
    active: usize,
    /// No compile pending any more: every loop takes jobs.
    open: bool,
    stats: GateStats,
}

impl<'w> Gate<'w> {
    /// A gate for the current rayon pool when `compiler` has a compile pending and the pool
    /// has threads to spare; `None` when the pass should simply run on every thread.
    pub fn new(compiler: Option<&'w dyn Compiler>) -> Option<Gate<'w>> {
        let compiler = compiler?;
        let threads = rayon::current_num_threads();
        (threads > 1 && compiler.activity() != TierUpActivity::Idle).then_some(Gate {
            compiler,
            threads,
            permits: threads - 1,
        })
    }

    /// Run jobs `0..jobs` on the current pool under the gate; their results in job order.
    pub fn run<T: Send>(&self, jobs: usize, job: impl Fn(usize) -> T + Sync) -> (Vec<T>, GateStats) {
        let state = Mutex::new(State {
            next: 0,
            active: 0,
            open: false,
            stats: GateStats::default(),
        });
        let changed = Condvar::new();
        let done: Mutex<Vec<(usize, T)>> = Mutex::new(Vec::with_capacity(jobs));
        rayon::scope(|s| {
            for _ in 0..self.threads {
                s.spawn(|_| self.claim_loop(jobs, &state, &changed, &done, &job));
            }
        });
        let mut done = done.into_inner().unwrap_or_else(|e| e.into_inner());
        // Each index was handed out once, so sorting restores job order exactly.
        done.sort_unstable_by_key(|&(i, _)| i);
        let stats = state.into_inner().unwrap_or_else(|e| e.into_inner()).stats;
        (done.into_iter().map(|(_, r)| r).collect(), stats)
    }

    /// One pool thread's share: claim jobs until none is left, holding a permit (kept until
    /// the loop ends) while the gate is closed.
    fn claim_loop<T: Send>(
        &self,
        jobs: usize,
        state: &Mutex<State>,
        changed: &Condvar,
        done: &Mutex<Vec<(usize, T)>>,
        job: &(impl Fn(usize) -> T + Sync),
    ) {
        let mut holds_permit = false;
        loop {
            let mut st = state.lock().unwrap_or_else(|e| e.into_inner());
            let claimed = loop {
                if st.next >= jobs {
                    break None;
                }
                let compiling = !st.open && {
                    match self.compiler.activity() {
                        TierUpActivity::Idle => {
                            st.open = true;
                            changed.notify_all();
                            false
                        }
                        TierUpActivity::Held => false,
                        TierUpActivity::Compiling => true,
                    }
                };
                if !compiling || holds_permit {
                    break Some((st.next, compiling));
                }
                if st.active < self.permits {
                    st.active += 1;
                    holds_permit = true;
                    st.stats.peak_threads = st.stats.peak_threads.max(st.active);
                    break Some((st.next, true));
                }
                st = changed.wait_timeout(st, POLL).unwrap_or_else(|e| e.into_inner()).0;
            };
            let Some((i, gated)) = claimed else {
                if holds_permit {
                    st.active -= 1;
                }
                // The waiting loops leave now rather than at their next poll.
                changed.notify_all();
                return;
            };
            st.next += 1;
            st.stats.gated_jobs += usize::from(gated);
            drop(st);
            let result = job(i);
            done.lock().unwrap_or_else(|e| e.into_inner()).push((i, result));
        }
    }
}
