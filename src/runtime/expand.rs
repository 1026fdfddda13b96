//! Expansion: run a calling primitive's setup once per instance, not once per tile.
//!
//! A primitive with no pixel part of its own whose setup calls primitives
//! ([`abi::expands`](crate::abi::expands): polygon -> screen_triangle, nurb_surface -> polygon)
//! draws only through its calls. Binned by its whole bound, its kernel would redo the whole
//! setup (clipping, de Boor evaluation, tessellation) in every tile it touches. Instead, after
//! compiling and before binning, the renderer runs it once in `MODE_EXPAND`: every call it
//! makes reaches [`record_call`] through `TileCtx::expand` (with the callee's kernel entry, its
//! `FuncId` and a copy of the argument block the call built) instead of running. Recorded
//! callees that expand themselves are expanded in turn at their recorded call depth; the others
//! become *draws* that replace the instance in the draw list, in call order. The renderer then
//! bounds, bins and renders draws exactly as it did instances.
//!
//! Invariant: a tile runs the same kernels with the same argument blocks in the same order as
//! it would have run through the calling instance (a call made in a tile the callee's bound
//! misses draws nothing there, binning being conservative), so the frame is bit-identical to
//! the per-tile path. The exceptions are limits, not pixels: a draw gets fresh setup fuel of
//! its own (the per-tile path shares one invocation's setup fuel between the caller and all
//! its calls), and run-time errors of the caller's setup are counted once, by the expand run.
//!
//! Fuel and errors: every expand and bound run counts its setup's run-time errors
//! (`super::errors`: the render runs count only their pixel code's), and the loop that ran
//! out of setup fuel, which the kernel leaves in `TileCtx::fuel`. A draw whose bound run
//! runs out of setup fuel is put in no tile: its setup would run out at the same loop in
//! every tile (setup fuel is per invocation and the setup does not depend on the tile), so
//! an endless setup loop costs one bound run, whatever the image size. Likewise an expand
//! run that runs out of fuel records no draws (what it recorded is dropped).
//!
//! Instances are expanded and their draws bound (`MODE_BOUND`) in parallel (rayon jobs of a
//! few hundred instances, and an instance's many calls in chunks of their own), each
//! instance with its own recorder and argument pool; a draw's bound is turned into the
//! rectangle of tiles it overlaps right there. The renderer then
//! bins the draws sequentially in instance order, so every tile's draw list does not depend
//! on the thread count. An instance drawn as itself (the usual case) allocates nothing.
//!
//! The recorded words are budgeted (`RenderOptions::expand_budget_words`, one counter for the
//! frame): an instance whose expansion would exceed what is left is rolled back (its words
//! refunded) and rendered per tile, as without expansion. Under that pressure, which
//! instances fall back can depend on the order jobs run in; the pixels never do.
//! Where it sits: `render::Renderer::render` step 2, between compiling and binning.

use std::collections::HashMap;
use std::ffi::c_void;
use std::sync::atomic::{AtomicUsize, Ordering};

use rayon::prelude::*;

use crate::abi::{
    expands, setup_fuel_ran_out, ArgLayout, ErrorSlot, Kernel, KernelFn, TileCtx, VariantKey, CALLEE_UNKNOWN,
    MAX_CALL_DEPTH, MODE_BOUND, MODE_EXPAND,
};
use crate::ir::{FuncId, Program};

use super::api::{Instance, RenderOptions};
use super::errors::{CountArrays, Counts};
use super::tiergate::{self, Compiler};

/// Budget charged per recorded call on top of its argument words (what its bookkeeping takes).
const CALL_WORDS: usize = 12;

/// An expanded instance with at least this many draws binds them in parallel, in chunks of
/// at least [`BOUND_CHUNK`] (a bound run of screen_triangle takes ~0.3-1 us: smaller
/// chunks would cost rayon's bookkeeping more than they spread).
const PARALLEL_BOUNDS: usize = 256;
const BOUND_CHUNK: usize = 64;

/// One kernel invocation per tile it is binned into: a submitted instance, or a call that an
/// expanded instance made.
#[derive(Clone, Copy)]
pub struct Draw<'a> {
    pub entry: KernelFn,
    pub args: &'a [u32],
    /// `TileCtx::call_depth` to run it at (0 for an instance, the call's depth for a call).
    pub call_depth: u32,
}

