//! IR -> CLIF: builds the Cranelift function of one primitive specialised for one variant key.
//!
//! [`lower_kernel`] builds one [`Lower`], the state of one kernel's lowering, from the
//! middle end's [`Plan`] for the (function, key, tier) ([`crate::mid::plan`]: every analysis
//! the lowering consults, computed before it starts), and [`Lower::body`] gives the
//! top-level order: the setup as scalar code, then the pixel part's loops. `Lower`'s
//! methods live by concept in the child modules:
//! - [`frame`]: the kernel's exits, `ctx`, bound mode, run-time errors and their deferral;
//! - [`stmt`]: statements and the lane masks of pixel code; loops, fuel;
//! - [`expr`]: expressions, operators, conversions, value numbering;
//! - [`storage`]: where locals live (frames), places and accesses, index checks;
//! - [`planes`]: interpolation data, arms, inlined interpolators, G-buffer planes;
//! - [`call`]: primitive calls;
//! - [`spill`]: the uniform frame the pixel loops read the setup's values from, and the
//!   row terms hoisted into it;
//! - [`loops`]: the pixel passes, the copies of the loops unswitching plans, rows and
//!   groups, and [`walk`] the block walk;
//! - [`block`]: the block walk's interval evaluation of the guard prefix; [`carry`]: the
//!   int terms carried along a row;
//! - [`outline`]: tier 0's split of a kernel in two functions.
//!
//! Shape of every kernel (`fn(ctx, args)`):
//! 1. `setup` as scalar code: uniform values are `f32`/`i32`/`i8` SSA variables; `bound`
//!    unions into `ctx.bound` in bound mode and sets the pass rectangle; primitive calls
//!    call the callee directly, or in `MODE_EXPAND` hand it to `ctx.expand` (see [`call`]).
//! 2. If there is a pixel part: the pixel loops (see [`loops`]).
//! 3. Per group the pixel statements run on vectors under lane masks (see [`stmt`]).
//!
//! Nothing here panics on a checked program; an IR shape the checker should have excluded
//! gives a [`JitError`]. Each child module states the invariants its code keeps.

use cranelift_codegen::ir::{
    self, condcodes::IntCC, types, Block, InstBuilder, StackSlot, StackSlotData, StackSlotKind,
};
use cranelift_frontend::{FunctionBuilder, Variable};

use super::fixed;
use super::libm::LibmFn;
use super::value::{cl_type, ctx_off, mem_flags, Val, VnTable, F32X4};
use super::JitError;
use crate::abi::{ArgLayout, BindingKind, ParamSlot, VariantKey, ERR_STACK};
use crate::ir::{
    ConstValue, Elem, ExprId, ExprKind, Exprs, FixedFormat, FuncId, Function, LocalId, LoopId, Program, Scalar, StmtId,
    StmtKind, Type,
};
use crate::mid::pred::{const_index_in_range, const_int, key_constant, speculable_expr};
use crate::mid::{bounds, PixelPlan, Plan, Tier};

mod block;
mod call;
mod carry;
mod expr;
mod frame;
mod loops;
mod outline;
mod planes;
mod rows;
mod spill;
mod stmt;
mod storage;
mod texture;
mod walk;

pub(crate) use outline::pixel_signature;

pub(crate) type Res<T> = Result<T, JitError>;

/// Pixel groups (of 4) per step of the inner loop: copies of the group code one after the
/// other, so loop overhead is paid once per `4 * UNROLL` pixels. Measured (docs/performance.md):
/// 2 and 4 copies were no faster than 1 on the fill workloads (the group body, not the loop,
/// is the cost) and cost compile time in proportion, so 1.
const UNROLL: u32 = 1;
/// Block size of block-level culling, in pixels (BLOCK_W a multiple of `4 * UNROLL`).
const BLOCK_W: u32 = 16;
const BLOCK_H: u32 = 8;
/// `vhigh_bits` of a lane mask with every lane of a group set.
const ALL_LANE_BITS: i64 = (1 << 4) - 1;
/// Pass rectangles smaller than this many pixels skip the block evaluation.
const SMALL_RECT: i64 = 128;

/// A frame local's stores left to one side of an unswitched condition
/// (`Lower::defer_frame_stores`).
struct DeferredStore {
    /// The side (`true`: then) whose dispatch block stores it.
    on: bool,
    vars: Vec<Variable>,
    first_word: u32,
    scalar: Scalar,
}

