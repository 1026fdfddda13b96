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
//! the per-tile path. The exceptions are limits, not pixels: a draw gets fresh fuel of its own
//! (the per-tile path shares one invocation's fuel between the caller and all its calls), and
//! run-time errors of the caller's setup are recorded once, by the expand run.
//!
//! The recorded words are budgeted (`RenderOptions::expand_budget_words`); an instance whose
//! expansion would exceed the budget is rolled back and rendered per tile, as without
//! expansion. Where it sits: `frame::Renderer::render` step 2, between compiling and binning.

use std::collections::HashMap;
use std::ffi::c_void;

use crate::abi::{expands, ArgLayout, KernelFn, TileCtx, VariantKey, CALLEE_UNKNOWN, MAX_CALL_DEPTH, MODE_EXPAND};
use crate::ir::{FuncId, Program};
use crate::jit::Kernel;

use super::api::{Instance, RenderOptions};
use super::frame::fresh_ctx;

/// Budget charged per recorded call on top of its argument words (what its bookkeeping takes).
const CALL_WORDS: usize = 12;

/// One kernel invocation per tile it is binned into: a submitted instance, or a call that an
/// expanded instance made.
pub(crate) struct Draw<'a> {
    pub entry: KernelFn,
    pub args: &'a [u32],
    /// `TileCtx::call_depth` to run it at (0 for an instance, the call's depth for a call).
    pub call_depth: u32,
    /// The submitted instance it comes from (its run-time errors are reported as that one's).
    pub instance: usize,
}

/// Where a draw's argument block lives.
#[derive(Clone, Copy)]
enum Args {
    /// The submitted instance's own block.
    Instance,
    /// `pool[start..start + len]`.
    Pool { start: usize, len: usize },
}

#[derive(Clone, Copy)]
struct Item {
    entry: KernelFn,
    args: Args,
    call_depth: u32,
    instance: usize,
}

/// The draw list built instance by instance, and what expanding cost.
pub(crate) struct Expansion<'p> {
    program: &'p Program,
    opts: &'p RenderOptions,
    /// Argument blocks of recorded calls, back to back.
    pool: Vec<u32>,
    items: Vec<Item>,
    budget_left: usize,
    /// Layouts of recorded callees under the frame's key, to check each block's length.
    layouts: HashMap<VariantKey, HashMap<u32, ArgLayout>>,
    /// Instances replaced by their calls.
    pub expanded_instances: usize,
    /// Draws those instances produced.
    pub expanded_calls: usize,
    /// Instances whose expansion exceeded the budget (rendered per tile).
    pub over_budget: usize,
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
struct Recorder {
    words: Vec<u32>,
    calls: Vec<Call>,
    budget_left: usize,
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
    if rec.over_budget || cost > rec.budget_left {
        // Keep running (the setup ends on its own, fuel-bounded); the expansion is dropped.
        rec.over_budget = true;
        return;
    }
    rec.budget_left -= cost;
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

/// Run `entry` on `args` once in `MODE_EXPAND` at `call_depth`: the calls it made, and its
/// run-time error.
fn run_expand(
    entry: KernelFn,
    args: &[u32],
    call_depth: u32,
    opts: &RenderOptions,
    budget_left: usize,
) -> (Recorder, Option<(u32, u32)>) {
    let mut rec = Recorder {
        words: vec![],
        calls: vec![],
        budget_left,
        over_budget: false,
    };
    let mut ctx = fresh_ctx(opts, MODE_EXPAND);
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
    // SAFETY: `ctx` names (empty) buffers that outlive the call and a recorder that is not
    // touched otherwise until the call returns; `args` is at least as long as the kernel's
    // layout reads (checked by the caller for instances, by `Expansion::fits` for calls).
    unsafe { entry(&mut ctx, args.as_ptr()) };
    let error = (ctx.error != 0).then_some((ctx.error, ctx.error_site));
    (rec, error)
}

impl<'p> Expansion<'p> {
    pub fn new(program: &'p Program, opts: &'p RenderOptions) -> Expansion<'p> {
        Expansion {
            program,
            opts,
            pool: vec![],
            items: vec![],
            budget_left: opts.expand_budget_words,
            layouts: HashMap::new(),
            expanded_instances: 0,
            expanded_calls: 0,
            over_budget: 0,
        }
    }

    /// Draws so far.
    pub fn len(&self) -> usize {
        self.items.len()
    }