/// Run a draw's kernel in bound mode: its screen bound (if it recorded one), the run-time
/// errors it counted and whether its setup ran out of fuel.
fn run_bound(program: &Program, draw: &Draw, opts: &RenderOptions) -> (Option<[f32; 4]>, Counts, bool) {
    let mut ctx = context(MODE_BOUND, opts);
    ctx.call_depth = draw.call_depth;
    // Zero-size buffers: bound mode never touches them, and the empty tile rectangle
    // (x0 = x1 = 0) means even a pixel pass would cover no pixel.
    let mut no_depth: Vec<u32> = Vec::new();
    let mut no_planes: Vec<f32> = Vec::new();
    let mut no_counts: Vec<u32> = Vec::new();
    ctx.depth = no_depth.as_mut_ptr();
    ctx.gbuf = no_planes.as_mut_ptr();
    ctx.write_count = no_counts.as_mut_ptr();
    let mut errors = Counts::new();
    CountArrays::with(program, |counts| {
        ctx.setup_counts = counts.counts();
        ctx.pixel_counts = counts.counts();
        // SAFETY: `ctx` is a valid TileCtx naming (empty) buffers that outlive the call and
        // count arrays of the program's slots, and `draw.args` holds at least the words
        // the kernel's layout reads (checked when the kernel was made ready, or when the
        // call was recorded), which is all the ABI lets a kernel read.
        unsafe { (draw.entry)(&mut ctx, draw.args.as_ptr()) };
        if ctx.error != 0 {
            counts.take(&mut errors);
        }
    });
    let ran_out = count_setup_fuel(program, &ctx, &mut errors);
    let bound = (ctx.bound_set != 0).then_some(ctx.bound);
    (bound, errors, ran_out)
}

/// Whether the run that left `ctx` ran out of setup fuel; if so, its loop's count (kernels
/// leave it to the runner, `abi::setup_fuel_ran_out`) goes to `errors`.
fn count_setup_fuel(program: &Program, ctx: &TileCtx, errors: &mut Counts) -> bool {
    let Some(site) = setup_fuel_ran_out(ctx.fuel) else {
        return false;
    };
    errors.push((ErrorSlot::Fuel(site).index(program.sites.len()) as u32, 1));
    true
}

/// A context for `mode` with the frame's viewport and fuel (no tile, no buffers, no counts).
pub(super) fn context(mode: u32, opts: &RenderOptions) -> TileCtx {
    // Kernels take fuel as a signed count (a negative one is spent): cap at i64::MAX.
    let cap = |fuel: u64| fuel.min(i64::MAX as u64);
    TileCtx {
        fuel: cap(opts.setup_fuel),
        pixel_fuel: cap(opts.pixel_fuel),
        group_fuel_floor: cap(opts.group_fuel_floor),
        ..TileCtx::new(mode, opts.width, opts.height)
    }
}

/// An inclusive rectangle of tile indices: (tx0, ty0, tx1, ty1).
pub type TileRect = (usize, usize, usize, usize);

/// Where a draw's argument block lives.
#[derive(Clone, Copy)]
enum Args {
    /// The submitted instance's own block.
    Instance,
    /// `pool[start..start + len]` of the instance's [`Expanded`].
    Pool { start: usize, len: usize },
}

#[derive(Clone, Copy)]
struct Item {
    entry: KernelFn,
    args: Args,
    call_depth: u32,
}

/// The words the frame's expansion may still record, shared by the parallel jobs.
pub(crate) struct Budget(AtomicUsize);

impl Budget {
    pub fn new(words: usize) -> Budget {
        Budget(AtomicUsize::new(words))
    }

    /// Take `cost` words; false (and nothing taken) when fewer are left.
    fn take(&self, cost: usize) -> bool {
        self.0
            .fetch_update(Ordering::Relaxed, Ordering::Relaxed, |left| left.checked_sub(cost))
            .is_ok()
    }

    fn refund(&self, words: usize) {
        self.0.fetch_add(words, Ordering::Relaxed);
    }
}

/// One submitted instance's draws (itself, or the calls it made), the tiles each overlaps
/// and the run-time errors met on the way, in order.
pub enum Expanded {
    /// Drawn as itself (the usual case: a frame may hold hundreds of thousands of small
    /// triangles, so this allocates nothing and stays small).
    Itself {
        entry: KernelFn,
        /// The tiles its `MODE_BOUND` bound overlaps (`None`: no tile, also when its bound
        /// run ran out of setup fuel).
        tiles: Option<TileRect>,
        /// The run-time errors its bound run counted.
        errors: Box<[(u32, u64)]>,
        /// Its expansion exceeded the budget (it is drawn per tile instead).
        over_budget: bool,
    },
    /// Replaced by the calls it made.
    Calls(Box<CallDraws>),
}