/// The render pass's rectangle and tile geometry, shared by the loops that walk it.
struct PassRect {
    x0: ir::Value,
    y0: ir::Value,
    lo_x: ir::Value,
    stride64: ir::Value,
    /// A group starting at `g` has all four lanes inside [lo_x, hi_x) iff
    /// `(g - lo_x) <u interior_lim` (`max(hi_x - lo_x - 3, 0)`: 0 makes no group interior).
    interior_lim: ir::Value,
}

pub(crate) fn err<T>(msg: impl Into<String>) -> Res<T> {
    Err(JitError { message: msg.into() })
}

/// Resolves the functions a kernel calls: other kernels (same key) and libm helpers.
pub(crate) trait Linker {
    fn kernel_ref(&mut self, func: &mut ir::Function, callee: FuncId) -> Res<ir::FuncRef>;
    fn libm_ref(&mut self, func: &mut ir::Function, f: LibmFn) -> Res<ir::FuncRef>;
    /// The kernel's outlined pixel function (signature `sig`; see [`outline`]).
    fn pixel_ref(&mut self, func: &mut ir::Function, sig: ir::Signature) -> Res<ir::FuncRef>;
    /// Tier 0: the kernel is finished before its outlined pixel function is lowered (see
    /// [`outline`]). The linker may take `func` (leaving an empty function in its place) to
    /// compile it meanwhile; left in place, it is in the caller's function as usual.
    fn kernel_finished(&mut self, _func: &mut ir::Function) {}
}

/// Where a deferred error's code starts in `Lower::pending_error` (its site + 1 below).
const PENDING_CODE_SHIFT: u32 = 28;

/// A setup-code clear of more bytes than this is a loop (see `Lower::zero_stack_bytes`):
/// above the NURB tessellation's per-vertex arrays (`float row_points[16][4]`, 256 bytes,
/// cleared per row of every vertex stay straight stores), below its per-patch ones.
const ZERO_LOOP_BYTES: u32 = 256;

/// A clear of more bytes than this in pixel code is a loop, unless the code is flat (see
/// `Lower::zero_stack_bytes`): a varying array of up to `MAX_FLAT_ARRAY` floats, which
/// flat code may have, stays straight stores.
const ZERO_LOOP_PIXEL_BYTES: u32 = 16 * crate::mid::flat::MAX_FLAT_ARRAY;

/// The format depth values have in the depth buffer.
const DEPTH_FORMAT: FixedFormat = FixedFormat { bits: 32, frac: 32 };

/// Where a local lives.
#[derive(Clone)]
enum Storage {
    /// One SSA variable per flattened component.
    Vars(Vec<Variable>),
    /// A stack slot (dynamically indexed locals): 4 bytes per uniform component, 16 per
    /// varying one.
    Stack(StackSlot),
    /// In the uniform frame at this word (uniform locals the pixel part never assigns; see
    /// `spill_uniforms`). Read-only from then on.
    Frame(u32),
    /// The primitive's own Z: assignments also mark `z_written`.
    Z(Variable),
    /// A parameter read from the argument block.
    Args,
}

/// A loop of the IR being lowered.
struct LoopCtx {
    id: Option<LoopId>,
    varying: bool,
    step: Block,
    exit: Block,
    /// Varying loops: lanes still in the loop, and lanes that continued this iteration.
    mask: Option<Variable>,
    cont: Option<Variable>,
}

/// One function being lowered: the primitive itself, or a shared interpolator inlined into it.
struct Frame<'a> {
    func: &'a Function,
    /// `func`'s id in the program.
    id: FuncId,
    slots: Vec<ParamSlot>,
    fixed_words: u32,
    storage: Vec<Storage>,
    loops: Vec<LoopCtx>,
    /// For an inlined interpolator: the binding its result goes to.
    interp_binding: Option<usize>,
}

/// Per-group state of the pixel loop.
struct PixelState {
    alive: Variable,
    exec: Variable,
    z_written: Variable,
    group_end: Block,
    /// Element index of the group's first pixel in the tile buffers.
    tile_idx: ir::Value,
    /// Pixel centres of the group's lanes.
    x_f: ir::Value,
    y_f: ir::Value,
    /// The uniform frame's address, loaded in this group (see `spill_uniforms`).
    frame_base: Option<ir::Value>,
    /// The depth buffer's raw values for the group (if loaded).
    z_raw: Option<ir::Value>,
    /// Nesting of varying control flow (varying ifs, varying loops, inlined interpolators).
    varying_depth: u32,
}

