//! The kernel contract: what a kernel source (the JIT, the hand-written kernels, a test's
//! own) hands the runtime for one (primitive, variant key), the error it reports instead, and
//! the watch on a source's background compiler.
//!
//! A [`Kernel`] is an entry point with the [`ArgLayout`] it reads (`ArgLayout::new(program,
//! func, key)`); the entry stays callable while the source that made it is alive. A
//! [`KernelError`] says why a source could not make one. A source whose kernels get faster
//! code later (a tiered JIT) hands out a [`TierUpWatch`]: the renderer asks it whether the
//! background compiler is idle, held or compiling, and holds it for the start of a frame
//! (`runtime::tiergate`). The crate-private side of the watch is the worker's: it counts
//! requests in and out, waits while a hold keeps it, and is closed when its source goes. A
//! request counts as pending from before the worker can receive it until its result is
//! recorded; the count and the result change under one lock, so whoever sees the count drop
//! also sees the result.

use std::sync::{Arc, Condvar, Mutex};
use std::time::Instant;

use super::{ArgLayout, KernelFn, VariantKey};
use crate::diag::Span;
use crate::ir::FuncId;

/// A compiled kernel for one (primitive, variant key).
#[derive(Debug)]
pub struct Kernel {
    pub func: FuncId,
    pub key: VariantKey,
    /// Entry point; valid while the source that made it is alive.
    pub entry: KernelFn,
    pub layout: ArgLayout,
    /// Wall time spent building and compiling this kernel (callees excluded), microseconds.
    pub compile_micros: u64,
    /// Things the specialisation noticed (a bound parameter no arm writes, ...).
    pub warnings: Vec<KernelWarning>,
}

/// Something the specialisation noticed about one binding of its key (the runtime reports
/// it as W0802, naming the shading parameter: a source knows only its index).
#[derive(Clone, Debug, PartialEq)]
pub struct KernelWarning {
    /// Index into the key's bindings.
    pub binding: usize,
    /// What happens to the parameter; `{param}` stands for its name.
    pub message: String,
    /// The source it is about (an arm, an `interpolator_return` value, a primitive's name).
    pub span: Span,
    /// What the underline says.
    pub label: String,
}

impl KernelWarning {
    /// The message with the parameter's name (or its index, when `names` has none for it).
    pub fn message_for(&self, names: &[&str]) -> String {
        let name = match names.get(self.binding) {
            Some(n) => format!("`{n}`"),
            None => format!("{}", self.binding),
        };
        self.message.replace("{param}", &name)
    }
}

/// Why a kernel source could not make a kernel (the JIT calls it `JitError`).
#[derive(Debug, Clone)]
pub struct KernelError {
    pub message: String,
}

impl std::fmt::Display for KernelError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for KernelError {}

/// What a background compiler's worker and its watches share (the source keeps its results
/// apart, recorded under this lock: [`TierUpWatch::finish_request`]).
struct TierUpState {
    /// Requests sent and not yet answered.
    pending: usize,
    /// Live [`TierUpHold`]s: the worker starts no compile while one holds.
    holds: Vec<HoldEntry>,
    next_hold: u64,
    /// How long a renderer holds the worker back after a frame's kernels are compiled, per
    /// unit of time that compiling them took ([`Jit::set_tier_up_grace`]).
    ///
    /// [`Jit::set_tier_up_grace`]: crate::jit::Jit::set_tier_up_grace
    grace_per_compile: f64,
    /// The feeding JIT is gone: the worker ignores holds and drains its queue.
    closing: bool,
}

/// One [`TierUpHold`] as the worker sees it.
struct HoldEntry {
    id: u64,
    /// When it stops holding (None: when it drops).
    deadline: Option<Instant>,
    /// A stall ([`Jit::stall_tier_up`]): holds the worker, but [`TierUpWatch::activity`]
    /// reports the worker compiling, as if its compile took that long.
    ///
    /// [`Jit::stall_tier_up`]: crate::jit::Jit::stall_tier_up
    stall: bool,
}

/// The default grace per unit of tier-0 compile time (see [`TierUpWatch::grace`]).
pub const DEFAULT_TIER_UP_GRACE: f64 = 3.0;

impl Default for TierUpState {
    fn default() -> TierUpState {
        TierUpState {
            pending: 0,
            holds: vec![],
            next_hold: 0,
            grace_per_compile: DEFAULT_TIER_UP_GRACE,
            closing: false,
        }
    }
}