/// The draws of an instance replaced by its calls.
pub struct CallDraws {
    /// Argument blocks of the recorded calls, back to back.
    pool: Vec<u32>,
    items: Vec<Item>,
    /// The tiles each item's `MODE_BOUND` bound overlaps (`None`: no tile, also when its
    /// bound run ran out of setup fuel).
    tiles: Vec<Option<TileRect>>,
    /// The run-time errors the expand and bound runs counted.
    errors: Counts,
}

/// One call recorded by [`record_call`].
struct Call {
    callee: u32,
    entry: KernelFn,
    start: usize,
    len: usize,
    call_depth: u32,
}

/// What one `MODE_EXPAND` run recorded (`TileCtx::expand_state` points at it during the run).
struct Recorder<'b> {
    words: Vec<u32>,
    calls: Vec<Call>,
    budget: &'b Budget,
    /// Words taken from `budget` by this recorder.
    charged: usize,
    over_budget: bool,
}

/// `abi::ExpandFn`: copy one call into the recorder named by `ctx.expand_state`.
///
/// # Safety
/// `ctx` is the context of a running `MODE_EXPAND` invocation whose `expand_state` points at
/// a live `Recorder` no one else touches during the call, and `args` is `words` words long
/// (both as [`run_expand`] and the kernels that call this guarantee).
unsafe extern "C" fn record_call(
    ctx: *mut TileCtx,
    callee: u32,
    entry: Option<KernelFn>,
    args: *const u32,
    words: u32,
) {
    // SAFETY: the contract above; nothing else holds a reference to either while this runs.
    let (ctx, rec) = unsafe { (&*ctx, &mut *(*ctx).expand_state.cast::<Recorder>()) };
    let (Some(entry), false) = (entry, args.is_null()) else {
        return;
    };
    let len = words as usize;
    let cost = len.saturating_add(CALL_WORDS);
    if rec.over_budget || !rec.budget.take(cost) {
        // Keep running (the setup ends on its own, fuel-bounded); the expansion is dropped.
        rec.over_budget = true;
        return;
    }
    rec.charged += cost;
    let start = rec.words.len();
    // SAFETY: `args` is `words` words long (the contract above).
    rec.words
        .extend_from_slice(unsafe { std::slice::from_raw_parts(args, len) });
    rec.calls.push(Call {
        callee,
        entry,
        start,
        len,
        call_depth: ctx.call_depth,
    });
}

/// Run `entry` on `args` once in `MODE_EXPAND` at `call_depth`: the calls it made, the
/// run-time errors it counted and whether its setup ran out of fuel.
fn run_expand<'b>(
    program: &Program,
    entry: KernelFn,
    args: &[u32],
    call_depth: u32,
    opts: &RenderOptions,
    budget: &'b Budget,
) -> (Recorder<'b>, Counts, bool) {
    let mut rec = Recorder {
        words: vec![],
        calls: vec![],
        budget,
        charged: 0,
        over_budget: false,
    };
    let mut ctx = context(MODE_EXPAND, opts);
    ctx.call_depth = call_depth;
    // Zero-size buffers and an empty tile, as in bound mode: nothing can be drawn.
    let mut no_depth: Vec<u32> = Vec::new();
    let mut no_planes: Vec<f32> = Vec::new();
    let mut no_counts: Vec<u32> = Vec::new();
    ctx.depth = no_depth.as_mut_ptr();
    ctx.gbuf = no_planes.as_mut_ptr();
    ctx.write_count = no_counts.as_mut_ptr();
    ctx.expand = Some(record_call);
    ctx.expand_state = (&mut rec as *mut Recorder).cast::<c_void>();
    let mut errors = Counts::new();
    CountArrays::with(program, |counts| {
        ctx.setup_counts = counts.counts();
        ctx.pixel_counts = counts.counts();
        // SAFETY: `ctx` names (empty) buffers that outlive the call, count arrays of the
        // program's slots and a recorder that is not touched otherwise until the call
        // returns; `args` is at least as long as the kernel's layout reads (checked by the
        // renderer for instances, by `Expander::fits` for calls).
        unsafe { entry(&mut ctx, args.as_ptr()) };
        if ctx.error != 0 {
            counts.take(&mut errors);
        }
    });
    let ran_out = count_setup_fuel(program, &ctx, &mut errors);
    (rec, errors, ran_out)
}