/// The dynamic part of a component offset.
#[derive(Clone, Copy)]
enum Dyn {
    None,
    Uniform(ir::Value),
    Varying(ir::Value),
}

#[derive(Clone)]
enum Root {
    Local { frame: usize, local: LocalId },
    Stack { slot: StackSlot, varying: bool },
    Temp(Val),
}

/// A (possibly indexed) value not yet loaded.
struct Access<'a> {
    root: Root,
    ty: AccessTy<'a>,
    scalar: Scalar,
    base: u32,
    dyn_off: Dyn,
    /// Interp elements hold only the view's components (temporaries), not all of them.
    compact: bool,
}

/// The type of an [`Access`]: a local's or an expression's type with the dimensions already
/// indexed away (without building a `Type` per index: its dimension vector was two
/// allocations per indexed access).
#[derive(Clone, Copy)]
struct AccessTy<'a> {
    base: &'a Type,
    /// The run-time dimension is still there (`Type::per_seq`).
    per_seq: bool,
    /// Fixed dimensions indexed away.
    skip: usize,
}

impl<'a> AccessTy<'a> {
    fn of(base: &'a Type) -> AccessTy<'a> {
        AccessTy {
            base,
            per_seq: base.per_seq,
            skip: 0,
        }
    }

    fn dims(&self) -> &'a [u32] {
        self.base.dims.get(self.skip..).unwrap_or(&[])
    }

    fn elem(&self) -> Elem {
        self.base.elem
    }

    fn fixed_len(&self) -> u32 {
        self.dims().iter().product()
    }

    /// The type of `self[i]` (see `Type::element`).
    fn element(self) -> AccessTy<'a> {
        if self.per_seq {
            AccessTy { per_seq: false, ..self }
        } else {
            AccessTy {
                skip: self.skip + 1,
                ..self
            }
        }
    }
}

/// What an `interpolation` arm serves.
#[derive(Clone)]
struct ArmInfo {
    /// Kind bindings (indices into `key.bindings`) this arm writes.
    bindings: Vec<usize>,
}