impl TierUpState {
    /// Whether a hold (stalls included when `stalls`) keeps the worker from starting a
    /// compile at `now`: `None` if not, `Some(None)` until a hold drops, `Some(Some(t))`
    /// until `t` at the latest.
    fn held_at(&self, now: Instant, stalls: bool) -> Option<Option<Instant>> {
        if self.closing {
            return None;
        }
        let mut until: Option<Option<Instant>> = None;
        for hold in self.holds.iter().filter(|h| stalls || !h.stall) {
            match hold.deadline {
                None => return Some(None),
                Some(t) if t > now => until = Some(Some(until.flatten().map_or(t, |u| u.max(t)))),
                Some(_) => {}
            }
        }
        until
    }
}

/// What a tiered JIT's background compiler is doing, as [`TierUpWatch::activity`] sees it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TierUpActivity {
    /// Every compile requested so far has finished (or failed).
    Idle,
    /// A compile is pending but a [`TierUpHold`] keeps the worker from starting it.
    Held,
    /// A compile is pending or in progress and the worker is free to run it.
    Compiling,
}

/// What a renderer (or anyone running a tiered JIT's kernels) can ask of its background
/// tier-1 compiler without borrowing the JIT: what it is doing, a bounded wait for it, and
/// a hold that keeps it from starting a compile (see `runtime::tiergate`, which holds it for
/// the start of a frame and then keeps one render thread fewer than the pool has busy while
/// it compiles). Cloning shares the same state.
#[derive(Clone)]
pub struct TierUpWatch {
    state: Arc<(Mutex<TierUpState>, Condvar)>,
}

impl TierUpWatch {
    /// What the worker is doing now (see [`TierUpActivity`]).
    pub fn activity(&self) -> TierUpActivity {
        let st = self.state.0.lock().unwrap_or_else(|e| e.into_inner());
        if st.pending == 0 {
            TierUpActivity::Idle
        } else if st.held_at(Instant::now(), false).is_some() {
            TierUpActivity::Held
        } else {
            TierUpActivity::Compiling
        }
    }

    /// Wait until no compile is pending or `timeout` has passed, whichever is first; true
    /// when one is still pending.
    pub fn wait(&self, timeout: std::time::Duration) -> bool {
        let (lock, done) = &*self.state;
        let st = lock.lock().unwrap_or_else(|e| e.into_inner());
        let (st, _) = done
            .wait_timeout_while(st, timeout, |st| st.pending > 0)
            .unwrap_or_else(|e| e.into_inner());
        st.pending > 0
    }

    /// Keep the worker from starting a compile until the returned hold drops or reaches
    /// the deadline given to [`TierUpHold::release_at`] (the compile in progress, if any,
    /// finishes).
    pub fn hold(&self) -> TierUpHold {
        self.add_hold(false)
    }

    /// How long a renderer holds the worker back after a frame whose kernels took
    /// `tier0_compile` to compile: that times [`Jit::set_tier_up_grace`]'s factor (default
    /// [`DEFAULT_TIER_UP_GRACE`]).
    ///
    /// Why proportional: a tier-1 compile costs about ten times the tier-0 one, and while it
    /// runs the frame loses a thread to it. Like renting skis until the rent paid equals the
    /// price, a frame runs on every thread for a time in proportion to what tier 1 will cost
    /// before it pays for it: a frame shorter than that (the example scenes' tiles take
    /// 1-6 ms) never has the worker in its way, a longer one gets tier-1 code at most that
    /// much later. Kernels already compiled (a later frame) give no grace.
    ///
    /// [`Jit::set_tier_up_grace`]: crate::jit::Jit::set_tier_up_grace
    pub fn grace(&self, tier0_compile: std::time::Duration) -> std::time::Duration {
        let factor = self.state.0.lock().unwrap_or_else(|e| e.into_inner()).grace_per_compile;
        // At most an hour: whatever the factor, a deadline that far is "until the frame ends",
        // and an instant plus it cannot overflow.
        let most = std::time::Duration::from_secs(3600);
        let secs = tier0_compile.as_secs_f64() * factor;
        if secs.is_nan() {
            // An infinite factor times no compile: nothing compiled, no grace.
            return std::time::Duration::ZERO;
        }
        std::time::Duration::try_from_secs_f64(secs).map_or(most, |g| g.min(most))
    }