/// Expands one instance.
struct Expander<'p> {
    program: &'p Program,
    opts: &'p RenderOptions,
    budget: &'p Budget,
    key: &'p VariantKey,
    pool: Vec<u32>,
    items: Vec<Item>,
    errors: Counts,
    /// Words this instance took from the budget (refunded if it falls back).
    charged: usize,
    /// Layouts of recorded callees under the key, to check each block's length.
    layouts: HashMap<u32, ArgLayout>,
}

/// The draws of instance `inst` (whose kernel is `kernel`), each bound and its bound turned
/// into the tiles it overlaps by `tiles_of`: its calls if its primitive expands (and
/// expansion is on and fits the budget), else itself. `compiler`: the frame's background
/// compiler, whose gate (`tiergate`) decides whether many calls are bound in parallel.
pub(crate) fn expand_instance(
    program: &Program,
    opts: &RenderOptions,
    budget: &Budget,
    inst: &Instance,
    kernel: &Kernel,
    compiler: Option<&dyn Compiler>,
    tiles_of: impl Fn([f32; 4]) -> Option<TileRect> + Sync,
) -> Expanded {
    let mut over_budget = false;
    if opts.expand_calls && expands(program, inst.func) {
        let mut e = Expander {
            program,
            opts,
            budget,
            key: &kernel.key,
            pool: vec![],
            items: vec![],
            errors: vec![],
            charged: 0,
            layouts: HashMap::new(),
        };
        if e.expand(kernel.entry, &inst.args, 0) {
            let bound_one = |item: &Item| {
                let (bound, errors, ran_out) = run_bound(program, &item.draw(&e.pool, inst), opts);
                (bound.filter(|_| !ran_out).and_then(&tiles_of), errors)
            };
            // A tessellation's thousands of draws are bound in parallel chunks, so a thread
            // done with its own instances helps with a large patch's (one pass after the
            // expansion instead waited for the largest patch's setup: measured slower). Not
            // under a closed gate, which leaves the pool's other thread to the compiler.
            // (A chunk as long as the whole list is never split: it runs on this thread.)
            let in_parallel = e.items.len() >= PARALLEL_BOUNDS && !tiergate::closed(compiler);
            let chunk = if in_parallel { BOUND_CHUNK } else { usize::MAX };
            let (tiles, errors): (Vec<_>, Vec<_>) = e.items.par_iter().with_min_len(chunk).map(bound_one).unzip();
            e.errors.extend(errors.into_iter().flatten());
            return Expanded::Calls(Box::new(CallDraws {
                pool: e.pool,
                items: e.items,
                tiles,
                errors: e.errors,
            }));
        }
        // Over budget: forget what it recorded (errors included) and render it per tile, as
        // without expansion (which reports its run-time errors again).
        budget.refund(e.charged);
        over_budget = true;
    }
    let itself = Item {
        entry: kernel.entry,
        args: Args::Instance,
        call_depth: 0,
    };
    let (bound, errors, ran_out) = run_bound(program, &itself.draw(&[], inst), opts);
    Expanded::Itself {
        entry: kernel.entry,
        tiles: bound.filter(|_| !ran_out).and_then(tiles_of),
        errors: errors.into_boxed_slice(),
        over_budget,
    }
}

impl Draw<'_> {
    /// A placeholder (no arguments, a kernel that does nothing) for slots about to be
    /// overwritten.
    pub const NONE: Draw<'static> = Draw {
        entry: no_draw,
        args: &[],
        call_depth: 0,
    };
}

/// The placeholder kernel of [`Draw::NONE`]: touches nothing.
unsafe extern "C" fn no_draw(_ctx: *mut TileCtx, _args: *const u32) {}

impl Item {
    /// This item of instance `inst` whose recorded blocks are in `pool`.
    fn draw<'a>(&self, pool: &'a [u32], inst: &'a Instance) -> Draw<'a> {
        let args = match self.args {
            Args::Instance => inst.args.as_slice(),
            Args::Pool { start, len } => &pool[start..start + len],
        };
        Draw {
            entry: self.entry,
            args,
            call_depth: self.call_depth,
        }
    }
}