pub(crate) struct Lower<'a, 'b> {
    pub(crate) b: FunctionBuilder<'b>,
    program: &'a Program,
    key: &'a VariantKey,
    layout: &'a ArgLayout,
    n_interp: u32,
    linker: &'b mut dyn Linker,
    ctx: ir::Value,
    args: ir::Value,
    /// Where a `return` goes: `kernel_exit`, or while the setup defers its errors the block
    /// that flushes them first (`setup_exit`).
    exit: Block,
    /// The block that ends the function being lowered (stores the fuel, returns).
    kernel_exit: Block,
    frames: Vec<Frame<'a>>,
    pix: Option<PixelState>,
    /// Varying loop masks from outermost to innermost (all frames), for restoring `exec`.
    vloops: Vec<(Variable, Variable)>,
    view: Vec<u32>,
    arm: Option<ArmInfo>,
    bound_vars: [Variable; 4],
    has_bound: Variable,
    /// The setup fuel left (`ctx.fuel` while the kernel runs, kept in a register: loaded at
    /// entry, stored at the exit and around direct primitive calls, whose callees' setups
    /// spend it too). Setup loops spend it.
    fuel: Variable,
    /// The fuel left to the current pixel group: `ctx.group_fuel` at the start of every
    /// group (see [`loops`]); loops of pixel code spend it. Defined only when the pixel code
    /// has loops (`group_fuel_used`).
    group_fuel: Variable,
    group_fuel_used: bool,
    /// The `return` of the function's stack check that fails, before which
    /// [`Self::count_stack_error`] adds the count of `ERR_STACK` once the function is
    /// otherwise complete.
    stack_count: Option<ir::Inst>,
    /// The first run-time error of the setup code not yet in `ctx` (see
    /// [`Self::defer_error`]): `code << PENDING_CODE_SHIFT | (site + 1)`, 0 for none. Never
    /// reset: once set, a flush has put it (or an earlier error) into `ctx.error`, so
    /// flushing it again changes nothing.
    pending_error: Variable,
    /// The kernel defers its setup's index and fuel errors into `pending_error` (its setup
    /// has index sites that may fail; see [`crate::mid::sites::setup_may_fail_index`]), so
    /// they are flushed wherever the error state can be observed ([`Self::flush_errors`]).
    defer_errors: bool,
    /// Lowering setup code of such a kernel: errors go to `pending_error`.
    deferring_errors: bool,
    /// The uniform frame's slot and the slot holding its address (see `spill_uniforms`).
    uniform_frame: Option<(StackSlot, StackSlot)>,
    /// Uniform locals the pixel part assigns: (slot holding the setup's final value, the
    /// slot pixel code reads and writes, bytes). Every pixel group starts by copying the
    /// first into the second (see `spill_uniforms`).
    group_resets: Vec<(StackSlot, StackSlot, u32)>,
    /// Byte offset of the uniform frame's vector section (word `w` splatted at
    /// `vec_section + 16 * w`; see [`crate::mid::spill`]).
    vec_section: u32,
    /// Byte offset in the uniform frame of the render pass's lo_x and hi_x, as f32x4 splats.
    x_range_at: u32,
    /// What the middle end planned for this kernel (see [`crate::mid`]).
    plan: &'a Plan<'a>,
    /// In the pixel loops: the copy being lowered (see [`crate::mid::unswitch`]).
    copy: Option<&'a crate::mid::unswitch::LoopsCopy>,
    /// While a row term is evaluated in the row prologue: read row locals as their values.
    substitute_row_locals: bool,
    /// The row locals' values already computed in the current row prologue, with the block
    /// they were computed in: a local read by several row terms is evaluated once per row.
    row_local_values: std::collections::HashMap<LocalId, (ir::Block, Val)>,
    /// Outside the groups, while carried terms are evaluated (see [`carry`]): the uniform
    /// frame's address, and whether the row section holds the current row's terms.
    prologue_frame: Option<(ir::Value, bool)>,
    /// In the group being lowered: each carried term's value.
    carry_now: Vec<(ExprId, ir::Value)>,
    /// Scalar frame reads of the current group -> the byte offset of their splat.
    splat_src: std::collections::HashMap<ir::Value, u32>,
    /// The setup's store of each word's splat, by the splat's byte offset (see
    /// `spill_uniforms`), and the offsets some group loaded: the other stores are removed
    /// once the pixel code is lowered (`drop_unread_splats`).
    splat_stores: Vec<(u32, ir::Inst)>,
    splats_read: std::collections::HashSet<u32>,
    /// Frame words only one side of the first unswitched condition reads (tier 1, see
    /// [`crate::mid::spill::deferred_stores`]): that condition's id and the stores left to
    /// its sides' dispatch blocks.
    deferred_frame: Option<(ExprId, Vec<DeferredStore>)>,
    /// A 16-byte slot that stores to planes the frame does not have go to.
    scratch: StackSlot,
    /// Per binding component: its G-buffer plane's base address (see `plane_table`).
    plane_ptrs: Option<StackSlot>,
    written: Vec<bool>,
    /// Per binding: the last `interpolation` arm lowered for it (its kind, span), so the
    /// warning for a binding never written says which arm left it so.
    served_by: Vec<Option<(crate::ir::ArmKind, crate::diag::Span)>>,
    /// Walk pass rectangles in blocks with interval facts (see [`block`]); off in tier 0,
    /// where the extra variant of the pixel code costs more compile time than it saves.
    /// Off means tier 0 (see [`Self::tier0`]).
    block_culling: bool,
    /// While lowering an arm of `c ? a : b`: the uniform condition under which that arm is
    /// the one taken. A run-time error in an untaken arm is not an error (the language
    /// evaluates one arm; the JIT evaluates both and selects).
    error_guard: Option<ir::Value>,
    /// Tier 0: constants, pure operations, address arithmetic and argument reads already
    /// lowered in a block (value numbering while lowering, see [`Self::numbered`]); tier 1
    /// leaves this to Cranelift's e-graph.
    vn: VnTable,
    /// Local components given SSA variables so far, in all frames (see
    /// [`Self::take_var_words`]).
    var_words: u32,
    /// Tier 0, lowering the pixel part: it is lowered *flat*, without a group's early exits
    /// (see [`crate::mid::flat`]).
    flat: bool,
    /// Uniform conditions of the primitive's pixel code decided for the copy of the pixel
    /// loops being lowered (see [`crate::mid::unswitch`]); empty outside the pixel loops and
    /// in tier 0.
    unswitched: std::collections::HashMap<ExprId, bool>,
    /// What the pixel code's guards say about float locals at the statement being lowered
    /// (see [`crate::mid::bounds`]); empty outside a group body.
    guard_facts: bounds::GuardFacts,
    /// Blocks sealed as soon as they were created (a guard's continuation, see
    /// `varying_guard_return`); `seal_blocks_from` skips them.
    sealed_early: std::collections::HashSet<Block>,
    /// Blocks no path from the entry reaches: the code after an unconditional `break`,
    /// `continue` or `return`, and the blocks of uniform `if`s and loops inside it (see
    /// [`Self::jump_live`]).
    dead_blocks: std::collections::HashSet<Block>,
    /// Blocks [`Self::jump_live`] has jumped to from live code.
    live_targets: std::collections::HashSet<Block>,
    /// Spare component-offset lists (see [`Self::comp_offsets`]).
    offs_spare: Vec<Vec<u32>>,
    pub(crate) warnings: Vec<crate::abi::KernelWarning>,
    /// The types of the SSA variables declared so far, in order (see [`outline`]).
    var_types: Vec<ir::Type>,
    /// Tier 0: the pixel loops' own function (see [`outline`]).
    outline: outline::Outline<'b>,
    /// Tier 0, a setup that may fail: the block its early exits go to, which flushes the
    /// deferred error (filled by [`Self::finish_function`]).
    setup_exit: Option<Block>,
    func_id: FuncId,
    frontend: cranelift_codegen::isa::TargetFrontendConfig,
}