    /// Append instance `index`'s draws: its calls if it expands (and expansion is on and fits
    /// the budget), else the instance itself. Run-time errors of expand runs go to `errors`
    /// as (instance, code, site).
    pub fn add(&mut self, index: usize, inst: &Instance, kernel: &Kernel, errors: &mut Vec<(usize, u32, u32)>) {
        let itself = Item {
            entry: kernel.entry,
            args: Args::Instance,
            call_depth: 0,
            instance: index,
        };
        if !(self.opts.expand_calls && expands(self.program, inst.func)) {
            self.items.push(itself);
            return;
        }
        let (pool_mark, items_mark, budget_mark, errors_mark) =
            (self.pool.len(), self.items.len(), self.budget_left, errors.len());
        if self.expand(kernel.entry, &inst.args, 0, &kernel.key, index, errors) {
            self.expanded_instances += 1;
            self.expanded_calls += self.items.len() - items_mark;
            return;
        }
        // Over budget: forget what it recorded and render it per tile, as without expansion
        // (which reports its run-time errors again).
        self.pool.truncate(pool_mark);
        self.items.truncate(items_mark);
        self.budget_left = budget_mark;
        errors.truncate(errors_mark);
        self.over_budget += 1;
        self.items.push(itself);
    }

    /// Expand one invocation (`entry` on `args` at `call_depth`) into draws; false when the
    /// budget ran out.
    fn expand(
        &mut self,
        entry: KernelFn,
        args: &[u32],
        call_depth: u32,
        key: &VariantKey,
        instance: usize,
        errors: &mut Vec<(usize, u32, u32)>,
    ) -> bool {
        let (rec, error) = run_expand(entry, args, call_depth, self.opts, self.budget_left);
        self.budget_left = rec.budget_left;
        if let Some((code, site)) = error {
            errors.push((instance, code, site));
        }
        if rec.over_budget {
            return false;
        }
        for call in &rec.calls {
            let block = &rec.words[call.start..call.start + call.len];
            if !self.fits(call.callee, key, block) {
                // Cannot happen for blocks the JIT or the hand-written kernels build; never
                // hand a kernel a block shorter than its layout reads.
                continue;
            }
            let expands_too = call.callee != CALLEE_UNKNOWN
                && call.call_depth <= MAX_CALL_DEPTH
                && expands(self.program, FuncId(call.callee));
            if expands_too {
                if !self.expand(call.entry, block, call.call_depth, key, instance, errors) {
                    return false;
                }
                continue;
            }
            let start = self.pool.len();
            self.pool.extend_from_slice(block);
            self.items.push(Item {
                entry: call.entry,
                args: Args::Pool { start, len: call.len },
                call_depth: call.call_depth,
                instance,
            });
        }
        true
    }

    /// Whether `block` is at least as long as `callee`'s layout under `key` reads (an
    /// unknown callee is taken at its word: its block is what a native kernel built for it).
    fn fits(&mut self, callee: u32, key: &VariantKey, block: &[u32]) -> bool {
        if callee == CALLEE_UNKNOWN {
            return true;
        }
        if callee as usize >= self.program.functions.len() {
            return false;
        }
        let program = self.program;
        if !self.layouts.contains_key(key) {
            self.layouts.insert(key.clone(), HashMap::new());
        }
        let Some(of_key) = self.layouts.get_mut(key) else {
            return false;
        };
        let layout = of_key
            .entry(callee)
            .or_insert_with(|| ArgLayout::new(program, FuncId(callee), key));
        let n_seq = block.first().copied().unwrap_or(0);
        layout.words(n_seq) <= block.len()
    }

    /// Draw `i` (below [`Self::len`]).
    pub fn draw<'a>(&'a self, i: usize, instances: &'a [Instance]) -> Draw<'a> {
        let item = self.items[i];
        let args = match item.args {
            Args::Instance => instances[item.instance].args.as_slice(),
            Args::Pool { start, len } => &self.pool[start..start + len],
        };
        Draw {
            entry: item.entry,
            args,
            call_depth: item.call_depth,
            instance: item.instance,
        }
    }

    /// Every draw, in order.
    pub fn draws<'a>(&'a self, instances: &'a [Instance]) -> Vec<Draw<'a>> {
        (0..self.items.len()).map(|i| self.draw(i, instances)).collect()
    }
}