impl Expander<'_> {
    /// Expand one invocation (`entry` on `args` at `call_depth`) into draws; false when the
    /// budget ran out.
    fn expand(&mut self, entry: KernelFn, args: &[u32], call_depth: u32) -> bool {
        let (rec, errors, ran_out) = run_expand(self.program, entry, args, call_depth, self.opts, self.budget);
        self.charged += rec.charged;
        self.errors.extend(errors);
        if rec.over_budget {
            return false;
        }
        if ran_out {
            // The invocation draws nothing (its setup would run out in every tile).
            self.budget.refund(rec.charged);
            self.charged -= rec.charged;
            return true;
        }
        // The first recorder's words become the pool as they are (its kept calls stay where
        // they were recorded): a tessellation records megabytes, and copying them faulted
        // in fresh pages for all of it. Later recorders' kept blocks are appended.
        let recorded = if self.pool.is_empty() {
            self.pool = rec.words;
            None
        } else {
            Some(rec.words)
        };
        for call in &rec.calls {
            let range = call.start..call.start + call.len;
            let block = match &recorded {
                Some(words) => &words[range.clone()],
                None => &self.pool[range.clone()],
            };
            if !fits(&mut self.layouts, self.program, self.key, call.callee, block) {
                // Cannot happen for blocks the JIT or the hand-written kernels build; never
                // hand a kernel a block shorter than its layout reads.
                continue;
            }
            let expands_too = call.callee != CALLEE_UNKNOWN
                && call.call_depth <= MAX_CALL_DEPTH
                && expands(self.program, FuncId(call.callee));
            if expands_too {
                // A copy: the nested expansion appends to the pool this may point into.
                let block = block.to_vec();
                if !self.expand(call.entry, &block, call.call_depth) {
                    return false;
                }
                continue;
            }
            let start = match &recorded {
                Some(words) => {
                    let start = self.pool.len();
                    self.pool.extend_from_slice(&words[range]);
                    start
                }
                None => call.start,
            };
            self.items.push(Item {
                entry: call.entry,
                args: Args::Pool { start, len: call.len },
                call_depth: call.call_depth,
            });
        }
        true
    }
}

/// Whether `block` is at least as long as `callee`'s layout under `key` reads (an unknown
/// callee is taken at its word: its block is what a native kernel built for it); `layouts`
/// keeps the layouts made.
fn fits(
    layouts: &mut HashMap<u32, ArgLayout>,
    program: &Program,
    key: &VariantKey,
    callee: u32,
    block: &[u32],
) -> bool {
    if callee == CALLEE_UNKNOWN {
        return true;
    }
    if callee as usize >= program.functions.len() {
        return false;
    }
    let layout = layouts
        .entry(callee)
        .or_insert_with(|| ArgLayout::new(program, FuncId(callee), key));
    let n_seq = block.first().copied().unwrap_or(0);
    layout.words(n_seq) <= block.len()
}

impl Expanded {
    /// Draws of this instance.
    pub fn len(&self) -> usize {
        match self {
            Expanded::Itself { .. } => 1,
            Expanded::Calls(calls) => calls.items.len(),
        }
    }

    /// Whether the instance was replaced by its calls.
    pub fn expanded(&self) -> bool {
        matches!(self, Expanded::Calls(_))
    }

    /// Whether its expansion exceeded the budget (it is drawn per tile instead).
    pub fn over_budget(&self) -> bool {
        matches!(self, Expanded::Itself { over_budget: true, .. })
    }

    /// The run-time errors the expand and bound runs counted.
    pub fn errors(&self) -> &[(u32, u64)] {
        match self {
            Expanded::Itself { errors, .. } => errors,
            Expanded::Calls(calls) => &calls.errors,
        }
    }

    /// The tiles draw `i` (below [`Self::len`]) overlaps.
    pub fn tiles(&self, i: usize) -> Option<TileRect> {
        match self {
            Expanded::Itself { tiles, .. } => *tiles,
            Expanded::Calls(calls) => calls.tiles[i],
        }
    }

    /// Draw `i` (below [`Self::len`]) of instance `inst`.
    pub fn draw<'a>(&'a self, i: usize, inst: &'a Instance) -> Draw<'a> {
        match self {
            Expanded::Itself { entry, .. } => Draw {
                entry: *entry,
                args: &inst.args,
                call_depth: 0,
            },
            Expanded::Calls(calls) => calls.items[i].draw(&calls.pool, inst),
        }
    }
}