/// What [`lower_kernel`] made besides the kernel's CLIF.
pub(crate) struct Lowered {
    pub warnings: Vec<crate::abi::KernelWarning>,
    /// The pixel loops went to the function given for them (see [`outline`]).
    pub outlined: bool,
}

/// Lower the primitive of `plan` (the middle end's plan for it, `key` and the tier) into
/// `func` (whose signature is already the kernel's).
///
/// `pixels`: where tier 0 may put the pixel loops, as a function of their own (see
/// [`outline`]; [`Lowered::outlined`] says whether it did).
///
/// `upgrade`: the address of the word a tiered JIT's worker fills with this kernel's tier-1
/// entry point once it is compiled (see `super::TierUp`). The kernel then starts by reading
/// it and, when set, calls that entry with its own arguments and returns: every caller
/// holding the tier-0 entry (draws already binned, expanded calls, other tier-0 kernels'
/// direct calls) runs tier-1 code from then on, mid-frame. Both tiers compute the same
/// buffers bit for bit, so which tier runs which call never shows in a frame.
#[allow(clippy::too_many_arguments)]
pub(crate) fn lower_kernel<'b>(
    program: &Program,
    plan: &Plan,
    key: &VariantKey,
    layout: &ArgLayout,
    func: &'b mut ir::Function,
    fctx: &'b mut cranelift_frontend::FunctionBuilderContext,
    pixels: Option<(&'b mut ir::Function, &'b mut cranelift_frontend::FunctionBuilderContext)>,
    linker: &'b mut dyn Linker,
    frontend: cranelift_codegen::isa::TargetFrontendConfig,
    upgrade: Option<*const std::sync::atomic::AtomicUsize>,
) -> Res<Lowered> {
    // The plan's function is the primitive's body as the middle end rewrote it (forwarded
    // and unrolled); callees and interpolators come from `program`.
    let f: &Function = plan.function;
    let func_id = plan.func;
    let block_culling = plan.tier == Tier::Optimised;
    let mut b = FunctionBuilder::new(func, fctx);
    let entry = b.create_block();
    b.append_block_params_for_function_params(entry);
    b.switch_to_block(entry);
    let ctx = b.block_params(entry)[0];
    let args = b.block_params(entry)[1];
    let stack_count = stack_check(&mut b, ctx, func_id);
    if let Some(word) = upgrade {
        let word = b.ins().iconst(types::I64, word as i64);
        // An acquiring load: the worker publishes the entry after making its code executable.
        let tier1 = b.ins().atomic_load(types::I64, mem_flags().with_aligned(), word);
        let run_tier1 = b.create_block();
        let run_own = b.create_block();
        b.ins().brif(tier1, run_tier1, &[], run_own, &[]);
        b.switch_to_block(run_tier1);
        let sig = b.func.signature.clone();
        let sig = b.import_signature(sig);
        b.ins().call_indirect(sig, tier1, &[ctx, args]);
        b.ins().return_(&[]);
        b.switch_to_block(run_own);
    }
    let exit = b.create_block();
    let mut var_types = vec![];
    let mut declare_var = |ty: ir::Type| {
        var_types.push(ty);
        b.declare_var(ty)
    };
    let bound_vars = [
        declare_var(types::F32),
        declare_var(types::F32),
        declare_var(types::F32),
        declare_var(types::F32),
    ];
    let has_bound = declare_var(types::I8);
    let fuel = declare_var(types::I64);
    let group_fuel = declare_var(types::I64);
    let pending_error = declare_var(types::I32);
    let scratch = b.create_sized_stack_slot(StackSlotData::new(StackSlotKind::ExplicitSlot, 16, 4));
    let mut l = Lower {
        b,
        program,
        key,
        layout,
        n_interp: key.interp_components(),
        linker,
        ctx,
        args,
        exit,
        kernel_exit: exit,
        frames: vec![],
        pix: None,
        vloops: vec![],
        view: (0..key.interp_components()).collect(),
        arm: None,
        bound_vars,
        has_bound,
        fuel,
        group_fuel,
        group_fuel_used: false,
        stack_count: Some(stack_count),
        pending_error,
        defer_errors: false,
        deferring_errors: false,
        uniform_frame: None,
        group_resets: vec![],
        vec_section: 0,
        x_range_at: 0,
        plan,
        copy: None,
        substitute_row_locals: false,
        row_local_values: std::collections::HashMap::new(),
        prologue_frame: None,
        carry_now: vec![],
        splat_src: std::collections::HashMap::new(),
        splat_stores: vec![],
        splats_read: std::collections::HashSet::new(),
        deferred_frame: None,
        scratch,
        plane_ptrs: None,
        written: vec![false; key.bindings.len()],
        served_by: vec![None; key.bindings.len()],
        block_culling,
        error_guard: None,
        vn: VnTable::default(),
        var_words: 0,
        flat: false,
        unswitched: std::collections::HashMap::new(),
        guard_facts: bounds::GuardFacts::default(),
        sealed_early: std::collections::HashSet::new(),
        dead_blocks: std::collections::HashSet::new(),
        live_targets: std::collections::HashSet::new(),
        offs_spare: vec![],
        warnings: vec![],
        var_types,
        // Tier 0 only, and only a kernel with pixel loops or a setup worth splitting.
        outline: outline::Outline::new(
            pixels.filter(|_| !block_culling),
            f,
            plan.setup_split.as_ref().map(|s| s.at),
        ),
        setup_exit: None,
        func_id,
        frontend,
    };
    l.body(f)?;
    l.drop_unread_splats();
    for (i, b) in key.bindings.iter().enumerate() {
        if let BindingKind::Kind(k) = &b.kind {
            if !l.written[i] {
                let w = unwritten_warning(f, i, k, l.served_by[i].take());
                l.warnings.push(w);
            }
        }
    }
    l.b.seal_all_blocks();
    l.count_stack_error();
    let lowered = Lowered {
        warnings: std::mem::take(&mut l.warnings),
        outlined: l.outline.done,
    };
    l.b.finalize(frontend);
    Ok(lowered)
}