    /// A hold; a stall (`stall`) also makes [`TierUpWatch::activity`] report the worker
    /// compiling.
    pub(crate) fn add_hold(&self, stall: bool) -> TierUpHold {
        let mut st = self.state.0.lock().unwrap_or_else(|e| e.into_inner());
        let id = st.next_hold;
        st.next_hold += 1;
        st.holds.push(HoldEntry {
            id,
            deadline: None,
            stall,
        });
        TierUpHold {
            state: self.state.clone(),
            id,
        }
    }
}

/// The worker's side (the source that owns the worker; see the module doc).
impl TierUpWatch {
    /// A watch on a worker with nothing requested, no hold and the default grace.
    pub(crate) fn new() -> TierUpWatch {
        TierUpWatch { state: Arc::default() }
    }

    /// Set the grace per unit of compile time ([`TierUpWatch::grace`]).
    pub(crate) fn set_grace_per_compile(&self, factor: f64) {
        self.state.0.lock().unwrap_or_else(|e| e.into_inner()).grace_per_compile = factor;
    }

    /// Count a request as pending if `send` (run under the lock, so the worker cannot answer
    /// it before it is counted) says it was sent.
    pub(crate) fn count_request(&self, send: impl FnOnce() -> bool) {
        let mut st = self.state.0.lock().unwrap_or_else(|e| e.into_inner());
        if send() {
            st.pending += 1;
        }
    }

    /// Held back (a test, or a renderer keeping a short frame's cores): wait for the drop or
    /// the deadline.
    pub(crate) fn wait_while_held(&self) {
        let (lock, changed) = &*self.state;
        let mut st = lock.lock().unwrap_or_else(|e| e.into_inner());
        while let Some(until) = st.held_at(Instant::now(), true) {
            st = match until {
                None => changed.wait(st).unwrap_or_else(|e| e.into_inner()),
                Some(t) => {
                    let left = t.saturating_duration_since(Instant::now());
                    changed.wait_timeout(st, left).unwrap_or_else(|e| e.into_inner()).0
                }
            };
        }
    }

    /// One request answered: `record` (run under the lock) stores its result, then it stops
    /// being pending.
    pub(crate) fn finish_request(&self, record: impl FnOnce()) {
        let (lock, done) = &*self.state;
        let mut st = lock.lock().unwrap_or_else(|e| e.into_inner());
        record();
        st.pending -= 1;
        done.notify_all();
    }

    /// Wait until no request is pending (a hold without a deadline kept alive meanwhile
    /// makes this wait until it drops).
    pub(crate) fn wait_idle(&self) {
        let (lock, done) = &*self.state;
        let mut st = lock.lock().unwrap_or_else(|e| e.into_inner());
        while st.pending > 0 {
            st = done.wait(st).unwrap_or_else(|e| e.into_inner());
        }
    }

    /// The source is going: the worker ignores holds from now on and drains its queue.
    pub(crate) fn close(&self) {
        let (lock, changed) = &*self.state;
        lock.lock().unwrap_or_else(|e| e.into_inner()).closing = true;
        changed.notify_all();
    }
}

/// While it holds, the tier-1 worker of the JIT it came from starts no compile (it finishes
/// the one in progress): [`TierUpWatch::hold`], [`Jit::stall_tier_up`]. It holds until it
/// drops or, once given one ([`TierUpHold::release_at`]), until its deadline, dropped or
/// not; a JIT being dropped ignores it.
///
/// [`Jit::stall_tier_up`]: crate::jit::Jit::stall_tier_up
pub struct TierUpHold {
    state: Arc<(Mutex<TierUpState>, Condvar)>,
    id: u64,
}

impl TierUpHold {
    /// Hold only until `deadline`, whether dropped before then or not.
    pub fn release_at(&mut self, deadline: Instant) {
        let (lock, changed) = &*self.state;
        let mut st = lock.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(h) = st.holds.iter_mut().find(|h| h.id == self.id) {
            h.deadline = Some(deadline);
        }
        changed.notify_all();
    }
}

impl Drop for TierUpHold {
    /// A hold without a deadline ends here; one with a deadline keeps it (the renderer's
    /// hold ends with its frame, and a worker let go right then would compete with the
    /// thread that waits for the frame to come back, which under load gave that frame's
    /// caller its result milliseconds late).
    fn drop(&mut self) {
        let (lock, changed) = &*self.state;
        let mut st = lock.lock().unwrap_or_else(|e| e.into_inner());
        let now = Instant::now();
        // Expired deadlines go too, whoever's.
        st.holds.retain(|h| match h.deadline {
            Some(t) => t > now,
            None => h.id != self.id,
        });
        changed.notify_all();
    }
}