/// W0802 for Kind binding `binding` (kind `kind`) that no lowered code of `f` stores,
/// saying why: no arm serves the kind, or the arm that does (`served_by`) stores no value.
fn unwritten_warning(
    f: &crate::ir::Function,
    binding: usize,
    kind: &str,
    served_by: Option<(crate::ir::ArmKind, crate::diag::Span)>,
) -> crate::abi::KernelWarning {
    let keeps = "its pixels keep the value drawn there before";
    let (why, span, label) = match served_by {
        None => (
            format!("no `interpolation` arm of `{}` handles kind `{kind}`", f.name),
            f.span,
            format!("no `{kind}:` or `default:` arm"),
        ),
        Some((crate::ir::ArmKind::Named(_), span)) => (
            format!("its `{kind}:` arm stores no value"),
            span,
            "no `interpolator_return(value)` runs in this arm".to_string(),
        ),
        Some((crate::ir::ArmKind::Default, span)) => (
            format!("the `default:` arm handles kind `{kind}` but stores no value"),
            span,
            "no `interpolator_return(value)` runs in this arm (a bare `interpolator_return;` runs only shared interpolators and constants)".to_string(),
        ),
    };
    crate::abi::KernelWarning {
        binding,
        message: format!(
            "`{}` never writes shading parameter {{param}}, bound to kind `{kind}`: {why}; {keeps}",
            f.name
        ),
        span,
        label,
    }
}

/// The kernel's first instructions: when the frame its prologue reserved reaches below
/// `ctx.stack_limit`, record `ERR_STACK` (site: the kernel's `FuncId`) if no error came
/// first and return. Nothing has been stored in the frame's lower part yet (the prologue
/// saves registers at its top; spill slots lie above the explicit ones), and no call has
/// pushed a return address at its bottom, so a frame too big for the stack is never
/// touched. Four instructions on the path that runs. Returns the failing path's `return`:
/// [`Lower::count_stack_error`] adds the error's count before it.
fn stack_check(b: &mut FunctionBuilder, ctx: ir::Value, func_id: FuncId) -> ir::Inst {
    let sp = b.ins().get_stack_pointer(types::I64);
    let limit = b.ins().load(types::I64, mem_flags(), ctx, ctx_off::STACK_LIMIT);
    let short = b.ins().icmp(IntCC::UnsignedLessThan, sp, limit);
    let no_room = b.create_block();
    let room = b.create_block();
    b.ins().brif(short, no_room, &[], room, &[]);
    b.set_cold_block(no_room);
    b.switch_to_block(no_room);
    b.seal_block(no_room);
    let old = b.ins().load(types::I32, mem_flags(), ctx, ctx_off::ERROR);
    let old_site = b.ins().load(types::I32, mem_flags(), ctx, ctx_off::ERROR_SITE);
    let first = b.ins().icmp_imm_s(IntCC::Equal, old, 0);
    let code = b.ins().iconst(types::I32, ERR_STACK as i64);
    let code = b.ins().select(first, code, old);
    let site = b.ins().iconst(types::I32, func_id.0 as i64);
    let site = b.ins().select(first, site, old_site);
    b.ins().store(mem_flags(), code, ctx, ctx_off::ERROR);
    b.ins().store(mem_flags(), site, ctx, ctx_off::ERROR_SITE);
    let ret = b.ins().return_(&[]);
    b.switch_to_block(room);
    b.seal_block(room);
    ret
}

impl<'a, 'b> Lower<'a, 'b> {
    fn body(&mut self, f: &'a Function) -> Res<()> {
        let fuel = self.load_ctx(types::I64, ctx_off::FUEL);
        self.b.def_var(self.fuel, fuel);
        // The pass rectangle defaults to everything; `bound` narrows it.
        let ninf = self.f32const_here(f32::NEG_INFINITY);
        let pinf = self.f32const_here(f32::INFINITY);
        self.b.def_var(self.bound_vars[0], ninf);
        self.b.def_var(self.bound_vars[1], ninf);
        self.b.def_var(self.bound_vars[2], pinf);
        self.b.def_var(self.bound_vars[3], pinf);
        let no = self.iconst_here(types::I8, 0);
        self.b.def_var(self.has_bound, no);

        let frame = self.make_frame(
            f,
            self.func_id,
            self.layout.params.clone(),
            self.layout.fixed_words,
            None,
        )?;
        self.frames.push(frame);
        // Setup errors are deferred into a variable (see `defer_error`): the setup's early
        // exits go through `setup_exit`, which flushes it, and so does the end of the
        // setup; from there on errors are recorded in `ctx` directly and the variable is
        // dead (it never lives into the pixel loops).
        // Tier 0 only: tier 1 keeps its records in cold blocks, where they cost no run time
        // (deferring there too: CLIF -11 %, NURB frame -0.6 % by instructions, but the
        // out-of-fuel blocks then store nothing to `ctx`, which `tests/jit/unroll.rs`
        // counts to see loops).
        let setup_exit = self.tier0() && self.plan.setup_may_fail_index;
        self.setup_exit = setup_exit.then(|| {
            let none = self.iconst_here(types::I32, 0);
            self.b.def_var(self.pending_error, none);
            self.defer_errors = true;
            self.deferring_errors = true;
            self.exit = self.b.create_block();
            self.exit
        });
        let pending_return = self.setup_stmts(f)?;
        if self.setup_exit.is_some() {
            self.flush_errors();
            self.deferring_errors = false;
            self.exit = self.kernel_exit;
        }
        if !f.pixel.is_empty() {
            self.flat = self.pixel_plan()?.flat;
            self.pixel_passes(f, pending_return)?;
        } else if let Some(p) = pending_return {
            self.return_if(p);
        }
        self.finish_function();
        Ok(())
    }

    /// The plan of the pixel part (the pixel loops are lowered only when there is one).
    fn pixel_plan(&self) -> Res<&'a PixelPlan> {
        match &self.plan.pixel {
            Some(p) => Ok(p),
            None => err("no pixel part planned"),
        }
    }

    /// The plan's row and per-run terms (none without a pixel part).
    fn hoists(&self) -> &'a [crate::mid::hoist::Hoist] {
        self.plan.pixel.as_ref().map_or(&[], |p| &p.hoists)
    }

    /// Compiling for tier 0 (`Tier::Fast`): besides skipping block culling, the lowering
    /// then emits less CLIF and fewer blocks where that costs run time only in the one
    /// frame tier 0 serves (each use says what it skips; the larger ones are
    /// [`crate::mid::flat`] pixel code, [`crate::mid::dead`] setup code and
    /// [`Self::setup_stmts`]), and numbers values while
    /// lowering ([`Self::numbered`]) where tier 1 leaves that to Cranelift's e-graph. Results are
    /// bit-identical either way (`tests/jit/tiers.rs`, `tests/jit/tier0.rs`).
    fn tier0(&self) -> bool {
        !self.block_culling
    }
}

/// The value type of one component of `ty` (Interp components are floats).
pub(crate) fn elem_scalar(ty: &Type) -> Scalar {
    match ty.elem {
        Elem::Scalar(s) => s,
        Elem::Interp => Scalar::Float,
    }
}

#[allow(non_snake_case)]
fn I32X4_or(sc: Scalar) -> ir::Type {
    cl_type(sc, true)
}

/// One component as a 32-bit argument word (bools 0/1).
fn word_of(b: &mut FunctionBuilder, sc: Scalar, c: ir::Value) -> ir::Value {
    match sc {
        Scalar::Bool => b.ins().uextend(types::I32, c),
        _ => c,
    }
}

/// Whether running setup statement `s` can matter to a bound run only through its value:
/// no `bound`, no primitive call, no loop (fuel), no index that may record an error. (An
/// early `return` is fine: the bound already recorded stays.)
fn quiet_stmt(f: &Function, s: StmtId) -> bool {
    match &f.stmts[s] {
        StmtKind::Assign { place, value } => {
            // Each index of the place a constant inside its dimension.
            let Some(local) = f.locals.get(place.local.0 as usize) else {
                return false;
            };
            let mut ty = local.ty.clone();
            let in_range = place.indices.iter().all(|(index, _)| {
                let ok = const_index_in_range(&f.exprs, &ty, *index);
                if ok {
                    ty = ty.element();
                }
                ok
            });
            in_range && speculable_expr(&f.exprs, *value)
        }
        StmtKind::If { cond, then, otherwise } => {
            speculable_expr(&f.exprs, *cond) && then.iter().chain(otherwise).all(|&t| quiet_stmt(f, t))
        }
        StmtKind::Return => true,
        _ => false,
    }
}

/// Whether `e` is a constant (or a literal of constants) whose every component has all bits
/// zero (so `-0.0` is not).
fn all_zero_bits(x: &Exprs, e: ExprId) -> bool {
    match &x[e].kind {
        ExprKind::Const(ConstValue::Float(f)) => f.to_bits() == 0,
        ExprKind::Const(ConstValue::Int(v) | ConstValue::Fixed(v)) => *v == 0,
        ExprKind::Const(ConstValue::Bool(b)) => !b,
        ExprKind::List(items) => items.iter().all(|i| all_zero_bits(x, *i)),
        ExprKind::Splat(item) => all_zero_bits(x, *item),
        // Every conversion (to interpolation data too: a broadcast) keeps zero bits zero.
        ExprKind::Convert(inner) => all_zero_bits(x, *inner),
        _ => false,
    }
}

/// The value of `v` if it is a float constant: an `f32const`, or a splat of one.
fn float_const(func: &ir::Function, v: ir::Value) -> Option<f32> {
    let inst = func.dfg.value_def(v).inst()?;
    match func.dfg.insts[inst] {
        ir::InstructionData::UnaryIeee32 {
            opcode: ir::Opcode::F32const,
            imm,
        } => Some(f32::from_bits(imm.bits())),
        ir::InstructionData::Unary {
            opcode: ir::Opcode::Splat,
            arg,
        } => float_const(func, arg),
        _ => None,
    }
}

/// `1 / c` when `v` is a float constant `c` that is a power of two whose reciprocal is a
/// normal float: the divisors by which dividing and multiplying by the reciprocal give the
/// same result for every dividend.
fn exact_reciprocal(func: &ir::Function, v: ir::Value) -> Option<f32> {
    let c = float_const(func, v)?;
    let r = 1.0 / c;
    let power_of_two = c.is_normal() && c.abs().to_bits() & 0x007f_ffff == 0;
    (power_of_two && r.is_normal()).then_some(r)
}
