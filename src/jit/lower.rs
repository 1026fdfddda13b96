//! IR -> CLIF: builds the Cranelift function of one primitive specialised for one variant key.
//!
//! Shape of every kernel (`fn(ctx, args)`):
//! 1. `setup` as scalar code: uniform values are `f32`/`i32`/`i8` SSA variables; `bound`
//!    unions into `ctx.bound` in bound mode and sets the pass rectangle; primitive calls build
//!    the callee's argument block in a stack slot and call it directly, or in `MODE_EXPAND`
//!    hand it to `ctx.expand` (the runtime renders the call later as an instance).
//! 2. If there is a pixel part: in bound mode record the viewport unless a bound ran, and
//!    return; in render mode (at tier 0 in a function of its own the kernel calls, see
//!    [`outline`]) loop rows, then 4-pixel groups of the pass rectangle clipped to
//!    the tile (groups start at tile-aligned x; lanes outside start dead), `UNROLL` groups
//!    per loop step. Loop headers branch exit-first so Cranelift keeps hoisting uniform work
//!    out of them. Uniform locals move to a stack frame first (`spill_uniforms`) and the
//!    G-buffer plane addresses are computed once (`plane_table`).
//!    When the pixel part opens with coverage tests (`if (c) return;`), the rectangle is
//!    walked in blocks instead: first the whole rectangle as one block, and only when that
//!    is neither dead nor passing, blocks of `BLOCK_W` x `BLOCK_H` pixels; [`block`]
//!    evaluates the tests over each block with interval arithmetic (their uniform and
//!    Y-only terms once per block row) and skips blocks no lane survives, and runs blocks
//!    every lane passes with a variant of the pixel code without those tests; consecutive
//!    pass blocks of a block row run as one span, the others run the full code. Per row, the pixel terms that
//!    depend on Y alone are evaluated once ([`hoist`]); X steps by 4.0 per group; only the
//!    groups at the rectangle's ends build a lane mask (the others start all ones).
//!    Tier 1 first decides up to two uniform `if`s of the pixel code whose conditions no
//!    group can change, once per draw, and lowers the loops once per side ([`unswitch`]).
//! 3. Per group the pixel statements run on vectors under masks: `alive` (lanes not yet
//!    retired) and `exec` (the lanes the current statement runs for, always a subset of
//!    `alive`). Varying `if` runs both sides under their masks, skipping a side with no lane;
//!    varying loops keep a loop mask and run until it is empty; break/continue/return remove
//!    lanes. Z is written back at the end of the group for the lanes that assigned it.
//!
//! Interpolation data is specialised away: an interpolation_data value is just the float
//! components of the current *view* (all Kind-bound components outside an `interpolation`
//! arm, the arm's kind's inside). Shared interpolators are inlined at a bare
//! `interpolator_return;` as a one-trip masked loop whose `return` is a break.
//!
//! Safety invariants the code keeps: every index is clamped into its array (and the error
//! recorded, in tier 1 from a cold block) unless [`crate::ir::range`] proved it in range,
//! every G-buffer store goes to a plane below `ctx.num_planes` (stores to other
//! planes are skipped), and every loop trip spends fuel (kept in a variable, `ctx.fuel`
//! at the exit and around primitive calls). In tier 0 a run-time error of the setup code
//! (an index out of range, out of fuel) is kept in a variable too and reaches `ctx.error`
//! at the setup's exits and before primitive calls, so `ctx` holds the invocation's first
//! error wherever anyone can read it ([`Lower::defer_error`]). Nothing here panics on a checked
//! program; an IR shape the checker should have excluded gives a [`JitError`].

use cranelift_codegen::ir::{
    self, condcodes::FloatCC, condcodes::IntCC, types, Block, InstBuilder, StackSlot, StackSlotData, StackSlotKind,
};
use cranelift_frontend::{FunctionBuilder, Variable};

use super::fixed;
use super::libm::LibmFn;
use super::value::{
    args_flags, blend, cl_type, comp_bytes, ctx_off, mask_const, mem_flags, splat, zero, Val, VnKey, VnTable, F32X4,
    I32X4, VN_NEG, VN_NOT,
};
use super::{Body, JitError};
use crate::abi::{
    interpolator_arg_words, type_words, ArgLayout, BindingKind, ParamSlot, VariantKey, ERR_CALL_DEPTH, ERR_FUEL,
    ERR_INDEX, ERR_STACK, MAX_CALL_DEPTH, MODE_BOUND, MODE_EXPAND,
};
use crate::ir::{
    for_each_assign, ArmKind, BinOp, ConstValue, Elem, Expr, ExprKind, FixedFormat, FuncId, FuncKind, Function,
    LocalId, LoopId, ParamRole, Place, Program, Scalar, SiteId, Stmt, StmtKind, Type, UnaryOp,
};

mod affine;
mod block;
mod bounds;
mod dead;
mod flat;
mod hoist;
mod init;
mod outline;
mod unswitch;

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

/// The format depth values have in the depth buffer.
const DEPTH_FORMAT: FixedFormat = FixedFormat { bits: 32, frac: 32 };

/// Most components a local kept in SSA variables may have, and most such components a
/// kernel may have in all its frames (see [`Lower::take_var_words`]); the rest live on the
/// stack. The built-in primitives' largest register local has 64.
const MAX_LOCAL_VAR_WORDS: u32 = 1024;
const MAX_VAR_WORDS: u32 = 16384;

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
    /// The fuel left (`ctx.fuel` while the kernel runs, kept in a register: loaded at entry,
    /// stored at the exit and around direct primitive calls, whose callees spend it too).
    fuel: Variable,
    /// The first run-time error of the setup code not yet in `ctx` (see
    /// [`Self::defer_error`]): `code << PENDING_CODE_SHIFT | (site + 1)`, 0 for none. Never
    /// reset: once set, a flush has put it (or an earlier error) into `ctx.error`, so
    /// flushing it again changes nothing.
    pending_error: Variable,
    /// The kernel defers its setup's index and fuel errors into `pending_error` (its setup
    /// has index sites that may fail; see [`Self::setup_may_fail_index`]), so they are
    /// flushed wherever the error state can be observed ([`Self::flush_errors`]).
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
    /// `vec_section + 16 * w`; see [`hoist`]).
    vec_section: u32,
    /// Byte offset in the uniform frame of the render pass's lo_x and hi_x, as f32x4 splats.
    x_range_at: u32,
    /// Row-invariant pixel terms evaluated once per row into the frame's row section.
    hoists: Vec<hoist::Hoist<'a>>,
    /// Pixel locals with a row-invariant value, by their defining expression (see [`hoist`]).
    row_locals: std::collections::HashMap<LocalId, &'a Expr>,
    /// While a row term is evaluated in the row prologue: read row locals as their values.
    substitute_row_locals: bool,
    /// The row locals' values already computed in the current row prologue, with the block
    /// they were computed in: a local read by several row terms is evaluated once per row.
    row_local_values: std::collections::HashMap<LocalId, (ir::Block, Val)>,
    /// Int terms affine in the pixel column, carried along the row (see [`affine`]).
    carried: Vec<affine::Carried<'a>>,
    /// Pixel locals the carried terms read, by their single defining value (see [`affine`]).
    affine_defs: std::collections::HashMap<LocalId, &'a Expr>,
    /// The primitive's X while `carried` is not empty.
    affine_x: Option<LocalId>,
    /// The primitive's Y when carried terms may be affine in the row too.
    affine_y: Option<LocalId>,
    /// Outside the groups, while carried terms are evaluated (see [`affine`]): the uniform
    /// frame's address, and whether the row section holds the current row's terms.
    prologue_frame: Option<(ir::Value, bool)>,
    /// Pixel locals no group reads, because only carried terms (see [`affine`]) or only row
    /// terms (see [`hoist`]) read them: their assignment is not lowered in a group.
    unread_in_groups: std::collections::HashSet<LocalId>,
    /// Addresses of the expressions in those locals' values (their row terms are not
    /// stored per row).
    unstored_terms: std::collections::HashSet<usize>,
    /// In the group being lowered: each carried term's value (by address).
    carry_now: Vec<(usize, ir::Value)>,
    /// Scalar frame reads of the current group -> the byte offset of their splat.
    splat_src: std::collections::HashMap<ir::Value, u32>,
    /// The setup's store of each word's splat, by the splat's byte offset (see
    /// `spill_uniforms`), and the offsets some group loaded: the other stores are removed
    /// once the pixel code is lowered (`drop_unread_splats`).
    splat_stores: Vec<(u32, ir::Inst)>,
    splats_read: std::collections::HashSet<u32>,
    /// Frame words only one side of the first unswitched condition reads (tier 1, see
    /// `defer_frame_stores`): that condition's key and the stores left to its sides'
    /// dispatch blocks.
    deferred_frame: Option<(usize, Vec<DeferredStore>)>,
    /// A 16-byte slot that stores to planes the frame does not have go to.
    scratch: StackSlot,
    /// Per binding component: its G-buffer plane's base address (see `plane_table`).
    plane_ptrs: Option<StackSlot>,
    written: Vec<bool>,
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
    /// The primitive's body as shared by the JITs of its program (`body` in
    /// [`lower_kernel`]), with its index sites proven in range at every occurrence
    /// ([`crate::ir::range`]: indexed without clamp or error record). The analysis runs
    /// when the first index that is not a constant is lowered: most kernels, their loops
    /// unrolled, have none, and it was ~2% of a tier-0 compile of screen_triangle.
    shared_body: &'a Body,
    /// Tier 0: the pixel code is lowered *flat*, without a group's early exits (see
    /// [`flat`]).
    flat: bool,
    /// Tier 0: the locals live code reads; setup assignments to others are not lowered
    /// (see [`dead`]). `None`: every assignment is lowered.
    setup_live: Option<Vec<bool>>,
    /// Uniform conditions of the pixel code decided for the copy of the pixel loops being
    /// lowered, by address (see [`unswitch`]); empty outside the pixel loops and in tier 0.
    unswitched: std::collections::HashMap<usize, bool>,
    /// Bounds of float locals per function being lowered (by address), computed when its
    /// first varying float -> int or fixed conversion is lowered (see [`bounds`]).
    local_bounds: std::collections::HashMap<usize, bounds::LocalBounds>,
    /// What the pixel code's guards say about float locals at the statement being lowered
    /// (see [`bounds`]); empty outside a group body.
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
    pub(crate) warnings: Vec<String>,
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
    pub warnings: Vec<String>,
    /// The pixel loops went to the function given for them (see [`outline`]).
    pub outlined: bool,
}

/// Lower `func_id` for `key` into `func` (whose signature is already the kernel's).
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
    func_id: FuncId,
    body: &Body,
    key: &VariantKey,
    layout: &ArgLayout,
    func: &'b mut ir::Function,
    fctx: &'b mut cranelift_frontend::FunctionBuilderContext,
    pixels: Option<(&'b mut ir::Function, &'b mut cranelift_frontend::FunctionBuilderContext)>,
    linker: &'b mut dyn Linker,
    frontend: cranelift_codegen::isa::TargetFrontendConfig,
    block_culling: bool,
    upgrade: Option<*const std::sync::atomic::AtomicUsize>,
) -> Res<Lowered> {
    // `body` is `func_id`'s function, possibly rewritten by IR passes (`super::unroll`);
    // callees and interpolators come from `program`.
    if program.functions.get(func_id.0 as usize).is_none() {
        return err(format!("no function {}", func_id.0));
    }
    if let Some(e) = &body.invalid {
        return Err(e.clone());
    }
    let f: &Function = &body.function;
    if f.kind != FuncKind::Primitive {
        return err(format!(
            "`{}` is an interpolator, not a primitive: it has no kernel",
            f.name
        ));
    }
    let mut b = FunctionBuilder::new(func, fctx);
    let entry = b.create_block();
    b.append_block_params_for_function_params(entry);
    b.switch_to_block(entry);
    let ctx = b.block_params(entry)[0];
    let args = b.block_params(entry)[1];
    stack_check(&mut b, ctx, func_id);
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
        pending_error,
        defer_errors: false,
        deferring_errors: false,
        uniform_frame: None,
        group_resets: vec![],
        vec_section: 0,
        x_range_at: 0,
        hoists: vec![],
        row_locals: std::collections::HashMap::new(),
        substitute_row_locals: false,
        row_local_values: std::collections::HashMap::new(),
        carried: vec![],
        affine_defs: std::collections::HashMap::new(),
        affine_x: None,
        affine_y: None,
        prologue_frame: None,
        carry_now: vec![],
        unread_in_groups: std::collections::HashSet::new(),
        unstored_terms: std::collections::HashSet::new(),
        splat_src: std::collections::HashMap::new(),
        splat_stores: vec![],
        splats_read: std::collections::HashSet::new(),
        deferred_frame: None,
        scratch,
        plane_ptrs: None,
        written: vec![false; key.bindings.len()],
        block_culling,
        error_guard: None,
        vn: VnTable::default(),
        var_words: 0,
        shared_body: body,
        flat: false,
        setup_live: None,
        unswitched: std::collections::HashMap::new(),
        local_bounds: std::collections::HashMap::new(),
        guard_facts: bounds::GuardFacts::default(),
        sealed_early: std::collections::HashSet::new(),
        dead_blocks: std::collections::HashSet::new(),
        live_targets: std::collections::HashSet::new(),
        offs_spare: vec![],
        warnings: vec![],
        var_types,
        // Tier 0 only, and only a kernel with pixel loops or a setup worth splitting.
        outline: outline::Outline::new(pixels.filter(|_| !block_culling), f),
        setup_exit: None,
        func_id,
        frontend,
    };
    l.body(f)?;
    l.drop_unread_splats();
    for (i, b) in key.bindings.iter().enumerate() {
        if let BindingKind::Kind(k) = &b.kind {
            if !l.written[i] {
                l.warnings.push(format!(
                    "`{}`: shading parameter {} is bound to kind `{}` but no interpolation arm writes it",
                    f.name, i, k
                ));
            }
        }
    }
    l.b.seal_all_blocks();
    let lowered = Lowered {
        warnings: std::mem::take(&mut l.warnings),
        outlined: l.outline.done,
    };
    l.b.finalize(frontend);
    Ok(lowered)
}

/// The kernel's first instructions: when the frame its prologue reserved reaches below
/// `ctx.stack_limit`, record `ERR_STACK` (site: the kernel's `FuncId`) if no error came
/// first and return. Nothing has been stored in the frame's lower part yet (the prologue
/// saves registers at its top; spill slots lie above the explicit ones), and no call has
/// pushed a return address at its bottom, so a frame too big for the stack is never
/// touched. Four instructions on the path that runs.
fn stack_check(b: &mut FunctionBuilder, ctx: ir::Value, func_id: FuncId) {
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
    b.ins().return_(&[]);
    b.switch_to_block(room);
    b.seal_block(room);
}

impl<'a, 'b> Lower<'a, 'b> {
    // ---------------------------------------------------------------- kernel shape

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

        let frame = self.make_frame(f, self.layout.params.clone(), self.layout.fixed_words, None)?;
        self.frames.push(frame);
        if self.tier0() {
            let mut live = vec![false; f.locals.len()];
            self.live_pixel_flags(&f.pixel, &mut live);
            let removable = |s: &Stmt| self.speculable_stmts(std::slice::from_ref(s), &mut usize::MAX.clone());
            self.setup_live = Some(dead::live_setup_locals(&f.setup, live, &removable));
        }
        // Setup errors are deferred into a variable (see `defer_error`): the setup's early
        // exits go through `setup_exit`, which flushes it, and so does the end of the
        // setup; from there on errors are recorded in `ctx` directly and the variable is
        // dead (it never lives into the pixel loops).
        // Tier 0 only: tier 1 keeps its records in cold blocks, where they cost no run time
        // (deferring there too: CLIF -11 %, NURB frame -0.6 % by instructions, but the
        // out-of-fuel blocks then store nothing to `ctx`, which `tests/jit_unroll.rs`
        // counts to see loops).
        let setup_exit = self.tier0() && self.setup_may_fail_index(&f.setup);
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
            self.flat = self.tier0() && flat::pixel_code_is_flattenable(self.program, f, self.key);
            self.pixel_passes(f, pending_return)?;
        } else if let Some(p) = pending_return {
            self.return_if(p);
        }
        self.finish_function();
        Ok(())
    }

    /// End the function being lowered where its code ends: jump to the exit, fill the
    /// setup's error exit (the kernel's only) and the exit. The kernel of an outlined pixel
    /// function ends at the call (see [`outline`]), the pixel function here.
    fn finish_function(&mut self) {
        self.b.ins().jump(self.exit, &[]);
        if let Some(setup_exit) = self.setup_exit.take() {
            // Every jump here was lowered by now: sealed, it knows whether any exists.
            self.b.switch_to_block(setup_exit);
            self.seal_now(setup_exit);
            if self.b.is_unreachable() {
                // No early exit: a jump from here would make this block a predecessor of
                // the exit whose variables read as undefined (see `jump_live`).
                self.b.ins().trap(ir::TrapCode::unwrap_user(1));
            } else {
                self.flush_errors();
                self.b.ins().jump(self.exit, &[]);
            }
        }
        self.return_at_exit();
    }

    /// Fill the exit block: store the fuel left to `ctx` and return.
    fn return_at_exit(&mut self) {
        self.b.switch_to_block(self.exit);
        let fuel = self.b.use_var(self.fuel);
        self.store_ctx(fuel, ctx_off::FUEL);
        self.b.ins().return_(&[]);
    }

    /// Compiling for tier 0 (`Tier::Fast`): besides skipping block culling, the lowering
    /// then emits less CLIF and fewer blocks where that costs run time only in the one
    /// frame tier 0 serves (each use says what it skips; the larger ones are [`flat`]
    /// pixel code, [`dead`] setup code and [`Self::setup_stmts`]), and numbers values while
    /// lowering ([`Self::numbered`]) where tier 1 leaves that to Cranelift's e-graph. Results are
    /// bit-identical either way (`tests/jit_tiers.rs`, `tests/jit_tier0.rs`).
    fn tier0(&self) -> bool {
        !self.block_culling
    }

    fn load_ctx(&mut self, ty: ir::Type, off: i32) -> ir::Value {
        self.b.ins().load(ty, mem_flags(), self.ctx, off)
    }

    fn store_ctx(&mut self, v: ir::Value, off: i32) {
        self.b.ins().store(mem_flags(), v, self.ctx, off);
    }

    /// After a terminator in the middle of a statement list: keep emitting into a fresh
    /// block no edge reaches (Cranelift drops it).
    fn continue_unreachable(&mut self) {
        let dead = self.b.create_block();
        // Nothing jumps here: sealed, its reads need no block parameters.
        self.seal_now(dead);
        self.dead_blocks.insert(dead);
        self.b.switch_to_block(dead);
    }

    /// Is the block being filled one no path from the entry reaches?
    fn in_dead_block(&self) -> bool {
        self.b.current_block().is_some_and(|b| self.dead_blocks.contains(&b))
    }

    /// End the current block with a jump to `dest`, or, in a dead block, with a trap that
    /// never runs: a jump from dead code would make it a predecessor of `dest` whose
    /// variables all read as undefined (zero), so every variable live at `dest` needed a
    /// block parameter merging that zero with its real value (the NURB setup's loops and
    /// `if`s carried ~40 such parameters each). False if it did not jump.
    fn jump_live(&mut self, dest: Block) -> bool {
        if self.in_dead_block() {
            self.b.ins().trap(ir::TrapCode::unwrap_user(1));
            false
        } else {
            self.b.ins().jump(dest, &[]);
            self.live_targets.insert(dest);
            true
        }
    }

    /// Evaluate `e` as the language would only when the bool `cb` is `taken`: the arm of
    /// `c ? a : b`, the right side of `&&` / `||`. The JIT evaluates it regardless, so its
    /// run-time errors are guarded: by `cb` itself when uniform; for a varying `cb` (lane
    /// masks) the executing lanes narrow to those where `cb == taken`, and uniform errors
    /// inside count if some such lane exists.
    fn eval_guarded(&mut self, e: &'a Expr, varying: bool, cb: ir::Value, taken: bool) -> Res<Val> {
        // Tier 0: a uniform guard is only read by an error record, so an expression that
        // cannot record one needs none (Cranelift would drop it, after we built it).
        if !varying && self.tier0() && speculable_expr(e) {
            return self.eval(e);
        }
        let outer_guard = self.error_guard;
        let outer_exec = self.exec();
        let guard = if varying {
            let lanes = if taken { cb } else { self.b.ins().bnot(cb) };
            let lanes = match outer_exec {
                Some(x) => self.b.ins().band(x, lanes),
                None => lanes,
            };
            self.set_exec(lanes);
            self.b.ins().vany_true(lanes)
        } else {
            let cc = if taken { IntCC::NotEqual } else { IntCC::Equal };
            self.b.ins().icmp_imm_s(cc, cb, 0)
        };
        self.error_guard = Some(match outer_guard {
            Some(g) => self.b.ins().band(g, guard),
            None => guard,
        });
        let v = self.eval(e);
        self.error_guard = outer_guard;
        if let Some(x) = outer_exec {
            self.set_exec(x);
        }
        v
    }

    /// Record `code` at `site` if no error was recorded yet and `cond` (i8) holds.
    fn record_error(&mut self, code: u32, site: u32, cond: Option<ir::Value>) {
        let old = self.load_ctx(types::I32, ctx_off::ERROR);
        let mut first = self.b.ins().icmp_imm_s(IntCC::Equal, old, 0);
        for c in cond.into_iter().chain(self.error_guard) {
            first = self.b.ins().band(first, c);
        }
        // Flat pixel code also runs statements no lane executes (see [`flat`]); tier 1
        // runs them only when some lane does, and only then can they fail.
        if self.flat {
            if let Some(e) = self.exec() {
                let any = self.b.ins().vany_true(e);
                first = self.b.ins().band(first, any);
            }
        }
        let code_v = self.iconst_here(types::I32, code as i64);
        let new = self.b.ins().select(first, code_v, old);
        self.store_ctx(new, ctx_off::ERROR);
        let old_site = self.load_ctx(types::I32, ctx_off::ERROR_SITE);
        let site_v = self.iconst_here(types::I32, site as i32 as i64);
        let new_site = self.b.ins().select(first, site_v, old_site);
        self.store_ctx(new_site, ctx_off::ERROR_SITE);
    }

    /// Record `code` (ERR_INDEX or ERR_FUEL) at `site` if no error was recorded yet and
    /// `cond` (i8) holds. In the tier-0 setup code of a kernel that defers them, only
    /// `pending_error` changes: a select keeps the first error (~4 instructions instead of
    /// two loads, two stores and ~10 more; ~60 index sites and ~80 loops of the NURB setup
    /// record one).
    fn defer_error(&mut self, code: u32, site: SiteId, cond: Option<ir::Value>) {
        let site_plus_one = i64::from(site.0) + 1;
        if !self.deferring_errors || site_plus_one >= 1 << PENDING_CODE_SHIFT {
            // Not deferred: after the deferred ones, which came first.
            if self.deferring_errors {
                self.flush_errors();
            }
            return self.record_error(code, site.0, cond);
        }
        let bad = match (cond, self.error_guard) {
            (Some(c), Some(g)) => Some(self.b.ins().band(c, g)),
            (c, g) => c.or(g),
        };
        let pending = self.b.use_var(self.pending_error);
        let error = self
            .b
            .ins()
            .iconst(types::I32, i64::from(code) << PENDING_CODE_SHIFT | site_plus_one);
        let candidate = match bad {
            Some(c) => self.b.ins().select(c, error, pending),
            None => error,
        };
        // An earlier error (pending != 0) stays.
        let new = self.b.ins().select(pending, pending, candidate);
        self.b.def_var(self.pending_error, new);
    }

    /// Put the setup's deferred error into `ctx.error` / `ctx.error_site` unless an error
    /// is already there (one recorded earlier: by a callee, a call too deep, or before the
    /// kernel ran). Called wherever the error state can be observed or an error that is
    /// not deferred be recorded: the setup's exits and its end, and before primitive calls
    /// (the callee, or the expand recorder, runs with `ctx`), so the first error of the run
    /// wins across kinds.
    fn flush_errors(&mut self) {
        if !self.defer_errors {
            return;
        }
        let pending = self.b.use_var(self.pending_error);
        let old = self.load_ctx(types::I32, ctx_off::ERROR);
        let zero = self.iconst_here(types::I32, 0);
        // The pending error if it is to be recorded now, else 0.
        let first = self.b.ins().select(old, zero, pending);
        // `first` is 0 where `old` is not: the OR keeps `old` then.
        let code = self.b.ins().ushr_imm_u(first, i64::from(PENDING_CODE_SHIFT));
        let new = self.b.ins().bor(old, code);
        self.store_ctx(new, ctx_off::ERROR);
        let old_site = self.load_ctx(types::I32, ctx_off::ERROR_SITE);
        let site = self.b.ins().band_imm_u(first, (1i64 << PENDING_CODE_SHIFT) - 1);
        let site = self.b.ins().iadd_imm_s(site, -1);
        let new_site = self.b.ins().select(first, site, old_site);
        self.store_ctx(new_site, ctx_off::ERROR_SITE);
    }

    /// Whether lowering `setup` may record an index error: some index site is neither a
    /// constant inside a fixed array nor proven in range (mirrors [`Self::index_access`]).
    /// Kernels without one (screen_triangle, the sphere, ...) keep their code unchanged.
    fn setup_may_fail_index(&mut self, setup: &'a [Stmt]) -> bool {
        let mut sites = vec![];
        collect_setup_index_sites(self.frame().func, setup, &mut sites);
        sites
            .into_iter()
            .any(|(static_len, index, site)| match (static_len, const_int(index)) {
                (Some(len), Some(k)) => k < 0 || k >= i64::from(len),
                _ => !self.site_proven(site),
            })
    }

    /// Union a rectangle into `ctx.bound` (bound mode only; the caller checks for NaN).
    /// `go`: only if this holds; the fields are then rewritten with their own values
    /// otherwise (branch-free, for tier 0's setup: one block fewer).
    fn union_bound(&mut self, r: [ir::Value; 4], go: Option<ir::Value>) {
        let set = self.load_ctx(types::I32, ctx_off::BOUND_SET);
        let has = self.b.ins().icmp_imm_s(IntCC::NotEqual, set, 0);
        for (i, &v) in r.iter().enumerate() {
            let off = ctx_off::BOUND + 4 * i as i32;
            let cur = self.load_ctx(types::F32, off);
            let merged = if i < 2 {
                self.b.ins().fmin(cur, v)
            } else {
                self.b.ins().fmax(cur, v)
            };
            let new = self.b.ins().select(has, merged, v);
            let new = match go {
                Some(go) => self.b.ins().select(go, new, cur),
                None => new,
            };
            self.store_ctx(new, off);
        }
        let one = self.iconst_here(types::I32, 1);
        let one = match go {
            Some(go) => self.b.ins().select(go, one, set),
            None => one,
        };
        self.store_ctx(one, ctx_off::BOUND_SET);
    }

    /// `bound(...)`. `then_done`: nothing after it in the setup matters to a bound run
    /// (see `body`), so in bound mode the kernel returns right after recording it.
    fn lower_bound(&mut self, es: &'a [Expr; 4], then_done: bool) -> Res<()> {
        let mut r = [self.f32const_here(0.0); 4];
        for (i, e) in es.iter().enumerate() {
            let v = self.eval_uniform(e)?;
            r[i] = fixed::convert(&mut self.b, v.scalar, Scalar::Float, v.comps[0]);
        }
        let mut nan = self.b.ins().fcmp(FloatCC::Unordered, r[0], r[1]);
        let n2 = self.b.ins().fcmp(FloatCC::Unordered, r[2], r[3]);
        nan = self.b.ins().bor(nan, n2);
        let mode = self.load_ctx(types::I32, ctx_off::MODE);
        let is_bound = self.b.ins().icmp_imm_s(IntCC::Equal, mode, MODE_BOUND as i64);
        let skip = self.b.ins().bnot(nan);
        let go = self.b.ins().band(is_bound, skip);
        if self.tier0() {
            // Tier 0: no block for the union (see `union_bound`) and no early end of a
            // bound run (blocks cost tier 0 more compile time than the bound run saves).
            self.union_bound(r, Some(go));
        } else {
            let union_blk = self.b.create_block();
            let after = self.b.create_block();
            self.b.ins().brif(go, union_blk, &[], after, &[]);
            self.b.switch_to_block(union_blk);
            self.union_bound(r, None);
            if then_done {
                self.b.ins().jump(self.exit, &[]);
                // The NaN bound of a bound run is not recorded, and nothing else is either.
                let render = self.b.create_block();
                self.b.switch_to_block(after);
                self.b.ins().brif(is_bound, self.exit, &[], render, &[]);
                self.b.switch_to_block(render);
            } else {
                self.b.ins().jump(after, &[]);
                self.b.switch_to_block(after);
            }
        }
        for (i, &v) in r.iter().enumerate() {
            self.b.def_var(self.bound_vars[i], v);
        }
        let yes = self.iconst_here(types::I8, 1);
        self.b.def_var(self.has_bound, yes);
        Ok(())
    }

    /// The pixel loops (render mode) or the viewport bound (bound mode).
    /// `pending_return`: a condition on which the kernel ends, left by [`Self::setup_stmts`].
    fn pixel_passes(&mut self, f: &'a Function, pending_return: Option<ir::Value>) -> Res<()> {
        // Tier 0 stores the uniform frame here, before the bound/render branch, in the
        // block that computed its values: they then die in that block instead of living
        // into the render block, where the single-pass allocator would reload each one
        // after spilling it at the block's end. (Bound mode stores a frame it does not
        // read: a few dozen stores, once per primitive.)
        let early_frame = self.tier0();
        if early_frame {
            self.spill_uniforms(f);
        }
        // After the frame stores (stores to the kernel's own stack only), so the values
        // they store die in the block that computed them.
        if let Some(p) = pending_return {
            self.return_if(p);
        }
        let mode = self.load_ctx(types::I32, ctx_off::MODE);
        let is_bound = self.b.ins().icmp_imm_s(IntCC::Equal, mode, MODE_BOUND as i64);
        let bound_blk = self.b.create_block();
        let render_blk = self.b.create_block();
        self.b.ins().brif(is_bound, bound_blk, &[], render_blk, &[]);

        // Bound mode: no `bound` ran, so the primitive may cover the whole viewport.
        self.b.switch_to_block(bound_blk);
        let has = self.b.use_var(self.has_bound);
        // Tier 0: a `bound` among the setup's top-level statements runs on every path
        // that gets here (`has` is 1), so the viewport union is not emitted.
        let always_bound = f.setup.iter().any(|s| matches!(s.kind, StmtKind::Bound(_)));
        if self.tier0() && always_bound {
            self.b.ins().jump(self.exit, &[]);
        } else {
            let vp_blk = self.b.create_block();
            self.b.ins().brif(has, self.exit, &[], vp_blk, &[]);
            self.b.switch_to_block(vp_blk);
            let w = self.load_ctx(types::I32, ctx_off::WIDTH);
            let h = self.load_ctx(types::I32, ctx_off::HEIGHT);
            let wf = self.b.ins().fcvt_from_uint(types::F32, w);
            let hf = self.b.ins().fcvt_from_uint(types::F32, h);
            let z = self.f32const_here(0.0);
            self.union_bound([z, z, wf, hf], None);
            self.b.ins().jump(self.exit, &[]);
        }

        self.b.switch_to_block(render_blk);
        if !early_frame {
            self.spill_uniforms(f);
        }
        // Tier 0: from here on into the pixel function, if there is one (see [`outline`]).
        self.begin_outlined_pixels()?;
        self.run_hoists()?;
        self.carry_steps()?;
        self.plane_table();
        let x0 = self.load_ctx(types::I32, ctx_off::X0);
        let y0 = self.load_ctx(types::I32, ctx_off::Y0);
        let x1 = self.load_ctx(types::I32, ctx_off::X1);
        let y1 = self.load_ctx(types::I32, ctx_off::Y1);
        let bx = [
            self.b.use_var(self.bound_vars[0]),
            self.b.use_var(self.bound_vars[1]),
            self.b.use_var(self.bound_vars[2]),
            self.b.use_var(self.bound_vars[3]),
        ];
        let (lo_x, hi_x) = self.pass_range(bx[0], bx[2], x0, x1);
        let (lo_y, hi_y) = self.pass_range(bx[1], bx[3], y0, y1);
        // Any NaN component: the pass rectangle is empty.
        let n1 = self.b.ins().fcmp(FloatCC::Unordered, bx[0], bx[1]);
        let n2 = self.b.ins().fcmp(FloatCC::Unordered, bx[2], bx[3]);
        let nan = self.b.ins().bor(n1, n2);
        let hi_y = self.b.ins().select(nan, lo_y, hi_y);

        let stride = self.load_ctx(types::I32, ctx_off::STRIDE);
        let stride64 = self.b.ins().uextend(types::I64, stride);
        // Groups start at tile-aligned x.
        let off = self.b.ins().isub(lo_x, x0);
        let off = self.b.ins().band_imm_s(off, !3i64);
        let gx_start = self.b.ins().iadd(x0, off);
        let width = self.b.ins().isub(hi_x, lo_x);
        let lim = self.b.ins().iadd_imm_s(width, -3);
        let zero_i = self.iconst_here(types::I32, 0);
        let interior_lim = self.b.ins().smax(lim, zero_i);
        // lo_x and hi_x as f32x4 splats in the uniform frame, for the groups at either end
        // of a row (`pixel_group`).
        let Some((fs, _)) = self.uniform_frame else {
            return err("uniform frame missing");
        };
        let addr = self.slot_addr(fs);
        for (k, v) in [lo_x, hi_x].into_iter().enumerate() {
            let f = self.b.ins().fcvt_from_sint(types::F32, v);
            let fv = self.b.ins().splat(F32X4, f);
            self.b
                .ins()
                .store(mem_flags(), fv, addr, (self.x_range_at + 16 * k as u32) as i32);
        }
        let rect = PassRect {
            x0,
            y0,
            lo_x,
            stride64,
            interior_lim,
        };
        let loops_done = self.b.create_block();
        // One copy of the loops per combination of the uniform conditions decided before
        // them (tier 1; see [`unswitch`]).
        self.unswitched_loops(f, 0, &mut |l: &mut Self| {
            l.pixel_loops(f, &rect, [lo_y, hi_y], [gx_start, hi_x], loops_done)
        })?;
        self.b.switch_to_block(loops_done);
        Ok(())
    }

    /// The pixel loops over the pass rectangle (rows `ys`, groups from `gs[0]`, tile-aligned,
    /// to `gs[1]`): plain rows, or the block walk when the pixel code opens with guards.
    /// Ends by jumping to `loops_done`; lowered under the conditions in `self.unswitched`.
    fn pixel_loops(
        &mut self,
        f: &'a Function,
        rect: &PassRect,
        ys: [ir::Value; 2],
        gs: [ir::Value; 2],
        loops_done: Block,
    ) -> Res<()> {
        let [lo_y, hi_y] = ys;
        let [gx_start, hi_x] = gs;
        let lo_x = rect.lo_x;
        let prefix = block::prefix(f, &self.unswitched);
        if prefix.guards == 0 || !self.block_culling {
            return self.pixel_rows(f, rect, [lo_y, hi_y], [gx_start, hi_x], None, loops_done);
        }

        // Blocks of BLOCK_W x BLOCK_H pixels; per block, interval facts choose: skip, the
        // pass variant (decidable guards dropped) or the full pixel code.
        // A pass rectangle under SMALL_RECT pixels (a small triangle's) runs the full code
        // without block facts: evaluating them costs more than they can save there.
        let w = self.b.ins().isub(hi_x, lo_x);
        let h = self.b.ins().isub(hi_y, lo_y);
        let w64 = self.b.ins().sextend(types::I64, w);
        let h64 = self.b.ins().sextend(types::I64, h);
        let area = self.b.ins().imul(w64, h64);
        let small_rect = self.b.ins().icmp_imm_s(IntCC::SignedLessThan, area, SMALL_RECT);
        // Shape of the walk, block row by block row:
        // - `row_stage` evaluates the prefix terms that depend on uniforms and Y alone, once
        //   for the block row ([`block`] caches them); the block loop after it evaluates
        //   only the X-dependent rest per block.
        // - Consecutive pass blocks of a block row run as one *span* (one row prologue per
        //   pixel row for the whole run, not per block): a pass block extends the pending
        //   span; a dead or full block, or the row's end, first flushes it. `after` says
        //   what follows the flush: 0 the next block row, 1 the next block (dead), 2 the
        //   full code on this block.
        // - The full code runs outside the block loop (`full_entry`, one instance for the
        //   blocks and for small rectangles) and comes back to `brow_resume`, which
        //   re-evaluates the row stage: the block loop's values then need no merging, and
        //   full blocks are few (a primitive's edges).
        // - The walk starts *coarse*: the whole rectangle as one block (one block row, one
        //   block), so a tile entirely inside or outside the primitive costs one evaluation.
        //   When the coarse block is neither dead nor passing, the walk restarts with
        //   BLOCK_W x BLOCK_H blocks.
        let by = self.declare_var(types::I32);
        let coarse = self.declare_var(types::I8);
        let bw = self.declare_var(types::I32);
        let bh = self.declare_var(types::I32);
        let yes = self.iconst_here(types::I8, 1);
        self.b.def_var(coarse, yes);
        let rect_w = self.b.ins().isub(hi_x, gx_start);
        let rect_h = self.b.ins().isub(hi_y, lo_y);
        self.b.def_var(bw, rect_w);
        self.b.def_var(bh, rect_h);
        let bxv = self.declare_var(types::I32);
        let span_lo = self.declare_var(types::I32);
        let span_hi = self.declare_var(types::I32);
        let after = self.declare_var(types::I32);
        // The full run's rectangle and where it returns: 0 the block after it, 1 the end.
        let full_ys = [self.declare_var(types::I32), self.declare_var(types::I32)];
        let full_gs = [self.declare_var(types::I32), self.declare_var(types::I32)];
        let full_then = self.declare_var(types::I32);
        self.b.def_var(by, lo_y);
        let brow_hdr = self.b.create_block();
        let brow_body = self.b.create_block();
        let brow_resume = self.b.create_block();
        let brow_next = self.b.create_block();
        let small_full = self.b.create_block();
        let row_stage = self.b.create_block();
        let blk_hdr = self.b.create_block();
        let blk_body = self.b.create_block();
        let blk_next = self.b.create_block();
        let blk_choose = self.b.create_block();
        let blk_full = self.b.create_block();
        let blk_extend = self.b.create_block();
        let row_end = self.b.create_block();
        let to_full = self.b.create_block();
        let to_dead = self.b.create_block();
        let flush = self.b.create_block();
        let flush_run = self.b.create_block();
        let flush_done = self.b.create_block();
        let after_flush = self.b.create_block();
        let after_not_end = self.b.create_block();
        let full_entry = self.b.create_block();
        let full_done = self.b.create_block();
        let full_resume = self.b.create_block();
        let refine = self.b.create_block();
        let to_full_fine = self.b.create_block();
        self.b.ins().jump(brow_hdr, &[]);

        self.b.switch_to_block(brow_hdr);
        let y = self.b.use_var(by);
        let done = self.b.ins().icmp(IntCC::SignedGreaterThanOrEqual, y, hi_y);
        self.b.ins().brif(done, loops_done, &[], brow_body, &[]);

        self.b.switch_to_block(brow_body);
        self.b.def_var(bxv, gx_start);
        self.b.ins().jump(brow_resume, &[]);

        self.b.switch_to_block(brow_resume);
        let y = self.b.use_var(by);
        let h = self.b.use_var(bh);
        let y_end = self.b.ins().iadd(y, h);
        let y_end = self.b.ins().smin(y_end, hi_y);
        let x = self.b.use_var(bxv);
        self.b.def_var(span_lo, x);
        self.b.def_var(span_hi, x);
        self.b.ins().brif(small_rect, small_full, &[], row_stage, &[]);

        // A small rectangle: the full code over all of it, once.
        self.b.switch_to_block(small_full);
        self.b.def_var(full_ys[0], lo_y);
        self.b.def_var(full_ys[1], hi_y);
        self.b.def_var(full_gs[0], gx_start);
        self.b.def_var(full_gs[1], hi_x);
        let one = self.iconst_here(types::I32, 1);
        self.b.def_var(full_then, one);
        self.b.ins().jump(full_entry, &[]);

        // Centres of the first and last live pixels, computed as the pixel code computes X
        // and Y (int -> float, + 0.5), so the endpoints are bit-identical.
        let centre = |l: &mut Self, i: ir::Value| {
            let f = l.b.ins().fcvt_from_sint(types::F32, i);
            let half = l.b.ins().f32const(0.5);
            l.b.ins().fadd(f, half)
        };
        self.b.switch_to_block(row_stage);
        let y_last = self.b.ins().iadd_imm_s(y_end, -1);
        let ys = [centre(self, y), centre(self, y_last)];
        let row_cache = self.block_cache_row(f, &prefix, ys)?;
        self.b.ins().jump(blk_hdr, &[]);

        self.b.switch_to_block(blk_hdr);
        let x = self.b.use_var(bxv);
        let done = self.b.ins().icmp(IntCC::SignedGreaterThanOrEqual, x, hi_x);
        self.b.ins().brif(done, row_end, &[], blk_body, &[]);

        self.b.switch_to_block(blk_body);
        let x = self.b.use_var(bxv);
        let w = self.b.use_var(bw);
        let x_end = self.b.ins().iadd(x, w);
        let x_end = self.b.ins().smin(x_end, hi_x);
        let x_first = self.b.ins().smax(x, lo_x);
        let x_last = self.b.ins().iadd_imm_s(x_end, -1);
        let xs = [centre(self, x_first), centre(self, x_last)];
        let facts = self.block_facts(f, &prefix, &row_cache, xs, ys)?;
        self.b.ins().brif(facts.dead, to_dead, &[], blk_choose, &[]);
        self.b.switch_to_block(blk_choose);
        self.b.ins().brif(facts.pass, blk_extend, &[], to_full_fine, &[]);

        // Neither dead nor passing: the coarse block is refined (nothing is pending then),
        // a fine block runs the full code.
        self.b.switch_to_block(to_full_fine);
        let c = self.b.use_var(coarse);
        self.b.ins().brif(c, refine, &[], to_full, &[]);
        self.b.switch_to_block(refine);
        let no = self.iconst_here(types::I8, 0);
        self.b.def_var(coarse, no);
        let fine_w = self.iconst_here(types::I32, BLOCK_W as i64);
        let fine_h = self.iconst_here(types::I32, BLOCK_H as i64);
        self.b.def_var(bw, fine_w);
        self.b.def_var(bh, fine_h);
        self.b.ins().jump(brow_body, &[]);

        // A pass block: start the span here if none is pending, and extend it to this
        // block's end (blocks are visited left to right, so the span stays contiguous).
        self.b.switch_to_block(blk_extend);
        let lo = self.b.use_var(span_lo);
        let hi = self.b.use_var(span_hi);
        let empty = self.b.ins().icmp(IntCC::SignedGreaterThanOrEqual, lo, hi);
        let lo = self.b.ins().select(empty, x, lo);
        self.b.def_var(span_lo, lo);
        self.b.def_var(span_hi, x_end);
        self.b.ins().jump(blk_next, &[]);

        for (blk, code) in [(row_end, 0), (to_dead, 1), (to_full, 2)] {
            self.b.switch_to_block(blk);
            let c = self.iconst_here(types::I32, code);
            self.b.def_var(after, c);
            self.b.ins().jump(flush, &[]);
        }

        self.b.switch_to_block(flush);
        let lo = self.b.use_var(span_lo);
        let hi = self.b.use_var(span_hi);
        let pending = self.b.ins().icmp(IntCC::SignedLessThan, lo, hi);
        self.b.ins().brif(pending, flush_run, &[], after_flush, &[]);
        self.b.switch_to_block(flush_run);
        self.pixel_rows(
            f,
            rect,
            [y, y_end],
            [lo, hi],
            Some((&prefix, &facts.decidable)),
            flush_done,
        )?;
        self.b.switch_to_block(flush_done);
        let hi = self.b.use_var(span_hi);
        self.b.def_var(span_lo, hi);
        self.b.ins().jump(after_flush, &[]);

        self.b.switch_to_block(after_flush);
        let a = self.b.use_var(after);
        let at_end = self.b.ins().icmp_imm_s(IntCC::Equal, a, 0);
        self.b.ins().brif(at_end, brow_next, &[], after_not_end, &[]);
        self.b.switch_to_block(after_not_end);
        let is_dead = self.b.ins().icmp_imm_s(IntCC::Equal, a, 1);
        self.b.ins().brif(is_dead, blk_next, &[], blk_full, &[]);

        self.b.switch_to_block(blk_next);
        let x = self.b.use_var(bxv);
        let w = self.b.use_var(bw);
        let x = self.b.ins().iadd(x, w);
        self.b.def_var(bxv, x);
        self.b.ins().jump(blk_hdr, &[]);

        // A full block: leave the block loop for the full code.
        self.b.switch_to_block(blk_full);
        let x = self.b.use_var(bxv);
        let w = self.b.use_var(bw);
        let x_end = self.b.ins().iadd(x, w);
        let x_end = self.b.ins().smin(x_end, hi_x);
        self.b.def_var(full_ys[0], y);
        self.b.def_var(full_ys[1], y_end);
        self.b.def_var(full_gs[0], x);
        self.b.def_var(full_gs[1], x_end);
        let zero = self.iconst_here(types::I32, 0);
        self.b.def_var(full_then, zero);
        self.b.ins().jump(full_entry, &[]);

        self.b.switch_to_block(full_entry);
        let fys = [self.b.use_var(full_ys[0]), self.b.use_var(full_ys[1])];
        let fgs = [self.b.use_var(full_gs[0]), self.b.use_var(full_gs[1])];
        self.pixel_rows(f, rect, fys, fgs, None, full_done)?;

        self.b.switch_to_block(full_done);
        let then = self.b.use_var(full_then);
        self.b.ins().brif(then, loops_done, &[], full_resume, &[]);
        self.b.switch_to_block(full_resume);
        let x = self.b.use_var(bxv);
        let w = self.b.use_var(bw);
        let x = self.b.ins().iadd(x, w);
        self.b.def_var(bxv, x);
        self.b.ins().jump(brow_resume, &[]);

        self.b.switch_to_block(brow_next);
        let y = self.b.use_var(by);
        let h = self.b.use_var(bh);
        let y = self.b.ins().iadd(y, h);
        self.b.def_var(by, y);
        self.b.ins().jump(brow_hdr, &[]);
        Ok(())
    }

    /// Move the primitive's uniform register locals into stack memory before the pixel
    /// loops; the pixel code then loads each where it uses it.
    ///
    /// Why: kept in SSA registers, every setup result (edge and plane coefficients: ~50 for
    /// four perspective parameters) is live across every block of the pixel loops. That is
    /// more than the 16 xmm registers, so they spill anyway, and regalloc2's live-range
    /// splitting over ~150 blocks was 75% of the compile time (10 of 14 ms per variant).
    ///
    /// Locals the pixel part never assigns go to one *uniform frame*, read in pixel code
    /// through a base pointer loaded once per group (`PixelState::frame_base`): those reads
    /// are pure (readonly, can_move), so Cranelift places each load next to its use, folds it
    /// into `vbroadcastss mem` and merges repeats, but cannot hoist them out of the group
    /// loop (their address is defined in it). Locals the pixel part assigns get a stack
    /// slot of their own with ordinary loads and stores.
    fn spill_uniforms(&mut self, f: &'a Function) {
        let pixel_assigned = dead::assigned_flags(&f.pixel, f.locals.len());
        // Uniform locals the variant's pixel code never touches (e.g. the `linear` planes
        // when only perspective_linear parameters are bound) are not stored: their setup
        // computations are then dead and Cranelift drops them.
        let mut pixel_used = vec![false; f.locals.len()];
        self.live_pixel_flags(&f.pixel, &mut pixel_used);
        let frame = &self.frames[0];
        let mut moves = vec![];
        for (i, st) in frame.storage.iter().enumerate() {
            let Storage::Vars(vars) = st else { continue };
            let local = &f.locals[i];
            let is_pixel_param = f
                .params
                .iter()
                .any(|p| p.local.0 as usize == i && matches!(p.role, ParamRole::X | ParamRole::Y | ParamRole::Z));
            if local.var.is_varying() || is_pixel_param || vars.is_empty() || !pixel_used[i] {
                continue;
            }
            moves.push((i, vars.clone(), pixel_assigned[i]));
        }
        let frozen_words: u32 = moves.iter().filter(|m| !m.2).map(|m| m.1.len() as u32).sum();
        // Words first, so the hoisting analysis sees which locals live in the frame.
        let mut next_word = 0;
        let mut placed = vec![];
        for (i, vars, assigned) in moves {
            let at = (!assigned).then(|| {
                let at = next_word;
                next_word += vars.len() as u32;
                self.frames[0].storage[i] = Storage::Frame(at);
                at
            });
            placed.push((i, vars, at));
        }
        self.vec_section = (4 * frozen_words).div_ceil(16) * 16;
        let row_section = self.vec_section + 16 * frozen_words;
        self.row_locals = self.collect_row_locals(f);
        self.hoists = self.collect_hoists(f, row_section);
        let carry_section = row_section + self.hoists.iter().map(|h| 16 * h.comps).sum::<u32>();
        if !self.tier0() {
            self.carried = self.collect_carried(f, carry_section);
        }
        self.mark_row_locals_unread_in_groups(f);
        let deferred = self.defer_frame_stores(f, &placed);
        let carried_end = self
            .carried
            .iter()
            .map(|c| c.row_step_offset.unwrap_or(c.step_offset) + 16)
            .fold(carry_section, u32::max);
        // Last, the render pass's x range as two splats (see `pixel_group`).
        self.x_range_at = carried_end.div_ceil(16) * 16;
        let frame_bytes = self.x_range_at + 32;
        let frame_slot =
            self.b
                .create_sized_stack_slot(StackSlotData::new(StackSlotKind::ExplicitSlot, frame_bytes, 4));
        // One frame address for all the stores below (they are consecutive, so it is live
        // only across them): a `stack_addr` per local was 36 of K=4's CLIF instructions.
        let frame_addr = placed
            .iter()
            .any(|(_, _, at)| at.is_some())
            .then(|| self.slot_addr(frame_slot));
        let mut deferred_stores = vec![];
        for (i, vars, at) in placed {
            let sc = elem_scalar(&f.locals[i].ty);
            if let (Some(&on), Some(first_word)) = (deferred.get(&i), at) {
                deferred_stores.push(DeferredStore {
                    on,
                    vars,
                    first_word,
                    scalar: sc,
                });
                continue;
            }
            match (at, frame_addr) {
                (Some(first), Some(addr)) => {
                    self.store_frame_words(addr, &vars, first, sc);
                }
                _ => {
                    let slot = self.b.create_sized_stack_slot(StackSlotData::new(
                        StackSlotKind::ExplicitSlot,
                        4 * vars.len() as u32,
                        2,
                    ));
                    let addr = self.slot_addr(slot);
                    for (c, v) in vars.iter().enumerate() {
                        let x = self.b.use_var(*v);
                        self.b.ins().store(mem_flags(), x, addr, (4 * c) as i32);
                    }
                    self.frames[0].storage[i] = Storage::Stack(slot);
                }
            }
        }
        // Per-pixel semantics: every pixel runs the pixel part from the setup's final state.
        // A uniform local the pixel part assigns (a loop counter, say) would otherwise
        // carry one group's last value into the next group, so its setup value is kept
        // aside here and every group starts from it (`reset_group_locals`).
        for (i, st) in self.frames[0].storage.iter().enumerate() {
            let Storage::Stack(slot) = *st else { continue };
            if f.locals[i].var.is_varying() || !pixel_assigned[i] {
                continue;
            }
            let bytes = self.b.func.sized_stack_slots[slot].size;
            self.group_resets.push((slot, slot, bytes));
        }
        for r in 0..self.group_resets.len() {
            let (work, _, bytes) = self.group_resets[r];
            let init = self
                .b
                .create_sized_stack_slot(StackSlotData::new(StackSlotKind::ExplicitSlot, bytes, 4));
            self.copy_slot(work, init, bytes);
            self.group_resets[r] = (init, work, bytes);
        }
        if let Some((cond, _)) = self.deferred_frame {
            self.deferred_frame = Some((cond, deferred_stores));
        }
        // The frame's address, reloaded per group through this slot (see above).
        let ptr_slot = self
            .b
            .create_sized_stack_slot(StackSlotData::new(StackSlotKind::ExplicitSlot, 8, 3));
        let addr = self.slot_addr(frame_slot);
        let pa = self.slot_addr(ptr_slot);
        self.b.ins().store(mem_flags(), addr, pa, 0);
        self.uniform_frame = Some((frame_slot, ptr_slot));
    }

    /// Row prologue: evaluate the hoisted terms for row centre `y_f` into the frame's row
    /// section (see [`hoist`]), with the operations the group code would use.
    /// `only`: the expressions the loop's variant lowers (a pass span's; `None`: all).
    fn row_hoists(
        &mut self,
        f: &'a Function,
        y_f: ir::Value,
        only: Option<&std::collections::HashSet<usize>>,
    ) -> Res<()> {
        let (Some((fs, _)), false) = (self.uniform_frame, self.hoists.is_empty()) else {
            return Ok(());
        };
        if let Some(p) = f.param_by_role(ParamRole::Y) {
            let i = p.local.0 as usize;
            if let (Storage::Vars(vs), Elem::Scalar(sc)) = (&self.frames[0].storage[i], f.local(p.local).ty.elem) {
                let var = vs[0];
                let v = fixed::convert(&mut self.b, Scalar::Float, sc, y_f);
                self.b.def_var(var, v);
            }
        }
        // A row term's uniform operations hoisted once per run (`int(oy * 16)` in
        // `int(Y * 16) - int(oy * 16)`) are read back from the frame, not recomputed per row.
        let addr = self.slot_addr(fs);
        self.prologue_frame = Some((addr, false));
        self.row_local_values.clear();
        let mut stored = Ok(());
        for k in 0..self.hoists.len() {
            let h = &self.hoists[k];
            let key = h.expr as *const Expr as usize;
            let skip = h.per_run || only.is_some_and(|set| !set.contains(&key)) || self.unstored_terms.contains(&key);
            if !skip {
                stored = self.store_hoist(fs, k);
                if stored.is_err() {
                    break;
                }
            }
        }
        self.prologue_frame = None;
        self.row_local_values.clear();
        stored
    }

    /// Once per kernel run, after setup (render mode): the hoisted uniform operations
    /// (`Hoist::per_run`; pure, so evaluating one a pass does not use changes nothing).
    fn run_hoists(&mut self) -> Res<()> {
        let Some((fs, _)) = self.uniform_frame else {
            return Ok(());
        };
        for k in 0..self.hoists.len() {
            if self.hoists[k].per_run {
                self.store_hoist(fs, k)?;
            }
        }
        Ok(())
    }

    /// Evaluate hoist `k` and store its splatted components in the row section of the
    /// uniform frame `fs`.
    fn store_hoist(&mut self, fs: StackSlot, k: usize) -> Res<()> {
        let (expr, view, offset, comps) = {
            let h = &self.hoists[k];
            (h.expr, h.view.clone(), h.offset, h.comps)
        };
        let saved = std::mem::replace(&mut self.view, view);
        self.substitute_row_locals = true;
        let v = self.eval(expr);
        self.substitute_row_locals = false;
        self.view = saved;
        let v = v?;
        if v.comps.len() != comps as usize {
            return err("hoisted row term has an unexpected number of components");
        }
        let addr = self.slot_addr(fs);
        for (c, &x) in v.comps.iter().enumerate() {
            let x = splat(&mut self.b, v.scalar, x);
            self.b
                .ins()
                .store(mem_flags(), x, addr, (offset + 16 * c as u32) as i32);
        }
        Ok(())
    }

    /// In a group: the value of a hoisted row term, read from the frame's row section.
    /// Also in a pixel loop's prologue while carried terms are evaluated (`prologue_frame`).
    fn hoisted(&mut self, e: &'a Expr) -> Option<Val> {
        let (base, rows_ready) = match (&self.pix, self.prologue_frame) {
            (Some(p), _) => (p.frame_base?, true),
            (None, Some(pf)) => pf,
            (None, None) => return None,
        };
        if self.frames.len() != 1 {
            return None;
        }
        let h = self
            .hoists
            .iter()
            .find(|h| std::ptr::eq(h.expr, e) && h.view == self.view && (rows_ready || h.per_run))?;
        let (offset, comps, scalar) = (h.offset, h.comps, h.scalar);
        let ty = cl_type(scalar, true);
        let comps = (0..comps)
            .map(|c| self.b.ins().load(ty, args_flags(), base, (offset + 16 * c) as i32))
            .collect();
        Some(Val {
            comps,
            scalar,
            varying: true,
        })
    }

    /// Tier 1: the frame locals (of `placed`, by local index) that only one side of the
    /// pixel code's first unswitched condition reads, with that side (`true`: then), when
    /// the condition is a top-level statement of the pixel code. Their stores are left to
    /// the side's dispatch block (`store_deferred_frame`), so Cranelift computes them only
    /// on the path that reads them: screen_triangle's float edges, read only when the
    /// triangle is not `exact`, were computed and stored in every render call.
    ///
    /// A local some other reader needs before the dispatch stays in setup: a per-run row
    /// term, a carried term (its steps are evaluated once per run) or the definition of a
    /// local either reads; so does one read outside the condition's sides (its row terms and
    /// block facts are pixel code too) or in the condition itself.
    fn defer_frame_stores(
        &mut self,
        f: &'a Function,
        placed: &[(usize, Vec<Variable>, Option<u32>)],
    ) -> std::collections::HashMap<usize, bool> {
        let mut deferred = std::collections::HashMap::new();
        if self.tier0() {
            return deferred;
        }
        let mut assigned = std::collections::HashSet::new();
        block::assigned_locals(&f.pixel, &mut assigned);
        let Some(cond) = unswitch::next_condition(&f.pixel, &std::collections::HashMap::new(), &assigned, self.key)
        else {
            return deferred;
        };
        let Some(at) = f
            .pixel
            .iter()
            .position(|s| matches!(&s.kind, StmtKind::If { cond: c, .. } if std::ptr::eq(c, cond)))
        else {
            return deferred;
        };
        let StmtKind::If { then, otherwise, .. } = &f.pixel[at].kind else {
            return deferred;
        };
        let n = f.locals.len();
        let mut outside = vec![false; n];
        self.visit_live_pixel_locals(&f.pixel[..at], &mut |l| mark_local(&mut outside, l));
        self.visit_live_pixel_locals(&f.pixel[at + 1..], &mut |l| mark_local(&mut outside, l));
        cond.for_each_local(&mut |l| mark_local(&mut outside, l));
        let early: Vec<&Expr> = self
            .hoists
            .iter()
            .filter(|h| h.per_run)
            .map(|h| h.expr)
            .chain(self.carried.iter().map(|c| c.expr))
            .chain(self.affine_defs.values().copied())
            .chain(self.row_locals.values().copied())
            .collect();
        for e in early {
            e.for_each_local(&mut |l| mark_local(&mut outside, l));
        }
        let mut in_then = vec![false; n];
        let mut in_else = vec![false; n];
        self.visit_live_pixel_locals(then, &mut |l| mark_local(&mut in_then, l));
        self.visit_live_pixel_locals(otherwise, &mut |l| mark_local(&mut in_else, l));
        for (i, _, word) in placed {
            let i = *i;
            if word.is_none() || outside[i] || in_then[i] == in_else[i] {
                continue;
            }
            deferred.insert(i, in_then[i]);
        }
        if !deferred.is_empty() {
            self.deferred_frame = Some((unswitch::cond_key(cond), vec![]));
        }
        deferred
    }

    /// In the dispatch block of side `on` of the condition `cond` (`unswitched_loops`): the
    /// frame stores `defer_frame_stores` left for that side, splats included.
    pub(super) fn store_deferred_frame(&mut self, cond: usize, on: bool) {
        let Some((key, locals)) = self.deferred_frame.take() else {
            return;
        };
        if key == cond {
            if let Some((fs, _)) = self.uniform_frame {
                let addr = self.slot_addr(fs);
                for d in locals.iter().filter(|d| d.on == on) {
                    self.store_frame_words(addr, &d.vars, d.first_word, d.scalar);
                }
            }
        }
        self.deferred_frame = Some((key, locals));
    }

    /// Store a frame local's variables `vars` to its words from `first` in the uniform
    /// frame at `addr`, and (tier 1, not bool) each word's splat to the vector section,
    /// recorded for `drop_unread_splats`. Tier 0 stores no splatted copy: a group splats
    /// the word it reads itself (one instruction per use instead of two stores per uniform
    /// here, which is less code for the tier that runs one frame).
    fn store_frame_words(&mut self, addr: ir::Value, vars: &[Variable], first: u32, sc: Scalar) {
        for (c, v) in vars.iter().enumerate() {
            let x = self.b.use_var(*v);
            let w = first + c as u32;
            self.b.ins().store(mem_flags(), x, addr, (4 * w) as i32);
            if sc != Scalar::Bool && !self.tier0() {
                let xv = splat(&mut self.b, sc, x);
                let off = self.vec_section + 16 * w;
                let st = self.b.ins().store(mem_flags(), xv, addr, off as i32);
                self.splat_stores.push((off, st));
            }
        }
    }

    /// Remove the setup's splat stores no group loads from (most words are read only by
    /// row terms, carried terms or other setup code, as scalars). The splats they stored
    /// are then dead, and Cranelift drops them: for screen_triangle with four perspective
    /// parameters ~45 of 57 splats, three instructions each per render call.
    fn drop_unread_splats(&mut self) {
        for (off, st) in std::mem::take(&mut self.splat_stores) {
            if !self.splats_read.contains(&off) {
                self.b.func.layout.remove_inst(st);
            }
        }
    }

    /// Broadcast uniform component `c` of scalar type `sc`: a frame word read in this group
    /// loads its splat from the vector section, anything else is splatted here.
    fn splat_of(&mut self, sc: Scalar, c: ir::Value) -> ir::Value {
        if self.b.func.dfg.value_type(c).is_vector() {
            return c;
        }
        if let (Some(&off), Some(base)) = (self.splat_src.get(&c), self.pix.as_ref().and_then(|p| p.frame_base)) {
            self.splats_read.insert(off);
            return self.b.ins().load(cl_type(sc, true), args_flags(), base, off as i32);
        }
        splat(&mut self.b, sc, c)
    }

    pub(crate) fn make_varying(&mut self, v: Val) -> Val {
        if v.varying {
            return v;
        }
        let comps = v.comps.iter().map(|&c| self.splat_of(v.scalar, c)).collect();
        Val {
            comps,
            scalar: v.scalar,
            varying: true,
        }
    }

    /// Rows [ys[0], ys[1]) x groups starting at gs[0] (tile-aligned) up to gs[1], `UNROLL`
    /// groups per loop step; lanes outside the pass rectangle start dead. `pass` selects the
    /// pass variant of the pixel code. Ends by jumping to `done`.
    fn pixel_rows(
        &mut self,
        f: &'a Function,
        rect: &PassRect,
        ys: [ir::Value; 2],
        gs: [ir::Value; 2],
        pass: Option<(&block::Prefix<'a>, &[bool])>,
        done: Block,
    ) -> Res<()> {
        let first_block = self.b.func.dfg.num_blocks();
        // The row terms this variant reads (a pass span drops guards, and their terms).
        // So does a copy of the loops for decided conditions (their untaken sides).
        let used_exprs = match pass {
            Some((prefix, decidable)) => {
                let mut live = std::collections::HashSet::new();
                self.live_pixel_locals(&f.pixel[prefix.len..], &mut live);
                Some(block::pass_exprs(
                    &prefix.stmts,
                    &f.pixel[prefix.len..],
                    decidable,
                    &live,
                    &self.unswitched,
                ))
            }
            None if !self.unswitched.is_empty() => Some(unswitch::full_code_exprs(f, &self.unswitched)),
            None => None,
        };
        let py = self.declare_var(types::I32);
        let gx = self.declare_var(types::I32);
        let xv = self.declare_var(F32X4);
        self.b.def_var(py, ys[0]);
        // The row's element index of pixel x = 0 (`(y - y0) * stride - x0`; the tile's x0
        // subtracted once, so a group's index is one add) and its centre Y, carried from row
        // to row by an add: both exact (integers; multiples of 0.5 below 2^22 in f32).
        let row_base_var = self.declare_var(types::I64);
        let yf_var = self.declare_var(types::F32);
        {
            let row = self.b.ins().isub(ys[0], rect.y0);
            let row64 = self.b.ins().sextend(types::I64, row);
            let row_base = self.b.ins().imul(row64, rect.stride64);
            let x0_64 = self.b.ins().sextend(types::I64, rect.x0);
            let row_base = self.b.ins().isub(row_base, x0_64);
            self.b.def_var(row_base_var, row_base);
            let yf = self.b.ins().fcvt_from_sint(types::F32, ys[0]);
            let half = self.f32const_here(0.5);
            let yf = self.b.ins().fadd(yf, half);
            self.b.def_var(yf_var, yf);
        }
        let row_carry = self.carry_rows_start(f, gs[0], ys[0], used_exprs.as_ref())?;
        let row_hdr = self.b.create_block();
        let row_body = self.b.create_block();
        let row_next = self.b.create_block();
        let grp_hdr = self.b.create_block();
        let grp_next = self.b.create_block();
        self.b.ins().jump(row_hdr, &[]);

        // Loop headers branch exit-first so Cranelift keeps hoisting uniform work.
        self.b.switch_to_block(row_hdr);
        let y = self.b.use_var(py);
        let finished = self.b.ins().icmp(IntCC::SignedGreaterThanOrEqual, y, ys[1]);
        self.b.ins().brif(finished, done, &[], row_body, &[]);

        self.b.switch_to_block(row_body);
        let row_y = self.b.use_var(py);
        let row_base = self.b.use_var(row_base_var);
        let yf = self.b.use_var(yf_var);
        let y_f = self.b.ins().splat(F32X4, yf);
        self.row_hoists(f, y_f, used_exprs.as_ref())?;
        self.b.def_var(gx, gs[0]);
        // X of the group's lanes, carried across the row: centre of the first group's
        // lanes (int -> float, + 0.5, as the pixel's X is defined), then + 4.0 per group.
        // Exact, so bit-identical to converting each group's lane indices: every value is
        // a multiple of 0.5 below 2^22 in magnitude (images are at most 16384 pixels wide).
        let x0_f = self.lane_centres(gs[0]);
        self.b.def_var(xv, x0_f);
        // Int terms affine in the column: their value at the first group, carried (see
        // [`affine`]); after the row hoists, which define Y's variable the same way.
        let carry = self.carry_prologue(f, x0_f, y_f, used_exprs.as_ref(), &row_carry)?;
        self.b.ins().jump(grp_hdr, &[]);

        self.b.switch_to_block(grp_hdr);
        let g = self.b.use_var(gx);
        let finished = self.b.ins().icmp(IntCC::SignedGreaterThanOrEqual, g, gs[1]);
        let first = self.b.create_block();
        self.b.ins().brif(finished, row_next, &[], first, &[]);
        self.b.switch_to_block(first);
        let unroll = UNROLL;
        for k in 0..unroll {
            let next = if k + 1 == unroll {
                grp_next
            } else {
                self.b.create_block()
            };
            let g = self.b.use_var(gx);
            let g = self.b.ins().iadd_imm_s(g, 4 * k as i64);
            let x_f = self.b.use_var(xv);
            let x_f = if k == 0 {
                x_f
            } else {
                let step = self.f32const_here(4.0 * k as f32);
                let step = self.b.ins().splat(F32X4, step);
                self.b.ins().fadd(x_f, step)
            };
            let mut vals: Vec<ir::Value> = carry.group.iter().map(|c| self.b.use_var(c.1)).collect();
            self.carry_advance(&mut vals, &carry, k);
            self.carry_now = carry.group.iter().zip(&vals).map(|(c, &v)| (c.0, v)).collect();
            let lowered = self.pixel_group(f, rect, g, row_base, [x_f, y_f], pass, next);
            self.carry_now.clear();
            lowered?;
            if k + 1 != unroll {
                self.b.switch_to_block(next);
            }
        }

        self.b.switch_to_block(grp_next);
        let g = self.b.use_var(gx);
        let g = self.b.ins().iadd_imm_s(g, 4 * unroll as i64);
        self.b.def_var(gx, g);
        let x_f = self.b.use_var(xv);
        let step = self.f32const_here(4.0 * unroll as f32);
        let step = self.b.ins().splat(F32X4, step);
        let x_f = self.b.ins().fadd(x_f, step);
        self.b.def_var(xv, x_f);
        let mut vals: Vec<ir::Value> = carry.group.iter().map(|c| self.b.use_var(c.1)).collect();
        self.carry_advance(&mut vals, &carry, unroll);
        for (c, v) in carry.group.iter().zip(vals) {
            self.b.def_var(c.1, v);
        }
        self.b.ins().jump(grp_hdr, &[]);

        // The row's y as read in `row_body` (dominates this block), not `use_var`: a read
        // here would be looked up through the group loop and carried through it.
        self.b.switch_to_block(row_next);
        let y = self.b.ins().iadd_imm_s(row_y, 1);
        self.b.def_var(py, y);
        let row_base = self.b.ins().iadd(row_base, rect.stride64);
        self.b.def_var(row_base_var, row_base);
        let one = self.f32const_here(1.0);
        let yf = self.b.ins().fadd(yf, one);
        self.b.def_var(yf_var, yf);
        self.carry_next_row(&carry);
        self.b.ins().jump(row_hdr, &[]);
        self.seal_blocks_from(first_block);
        Ok(())
    }

    /// Seal every block created since block number `first`: a finished loop nest whose
    /// blocks no later code jumps into.
    ///
    /// Why: a variable read after the loops (the block walk's span bounds, read when a
    /// span is flushed) is looked up through the loop blocks. Unsealed, each loop header
    /// on the way gets a speculative block parameter that the frontend cannot prove
    /// redundant later, so the value was carried (and spilled and reloaded) through every
    /// pixel group. Sealed, the lookup sees all predecessors and drops the parameter.
    fn seal_blocks_from(&mut self, first: usize) {
        for i in first..self.b.func.dfg.num_blocks() {
            let block = Block::from_u32(i as u32);
            if !self.sealed_early.contains(&block) {
                self.b.seal_block(block);
            }
        }
    }

    /// The pixel code for the group of 4 pixels starting at `g` (lane centres `xy_f`;
    /// `row_base` is the element index of x = 0 in the group's row); ends by jumping to
    /// `next`.
    #[allow(clippy::too_many_arguments)]
    fn pixel_group(
        &mut self,
        f: &'a Function,
        rect: &PassRect,
        g: ir::Value,
        row_base: ir::Value,
        xy_f: [ir::Value; 2],
        pass: Option<(&block::Prefix<'a>, &[bool])>,
        next: Block,
    ) -> Res<()> {
        let [x_f, y_f] = xy_f;
        let group_end = self.b.create_block();
        let g64 = self.b.ins().sextend(types::I64, g);
        let tile_idx = self.b.ins().iadd(row_base, g64);
        let frame_base = self.uniform_frame.map(|(_, ptr_slot)| {
            let pa = self.slot_addr(ptr_slot);
            self.b.ins().load(types::I64, mem_flags(), pa, 0)
        });
        // Lane i is live when lo_x <= g + i < hi_x, i.e. lo_x < X < hi_x for its centre X
        // (integers below 2^22 and their half-integer centres are exact in f32). The bounds'
        // splats are read from the frame: two compares with memory operands. (Splats of the
        // group-relative bounds cost 13 instructions a group; splats kept in registers
        // across the loops cost the fill workload's groups 4 % in spills.)
        let Some(base) = frame_base else {
            return err("uniform frame missing");
        };
        let edge_mask = |l: &mut Self| {
            let [lo, hi] = [0, 16].map(|k| l.b.ins().load(F32X4, args_flags(), base, (l.x_range_at + k) as i32));
            let ge = l.b.ins().fcmp(FloatCC::GreaterThan, x_f, lo);
            let lt = l.b.ins().fcmp(FloatCC::LessThan, x_f, hi);
            l.b.ins().band(ge, lt)
        };
        let mask = if self.flat {
            // Flat pixel code: every group computes its lane mask, in the block it starts
            // in (no branch, so no block boundary). A group with no live lane (only when
            // the pass is empty in x) then runs for no lane, which changes nothing there.
            edge_mask(self)
        } else {
            let grp_run = self.b.create_block();
            let mask = self.b.append_block_param(grp_run, I32X4);
            let edge = self.b.create_block();
            // Lanes outside [lo_x, hi_x) start dead. Only a group at either end of the
            // rectangle has such lanes: one unsigned compare tells the others apart.
            let d = self.b.ins().isub(g, rect.lo_x);
            let interior = self.b.ins().icmp(IntCC::UnsignedLessThan, d, rect.interior_lim);
            let all = mask_const(&mut self.b, true);
            self.b.ins().brif(interior, grp_run, &[all.into()], edge, &[]);

            self.b.switch_to_block(edge);
            let edge_mask = edge_mask(self);
            let any = self.b.ins().vany_true(edge_mask);
            let none = self.b.ins().icmp_imm_s(IntCC::Equal, any, 0);
            self.b.ins().brif(none, next, &[], grp_run, &[edge_mask.into()]);

            self.b.switch_to_block(grp_run);
            mask
        };
        let alive = self.declare_var(I32X4);
        let exec = self.declare_var(I32X4);
        let z_written = self.declare_var(I32X4);
        self.b.def_var(alive, mask);
        self.b.def_var(exec, mask);
        let none_mask = mask_const(&mut self.b, false);
        self.b.def_var(z_written, none_mask);
        let needs_depth = f.param_by_role(ParamRole::Z).is_some()
            || self
                .key
                .bindings
                .iter()
                .any(|b| matches!(b.kind, BindingKind::Shared(_)));
        let z_raw = if needs_depth {
            let addr = self.tile_addr(ctx_off::DEPTH, tile_idx);
            Some(self.b.ins().load(I32X4, mem_flags(), addr, 0))
        } else {
            None
        };
        self.pix = Some(PixelState {
            alive,
            exec,
            z_written,
            group_end,
            tile_idx,
            x_f,
            y_f,
            frame_base,
            z_raw,
            varying_depth: 0,
        });
        // Bind the primitive's X, Y, Z in its declared types.
        for (i, p) in f.params.iter().enumerate() {
            let local = f.local(p.local);
            let Elem::Scalar(sc) = local.ty.elem else { continue };
            let (src, from) = match p.role {
                ParamRole::X => (x_f, Scalar::Float),
                ParamRole::Y => (y_f, Scalar::Float),
                ParamRole::Z => match z_raw {
                    Some(z) => (z, Scalar::Fixed(DEPTH_FORMAT)),
                    None => continue,
                },
                _ => continue,
            };
            let v = fixed::convert(&mut self.b, from, sc, src);
            match &self.frames[0].storage[i] {
                Storage::Vars(vs) => {
                    let var = vs[0];
                    self.b.def_var(var, v)
                }
                Storage::Z(var) => {
                    let var = *var;
                    self.b.def_var(var, v)
                }
                _ => {}
            }
        }
        for r in 0..self.group_resets.len() {
            let (init, work, bytes) = self.group_resets[r];
            self.copy_slot(init, work, bytes);
        }
        if self.flat {
            self.flat_group_locals(f);
        }
        // Guard facts hold within one group body only (not in row prologues).
        self.guard_facts.clear();
        match pass {
            None => self.stmts(&f.pixel)?,
            Some((prefix, decidable)) => {
                let mut live = std::collections::HashSet::new();
                self.live_pixel_locals(&f.pixel[prefix.len..], &mut live);
                self.prefix_without_guards(&prefix.stmts, &prefix.stmts, decidable, &live)?;
                self.stmts(&f.pixel[prefix.len..])?;
            }
        }
        self.guard_facts.clear();
        self.b.ins().jump(group_end, &[]);

        // End of group: write Z back for the lanes that assigned it. Nothing else writes
        // the depth buffer during the group, so the depth loaded at its start is the old
        // value to blend with; when every lane assigned Z it is a plain store.
        self.b.switch_to_block(group_end);
        if let (Some(zp), Some(z_old)) = (f.param_by_role(ParamRole::Z), z_raw) {
            let zi = f.params.iter().position(|p| p.role == ParamRole::Z).unwrap_or(0);
            let zsc = match f.local(zp.local).ty.elem {
                Elem::Scalar(s) => s,
                Elem::Interp => Scalar::Float,
            };
            let zvar = match &self.frames[0].storage[zi] {
                Storage::Z(v) => *v,
                _ => return err("Z parameter without storage"),
            };
            let written = self.b.use_var(z_written);
            if self.tier0() {
                // Tier 0: one blended store, whatever the lanes (no blocks for the all and
                // none cases). The depth loaded at the group's start is still the buffer's
                // value, so unwritten lanes store back what they hold.
                self.store_depth(zvar, zsc, Some((written, z_old)), tile_idx);
                self.count_writes(written, tile_idx);
                self.b.ins().jump(next, &[]);
                self.pix = None;
                return Ok(());
            }
            // The written lanes' bits (`vmovmskps`): all four and none are compares of one
            // integer, cheaper than `vall_true` and `vany_true` on the vector.
            let bits = self.b.ins().vhigh_bits(types::I32, written);
            let all = self.b.ins().icmp_imm_s(IntCC::Equal, bits, ALL_LANE_BITS);
            let full_blk = self.b.create_block();
            let part_blk = self.b.create_block();
            let blend_blk = self.b.create_block();
            let stored = self.b.create_block();
            self.b.ins().brif(all, full_blk, &[], part_blk, &[]);

            self.b.switch_to_block(full_blk);
            self.store_depth(zvar, zsc, None, tile_idx);
            self.b.ins().jump(stored, &[]);

            self.b.switch_to_block(part_blk);
            let none = self.b.ins().icmp_imm_s(IntCC::Equal, bits, 0);
            self.b.ins().brif(none, next, &[], blend_blk, &[]);
            self.b.switch_to_block(blend_blk);
            self.store_depth(zvar, zsc, Some((written, z_old)), tile_idx);
            self.b.ins().jump(stored, &[]);

            self.b.switch_to_block(stored);
            self.count_writes(written, tile_idx);
        }
        self.b.ins().jump(next, &[]);
        self.pix = None;
        Ok(())
    }

    /// Store the group's Z (`zvar`, of scalar type `zsc`) to the depth buffer as
    /// `fixed<32,32>` raw: in every lane, or with `blend = (written, old)` only in the
    /// `written` lanes, the others keeping `old`.
    fn store_depth(&mut self, zvar: Variable, zsc: Scalar, blend: Option<(ir::Value, ir::Value)>, tile_idx: ir::Value) {
        let zval = self.b.use_var(zvar);
        let raw = fixed::convert(&mut self.b, zsc, Scalar::Fixed(DEPTH_FORMAT), zval);
        let addr = self.tile_addr(ctx_off::DEPTH, tile_idx);
        let new = match blend {
            Some((written, old)) => self.b.ins().blendv(written, raw, old),
            None => raw,
        };
        self.b.ins().store(mem_flags(), new, addr, 0);
    }

    /// Add one to the write count of the `written` lanes (when the key counts writes).
    fn count_writes(&mut self, written: ir::Value, tile_idx: ir::Value) {
        if !self.key.count_writes {
            return;
        }
        let caddr = self.tile_addr(ctx_off::WRITE_COUNT, tile_idx);
        let old = self.b.ins().load(I32X4, mem_flags(), caddr, 0);
        // Written lanes are -1: subtracting adds one.
        let new = self.b.ins().isub(old, written);
        self.b.ins().store(mem_flags(), new, caddr, 0);
    }

    /// Flat pixel code, at the start of a group: every varying local the pixel code
    /// assigns starts the group as zero.
    ///
    /// Why: flat code assigns such locals under masks (a declaration inside a uniform `if`
    /// run as a masked one blends), which reads the old value: left undefined, that is the
    /// previous group's, carried through the group and row loops as block parameters the
    /// single-pass allocator moves and spills at every loop edge. No lane reads what an
    /// earlier group left (a local is declared, so assigned, before any read of it in the
    /// same group), so the values the pixels see are the same.
    fn flat_group_locals(&mut self, f: &'a Function) {
        let assigned = dead::assigned_flags(&f.pixel, f.locals.len());
        // A local the setup assigns keeps the setup's value until the pixel code assigns it.
        let in_setup = dead::assigned_flags(&f.setup, f.locals.len());
        let mut zeros: std::collections::HashMap<Scalar, ir::Value> = std::collections::HashMap::new();
        for (i, local) in f.locals.iter().enumerate() {
            if !local.var.is_varying() || !assigned[i] || in_setup[i] {
                continue;
            }
            if f.params.iter().any(|p| p.local.0 as usize == i) {
                continue;
            }
            let Storage::Vars(vars) = &self.frames[0].storage[i] else {
                continue;
            };
            let vars = vars.clone();
            let sc = elem_scalar(&local.ty);
            let z = *zeros.entry(sc).or_insert_with(|| zero(&mut self.b, sc, true));
            for v in vars {
                self.b.def_var(v, z);
            }
        }
    }

    /// Pixels [lo, hi) of the tile range [t0, t1) whose centres lie in [bmin, bmax].
    /// Clamped in float first so huge or infinite bounds cannot overflow the conversion.
    fn pass_range(&mut self, bmin: ir::Value, bmax: ir::Value, t0: ir::Value, t1: ir::Value) -> (ir::Value, ir::Value) {
        let t0f = self.b.ins().fcvt_from_sint(types::F32, t0);
        let t1f = self.b.ins().fcvt_from_sint(types::F32, t1);
        let half = self.f32const_here(0.5);
        let one = self.f32const_here(1.0);
        let lo = self.b.ins().fsub(bmin, half);
        let lo = self.b.ins().ceil(lo);
        let lo = self.b.ins().fmax(lo, t0f);
        let lo = self.b.ins().fmin(lo, t1f);
        let hi = self.b.ins().fsub(bmax, half);
        let hi = self.b.ins().floor(hi);
        let hi = self.b.ins().fadd(hi, one);
        let hi = self.b.ins().fmax(hi, t0f);
        let hi = self.b.ins().fmin(hi, t1f);
        // NaN converts to 0 here; the caller empties the rectangle for NaN bounds.
        let lo_i = self.b.ins().fcvt_to_sint_sat(types::I32, lo);
        let hi_i = self.b.ins().fcvt_to_sint_sat(types::I32, hi);
        let hi_i = self.b.ins().smax(hi_i, lo_i);
        (lo_i, hi_i)
    }

    /// X of the lanes of the group starting at `g`: the pixel centres (int -> float, + 0.5,
    /// as the pixel's X is defined).
    fn lane_centres(&mut self, g: ir::Value) -> ir::Value {
        let g0 = self.b.ins().splat(I32X4, g);
        let iota = self.iota();
        let px0 = self.b.ins().iadd(g0, iota);
        let pxf = self.b.ins().fcvt_from_sint(F32X4, px0);
        let half = self.f32const_here(0.5);
        let halfv = self.b.ins().splat(F32X4, half);
        self.b.ins().fadd(pxf, halfv)
    }

    fn iota(&mut self) -> ir::Value {
        let mut bytes = vec![];
        for i in 0..4u32 {
            bytes.extend_from_slice(&i.to_le_bytes());
        }
        let c = self.b.func.dfg.constants.insert(bytes.into());
        self.b.ins().vconst(I32X4, c)
    }

    /// Address of element `idx` (i64) of the tile buffer whose pointer is at `ptr_off` in ctx.
    fn tile_addr(&mut self, ptr_off: i32, idx: ir::Value) -> ir::Value {
        // The context's buffer pointers never change while a kernel runs (the runtime sets
        // them before the call; kernels write only the error, bound, fuel and call-depth
        // fields): loaded as read-only, the group loop's two loads of the depth pointer
        // merge and leave the loop instead of reloading the context pointer every group.
        let base = self.b.ins().load(types::I64, args_flags(), self.ctx, ptr_off);
        let bytes = self.b.ins().ishl_imm_u(idx, 2);
        self.b.ins().iadd(base, bytes)
    }

    // ---------------------------------------------------------------- frames and storage

    /// Whether a local of `words` components may live in SSA variables (one each), counted
    /// against the kernel's budget of [`MAX_VAR_WORDS`]: otherwise it goes to the stack
    /// like a dynamically indexed one. Cranelift allows at most 65535 parameters per block,
    /// and a loop header can carry every variable (a `float a[65535]` read at constant
    /// indices panicked the SSA builder); SSA over that many values compiles slowly anyway.
    fn take_var_words(&mut self, words: u32) -> bool {
        let fits = words <= MAX_LOCAL_VAR_WORDS && self.var_words + words <= MAX_VAR_WORDS;
        if fits {
            self.var_words += words;
        }
        fits
    }

    fn make_frame(
        &mut self,
        f: &'a Function,
        slots: Vec<ParamSlot>,
        fixed_words: u32,
        interp_binding: Option<usize>,
    ) -> Res<Frame<'a>> {
        let mut dynamic = vec![false; f.locals.len()];
        for s in f.setup.iter().chain(f.pixel.iter()) {
            mark_dynamic_stmt(s, &mut dynamic);
        }
        // The primitive's own frame: only arrays some read may reach before a whole
        // assignment are cleared at entry (see [`init`]); an inlined interpolator's frame
        // clears all of its arrays.
        let entry_clear = if interp_binding.is_none() {
            Some(init::read_before_assigned(f))
        } else {
            None
        };
        let mut storage = Vec::with_capacity(f.locals.len());
        for (i, local) in f.locals.iter().enumerate() {
            let param_role = f.params.iter().find(|p| p.local.0 as usize == i).map(|p| p.role);
            let varying = local.var.is_varying();
            let sc = elem_scalar(&local.ty);
            let st = match param_role {
                Some(ParamRole::Z) if interp_binding.is_none() => Storage::Z(self.declare_var(I32X4_or(sc))),
                Some(ParamRole::X | ParamRole::Y | ParamRole::Z) => Storage::Vars(vec![self.declare_var(I32X4_or(sc))]),
                Some(_) => Storage::Args,
                None => {
                    if local.ty.per_seq {
                        return err(format!("local `{}` has a per-sequence-point type", local.name));
                    }
                    let n = type_words(&local.ty, self.n_interp);
                    if dynamic[i] || !self.take_var_words(n) {
                        let bytes = n.max(1) * comp_bytes(varying);
                        let slot =
                            self.b
                                .create_sized_stack_slot(StackSlotData::new(StackSlotKind::ExplicitSlot, bytes, 4));
                        // Zero it so no run reads stale stack memory, unless every read
                        // comes after a whole assignment.
                        if entry_clear.as_ref().is_none_or(|c| c.get(i).copied().unwrap_or(true)) {
                            let addr = self.slot_addr(slot);
                            self.zero_stack_bytes(addr, 0, bytes);
                        }
                        Storage::Stack(slot)
                    } else {
                        let ty = cl_type(sc, varying);
                        let vars = if !self.tier0() {
                            let z = zero(&mut self.b, sc, varying);
                            (0..n)
                                .map(|_| {
                                    let v = self.declare_var(ty);
                                    self.b.def_var(v, z);
                                    v
                                })
                                .collect()
                        } else {
                            // Tier 0: no explicit zero. A variable read where no assignment
                            // reaches is zero all the same (the SSA builder materialises
                            // zero there), without ~100 constants at entry and the block
                            // parameters they feed.
                            (0..n).map(|_| self.declare_var(ty)).collect()
                        };
                        Storage::Vars(vars)
                    }
                }
            };
            storage.push(st);
        }
        Ok(Frame {
            func: f,
            slots,
            fixed_words,
            storage,
            loops: vec![],
            interp_binding,
        })
    }

    fn frame(&self) -> &Frame<'a> {
        self.frames.last().expect("a frame is always pushed while lowering")
    }

    fn frame_mut(&mut self) -> &mut Frame<'a> {
        self.frames.last_mut().expect("a frame is always pushed while lowering")
    }

    fn exec(&mut self) -> Option<ir::Value> {
        let e = self.pix.as_ref()?.exec;
        Some(self.b.use_var(e))
    }

    fn set_exec(&mut self, v: ir::Value) {
        if let Some(p) = &self.pix {
            let e = p.exec;
            self.b.def_var(e, v);
        }
    }

    /// Assignments must blend with the old value (some live lane is not executing).
    fn masked(&self) -> bool {
        self.pix.as_ref().is_some_and(|p| p.varying_depth > 0)
    }

    fn in_pixel(&self) -> bool {
        self.pix.is_some()
    }

    fn depth_add(&mut self, d: i32) {
        if let Some(p) = &mut self.pix {
            p.varying_depth = (p.varying_depth as i32 + d) as u32;
        }
    }

    /// `exec` after leaving a construct entered with `entry`: the entry lanes that are still
    /// alive and have not left an enclosing varying loop.
    fn restore_exec(&mut self, entry: ir::Value) {
        let Some(p) = &self.pix else { return };
        let alive = p.alive;
        let a = self.b.use_var(alive);
        let mut m = self.b.ins().band(entry, a);
        for (mask, cont) in self.vloops.clone() {
            let lm = self.b.use_var(mask);
            let c = self.b.use_var(cont);
            let stay = self.b.ins().band_not(lm, c);
            m = self.b.ins().band(m, stay);
        }
        self.set_exec(m);
    }

    // ---------------------------------------------------------------- statements

    fn stmts(&mut self, stmts: &'a [Stmt]) -> Res<()> {
        // A guard's facts hold to the end of the statement list it is in.
        let mark = self.guard_facts.mark();
        for s in stmts {
            self.stmt(s)?;
        }
        self.guard_facts.truncate(mark);
        Ok(())
    }

    fn stmt(&mut self, s: &'a Stmt) -> Res<()> {
        match &s.kind {
            StmtKind::Assign { place, value } => {
                if self.dead_setup_assign(s, place.local) {
                    return Ok(());
                }
                // Only carried or row terms read it: nothing in the group does.
                if self.pix.is_some()
                    && self.frames.len() == 1
                    && place.indices.is_empty()
                    && self.unread_in_groups.contains(&place.local)
                {
                    return Ok(());
                }
                self.assign(place, value)
            }
            StmtKind::If { cond, then, otherwise } => {
                self.lower_if(cond, then, otherwise)?;
                // `if (c) return;`: every lane still executing has `c` false.
                if self.in_pixel()
                    && otherwise.is_empty()
                    && matches!(then.as_slice(), [t] if matches!(t.kind, StmtKind::Return))
                {
                    self.assume_guard(cond);
                }
                Ok(())
            }
            StmtKind::Loop {
                id,
                cond,
                body,
                step,
                varying,
                site,
            } => {
                // The body runs again after its assignments: no fact about what it assigns
                // holds in it (or after it).
                // (Setup code has none: no walk there.)
                if !self.guard_facts.is_empty() {
                    let frame = self.frames.len() - 1;
                    for_each_assign(body, &mut |p, _| self.guard_facts.kill(frame, p.local));
                    for_each_assign(step, &mut |p, _| self.guard_facts.kill(frame, p.local));
                }
                if *varying && self.in_pixel() {
                    self.varying_loop(*id, cond.as_ref(), body, step, *site)
                } else {
                    self.uniform_loop(*id, cond.as_ref(), body, step, *site)
                }
            }
            StmtKind::Break(id) => self.break_continue(*id, true),
            StmtKind::Continue(id) => self.break_continue(*id, false),
            StmtKind::Return => self.lower_return(),
            StmtKind::Interpolation { arms } => self.interpolation(arms),
            StmtKind::InterpolatorReturn(e) => self.interpolator_return(e.as_ref()),
            StmtKind::Bound(es) => {
                if self.in_pixel() || self.frames.len() > 1 {
                    return err("`bound` in per-pixel code");
                }
                self.lower_bound(es, false)
            }
            StmtKind::CallPrimitive { callee, args } => {
                if self.in_pixel() || self.frames.len() > 1 {
                    return err("primitive call in per-pixel code");
                }
                // The callee (compiled for the same key) answers for the bindings itself.
                self.written.iter_mut().for_each(|w| *w = true);
                self.call_primitive(*callee, args)
            }
        }
    }

    /// Tier 0: `s`, an assignment to `local` in the primitive's setup, computes a value no
    /// live code reads and has no other effect (see [`dead`]).
    fn dead_setup_assign(&self, s: &Stmt, local: LocalId) -> bool {
        let Some(live) = &self.setup_live else {
            return false;
        };
        let mut budget = usize::MAX;
        self.pix.is_none()
            && self.frames.len() == 1
            && !live.get(local.0 as usize).copied().unwrap_or(true)
            && self.speculable_stmts(std::slice::from_ref(s), &mut budget)
    }

    fn lower_if(&mut self, cond: &'a Expr, then: &'a [Stmt], otherwise: &'a [Stmt]) -> Res<()> {
        // `clipping()` (possibly negated) is a constant of the key: lower only the branch it
        // selects, so a trivially accepted variant contains no clipping code at all.
        if let Some(on) = key_constant(cond, self.key) {
            let taken = if on { then } else { otherwise };
            for s in taken {
                self.stmt(s)?;
            }
            return Ok(());
        }
        // A condition decided before the pixel loops (tier 1, see [`unswitch`]): this copy
        // of the loops holds the side it takes only.
        if let Some(&on) = self.unswitched.get(&unswitch::cond_key(cond)) {
            return self.stmts(if on { then } else { otherwise });
        }
        let c = self.eval(cond)?;
        if !c.varying {
            let c = fixed::convert(&mut self.b, c.scalar, Scalar::Bool, c.comps[0]);
            // Tier 0, flat pixel code: a uniform `if` whose sides run under masks as well
            // as after a branch is lowered like a varying one, with the condition splatted
            // to every lane: no blocks for its sides (see [`flat`]).
            if self.flat
                && self.frames.len() == 1
                && flat::maskable_stmts(self.frames[0].func, then)
                && flat::maskable_stmts(self.frames[0].func, otherwise)
            {
                if let Some(entry) = self.exec() {
                    let m = splat(&mut self.b, Scalar::Bool, c);
                    return self.masked_if(entry, m, then, otherwise);
                }
            }
            // Small assigning `if`s of setup code: straight-line (see `if_converted`).
            if self.pix.is_none() && self.if_convertible(then, otherwise) {
                return self.if_converted(c, then, otherwise);
            }
            // Tier 0: `if (c) return;` in setup is one branch to the exit, not a `then`
            // block, an unreachable block after its return and a join.
            if self.tier0()
                && otherwise.is_empty()
                && matches!(then, [s] if matches!(s.kind, StmtKind::Return))
                && self.pix.is_none()
                && self.frame().interp_binding.is_none()
            {
                let cont = self.b.create_block();
                self.b.ins().brif(c, self.exit, &[], cont, &[]);
                self.seal_now(cont);
                self.b.switch_to_block(cont);
                return Ok(());
            }
            let then_blk = self.b.create_block();
            let else_blk = self.b.create_block();
            let join = self.b.create_block();
            if self.in_dead_block() {
                self.dead_blocks.extend([then_blk, else_blk]);
            }
            self.b.ins().brif(c, then_blk, &[], else_blk, &[]);
            // Each block sealed once its predecessors are all known (see `seal_now`).
            self.seal_now(then_blk);
            self.seal_now(else_blk);
            self.b.switch_to_block(then_blk);
            self.stmts(then)?;
            let from_then = self.jump_live(join);
            self.b.switch_to_block(else_blk);
            self.stmts(otherwise)?;
            let from_else = self.jump_live(join);
            if !from_then && !from_else {
                self.dead_blocks.insert(join);
            }
            self.seal_now(join);
            self.b.switch_to_block(join);
            return Ok(());
        }
        let Some(entry) = self.exec() else {
            return err("varying condition outside per-pixel code");
        };
        let c = fixed::convert(&mut self.b, c.scalar, Scalar::Bool, c.comps[0]);
        self.masked_if(entry, c, then, otherwise)
    }

    /// `if (c) then else otherwise` for the lanes of `entry`, with `c` a lane mask: each
    /// side runs under its mask and is skipped when no lane takes it (flat pixel code runs
    /// both sides whatever the masks: see [`flat`]).
    fn masked_if(&mut self, entry: ir::Value, c: ir::Value, then: &'a [Stmt], otherwise: &'a [Stmt]) -> Res<()> {
        if otherwise.is_empty()
            && matches!(then, [s] if matches!(s.kind, StmtKind::Return))
            && self.frame().interp_binding.is_none()
        {
            return self.varying_guard_return(entry, c);
        }
        let then_mask = self.b.ins().band(entry, c);
        let else_mask = self.b.ins().band_not(entry, c);
        let then_out = self.declare_var(I32X4);
        self.b.def_var(then_out, then_mask);
        self.depth_add(1);
        self.masked_side(then_mask, then, then_out)?;
        let else_out = self.declare_var(I32X4);
        self.b.def_var(else_out, else_mask);
        if !otherwise.is_empty() {
            self.masked_side(else_mask, otherwise, else_out)?;
        }
        self.depth_add(-1);
        let t = self.b.use_var(then_out);
        let e = self.b.use_var(else_out);
        let m = self.b.ins().bor(t, e);
        self.set_exec(m);
        Ok(())
    }

    /// One side of [`Self::masked_if`]: `stmts` with `exec = mask`, skipped when `mask` is
    /// empty unless the pixel code is flat; `out` gets the lanes still executing after it.
    fn masked_side(&mut self, mask: ir::Value, stmts: &'a [Stmt], out: Variable) -> Res<()> {
        if self.flat {
            self.set_exec(mask);
            self.stmts(stmts)?;
            let x = self.exec().expect("pixel context");
            self.b.def_var(out, x);
            return Ok(());
        }
        let side = self.b.create_block();
        let join = self.b.create_block();
        let any = self.b.ins().vany_true(mask);
        let none = self.b.ins().icmp_imm_s(IntCC::Equal, any, 0);
        self.b.ins().brif(none, join, &[], side, &[]);
        self.b.switch_to_block(side);
        self.set_exec(mask);
        self.stmts(stmts)?;
        let x = self.exec().expect("pixel context");
        self.b.def_var(out, x);
        self.b.ins().jump(join, &[]);
        self.b.switch_to_block(join);
        Ok(())
    }

    // ------------------------------------------------ tier 0: deferred setup returns

    /// The primitive's setup statements. Tier 1 ends a bound run right after a `bound` that
    /// nothing after it can widen (see [`quiet_stmt`]). Tier 0 defers each `if (c) return;` among them to
    /// the end of the run of statements that can run speculatively around it: the
    /// statements after the guard run whether or not it returns (they compute values
    /// only), and one branch at the run's end returns if any of its guards held.
    ///
    /// Why: a guard splits the setup into blocks, and the single-pass allocator spills
    /// every value that lives across the split (screen_triangle's edge and plane
    /// computations around its area test: 20 values) and reloads it after. The statements
    /// run are those tier 1 runs plus ones whose results nothing reads when a guard holds
    /// (no stores, no possible run-time error, no loop), so results are the same.
    ///
    /// Returns the condition of the guards deferred to the end of the setup: the caller
    /// returns on it (after storing the uniform frame, see [`Self::pixel_passes`]).
    fn setup_stmts(&mut self, f: &'a Function) -> Res<Option<ir::Value>> {
        let setup = &f.setup;
        if !self.tier0() {
            for (i, s) in setup.iter().enumerate() {
                if let StmtKind::Bound(es) = &s.kind {
                    // A bound run wants nothing but the bound: when the rest of the setup can
                    // neither widen it (another `bound`, a call) nor record an error, it ends
                    // here (the rest is the render run's work: edge and plane equations...).
                    let last_effect = setup[i + 1..].iter().all(|t| quiet_stmt(f, t));
                    self.lower_bound(es, last_effect)?;
                } else {
                    self.stmt(s)?;
                }
            }
            return Ok(None);
        }
        // The OR of the guards deferred so far in this run.
        let mut pending: Option<ir::Value> = None;
        for (i, s) in setup.iter().enumerate() {
            if self.outline.setup_split == Some(i) {
                if let Some(p) = pending.take() {
                    self.return_if(p);
                }
                self.begin_outlined_setup(f, i)?;
            }
            if let Some(cond) = self.deferrable_guard(s) {
                let c = self.eval_uniform(cond)?;
                let c = fixed::convert(&mut self.b, c.scalar, Scalar::Bool, c.comps[0]);
                pending = Some(match pending {
                    Some(p) => self.b.ins().bor(p, c),
                    None => c,
                });
                continue;
            }
            let mut budget = usize::MAX;
            if !self.speculable_stmts(std::slice::from_ref(s), &mut budget) {
                if let Some(p) = pending.take() {
                    self.return_if(p);
                }
            }
            self.stmt(s)?;
        }
        Ok(pending)
    }

    /// `c` of a setup statement `if (c) return;` whose condition cannot fail.
    fn deferrable_guard(&self, s: &'a Stmt) -> Option<&'a Expr> {
        let StmtKind::If { cond, then, otherwise } = &s.kind else {
            return None;
        };
        let is_return = otherwise.is_empty() && matches!(then.as_slice(), [t] if matches!(t.kind, StmtKind::Return));
        (is_return && key_constant(cond, self.key).is_none() && speculable_expr(cond)).then_some(cond)
    }

    /// End the kernel if `c` (i8) holds; code goes on in a new block.
    fn return_if(&mut self, c: ir::Value) {
        let cont = self.b.create_block();
        self.b.ins().brif(c, self.exit, &[], cont, &[]);
        self.b.switch_to_block(cont);
    }

    // ------------------------------------------------ if-conversion in setup

    /// A small uniform `if` of setup code whose sides only assign SSA variables from
    /// expressions that cannot fail is lowered as straight-line code: both sides, then one
    /// `select` per variable either side assigns. The values assigned are the same, so
    /// results are bit-identical to the branching form. At tier 0 each block boundary
    /// costs the register allocator (it spills every live value there and reloads it on
    /// use), so fewer blocks compile faster. At tier 1 the e-graph places a pure value at
    /// its first use: a value used inside one side and again after the join was computed
    /// twice (screen_triangle's snapped vertices, used for `px` in the `exact` side and for
    /// the integer edges after it: 6 of its setup's rounds and conversions repeated).
    fn if_convertible(&self, then: &[Stmt], otherwise: &[Stmt]) -> bool {
        const MAX_STMTS: usize = 24;
        let mut budget = MAX_STMTS;
        self.speculable_stmts(then, &mut budget) && self.speculable_stmts(otherwise, &mut budget)
    }

    fn speculable_stmts(&self, stmts: &[Stmt], budget: &mut usize) -> bool {
        stmts.iter().all(|s| {
            if *budget == 0 {
                return false;
            }
            *budget -= 1;
            match &s.kind {
                StmtKind::Assign { place, value } => {
                    let fr = self.frame();
                    let Some(local) = fr.func.locals.get(place.local.0 as usize) else {
                        return false;
                    };
                    if !place.indices.is_empty() {
                        let mut ty = local.ty.clone();
                        for (idx, _) in &place.indices {
                            if !const_index_in_range(&ty, idx) {
                                return false;
                            }
                            ty = ty.element();
                        }
                    }
                    matches!(fr.storage.get(place.local.0 as usize), Some(Storage::Vars(_)))
                        && !local.var.is_varying()
                        && speculable_expr(value)
                }
                StmtKind::If { cond, then, otherwise } => {
                    key_constant(cond, self.key).is_none()
                        && speculable_expr(cond)
                        && self.speculable_stmts(then, budget)
                        && self.speculable_stmts(otherwise, budget)
                }
                _ => false,
            }
        })
    }

    /// Lower `if (c) then else otherwise` (checked by [`Self::if_convertible`]) without
    /// branches: `then` from the entry values, `otherwise` from the entry values, then each
    /// assigned variable selects its `then` or `otherwise` value by `c`.
    fn if_converted(&mut self, c: ir::Value, then: &'a [Stmt], otherwise: &'a [Stmt]) -> Res<()> {
        let mut locals = vec![];
        dead::visit_assigned(then, &mut |l| locals.push(l));
        dead::visit_assigned(otherwise, &mut |l| locals.push(l));
        locals.sort_unstable_by_key(|l| l.0);
        locals.dedup();
        let mut vars = vec![];
        for l in locals {
            if let Some(Storage::Vars(vs)) = self.frame().storage.get(l.0 as usize) {
                vars.extend(vs.iter().copied());
            }
        }
        let entry: Vec<ir::Value> = vars.iter().map(|&v| self.b.use_var(v)).collect();
        self.stmts(then)?;
        let then_vals: Vec<ir::Value> = vars.iter().map(|&v| self.b.use_var(v)).collect();
        for (&v, &x) in vars.iter().zip(&entry) {
            self.b.def_var(v, x);
        }
        self.stmts(otherwise)?;
        for (k, &v) in vars.iter().enumerate() {
            let else_val = self.b.use_var(v);
            if then_vals[k] != else_val {
                let x = self.b.ins().select(c, then_vals[k], else_val);
                self.b.def_var(v, x);
            }
        }
        Ok(())
    }

    /// `if (c) return;` with a varying `c` in the primitive's own pixel code (a coverage or
    /// depth guard): the lanes executing it with `c` set retire, the others go on.
    ///
    /// Same masks as the general path (`then` with `exec = entry & c`, `lower_return`, the
    /// join's `exec = else_mask`), without its branch on "any lane takes `then`" and the
    /// mask copies around it: `alive &= !(entry & c)`, `exec = entry & !c`, and the group
    /// ends when no lane is left. While pixel code runs `alive` is never empty (the group
    /// ends when it becomes so), so when no lane takes the `then` the test cannot end the
    /// group early: both paths end in the same state.
    fn varying_guard_return(&mut self, entry: ir::Value, c: ir::Value) -> Res<()> {
        let Some(p) = &self.pix else {
            return err("varying condition outside per-pixel code");
        };
        let (alive_var, group_end) = (p.alive, p.group_end);
        let alive = self.b.use_var(alive_var);
        let stay = self.not_and(entry, c);
        // Every live lane executing (no varying control flow entered yet, as at a leading
        // guard): `alive & !(entry & c)` is `stay` itself.
        let alive = if alive == entry {
            stay
        } else {
            let leaving = self.b.ins().band(entry, c);
            self.b.ins().band_not(alive, leaving)
        };
        self.b.def_var(alive_var, alive);
        self.set_exec(stay);
        // Flat pixel code goes on with no lane left (see [`flat`]).
        if self.flat {
            return Ok(());
        }
        let any = self.b.ins().vany_true(alive);
        let all_gone = self.b.ins().icmp_imm_s(IntCC::Equal, any, 0);
        let cont = self.b.create_block();
        self.b.ins().brif(all_gone, group_end, &[], cont, &[]);
        self.b.switch_to_block(cont);
        // This branch is `cont`'s only predecessor. Sealed now, the next guard's reads of
        // `alive` and `exec` are this block's values themselves, equal, so it takes the
        // `stay` path above; unsealed, each read got a block parameter of its own (merged
        // only when the function is sealed) and every guard after the first recomputed
        // `alive & !(entry & c)`: five instructions instead of two per integer edge test.
        self.b.seal_block(cont);
        self.sealed_early.insert(cont);
        Ok(())
    }

    /// After `if (cond) return;` in pixel code (lowered, or dropped by a block variant that
    /// proved it fires for no lane): record what `cond` being false says about float
    /// locals for the rest of the statement list (see [`bounds::GuardFacts`]).
    pub(super) fn assume_guard(&mut self, cond: &Expr) {
        let frame = self.frames.len() - 1;
        self.guard_facts.assume(frame, cond, false);
    }

    /// `m & !c` for a lane mask `m` and a varying condition `c`. When `c` is a vector
    /// integer compare, the complementary compare instead (`a <u b` -> `a >=u b`): same
    /// lanes, and x86 has no unsigned less-than, so `!(a <u b)` was min + compare + not.
    fn not_and(&mut self, m: ir::Value, c: ir::Value) -> ir::Value {
        let dfg = &self.b.func.dfg;
        if let ir::ValueDef::Result(inst, 0) = dfg.value_def(c) {
            if let ir::InstructionData::IntCompare {
                opcode: ir::Opcode::Icmp,
                cond,
                args,
            } = dfg.insts[inst]
            {
                use cranelift_codegen::ir::condcodes::CondCode;
                let inv = self.b.ins().icmp(cond.complement(), args[0], args[1]);
                return self.b.ins().band(m, inv);
            }
        }
        self.b.ins().band_not(m, c)
    }

    /// Spend one unit of fuel; out of fuel records ERR_FUEL and jumps to `exit`.
    fn spend_fuel(&mut self, site: SiteId, exit: Block) {
        let fuel = self.b.use_var(self.fuel);
        let empty = self.b.ins().icmp_imm_s(IntCC::Equal, fuel, 0);
        let out_blk = self.b.create_block();
        let ok_blk = self.b.create_block();
        self.b.ins().brif(empty, out_blk, &[], ok_blk, &[]);
        self.seal_now(out_blk);
        self.seal_now(ok_blk);
        self.b.set_cold_block(out_blk);
        self.b.switch_to_block(out_blk);
        self.defer_error(ERR_FUEL, site, None);
        self.b.ins().jump(exit, &[]);
        self.b.switch_to_block(ok_blk);
        let less = self.b.ins().iadd_imm_s(fuel, -1);
        self.b.def_var(self.fuel, less);
    }

    fn uniform_loop(
        &mut self,
        id: LoopId,
        cond: Option<&'a Expr>,
        body: &'a [Stmt],
        step: &'a [Stmt],
        site: SiteId,
    ) -> Res<()> {
        let header = self.b.create_block();
        let body_blk = self.b.create_block();
        let step_blk = self.b.create_block();
        let exit = self.b.create_block();
        if self.in_dead_block() {
            // Dead code: so is the whole loop (its jumps stay among dead blocks).
            self.dead_blocks.extend([header, body_blk, step_blk, exit]);
        }
        self.b.ins().jump(header, &[]);
        self.b.switch_to_block(header);
        self.spend_fuel(site, exit);
        if let Some(c) = cond {
            let v = self.eval_uniform(c)?;
            let v = fixed::convert(&mut self.b, v.scalar, Scalar::Bool, v.comps[0]);
            let done = self.b.ins().icmp_imm_s(IntCC::Equal, v, 0);
            self.b.ins().brif(done, exit, &[], body_blk, &[]);
        } else {
            self.b.ins().jump(body_blk, &[]);
        }
        self.seal_now(body_blk);
        self.b.switch_to_block(body_blk);
        self.frame_mut().loops.push(LoopCtx {
            id: Some(id),
            varying: false,
            step: step_blk,
            exit,
            mask: None,
            cont: None,
        });
        let r = self.stmts(body);
        self.frame_mut().loops.pop();
        r?;
        // A body that always leaves by `break` or `return` (and never `continue`s) leaves
        // the step dead.
        if !self.jump_live(step_blk) && !self.live_targets.contains(&step_blk) {
            self.dead_blocks.insert(step_blk);
        }
        // The body's `continue`s are lowered: the step's predecessors are all known; after
        // the back edge, the header's; after the step (its `break`s, if any), the exit's.
        self.seal_now(step_blk);
        self.b.switch_to_block(step_blk);
        self.stmts(step)?;
        self.jump_live(header);
        self.seal_now(header);
        self.seal_now(exit);
        self.b.switch_to_block(exit);
        Ok(())
    }

    /// Seal `block` now: every jump to it has been emitted. Uniform code seals its blocks
    /// as soon as their predecessors are known (an `if`'s sides and join, a uniform loop's
    /// blocks, the fuel check's): a variable read in a sealed block is looked up through
    /// its predecessors at once, where an unsealed block got a speculative block parameter
    /// per variable read in it, each resolved (mostly into an alias) only when the function
    /// was sealed whole. In the NURB kernel's setup those were ~2700 block parameters,
    /// ~5800 jump arguments and ~6400 aliases, and a quarter of the frontend's time.
    fn seal_now(&mut self, block: Block) {
        if self.sealed_early.insert(block) {
            self.b.seal_block(block);
        }
    }

    fn varying_loop(
        &mut self,
        id: LoopId,
        cond: Option<&'a Expr>,
        body: &'a [Stmt],
        step: &'a [Stmt],
        site: SiteId,
    ) -> Res<()> {
        let entry = self.exec().expect("pixel context");
        let alive_var = self.pix.as_ref().expect("pixel context").alive;
        let mask = self.declare_var(I32X4);
        let cont = self.declare_var(I32X4);
        self.b.def_var(mask, entry);
        let none_mask = mask_const(&mut self.b, false);
        self.b.def_var(cont, none_mask);
        let header = self.b.create_block();
        let fuel_blk = self.b.create_block();
        let body_blk = self.b.create_block();
        let step_blk = self.b.create_block();
        let exit = self.b.create_block();
        self.b.ins().jump(header, &[]);

        self.b.switch_to_block(header);
        let lm = self.b.use_var(mask);
        let alive = self.b.use_var(alive_var);
        let lm = self.b.ins().band(lm, alive);
        self.b.def_var(mask, lm);
        let any = self.b.ins().vany_true(lm);
        let none = self.b.ins().icmp_imm_s(IntCC::Equal, any, 0);
        self.b.ins().brif(none, exit, &[], fuel_blk, &[]);

        self.b.switch_to_block(fuel_blk);
        self.spend_fuel(site, exit);
        let none_mask = mask_const(&mut self.b, false);
        self.b.def_var(cont, none_mask);
        self.set_exec(lm);
        self.depth_add(1);
        if let Some(c) = cond {
            let v = self.eval(c)?;
            let v = fixed::convert(&mut self.b, v.scalar, Scalar::Bool, v.comps[0]);
            let cm = splat(&mut self.b, Scalar::Bool, v);
            let lm2 = self.b.ins().band(lm, cm);
            self.b.def_var(mask, lm2);
            self.set_exec(lm2);
            let any = self.b.ins().vany_true(lm2);
            let none = self.b.ins().icmp_imm_s(IntCC::Equal, any, 0);
            self.b.ins().brif(none, exit, &[], body_blk, &[]);
        } else {
            self.b.ins().jump(body_blk, &[]);
        }
        self.b.switch_to_block(body_blk);
        self.frame_mut().loops.push(LoopCtx {
            id: Some(id),
            varying: true,
            step: step_blk,
            exit,
            mask: Some(mask),
            cont: Some(cont),
        });
        self.vloops.push((mask, cont));
        let r = self.stmts(body);
        self.b.ins().jump(step_blk, &[]);
        self.b.switch_to_block(step_blk);
        // Continued lanes come back for the step; broken and retired ones do not.
        let lm = self.b.use_var(mask);
        let alive = self.b.use_var(alive_var);
        let ex = self.b.ins().band(lm, alive);
        self.set_exec(ex);
        let none_mask = mask_const(&mut self.b, false);
        self.b.def_var(cont, none_mask);
        let r2 = r.and_then(|_| self.stmts(step));
        self.vloops.pop();
        self.frame_mut().loops.pop();
        self.depth_add(-1);
        r2?;
        self.b.ins().jump(header, &[]);
        self.b.switch_to_block(exit);
        self.restore_exec(entry);
        Ok(())
    }

    fn break_continue(&mut self, id: LoopId, is_break: bool) -> Res<()> {
        let frame = self.frame();
        let Some(pos) = frame.loops.iter().rposition(|l| l.id == Some(id)) else {
            return err(format!("break/continue of loop {} outside it", id.0));
        };
        let target = &frame.loops[pos];
        let inner: Vec<(Option<Variable>, Option<Variable>)> =
            frame.loops[pos..].iter().map(|l| (l.mask, l.cont)).collect();
        if !target.varying {
            let dest = if is_break { target.exit } else { target.step };
            self.jump_live(dest);
            self.continue_unreachable();
            return Ok(());
        }
        let exec = self.exec().expect("varying loop in pixel context");
        for (k, (mask, cont)) in inner.into_iter().enumerate() {
            let outermost = k == 0;
            if outermost && !is_break {
                if let Some(c) = cont {
                    let old = self.b.use_var(c);
                    let new = self.b.ins().bor(old, exec);
                    self.b.def_var(c, new);
                }
            } else if let Some(m) = mask {
                let old = self.b.use_var(m);
                let new = self.b.ins().band_not(old, exec);
                self.b.def_var(m, new);
            }
        }
        let none = mask_const(&mut self.b, false);
        self.set_exec(none);
        Ok(())
    }

    /// Ends the inlined interpolator for the executing lanes (its `return`).
    fn leave_interpolator(&mut self) -> Res<()> {
        let exec = self.exec().expect("interpolators run in pixel context");
        let masks: Vec<Option<Variable>> = self.frame().loops.iter().map(|l| l.mask).collect();
        for m in masks.into_iter().flatten() {
            let old = self.b.use_var(m);
            let new = self.b.ins().band_not(old, exec);
            self.b.def_var(m, new);
        }
        let none = mask_const(&mut self.b, false);
        self.set_exec(none);
        Ok(())
    }

    fn lower_return(&mut self) -> Res<()> {
        if self.frame().interp_binding.is_some() {
            return self.leave_interpolator();
        }
        let Some(p) = &self.pix else {
            // Setup: the primitive ends.
            self.jump_live(self.exit);
            self.continue_unreachable();
            return Ok(());
        };
        let (alive_var, group_end, depth) = (p.alive, p.group_end, p.varying_depth);
        if depth == 0 {
            // Uniform control flow: every lane of the group retires.
            self.b.ins().jump(group_end, &[]);
            self.continue_unreachable();
            return Ok(());
        }
        let exec = self.exec().expect("pixel context");
        let alive = self.b.use_var(alive_var);
        let alive = self.b.ins().band_not(alive, exec);
        self.b.def_var(alive_var, alive);
        let none = mask_const(&mut self.b, false);
        self.set_exec(none);
        // Flat pixel code goes on with no lane left (see [`flat`]).
        if self.flat {
            return Ok(());
        }
        let any = self.b.ins().vany_true(alive);
        let all_gone = self.b.ins().icmp_imm_s(IntCC::Equal, any, 0);
        let cont = self.b.create_block();
        self.b.ins().brif(all_gone, group_end, &[], cont, &[]);
        self.b.switch_to_block(cont);
        Ok(())
    }

    // ---------------------------------------------------------------- interpolation

    fn kind_offsets(&self) -> Vec<(usize, u32, u32)> {
        // (binding index, first interp component, first global component)
        let mut out = vec![];
        let (mut ic, mut gc) = (0, 0);
        for (i, b) in self.key.bindings.iter().enumerate() {
            if matches!(b.kind, BindingKind::Kind(_)) {
                out.push((i, ic, gc));
                ic += b.components;
            }
            gc += b.components;
        }
        out
    }

    fn global_offset(&self, binding: usize) -> u32 {
        self.key.bindings[..binding].iter().map(|b| b.components).sum()
    }

    fn interpolation(&mut self, arms: &'a [crate::ir::InterpArm]) -> Res<()> {
        // In setup code the construct only computes (figure 8: interpolation data of new
        // vertices); `interpolator_return` there is refused by `interpolator_return` itself.
        let named: Vec<&str> = arms
            .iter()
            .filter_map(|a| match &a.kind {
                ArmKind::Named(k) => Some(k.as_str()),
                ArmKind::Default => None,
            })
            .collect();
        for arm in arms {
            let Some((view, bindings)) = self.arm_view(arms, &named, arm) else {
                continue;
            };
            let saved_view = std::mem::replace(&mut self.view, view);
            let saved_arm = self.arm.replace(ArmInfo { bindings });
            let r = self.stmts(&arm.body);
            self.view = saved_view;
            self.arm = saved_arm;
            r?;
        }
        Ok(())
    }

    /// The interpolation-data view and the bindings of `arm` under this key, or `None` if
    /// the key gives the arm nothing to do (it is not lowered). `named`: the arms' kinds.
    fn arm_view(
        &self,
        _arms: &[crate::ir::InterpArm],
        named: &[&str],
        arm: &crate::ir::InterpArm,
    ) -> Option<(Vec<u32>, Vec<usize>)> {
        let has_other = self
            .key
            .bindings
            .iter()
            .any(|b| matches!(b.kind, BindingKind::Shared(_) | BindingKind::Constant));
        let mut view = vec![];
        let mut bindings = vec![];
        let mut ic = 0;
        for (i, b) in self.key.bindings.iter().enumerate() {
            if let BindingKind::Kind(k) = &b.kind {
                let serves = match &arm.kind {
                    ArmKind::Named(n) => n == k,
                    ArmKind::Default => !named.contains(&k.as_str()),
                };
                if serves {
                    view.extend(ic..ic + b.components);
                    bindings.push(i);
                }
                ic += b.components;
            }
        }
        let needed = !view.is_empty() || (arm.kind == ArmKind::Default && has_other);
        needed.then_some((view, bindings))
    }

    /// Every local read or assigned by `stmts` as this key lowers them (arms the key gives
    /// nothing to do are skipped, like [`Self::interpolation`] skips them).
    fn live_pixel_locals(&self, stmts: &[Stmt], out: &mut std::collections::HashSet<LocalId>) {
        self.visit_live_pixel_locals(stmts, &mut |l| {
            out.insert(l);
        });
    }

    /// [`Self::live_pixel_locals`] as a flag per local (tier 0's analyses: a HashSet cost
    /// more than the walk itself).
    fn live_pixel_flags(&self, stmts: &[Stmt], out: &mut [bool]) {
        self.visit_live_pixel_locals(stmts, &mut |l| mark_local(out, l));
    }

    fn visit_live_pixel_locals(&self, stmts: &[Stmt], out: &mut dyn FnMut(LocalId)) {
        for s in stmts {
            match &s.kind {
                StmtKind::Assign { place, value } => {
                    out(place.local);
                    place.indices.iter().for_each(|(i, _)| i.for_each_local(out));
                    value.for_each_local(out);
                }
                StmtKind::If { cond, then, otherwise } => {
                    cond.for_each_local(out);
                    self.visit_live_pixel_locals(then, out);
                    self.visit_live_pixel_locals(otherwise, out);
                }
                StmtKind::Loop { cond, body, step, .. } => {
                    if let Some(c) = cond {
                        c.for_each_local(out);
                    }
                    self.visit_live_pixel_locals(body, out);
                    self.visit_live_pixel_locals(step, out);
                }
                StmtKind::Interpolation { arms } => {
                    let named: Vec<&str> = arms
                        .iter()
                        .filter_map(|a| match &a.kind {
                            ArmKind::Named(k) => Some(k.as_str()),
                            ArmKind::Default => None,
                        })
                        .collect();
                    for arm in arms {
                        if self.arm_view(arms, &named, arm).is_some() {
                            self.visit_live_pixel_locals(&arm.body, out);
                        }
                    }
                }
                StmtKind::InterpolatorReturn(Some(e)) => e.for_each_local(out),
                StmtKind::Bound(es) => es.iter().for_each(|e| e.for_each_local(out)),
                StmtKind::CallPrimitive { args, .. } => args.iter().for_each(|e| e.for_each_local(out)),
                StmtKind::Break(_) | StmtKind::Continue(_) | StmtKind::Return | StmtKind::InterpolatorReturn(None) => {}
            }
        }
    }

    /// Store a varying f32x4 into G-buffer component `g` (global binding component index)
    /// for the executing lanes; planes at or past `ctx.num_planes` are not written.
    fn store_plane(&mut self, g: u32, v: ir::Value) {
        self.store_planes(&[(g, v)]);
    }

    /// Store several components for the executing lanes, with one test for the common case:
    /// when every lane executes and every plane of the key exists (`plane_table`), each
    /// store is a plain vector store. Otherwise each is load + blend + store to its plane's
    /// address, or to a scratch slot for a plane the frame does not have (branch-free, so
    /// values shared by several stores, like a perspective divisor, are computed once).
    /// Same memory contents either way: a full mask blends nothing from the old value.
    fn store_planes(&mut self, stores: &[(u32, ir::Value)]) {
        let Some(table) = self.plane_ptrs else {
            return;
        };
        if stores.is_empty() {
            return;
        }
        let p = self.pix.as_ref().expect("plane stores run in pixel context");
        let tile_idx = p.tile_idx;
        let exec = self.exec().expect("pixel context");
        let bytes = self.b.ins().ishl_imm_u(tile_idx, 2);
        let slot_addr = self.slot_addr(table);
        // Tier 0: only the masked store (the all-lanes fast path is a second copy of every
        // store, which pays only in the long runs of full groups tier 1 serves).
        if self.tier0() {
            self.blended_plane_stores(stores, slot_addr, bytes, exec, false);
            return;
        }
        // One lane bit each (`vmovmskps`), masked by the table's all-planes word (0b1111
        // or 0): full iff the result is 0b1111. Three instructions fewer per group than
        // `vall_true` (a compare with zero, a test and a setcc) and a band with the flag.
        let lane_bits = self.b.ins().vhigh_bits(types::I32, exec);
        let n = self.key.total_components();
        let all_planes = self.b.ins().load(types::I32, mem_flags(), slot_addr, (8 * n) as i32);
        let both = self.b.ins().band(lane_bits, all_planes);
        let full = self.b.ins().icmp_imm_s(IntCC::Equal, both, ALL_LANE_BITS);
        let full_blk = self.b.create_block();
        let part_blk = self.b.create_block();
        let join = self.b.create_block();
        self.b.ins().brif(full, full_blk, &[], part_blk, &[]);

        self.b.switch_to_block(full_blk);
        for &(g, v) in stores {
            let base = self.b.ins().load(types::I64, mem_flags(), slot_addr, (8 * g) as i32);
            let addr = self.b.ins().iadd(base, bytes);
            self.b.ins().store(mem_flags(), v, addr, 0);
        }
        self.b.ins().jump(join, &[]);

        // Some lanes off: with every plane present (the table word is nonzero), the
        // blended stores need no scratch redirection (three instructions fewer per plane).
        self.b.switch_to_block(part_blk);
        let present_blk = self.b.create_block();
        let missing_blk = self.b.create_block();
        self.b.ins().brif(all_planes, present_blk, &[], missing_blk, &[]);
        self.b.switch_to_block(present_blk);
        self.blended_plane_stores(stores, slot_addr, bytes, exec, true);
        self.b.ins().jump(join, &[]);
        self.b.switch_to_block(missing_blk);
        self.blended_plane_stores(stores, slot_addr, bytes, exec, false);
        self.b.ins().jump(join, &[]);
        self.b.switch_to_block(join);
    }

    /// Load + blend + store of each `(plane-table index, value)` under the `exec` mask.
    /// Unless `all_present` (every table entry known non-null), a plane the frame lacks
    /// (null table entry) goes to the scratch slot, branch-free.
    fn blended_plane_stores(
        &mut self,
        stores: &[(u32, ir::Value)],
        slot_addr: ir::Value,
        bytes: ir::Value,
        exec: ir::Value,
        all_present: bool,
    ) {
        for &(g, v) in stores {
            let base = self.b.ins().load(types::I64, mem_flags(), slot_addr, (8 * g) as i32);
            let real = self.b.ins().iadd(base, bytes);
            let addr = if all_present {
                real
            } else {
                let dummy = self.slot_addr(self.scratch);
                self.b.ins().select(base, real, dummy)
            };
            let old = self.b.ins().load(F32X4, mem_flags(), addr, 0);
            let new = blend(&mut self.b, exec, v, old);
            self.b.ins().store(mem_flags(), new, addr, 0);
        }
    }

    /// Once per kernel run, before the pixel loops: the base address of every binding
    /// component's G-buffer plane (null when its plane index is not below
    /// `ctx.num_planes`), so a store costs a load and an add instead of recomputing it.
    /// After the `n` addresses, one i32: [`ALL_LANE_BITS`] when every plane exists, else 0
    /// (the stores' fast path masks the lane bits with it).
    fn plane_table(&mut self) {
        let n = self.key.total_components();
        if n == 0 {
            return;
        }
        let slot = self
            .b
            .create_sized_stack_slot(StackSlotData::new(StackSlotKind::ExplicitSlot, 8 * n + 8, 3));
        let num = self.load_ctx(types::I32, ctx_off::NUM_PLANES);
        let mut all_valid = self.iconst_here(types::I8, 1);
        let pstride = self.load_ctx(types::I32, ctx_off::PLANE_STRIDE);
        let ps64 = self.b.ins().uextend(types::I64, pstride);
        let gbuf = self.load_ctx(types::I64, ctx_off::GBUF);
        let null = self.iconst_here(types::I64, 0);
        let addr = self.slot_addr(slot);
        for g in 0..n {
            let plane = self.b.ins().load(
                types::I32,
                args_flags(),
                self.args,
                ((self.layout.plane_table + g) * 4) as i32,
            );
            let valid = self.b.ins().icmp(IntCC::UnsignedLessThan, plane, num);
            let plane64 = self.b.ins().uextend(types::I64, plane);
            let start = self.b.ins().imul(plane64, ps64);
            let bytes = self.b.ins().ishl_imm_u(start, 2);
            let base = self.b.ins().iadd(gbuf, bytes);
            let base = self.b.ins().select(valid, base, null);
            self.b.ins().store(mem_flags(), base, addr, (8 * g) as i32);
            all_valid = self.b.ins().band(all_valid, valid);
        }
        let all_bits = self.iconst_here(types::I32, ALL_LANE_BITS);
        let none_bits = self.iconst_here(types::I32, 0);
        let word = self.b.ins().select(all_valid, all_bits, none_bits);
        self.b.ins().store(mem_flags(), word, addr, (8 * n) as i32);
        self.plane_ptrs = Some(slot);
    }

    fn interpolator_return(&mut self, e: Option<&'a Expr>) -> Res<()> {
        if !self.in_pixel() {
            return err("`interpolator_return` outside per-pixel code");
        }
        if let Some(bi) = self.frame().interp_binding {
            // Inside an inlined shared interpolator: its result, then it ends for these lanes.
            if let Some(e) = e {
                let v = self.eval(e)?;
                let v = self.float_varying(v);
                let comps = self.key.bindings[bi].components;
                let g0 = self.global_offset(bi);
                if v.comps.len() == 1 || v.comps.len() == comps as usize {
                    let batch: Vec<(u32, ir::Value)> = (0..comps)
                        .map(|c| {
                            let x = if v.comps.len() == 1 {
                                v.comps[0]
                            } else {
                                v.comps[c as usize]
                            };
                            (g0 + c, x)
                        })
                        .collect();
                    self.store_planes(&batch);
                } else {
                    self.warnings.push(format!(
                        "interpolator `{}` returns {} components for a parameter of {}; not stored",
                        self.frame().func.name,
                        v.comps.len(),
                        comps
                    ));
                }
            }
            return self.leave_interpolator();
        }
        match e {
            Some(e) => self.store_kind_bindings(e),
            None => self.run_shared_and_constants(),
        }
    }

    fn float_varying(&mut self, v: Val) -> Val {
        let comps = v
            .comps
            .iter()
            .map(|&c| fixed::convert(&mut self.b, v.scalar, Scalar::Float, c))
            .collect();
        self.make_varying(Val {
            comps,
            scalar: Scalar::Float,
            varying: v.varying,
        })
    }

    fn store_kind_bindings(&mut self, e: &'a Expr) -> Res<()> {
        let is_interp = e.ty.elem == Elem::Interp && e.ty.dims.is_empty();
        let v = self.eval(e)?;
        let v = self.float_varying(v);
        let bindings: Vec<usize> = match &self.arm {
            Some(a) => a.bindings.clone(),
            None => self.kind_offsets().iter().map(|k| k.0).collect(),
        };
        let offsets = self.kind_offsets();
        let fname = self.frame().func.name.clone();
        // Every binding's components, stored together under one full-mask test.
        let mut batch = vec![];
        for bi in bindings {
            let Some(&(_, ic, gc)) = offsets.iter().find(|o| o.0 == bi) else {
                continue;
            };
            let comps = self.key.bindings[bi].components;
            let mut vals = vec![];
            for c in 0..comps {
                let x = if is_interp {
                    self.view
                        .iter()
                        .position(|&k| k == ic + c)
                        .and_then(|p| v.comps.get(p).copied())
                } else if v.comps.len() == 1 && e.ty.dims.is_empty() {
                    Some(v.comps[0])
                } else if v.comps.len() == comps as usize && e.ty.elem != Elem::Interp {
                    Some(v.comps[c as usize])
                } else {
                    None
                };
                vals.push(x);
            }
            if vals.iter().any(|x| x.is_none()) {
                self.warnings.push(format!(
                    "`{fname}`: interpolator_return value has {} components, shading parameter {bi} has {comps}; not stored",
                    v.comps.len()
                ));
                continue;
            }
            for (c, x) in vals.into_iter().enumerate() {
                batch.push((gc + c as u32, x.expect("checked above")));
            }
            self.written[bi] = true;
        }
        self.store_planes(&batch);
        Ok(())
    }

    fn run_shared_and_constants(&mut self) -> Res<()> {
        for (bi, b) in self.key.bindings.iter().enumerate() {
            match &b.kind {
                BindingKind::Kind(_) => {}
                BindingKind::Constant => {
                    let Some(Some(data)) = self.layout.binding_data.get(bi) else {
                        continue;
                    };
                    let g0 = self.global_offset(bi);
                    for c in 0..b.components {
                        let w = self
                            .b
                            .ins()
                            .load(types::F32, args_flags(), self.args, ((data + c) * 4) as i32);
                        let v = self.b.ins().splat(F32X4, w);
                        self.store_plane(g0 + c, v);
                    }
                }
                BindingKind::Shared(name) => self.inline_interpolator(bi, name)?,
            }
        }
        Ok(())
    }

    fn inline_interpolator(&mut self, bi: usize, name: &str) -> Res<()> {
        let Some(id) = self.program.find(name) else {
            self.warnings.push(format!(
                "shared interpolator `{name}` (shading parameter {bi}) does not exist; not written"
            ));
            return Ok(());
        };
        let f = self.program.func(id);
        if f.kind != FuncKind::Interpolator {
            self.warnings.push(format!(
                "`{name}` (shading parameter {bi}) is a primitive, not a shared interpolator"
            ));
            return Ok(());
        }
        if self.frames.iter().any(|fr| std::ptr::eq(fr.func, f)) {
            return err(format!("shared interpolator `{name}` is inlined into itself"));
        }
        let Some(Some(data)) = self.layout.binding_data.get(bi).copied() else {
            return err(format!("no argument words for shared interpolator `{name}`"));
        };
        let _ = interpolator_arg_words(self.program, id);
        let mut at = data;
        let mut slots = vec![];
        for p in &f.params {
            match p.role {
                ParamRole::X | ParamRole::Y | ParamRole::Z => slots.push(ParamSlot::Pixel),
                _ => {
                    let words = type_words(&f.local(p.local).ty, 0);
                    slots.push(ParamSlot::Fixed { offset: at, words });
                    at += words;
                }
            }
        }
        let frame = self.make_frame(f, slots, at, Some(bi))?;
        // X, Y, Z of the interpolator: this pixel's, in the interpolator's declared types.
        let (x_f, y_f, z_raw) = {
            let p = self.pix.as_ref().expect("pixel context");
            (p.x_f, p.y_f, p.z_raw)
        };
        let prim = self.frames[0].func;
        let prim_z =
            prim.params
                .iter()
                .position(|p| p.role == ParamRole::Z)
                .and_then(|i| match &self.frames[0].storage[i] {
                    Storage::Z(v) => Some((*v, elem_scalar(&prim.local(prim.params[i].local).ty))),
                    _ => None,
                });
        for (i, p) in f.params.iter().enumerate() {
            let sc = elem_scalar(&f.local(p.local).ty);
            let (src, from) = match p.role {
                ParamRole::X => (x_f, Scalar::Float),
                ParamRole::Y => (y_f, Scalar::Float),
                ParamRole::Z => match (prim_z, z_raw) {
                    (Some((var, zsc)), _) => (self.b.use_var(var), zsc),
                    (None, Some(z)) => (z, Scalar::Fixed(DEPTH_FORMAT)),
                    (None, None) => (zero(&mut self.b, Scalar::Float, true), Scalar::Float),
                },
                _ => continue,
            };
            let v = fixed::convert(&mut self.b, from, sc, src);
            if let Storage::Vars(vs) = &frame.storage[i] {
                self.b.def_var(vs[0], v);
            }
        }
        // The body is a one-trip masked loop: `return` and `interpolator_return(e)` leave it.
        let entry = self.exec().expect("pixel context");
        let mask = self.declare_var(I32X4);
        let cont = self.declare_var(I32X4);
        self.b.def_var(mask, entry);
        let none = mask_const(&mut self.b, false);
        self.b.def_var(cont, none);
        let end = self.b.create_block();
        let mut frame = frame;
        frame.loops.push(LoopCtx {
            id: None,
            varying: true,
            step: end,
            exit: end,
            mask: Some(mask),
            cont: Some(cont),
        });
        // The callee's locals are other variables than any earlier frame at this depth.
        self.guard_facts.kill_frames_from(self.frames.len());
        self.frames.push(frame);
        self.vloops.push((mask, cont));
        self.depth_add(1);
        let saved_view = std::mem::replace(&mut self.view, (0..self.n_interp).collect());
        let r = self.stmts(&f.setup).and_then(|_| self.stmts(&f.pixel));
        self.view = saved_view;
        self.depth_add(-1);
        self.vloops.pop();
        self.frames.pop();
        self.guard_facts.kill_frames_from(self.frames.len());
        r?;
        self.b.ins().jump(end, &[]);
        self.b.switch_to_block(end);
        self.restore_exec(entry);
        Ok(())
    }

    // ---------------------------------------------------------------- primitive calls

    fn call_primitive(&mut self, callee: FuncId, args: &'a [Expr]) -> Res<()> {
        let Some(cf) = self.program.functions.get(callee.0 as usize) else {
            return err(format!("call of unknown function {}", callee.0));
        };
        if cf.kind != FuncKind::Primitive {
            return err(format!("`{}` is not a primitive", cf.name));
        }
        if args.len() != cf.params.len() {
            return err(format!(
                "call of `{}` with {} arguments for {} parameters",
                cf.name,
                args.len(),
                cf.params.len()
            ));
        }
        let layout = ArgLayout::new(self.program, callee, self.key);
        // Sequence points: the length of the first per-sequence-point argument.
        let mut n_seq = 1u32;
        for (i, slot) in layout.params.iter().enumerate() {
            if let ParamSlot::Seq { .. } = slot {
                let a = &args[i];
                if a.ty.per_seq || a.ty.dims.is_empty() {
                    return err(format!(
                        "argument {} of the call to `{}`: a per-sequence-point parameter needs a fixed-size array argument",
                        i, cf.name
                    ));
                }
                n_seq = a.ty.dims[0];
                break;
            }
        }
        let words = layout.words(n_seq);
        let bytes = u32::try_from(words * 4).map_err(|_| JitError {
            message: "primitive call argument block too large".into(),
        })?;
        let slot = self
            .b
            .create_sized_stack_slot(StackSlotData::new(StackSlotKind::ExplicitSlot, bytes.max(4), 4));
        let base = self.slot_addr(slot);
        let store_word = |l: &mut Self, v: ir::Value, word: u32| {
            l.b.ins().store(mem_flags(), v, base, (word * 4) as i32);
        };
        let nv = self.iconst_here(types::I32, n_seq as i64);
        store_word(self, nv, 0);
        // Plane table and binding data: same key, so the same prefix as ours.
        let prefix_end = 1
            + self.key.total_components()
            + self
                .key
                .bindings
                .iter()
                .map(|b| match &b.kind {
                    BindingKind::Kind(_) => 0,
                    BindingKind::Constant => b.components,
                    BindingKind::Shared(n) => self
                        .program
                        .find(n)
                        .map(|id| interpolator_arg_words(self.program, id))
                        .unwrap_or(0),
                })
                .sum::<u32>();
        for w in 1..prefix_end {
            let v = self.b.ins().load(types::I32, args_flags(), self.args, (w * 4) as i32);
            store_word(self, v, w);
        }
        if let Some(dst) = layout.spaces {
            match self.layout.spaces {
                Some(src) => {
                    for w in 0..96 {
                        let v = self
                            .b
                            .ins()
                            .load(types::I32, args_flags(), self.args, ((src + w) * 4) as i32);
                        store_word(self, v, dst + w);
                    }
                }
                None => {
                    for m in 0..6 {
                        for k in 0..16 {
                            let one = if k % 5 == 0 { 1.0 } else { 0.0 };
                            let v = self.f32const_here(one);
                            store_word(self, v, dst + m * 16 + k);
                        }
                    }
                }
            }
        }
        for (i, pslot) in layout.params.iter().enumerate() {
            let (start, words, elems) = match pslot {
                ParamSlot::Pixel => continue,
                ParamSlot::Fixed { offset, words } => (*offset, *words, 1),
                ParamSlot::Seq { seq_offset, words } => (layout.fixed_words + n_seq * seq_offset, *words, n_seq),
            };
            let total = words * elems;
            let v = self.eval_uniform(&args[i])?;
            for w in 0..total {
                let comp = match v.comps.get(w as usize) {
                    Some(&c) => word_of(&mut self.b, v.scalar, c),
                    None => self.iconst_here(types::I32, 0),
                };
                store_word(self, comp, start + w);
            }
        }
        // The callee (or the expand recorder) runs with `ctx`: the index errors before the
        // call come first.
        if self.deferring_errors {
            self.flush_errors();
        }
        // Call depth guard.
        let depth = self.load_ctx(types::I32, ctx_off::CALL_DEPTH);
        let deeper = self.b.ins().iadd_imm_s(depth, 1);
        self.store_ctx(deeper, ctx_off::CALL_DEPTH);
        let too_deep = self
            .b
            .ins()
            .icmp_imm_s(IntCC::UnsignedGreaterThan, deeper, MAX_CALL_DEPTH as i64);
        let deep_blk = self.b.create_block();
        let call_blk = self.b.create_block();
        let after = self.b.create_block();
        self.b.ins().brif(too_deep, deep_blk, &[], call_blk, &[]);
        self.b.switch_to_block(deep_blk);
        self.record_error(ERR_CALL_DEPTH, u32::MAX, None);
        self.b.ins().jump(after, &[]);
        self.b.switch_to_block(call_blk);
        let fref = self.linker.kernel_ref(self.b.func, callee)?;
        // In MODE_EXPAND the call is recorded, not made (`abi::ExpandFn`): the runtime
        // renders it later as an instance of its own.
        let mode = self.load_ctx(types::I32, ctx_off::MODE);
        let expanding = self.b.ins().icmp_imm_s(IntCC::Equal, mode, MODE_EXPAND as i64);
        let record_blk = self.b.create_block();
        let run_blk = self.b.create_block();
        self.b.ins().brif(expanding, record_blk, &[], run_blk, &[]);
        self.b.switch_to_block(record_blk);
        self.record_call(callee, fref, base, words)?;
        self.b.ins().jump(after, &[]);
        self.b.switch_to_block(run_blk);
        // The callee spends the same fuel: hand it over in `ctx.fuel` and take back the rest.
        let fuel = self.b.use_var(self.fuel);
        self.store_ctx(fuel, ctx_off::FUEL);
        self.b.ins().call(fref, &[self.ctx, base]);
        let fuel = self.load_ctx(types::I64, ctx_off::FUEL);
        self.b.def_var(self.fuel, fuel);
        self.b.ins().jump(after, &[]);
        self.b.switch_to_block(after);
        let d = self.load_ctx(types::I32, ctx_off::CALL_DEPTH);
        let d = self.b.ins().iadd_imm_s(d, -1);
        self.store_ctx(d, ctx_off::CALL_DEPTH);
        Ok(())
    }

    /// Hand the call (callee id, its kernel's address, the argument block, its length) to
    /// `ctx.expand`; nothing when that is null.
    fn record_call(&mut self, callee: FuncId, fref: ir::FuncRef, base: ir::Value, words: usize) -> Res<()> {
        let words = u32::try_from(words).map_err(|_| JitError {
            message: "primitive call argument block too large".into(),
        })?;
        let recorder = self.load_ctx(types::I64, ctx_off::EXPAND);
        let have = self.b.ins().icmp_imm_s(IntCC::NotEqual, recorder, 0);
        let call_blk = self.b.create_block();
        let done = self.b.create_block();
        self.b.ins().brif(have, call_blk, &[], done, &[]);
        self.b.switch_to_block(call_blk);
        let mut sig = ir::Signature::new(self.b.func.signature.call_conv);
        sig.params.push(ir::AbiParam::new(types::I64)); // ctx
        sig.params.push(ir::AbiParam::new(types::I32)); // callee FuncId
        sig.params.push(ir::AbiParam::new(types::I64)); // callee kernel entry
        sig.params.push(ir::AbiParam::new(types::I64)); // argument block
        sig.params.push(ir::AbiParam::new(types::I32)); // its words
        let sig = self.b.import_signature(sig);
        let entry = self.b.ins().func_addr(types::I64, fref);
        let id = self.iconst_here(types::I32, i64::from(callee.0));
        let n = self.iconst_here(types::I32, i64::from(words));
        self.b
            .ins()
            .call_indirect(sig, recorder, &[self.ctx, id, entry, base, n]);
        self.b.ins().jump(done, &[]);
        self.b.switch_to_block(done);
        Ok(())
    }

    // ---------------------------------------------------------------- places and accesses

    fn local_access(&self, local: LocalId) -> Res<Access<'a>> {
        let f = self.frame().func;
        let Some(l) = f.locals.get(local.0 as usize) else {
            return err(format!("unknown local {}", local.0));
        };
        Ok(Access {
            root: Root::Local {
                frame: self.frames.len() - 1,
                local,
            },
            ty: AccessTy::of(&l.ty),
            scalar: elem_scalar(&l.ty),
            base: 0,
            dyn_off: Dyn::None,
            compact: false,
        })
    }

    /// Components in storage of one value of `fixed_len` elements of `elem` (`compact`:
    /// Interp holds only the view).
    fn value_comps(&self, elem: Elem, fixed_len: u32, compact: bool) -> u32 {
        match elem {
            Elem::Scalar(_) => fixed_len,
            Elem::Interp => fixed_len * if compact { self.view.len() as u32 } else { self.n_interp },
        }
    }

    /// Offsets of the components a value of `fixed_len` elements of `elem` shows (Interp:
    /// only the view's). The list comes from `offs_spare` when it has one: give it back when done
    /// ([`Self::give_back_offsets`]), so an access allocates no list.
    fn comp_offsets(&mut self, elem: Elem, fixed_len: u32, compact: bool) -> Vec<u32> {
        let mut out = self.offs_spare.pop().unwrap_or_default();
        out.clear();
        match elem {
            Elem::Scalar(_) => out.extend(0..fixed_len),
            Elem::Interp => {
                let per = if compact { self.view.len() as u32 } else { self.n_interp };
                for e in 0..fixed_len {
                    for (j, &v) in self.view.iter().enumerate() {
                        out.push(e * per + if compact { j as u32 } else { v });
                    }
                }
            }
        }
        out
    }

    fn give_back_offsets(&mut self, offs: Vec<u32>) {
        if self.offs_spare.len() < 4 {
            self.offs_spare.push(offs);
        }
    }

    fn seq_len(&mut self) -> ir::Value {
        // Tier 0: once per block (the NURB setup read it ~40 times, a load and a umax each).
        self.once_per_block(VnKey::SeqLen, |l| {
            let n = l.b.ins().load(types::I32, args_flags(), l.args, 0);
            let one = l.b.ins().iconst(types::I32, 1);
            l.b.ins().umax(n, one)
        })
    }

    /// Apply one index to an access (clamping it, recording ERR_INDEX when out of range).
    fn index_access(&mut self, mut acc: Access<'a>, index: &'a Expr, site: SiteId) -> Res<Access<'a>> {
        let base_ty = acc.ty;
        if base_ty.dims().is_empty() && !base_ty.per_seq {
            return err("indexing a scalar");
        }
        let elem_ty = base_ty.element();
        let stride = self.value_comps(elem_ty.elem(), elem_ty.fixed_len(), acc.compact);
        let static_len = if base_ty.per_seq { None } else { Some(base_ty.dims()[0]) };
        if let (Some(len), Some(k)) = (static_len, const_int(index)) {
            let clamped = k.clamp(0, len as i64 - 1) as u32;
            if k < 0 || k >= len as i64 {
                self.defer_error(ERR_INDEX, site, None);
            }
            acc.base += clamped * stride;
            acc.ty = elem_ty;
            return Ok(acc);
        }
        let idx = self.eval(index)?;
        let idx_comp = fixed::convert(&mut self.b, idx.scalar, Scalar::Int, idx.comps[0]);
        // A dynamic index into a temporary: spill it so it can be addressed.
        if let Root::Temp(v) = &acc.root {
            let v = v.clone();
            let bytes = comp_bytes(v.varying);
            let slot = self.b.create_sized_stack_slot(StackSlotData::new(
                StackSlotKind::ExplicitSlot,
                (v.comps.len() as u32).max(1) * bytes,
                4,
            ));
            for (i, &c) in v.comps.iter().enumerate() {
                let addr = self.slot_addr(slot);
                self.b.ins().store(mem_flags(), c, addr, (i as u32 * bytes) as i32);
            }
            acc.root = Root::Stack {
                slot,
                varying: v.varying,
            };
        }
        let off = if idx.varying {
            let (len, last) = self.len_and_last(static_len);
            let len_v = self.b.ins().splat(I32X4, len);
            let bad = self.b.ins().icmp(IntCC::UnsignedGreaterThanOrEqual, idx_comp, len_v);
            let bad = match self.exec() {
                Some(e) => self.b.ins().band(bad, e),
                None => bad,
            };
            let any = self.b.ins().vany_true(bad);
            self.record_error(ERR_INDEX, site.0, Some(any));
            let zero_v = mask_const(&mut self.b, false);
            let last_v = self.b.ins().splat(I32X4, last);
            let c = self.b.ins().smax(idx_comp, zero_v);
            let c = self.b.ins().smin(c, last_v);
            let stride_s = self.iconst_here(types::I32, stride as i64);
            let stride_v = self.b.ins().splat(I32X4, stride_s);
            let c = self.b.ins().imul(c, stride_v);
            match acc.dyn_off {
                Dyn::None => Dyn::Varying(c),
                Dyn::Uniform(u) => {
                    let us = self.b.ins().splat(I32X4, u);
                    Dyn::Varying(self.b.ins().iadd(us, c))
                }
                Dyn::Varying(v) => Dyn::Varying(self.b.ins().iadd(v, c)),
            }
        } else {
            // Proven in range for this frame's function (the primitive's own body only:
            // inlined interpolators have sites of their own, never in the set).
            let proven = self.frames.len() == 1 && self.site_proven(site);
            let c = if proven {
                idx_comp
            } else {
                self.checked_uniform_index(idx_comp, static_len, site)
            };
            let c = self.scaled(c, stride);
            match acc.dyn_off {
                Dyn::None => Dyn::Uniform(c),
                Dyn::Uniform(u) => Dyn::Uniform(self.b.ins().iadd(u, c)),
                Dyn::Varying(v) => {
                    let cs = self.b.ins().splat(I32X4, c);
                    Dyn::Varying(self.b.ins().iadd(v, cs))
                }
            }
        };
        acc.dyn_off = off;
        acc.ty = elem_ty;
        Ok(acc)
    }

    /// The length of an indexed array (`static_len`, or the sequence length) and its last
    /// index, built only where an index is checked: a proven site needs neither (tier 0
    /// has no pass that would drop them: they were ~1000 dead instructions of the NURB
    /// kernel's CLIF).
    fn len_and_last(&mut self, static_len: Option<u32>) -> (ir::Value, ir::Value) {
        match static_len {
            Some(n) => (
                self.iconst_here(types::I32, i64::from(n)),
                self.iconst_here(types::I32, i64::from(n) - 1),
            ),
            None => {
                let len = self.seq_len();
                (len, self.b.ins().iadd_imm_s(len, -1))
            }
        }
    }

    /// `x * k` for a non-negative `k`: nothing for 1, a shift for a power of two (which
    /// the x64 backend folds into an address as a scaled index), a multiply otherwise.
    fn scaled(&mut self, x: ir::Value, k: u32) -> ir::Value {
        match k {
            1 => x,
            k if k.is_power_of_two() => {
                let ty = self.b.func.dfg.value_type(x);
                let amount = self.iconst_here(ty, i64::from(k.trailing_zeros()));
                self.b.ins().ishl(x, amount)
            }
            k => self.b.ins().imul_imm_s(x, k as i64),
        }
    }

    /// The uniform component offset `u` as a byte offset (`u * bytes`, widened to i64);
    /// tier 0 computes it once per block.
    fn byte_offset(&mut self, u: ir::Value, bytes: u32) -> ir::Value {
        self.once_per_block(VnKey::ByteOffset(u, bytes), |l| {
            let wide = l.b.ins().uextend(types::I64, u);
            l.scaled(wide, bytes)
        })
    }

    /// `iconst` of `ty`; tier 0 makes each once per block (it has no pass that would
    /// merge the copies: the NURB setup's CLIF had ~250 duplicate shift amounts).
    fn iconst_here(&mut self, ty: ir::Type, v: i64) -> ir::Value {
        self.once_per_block(VnKey::IntConst(ty, v), |l| l.b.ins().iconst(ty, v))
    }

    /// `f32const` `x`, made once per block at tier 0 like [`Self::iconst_here`] (and shared
    /// with the source's float constants of the same bits).
    pub(super) fn f32const_here(&mut self, x: f32) -> ir::Value {
        self.once_per_block(VnKey::Const(0, x.to_bits(), Scalar::Float), |l| l.b.ins().f32const(x))
    }

    /// `make`'s value, or at tier 0 the one it made earlier in the current block for `key`
    /// (see [`Self::numbered`]).
    fn once_per_block(&mut self, key: VnKey, make: impl FnOnce(&mut Self) -> ir::Value) -> ir::Value {
        if let Some(v) = self.numbered(key) {
            return v;
        }
        let v = make(self);
        self.number(key, v);
        v
    }

    /// Is `site` of the primitive's own body proven in range (see `proven_sites`)?
    fn site_proven(&mut self, site: SiteId) -> bool {
        self.shared_body.proven_sites().contains(&site)
    }

    /// A uniform index `idx` into `len` elements (`last` = `len - 1`), clamped, with
    /// ERR_INDEX recorded at `site` when it is out of range. The in-range path is one
    /// unsigned compare and a branch; the clamp and the error record sit in a cold block.
    /// (Recorded inline with selects, the check was two loads, two stores and ten more
    /// instructions on every access: most of the NURB tessellation's time.)
    /// Tier 0 records inline with selects instead (same results): two blocks per access
    /// doubled the NURB kernel's tier-0 compile time; in setup code it records into the
    /// kernel's pending error (see [`Self::defer_error`]), not into `ctx`. And it checks an
    /// index once per block: checked again against the same length under the same error
    /// guard (or after an unguarded check), it is the first check's clamped value, since
    /// that check fails whenever this one would, and first, and the first error is the one
    /// kept (the NURB tessellation's de Boor loops checked each index up to five times in
    /// a row; -6 % of its tier-0 instructions). Not in flat pixel code, where a record also
    /// depends on the lanes executing.
    fn checked_uniform_index(&mut self, idx: ir::Value, static_len: Option<u32>, site: SiteId) -> ir::Value {
        if self.tier0() {
            let key = VnKey::CheckedIndex(idx, static_len, self.error_guard);
            let reusable = !(self.flat && self.pix.is_some());
            if reusable {
                let earlier = self
                    .numbered(key)
                    .or_else(|| self.numbered(VnKey::CheckedIndex(idx, static_len, None)));
                if let Some(c) = earlier {
                    return c;
                }
            }
            let (len, last) = self.len_and_last(static_len);
            let bad = self.b.ins().icmp(IntCC::UnsignedGreaterThanOrEqual, idx, len);
            self.defer_error(ERR_INDEX, site, Some(bad));
            let zero_s = self.iconst_here(types::I32, 0);
            let c = self.b.ins().smax(idx, zero_s);
            let c = self.b.ins().smin(c, last);
            if reusable {
                self.number(key, c);
            }
            return c;
        }
        let (len, last) = self.len_and_last(static_len);
        let bad = self.b.ins().icmp(IntCC::UnsignedGreaterThanOrEqual, idx, len);
        let cold = self.b.create_block();
        let in_range = self.b.create_block();
        let checked = self.b.append_block_param(in_range, types::I32);
        self.b.ins().brif(bad, cold, &[], in_range, &[idx.into()]);
        self.b.set_cold_block(cold);
        self.b.switch_to_block(cold);
        self.defer_error(ERR_INDEX, site, None);
        let zero_s = self.iconst_here(types::I32, 0);
        let c = self.b.ins().smax(idx, zero_s);
        let c = self.b.ins().smin(c, last);
        self.b.ins().jump(in_range, &[c.into()]);
        self.b.switch_to_block(in_range);
        checked
    }

    fn resolve(&mut self, e: &'a Expr) -> Res<Access<'a>> {
        match &e.kind {
            ExprKind::Local(l) => self.local_access(*l),
            ExprKind::Index { base, index, site } => {
                let acc = self.resolve(base)?;
                self.index_access(acc, index, *site)
            }
            _ => {
                let v = self.eval(e)?;
                Ok(Access {
                    root: Root::Temp(v.clone()),
                    ty: AccessTy::of(&e.ty),
                    scalar: v.scalar,
                    base: 0,
                    dyn_off: Dyn::None,
                    compact: true,
                })
            }
        }
    }

    /// The address of stack slot `slot`. Tier 0 has no pass that would merge repeated
    /// `stack_addr`s (one per array access: ~350 in the NURB kernel), so within one block
    /// the first is reused.
    fn slot_addr(&mut self, slot: StackSlot) -> ir::Value {
        self.once_per_block(VnKey::SlotAddr(slot), |l| match l.inherited_slot_addr(slot) {
            Some(addr) => addr,
            None => l.b.ins().stack_addr(types::I64, slot, 0),
        })
    }

    /// Copy `bytes` (a multiple of 4) from stack slot `from` to `to`, 16 bytes per load where
    /// they fit.
    fn copy_slot(&mut self, from: StackSlot, to: StackSlot, bytes: u32) {
        let src = self.slot_addr(from);
        let dst = self.slot_addr(to);
        let mut off = 0;
        while off + 4 <= bytes {
            let ty = if bytes - off >= 16 { I32X4 } else { types::I32 };
            let v = self.b.ins().load(ty, mem_flags(), src, off as i32);
            self.b.ins().store(mem_flags(), v, dst, off as i32);
            off += ty.bytes();
        }
    }

    /// A new SSA variable of type `ty` (its type recorded for [`outline`]).
    fn declare_var(&mut self, ty: ir::Type) -> Variable {
        self.var_types.push(ty);
        self.b.declare_var(ty)
    }

    /// Load a scalar of `sc` from `addr + off` bytes in uniform form (bools stored as bytes
    /// or words: any non-zero is true).
    pub(crate) fn load_uniform(
        &mut self,
        sc: Scalar,
        addr: ir::Value,
        off: i32,
        word_bools: bool,
        ro: bool,
    ) -> ir::Value {
        // Tier 0 has no e-graph pass to merge repeated loads of the same argument word (the
        // argument block is read-only while the kernel runs): within one block, reuse the
        // first load.
        if !(ro && addr == self.args) {
            return self.load_uniform_uncached(sc, addr, off, word_bools, ro);
        }
        self.once_per_block(VnKey::ArgLoad(off, sc, word_bools), |l| {
            l.load_uniform_uncached(sc, addr, off, word_bools, ro)
        })
    }

    fn load_uniform_uncached(
        &mut self,
        sc: Scalar,
        addr: ir::Value,
        off: i32,
        word_bools: bool,
        ro: bool,
    ) -> ir::Value {
        let flags = if ro { args_flags() } else { mem_flags() };
        match sc {
            Scalar::Float => self.b.ins().load(types::F32, flags, addr, off),
            Scalar::Bool => {
                let ty = if word_bools { types::I32 } else { types::I8 };
                let raw = self.b.ins().load(ty, flags, addr, off);
                self.b.ins().icmp_imm_s(IntCC::NotEqual, raw, 0)
            }
            _ => self.b.ins().load(types::I32, flags, addr, off),
        }
    }

    /// Read `count` uniform components laid out `bytes` apart from `base_addr` starting at
    /// component `first` (+ dynamic offset). A varying offset gathers lane by lane.
    /// Dynamic offsets are clamped indices times strides, never negative, so they widen
    /// to addresses by zero extension (free on x86_64 after a 32-bit operation; a sign
    /// extension was one `movslq` per indexed access).
    #[allow(clippy::too_many_arguments)]
    fn read_memory(
        &mut self,
        base_addr: ir::Value,
        sc: Scalar,
        varying_storage: bool,
        offs: &[u32],
        first: u32,
        dyn_off: Dyn,
        word_bools: bool,
        ro: bool,
    ) -> Val {
        let bytes = comp_bytes(varying_storage) as i64;
        let mut comps = Vec::with_capacity(offs.len());
        let out_varying = varying_storage || matches!(dyn_off, Dyn::Varying(_));
        // One address for every component of a uniform offset.
        let uniform_addr = match dyn_off {
            Dyn::Uniform(u) => self.uniform_dyn_addr(base_addr, u, bytes),
            _ => base_addr,
        };
        for &o in offs {
            let off = ((first + o) as i64 * bytes) as i32;
            let c = match dyn_off {
                Dyn::None | Dyn::Uniform(_) => {
                    let addr = uniform_addr;
                    if varying_storage {
                        let ty = cl_type(sc, true);
                        self.b.ins().load(ty, mem_flags(), addr, off)
                    } else {
                        self.load_uniform(sc, addr, off, word_bools, ro)
                    }
                }
                Dyn::Varying(dv) => {
                    let mut acc: Option<ir::Value> = None;
                    for lane in 0..4u8 {
                        let d = self.b.ins().extractlane(dv, lane);
                        let d64 = self.b.ins().uextend(types::I64, d);
                        let db = self.b.ins().imul_imm_s(d64, bytes);
                        let addr = self.b.ins().iadd(base_addr, db);
                        let lane_off = off + if varying_storage { 4 * lane as i32 } else { 0 };
                        let x = if varying_storage {
                            let lt = if sc == Scalar::Float { types::F32 } else { types::I32 };
                            self.b.ins().load(lt, mem_flags(), addr, lane_off)
                        } else {
                            let u = self.load_uniform(sc, addr, lane_off, word_bools, ro);
                            if sc == Scalar::Bool {
                                let w = self.b.ins().uextend(types::I32, u);
                                self.b.ins().ineg(w)
                            } else {
                                u
                            }
                        };
                        let vt = cl_type(sc, true);
                        acc = Some(match acc {
                            None => self.b.ins().scalar_to_vector(vt, x),
                            Some(a) => self.b.ins().insertlane(a, x, lane),
                        });
                    }
                    acc.expect("four lanes")
                }
            };
            comps.push(c);
        }
        Val {
            comps,
            scalar: sc,
            varying: out_varying,
        }
    }

    fn read(&mut self, acc: Access<'a>) -> Res<Val> {
        if acc.ty.per_seq {
            return err("a whole per-sequence-point array used as a value");
        }
        let offs = self.comp_offsets(acc.ty.elem(), acc.ty.fixed_len(), acc.compact);
        let v = self.read_at(acc, &offs);
        self.give_back_offsets(offs);
        v
    }

    /// [`Self::read`] of the components at `offs`.
    fn read_at(&mut self, acc: Access<'a>, offs: &[u32]) -> Res<Val> {
        let sc = acc.scalar;
        match acc.root {
            Root::Temp(v) => {
                let comps = offs
                    .iter()
                    .map(|&o| v.comps.get((acc.base + o) as usize).copied())
                    .collect::<Option<Vec<_>>>()
                    .ok_or_else(|| JitError {
                        message: "component out of range in a temporary".into(),
                    })?;
                Ok(Val {
                    comps,
                    scalar: v.scalar,
                    varying: v.varying,
                })
            }
            Root::Stack { slot, varying } => {
                let addr = self.slot_addr(slot);
                Ok(self.read_memory(addr, sc, varying, offs, acc.base, acc.dyn_off, false, false))
            }
            Root::Local { frame, local } => {
                let fr = &self.frames[frame];
                let varying = fr.func.local(local).var.is_varying();
                let at = local.0 as usize;
                if let Storage::Vars(_) = &fr.storage[at] {
                    if !matches!(acc.dyn_off, Dyn::None) {
                        return err("dynamic index into a register local");
                    }
                    // Each variable is looked up where it is read: cloning the local's
                    // variable list was an allocation per read.
                    let mut comps = Vec::with_capacity(offs.len());
                    for &o in offs {
                        let var = match &self.frames[frame].storage[at] {
                            Storage::Vars(vars) => vars.get((acc.base + o) as usize).copied(),
                            _ => None,
                        };
                        let Some(v) = var else {
                            return err("component out of range");
                        };
                        comps.push(self.b.use_var(v));
                    }
                    return Ok(Val {
                        comps,
                        scalar: sc,
                        varying,
                    });
                }
                match fr.storage[at].clone() {
                    Storage::Vars(_) => err("register local read as memory"),
                    Storage::Z(v) => Ok(Val::one(self.b.use_var(v), sc, true)),
                    Storage::Stack(slot) => {
                        let addr = self.slot_addr(slot);
                        Ok(self.read_memory(addr, sc, varying, offs, acc.base, acc.dyn_off, false, false))
                    }
                    Storage::Frame(word) => {
                        let in_group = self.pix.as_ref().and_then(|p| p.frame_base);
                        let (addr, pure) = match (in_group, self.uniform_frame) {
                            (Some(base), _) => (base, true),
                            (None, Some((fs, _))) => (self.slot_addr(fs), false),
                            (None, None) => return err("uniform frame missing"),
                        };
                        let v = self.read_memory(addr, sc, false, offs, word + acc.base, acc.dyn_off, false, pure);
                        // Tier 0 keeps no splatted copies (see `spill_uniforms`).
                        if pure && sc != Scalar::Bool && matches!(acc.dyn_off, Dyn::None) && !self.tier0() {
                            for (&c, &o) in v.comps.iter().zip(offs) {
                                let w = word + acc.base + o;
                                self.splat_src.insert(c, self.vec_section + 16 * w);
                            }
                        }
                        Ok(v)
                    }
                    Storage::Args => {
                        let pi = fr
                            .func
                            .params
                            .iter()
                            .position(|p| p.local == local)
                            .ok_or_else(|| JitError {
                                message: "parameter storage for a non-parameter".into(),
                            })?;
                        let slot = fr.slots.get(pi).cloned().unwrap_or(ParamSlot::Pixel);
                        let fixed_words = fr.fixed_words;
                        let (addr, first) = match slot {
                            ParamSlot::Fixed { offset, .. } => (self.args, offset + acc.base),
                            // The first sequence array starts right after the fixed words.
                            ParamSlot::Seq { seq_offset: 0, .. } => (self.args, fixed_words + acc.base),
                            ParamSlot::Seq { seq_offset, .. } => {
                                // fixed_words + max(n_seq,1) * seq_offset, in words.
                                let n = self.seq_len();
                                let n64 = self.b.ins().uextend(types::I64, n);
                                let w = self.b.ins().imul_imm_s(n64, seq_offset as i64);
                                let w = self.b.ins().iadd_imm_s(w, fixed_words as i64);
                                let bytes = self.b.ins().ishl_imm_u(w, 2);
                                (self.b.ins().iadd(self.args, bytes), acc.base)
                            }
                            ParamSlot::Pixel => return err("pixel parameter read from the argument block"),
                        };
                        Ok(self.read_memory(addr, sc, false, offs, first, acc.dyn_off, true, true))
                    }
                }
            }
        }
    }

    fn assign(&mut self, place: &'a Place, value: &'a Expr) -> Res<()> {
        let frame = self.frames.len() - 1;
        self.guard_facts.kill(frame, place.local);
        let mut acc = self.local_access(place.local)?;
        for (idx, site) in &place.indices {
            acc = self.index_access(acc, idx, *site)?;
        }
        if self.zero_uniform_array(place.local, &acc, value) {
            return Ok(());
        }
        let v = self.eval(value)?;
        let target = acc.scalar;
        let comps: Vec<ir::Value> = v
            .comps
            .iter()
            .map(|&c| fixed::convert(&mut self.b, v.scalar, target, c))
            .collect();
        let offs = self.comp_offsets(acc.ty.elem(), acc.ty.fixed_len(), false);
        let done = self.assign_at(place, acc, comps, &offs);
        self.give_back_offsets(offs);
        done
    }

    /// [`Self::assign`] of `comps` (converted to the place's scalar type) to the components
    /// of `acc` at `offs`.
    fn assign_at(&mut self, place: &'a Place, acc: Access<'a>, comps: Vec<ir::Value>, offs: &[u32]) -> Res<()> {
        let frame = self.frames.len() - 1;
        self.guard_facts.kill(frame, place.local);
        let target = acc.scalar;
        let comps = if comps.len() == 1 && offs.len() != 1 {
            vec![comps[0]; offs.len()]
        } else {
            comps
        };
        if comps.len() != offs.len() {
            return err(format!(
                "assignment of {} components to a place of {}",
                comps.len(),
                offs.len()
            ));
        }
        let frame_i = self.frames.len() - 1;
        let fr = &self.frames[frame_i];
        let local = fr.func.local(place.local);
        let varying = local.var.is_varying();
        // A register local's variables are looked up per component below (no clone of
        // its variable list per assignment).
        let at = place.local.0 as usize;
        let storage = match &fr.storage[at] {
            Storage::Vars(_) => Storage::Vars(vec![]),
            other => other.clone(),
        };
        let masked = self.masked();
        match storage {
            Storage::Args => err(format!("assignment to parameter `{}`", local.name)),
            Storage::Frame(_) => err(format!(
                "assignment to `{}`, which the pixel part never assigns",
                local.name
            )),
            Storage::Vars(_) => {
                for (o, c) in offs.iter().zip(comps) {
                    let var = match &self.frames[frame_i].storage[at] {
                        Storage::Vars(vars) => vars.get((acc.base + o) as usize).copied(),
                        _ => None,
                    };
                    let Some(var) = var else {
                        return err("component out of range");
                    };
                    let new = if varying {
                        let c = splat(&mut self.b, target, c);
                        if masked {
                            let old = self.b.use_var(var);
                            let exec = self.exec().expect("pixel context");
                            blend(&mut self.b, exec, c, old)
                        } else {
                            c
                        }
                    } else {
                        if self.b.func.dfg.value_type(c).is_vector() {
                            return err(format!("varying value assigned to uniform `{}`", local.name));
                        }
                        c
                    };
                    self.b.def_var(var, new);
                }
                Ok(())
            }
            Storage::Z(var) => {
                let c = splat(&mut self.b, target, comps[0]);
                let exec = self.exec().ok_or_else(|| JitError {
                    message: "Z assigned outside per-pixel code".into(),
                })?;
                let old = self.b.use_var(var);
                let new = blend(&mut self.b, exec, c, old);
                self.b.def_var(var, new);
                let zw = self.pix.as_ref().expect("pixel context").z_written;
                let w = self.b.use_var(zw);
                let w = self.b.ins().bor(w, exec);
                self.b.def_var(zw, w);
                Ok(())
            }
            Storage::Stack(slot) => {
                let base_addr = self.slot_addr(slot);
                let bytes = comp_bytes(varying) as i64;
                for (o, c) in offs.iter().zip(comps) {
                    let off = ((acc.base + o) as i64 * bytes) as i32;
                    if !varying {
                        if self.b.func.dfg.value_type(c).is_vector() {
                            return err(format!("varying value assigned to uniform `{}`", local.name));
                        }
                        let addr = self.dyn_addr(base_addr, acc.dyn_off, bytes)?;
                        self.b.ins().store(mem_flags(), c, addr, off);
                        continue;
                    }
                    let c = splat(&mut self.b, target, c);
                    match acc.dyn_off {
                        Dyn::Varying(dv) => {
                            // Scatter lane by lane; lanes not executing keep their old value.
                            let exec = self.exec();
                            for lane in 0..4u8 {
                                let d = self.b.ins().extractlane(dv, lane);
                                let d64 = self.b.ins().uextend(types::I64, d);
                                let db = self.b.ins().imul_imm_s(d64, bytes);
                                let addr = self.b.ins().iadd(base_addr, db);
                                let lt = if target == Scalar::Float {
                                    types::F32
                                } else {
                                    types::I32
                                };
                                let lane_off = off + 4 * lane as i32;
                                let x = self.b.ins().extractlane(c, lane);
                                let x = match exec {
                                    Some(e) => {
                                        let m = self.b.ins().extractlane(e, lane);
                                        let on = self.b.ins().icmp_imm_s(IntCC::NotEqual, m, 0);
                                        let old = self.b.ins().load(lt, mem_flags(), addr, lane_off);
                                        self.b.ins().select(on, x, old)
                                    }
                                    None => x,
                                };
                                self.b.ins().store(mem_flags(), x, addr, lane_off);
                            }
                        }
                        d => {
                            let addr = self.dyn_addr(base_addr, d, bytes)?;
                            let ty = cl_type(target, true);
                            let new = if masked {
                                let old = self.b.ins().load(ty, mem_flags(), addr, off);
                                let exec = self.exec().expect("pixel context");
                                blend(&mut self.b, exec, c, old)
                            } else {
                                c
                            };
                            self.b.ins().store(mem_flags(), new, addr, off);
                        }
                    }
                }
                Ok(())
            }
        }
    }

    /// A uniform stack array set whole to all zeros (a declaration without initialiser, or
    /// `{0, ...}`): cleared 16 bytes per store instead of 4, since all-zero bits are zero in
    /// every scalar type (the NURB tessellation zeroes ~480 words per vertex). Decided
    /// before the value is evaluated: evaluating it first left one dead constant per
    /// component (5700 of the NURB kernel's 32000 tier-0 CLIF lines) for Cranelift to
    /// process. False (nothing emitted) when the assignment is not such a clear.
    fn zero_uniform_array(&mut self, local: LocalId, acc: &Access<'a>, value: &Expr) -> bool {
        // Cheap tests first: this runs for every assignment.
        if !all_zero_bits(value) {
            return false;
        }
        let fr = &self.frames[self.frames.len() - 1];
        let varying = fr.func.local(local).var.is_varying();
        let Some(&Storage::Stack(slot)) = fr.storage.get(local.0 as usize) else {
            return false;
        };
        // interpolation_data counts too when the view is every component (outside the
        // arms that narrow it): `interpolation_data known_data[1280]` of the NURB tessellation
        // was 3840 one-word stores, 39 % of its kernel's tier-0 CLIF.
        // (A view holds distinct components: as many as the data has is all of them.)
        let whole = matches!(acc.dyn_off, Dyn::None)
            && !acc.compact
            && (matches!(acc.ty.elem(), Elem::Scalar(_)) || self.view.len() as u32 == self.n_interp);
        let words = self.value_comps(acc.ty.elem(), acc.ty.fixed_len(), false);
        // The value must cover the place exactly (or be one scalar, broadcast), as the
        // general path checks.
        let fits = value.ty.is_scalar()
            || match acc.ty.elem() {
                Elem::Scalar(_) => value.ty.fixed_len() == words,
                Elem::Interp => value.ty.elem == Elem::Interp && value.ty.fixed_len() == acc.ty.fixed_len(),
            };
        if varying || !whole || words < 8 || !fits {
            return false;
        }
        let base_addr = self.slot_addr(slot);
        self.zero_stack_bytes(base_addr, acc.base * 4, (acc.base + words) * 4);
        true
    }

    /// Store zeros to bytes `start..end` (multiples of 4) from `base_addr`, a stack slot's
    /// address. All-zero bits are zero in every scalar type, so 16 bytes per store (a word
    /// per store was a quarter of the NURB kernel's CLIF); a clear of more than
    /// [`ZERO_LOOP_BYTES`] in setup code is a counted loop of four such stores per trip
    /// (the NURB kernel's 2 KB tessellation arrays were 128 stores each: one CLIF
    /// instruction per 16 bytes to build, allocate and emit, for a clear that runs once per
    /// primitive). Pixel code keeps straight stores: its flat tier-0 form has no blocks.
    fn zero_stack_bytes(&mut self, base_addr: ir::Value, start: u32, end: u32) {
        let zero_vec = mask_const(&mut self.b, false);
        let mut at = start;
        if end - start > ZERO_LOOP_BYTES && self.pix.is_none() {
            let trip_bytes = 64;
            let loop_end = start + (end - start) / trip_bytes * trip_bytes;
            let first = self.b.ins().iadd_imm_s(base_addr, start as i64);
            let last = self.b.ins().iadd_imm_s(base_addr, loop_end as i64);
            let trip = self.b.create_block();
            let after = self.b.create_block();
            let p = self.b.append_block_param(trip, types::I64);
            self.b.ins().jump(trip, &[first.into()]);
            self.b.switch_to_block(trip);
            for k in 0..trip_bytes / 16 {
                self.b.ins().store(mem_flags(), zero_vec, p, (16 * k) as i32);
            }
            let next = self.b.ins().iadd_imm_s(p, trip_bytes as i64);
            let more = self.b.ins().icmp(IntCC::UnsignedLessThan, next, last);
            self.b.ins().brif(more, trip, &[next.into()], after, &[]);
            self.seal_now(trip);
            self.seal_now(after);
            self.b.switch_to_block(after);
            at = loop_end;
        }
        while at + 16 <= end {
            self.b.ins().store(mem_flags(), zero_vec, base_addr, at as i32);
            at += 16;
        }
        if at < end {
            let zero_word = self.iconst_here(types::I32, 0);
            while at < end {
                self.b.ins().store(mem_flags(), zero_word, base_addr, at as i32);
                at += 4;
            }
        }
    }

    /// `base + d * bytes` for a uniform dynamic offset `d` (see [`Self::read_memory`] on
    /// the zero extension). Tier 0 computes it once per block and offset: an access to
    /// `float p[4]` at a dynamic row reads or writes four components at one address, and
    /// the NURB setup reads the same element several times (tier 0 has no pass that would
    /// merge the copies: ~250 `uextend`s, shifts and adds of its CLIF).
    fn dyn_addr(&mut self, base: ir::Value, d: Dyn, bytes: i64) -> Res<ir::Value> {
        match d {
            Dyn::None => Ok(base),
            Dyn::Uniform(u) => Ok(self.uniform_dyn_addr(base, u, bytes)),
            Dyn::Varying(_) => err("varying index into a uniform local"),
        }
    }

    /// [`Self::dyn_addr`] of a uniform offset `u`.
    fn uniform_dyn_addr(&mut self, base: ir::Value, u: ir::Value, bytes: i64) -> ir::Value {
        self.once_per_block(VnKey::DynAddr(base, u, bytes as u32), |l| {
            let db = l.byte_offset(u, bytes as u32);
            l.b.ins().iadd(base, db)
        })
    }

    // ---------------------------------------------------------------- expressions

    /// The bound of float expression `e` of the function being lowered (see [`bounds`]),
    /// as (lo, hi), at the statement being lowered: every executing lane's value is a
    /// non-NaN f32 within it (an end may be infinite). The flag is true when the guards
    /// before this statement narrowed it: such a bound holds here only, not wherever the
    /// same value is computed (see [`Self::convert_here`]).
    fn float_bound_here(&mut self, e: &Expr) -> (Option<(f64, f64)>, bool) {
        let Some(frame) = self.frames.last() else {
            return (None, false);
        };
        let f = frame.func;
        let depth = self.frames.len() - 1;
        let table = self
            .local_bounds
            .entry(f as *const Function as usize)
            .or_insert_with(|| bounds::LocalBounds::of_function(f));
        let whole = table.expr(e).map(|b| (b.lo, b.hi));
        let here = table.expr_here(e, &self.guard_facts, depth);
        (here, here != whole)
    }

    /// Convert `c`, one component of a value of `e` (a `from` value), to `to`; with the
    /// bound `e` has here when it is a varying float going to int or fixed. Value numbered
    /// (tier 0) by `c` and the types; a conversion made with a bound the guards narrowed
    /// is not recorded (it is right only where the guards' facts hold: a varying `if`'s
    /// other side, in the same block in flat code, must not reuse it), but may reuse one
    /// that was (right for every lane, so for these).
    fn convert_here(&mut self, e: &Expr, from: Scalar, to: Scalar, c: ir::Value, varying: bool) -> ir::Value {
        let (bound, narrowed) = if varying && from == Scalar::Float && matches!(to, Scalar::Int | Scalar::Fixed(_)) {
            self.float_bound_here(e)
        } else {
            (None, false)
        };
        let key = VnKey::Convert(from, to, c);
        if let Some(r) = self.numbered(key) {
            return r;
        }
        let r = fixed::convert_bounded(&mut self.b, from, to, c, bound);
        if !narrowed {
            self.number(key, r);
        }
        r
    }

    /// While a row prologue substitutes row locals: the value of row local `l` (`None`: not
    /// a row local), evaluated from its defining expression once per prologue (the same
    /// operations every time, so reusing them changes no bit).
    fn row_local_value(&mut self, l: LocalId) -> Option<Res<Val>> {
        let &value = self.row_locals.get(&l)?;
        let block = self.b.current_block();
        if let Some((at, v)) = self.row_local_values.get(&l) {
            if Some(*at) == block {
                return Some(Ok(v.clone()));
            }
        }
        let v = self.eval(value);
        if let (Ok(v), Some(at)) = (&v, block) {
            if self.b.current_block() == Some(at) {
                self.row_local_values.insert(l, (at, v.clone()));
            }
        }
        Some(v)
    }

    /// While a row prologue substitutes row locals: element `k` of a one-dimensional row
    /// local (`along[1]`), from the local's value (see `hoist.rs`). `None` for anything else.
    fn row_local_element(&mut self, e: &'a Expr) -> Option<Res<Val>> {
        let ExprKind::Index { base, index, .. } = &e.kind else {
            return None;
        };
        let (ExprKind::Local(l), ExprKind::Const(ConstValue::Int(k))) = (&base.kind, &index.kind) else {
            return None;
        };
        if base.ty.dims.len() != 1 {
            return None;
        }
        let k = usize::try_from(*k).ok()?;
        Some(self.row_local_value(*l)?.and_then(|v| match v.comps.get(k) {
            Some(&c) => Ok(Val { comps: vec![c], ..v }),
            None => err("row local element out of range"),
        }))
    }

    pub(crate) fn eval_uniform(&mut self, e: &'a Expr) -> Res<Val> {
        let v = self.eval(e)?;
        if v.varying {
            return err("varying value where a uniform one is required");
        }
        Ok(v)
    }

    pub(crate) fn eval(&mut self, e: &'a Expr) -> Res<Val> {
        if let Some(v) = self.hoisted(e) {
            return Ok(v);
        }
        if self.substitute_row_locals {
            if let ExprKind::Local(l) = &e.kind {
                if let Some(v) = self.row_local_value(*l) {
                    return v;
                }
            }
            if let Some(v) = self.row_local_element(e) {
                return v;
            }
        }
        if let Some(v) = self.carried_value(e) {
            return Ok(v);
        }
        let sc = elem_scalar(&e.ty);
        match &e.kind {
            ExprKind::Const(c) => {
                let key = match *c {
                    ConstValue::Float(x) => VnKey::Const(0, x.to_bits(), sc),
                    ConstValue::Int(i) => VnKey::Const(1, i as u32, sc),
                    ConstValue::Bool(x) => VnKey::Const(2, x as u32, sc),
                    ConstValue::Fixed(i) => VnKey::Const(3, i as u32, sc),
                };
                if let Some(v) = self.numbered(key) {
                    return Ok(Val::one(v, sc, false));
                }
                let v = match *c {
                    ConstValue::Float(x) => self.f32const_here(x),
                    ConstValue::Int(i) | ConstValue::Fixed(i) => self.iconst_here(types::I32, i as i64),
                    ConstValue::Bool(x) => self.iconst_here(types::I8, x as i64),
                };
                // A constant of one scalar type used as another (defensive): convert.
                let from = match c {
                    ConstValue::Float(_) => Scalar::Float,
                    ConstValue::Int(_) => Scalar::Int,
                    ConstValue::Bool(_) => Scalar::Bool,
                    ConstValue::Fixed(_) => sc,
                };
                let v = fixed::convert(&mut self.b, from, sc, v);
                self.number(key, v);
                Ok(Val::one(v, sc, false))
            }
            ExprKind::Local(_) | ExprKind::Index { .. } => {
                let acc = self.resolve(e)?;
                self.read(acc)
            }
            ExprKind::Unary { op, expr } => {
                let v = self.eval(expr)?;
                let code = if *op == UnaryOp::Neg { VN_NEG } else { VN_NOT };
                let comps = v
                    .comps
                    .iter()
                    .map(|&c| {
                        let key = VnKey::Op(code, v.scalar, c, c);
                        if let Some(r) = self.numbered(key) {
                            return r;
                        }
                        let r = match (op, v.scalar) {
                            (UnaryOp::Neg, Scalar::Float) => self.b.ins().fneg(c),
                            (UnaryOp::Neg, Scalar::Fixed(f)) => fixed::neg(&mut self.b, f, c),
                            (UnaryOp::Neg, _) => self.b.ins().ineg(c),
                            (UnaryOp::Not, _) => {
                                let c = fixed::convert(&mut self.b, v.scalar, Scalar::Bool, c);
                                if v.varying {
                                    self.b.ins().bnot(c)
                                } else {
                                    self.b.ins().bxor_imm_s(c, 1)
                                }
                            }
                        };
                        self.number(key, r);
                        r
                    })
                    .collect();
                let scalar = if *op == UnaryOp::Not { Scalar::Bool } else { v.scalar };
                Ok(Val {
                    comps,
                    scalar,
                    varying: v.varying,
                })
            }
            ExprKind::Binary { op, lhs, rhs } => {
                let a = self.eval(lhs)?;
                let c = match op {
                    // `a && b` reads b only where a holds, `a || b` only where it does not.
                    BinOp::And | BinOp::Or if a.scalar == Scalar::Bool => {
                        self.eval_guarded(rhs, a.varying, a.comps[0], *op == BinOp::And)?
                    }
                    _ => self.eval(rhs)?,
                };
                self.binary(*op, a, c)
            }
            ExprKind::Convert(inner) => {
                let v = self.eval(inner)?;
                let mut comps: Vec<ir::Value> = v
                    .comps
                    .iter()
                    .map(|&c| match (v.scalar, sc, super::value::iconst_i32(&self.b, c)) {
                        // An int constant as a float (`float({1, 0, 0, 0})`): the constant
                        // itself (`as` rounds to nearest like `fcvt_from_sint`), shared like
                        // any other constant at tier 0, instead of a conversion at run time.
                        (Scalar::Int, Scalar::Float, Some(i)) => {
                            let x = i as f32;
                            let key = VnKey::Const(0, x.to_bits(), Scalar::Float);
                            self.numbered(key).unwrap_or_else(|| {
                                let f = self.f32const_here(x);
                                self.number(key, f);
                                f
                            })
                        }
                        _ if v.scalar == sc => c,
                        // A varying float whose lanes are proven finite and in the target's
                        // range converts without the saturation fix-ups
                        // (`fixed::convert_bounded`). Shared with an unbounded conversion
                        // of the same value: the value is in the bound, where both agree.
                        _ => self.convert_here(inner, v.scalar, sc, c, v.varying),
                    })
                    .collect();
                // A number converted to interpolation data stands for that number in every
                // component of the current view (the checker's zero-initialisation and
                // broadcasts).
                if e.ty.elem == Elem::Interp && inner.ty.elem != Elem::Interp && comps.len() == 1 {
                    let offs = self.comp_offsets(e.ty.elem, e.ty.fixed_len(), true);
                    let n = offs.len();
                    self.give_back_offsets(offs);
                    comps = vec![comps[0]; n];
                }
                Ok(Val {
                    comps,
                    scalar: sc,
                    varying: v.varying,
                })
            }
            ExprKind::Select { cond, then, otherwise } => {
                let c = self.eval(cond)?;
                let cb = fixed::convert(&mut self.b, c.scalar, Scalar::Bool, c.comps[0]);
                let t = self.eval_guarded(then, c.varying, cb, true)?;
                let o = self.eval_guarded(otherwise, c.varying, cb, false)?;
                let (t, o) = self.unify(t, o)?;
                if !c.varying {
                    // A uniform condition picks whole values, vectors too: a scalar `select`
                    // (a test and a move) instead of splatting the condition to a lane mask
                    // and blending (eight instructions per group for `a != 0 ? x : y`).
                    // `unify` left both arms equally varying.
                    let comps = t
                        .comps
                        .iter()
                        .zip(&o.comps)
                        .map(|(&x, &y)| self.b.ins().select(cb, x, y))
                        .collect();
                    return Ok(Val {
                        comps,
                        scalar: t.scalar,
                        varying: t.varying,
                    });
                }
                let t = self.make_varying(t);
                let o = self.make_varying(o);
                let m = splat(&mut self.b, Scalar::Bool, cb);
                let comps = t
                    .comps
                    .iter()
                    .zip(&o.comps)
                    .map(|(&x, &y)| blend(&mut self.b, m, x, y))
                    .collect();
                Ok(Val {
                    comps,
                    scalar: t.scalar,
                    varying: true,
                })
            }
            ExprKind::Builtin { func, args } => self.builtin(*func, args, e),
            ExprKind::List(items) => {
                let mut vals = vec![];
                for it in items {
                    vals.push(self.eval(it)?);
                }
                let varying = vals.iter().any(|v| v.varying);
                let mut comps = vec![];
                for v in vals {
                    let v = Val {
                        comps: v
                            .comps
                            .iter()
                            .map(|&c| fixed::convert(&mut self.b, v.scalar, sc, c))
                            .collect(),
                        scalar: sc,
                        varying: v.varying,
                    };
                    let v = if varying { self.make_varying(v) } else { v };
                    comps.extend(v.comps);
                }
                Ok(Val {
                    comps,
                    scalar: sc,
                    varying,
                })
            }
            ExprKind::Splat(item) => {
                let v = self.eval(item)?;
                let one: Vec<ir::Value> = v
                    .comps
                    .iter()
                    .map(|&c| fixed::convert(&mut self.b, v.scalar, sc, c))
                    .collect();
                Ok(Val {
                    comps: one.repeat(e.ty.fixed_len() as usize),
                    scalar: sc,
                    varying: v.varying,
                })
            }
            ExprKind::MatMul { lhs, rhs } => {
                let a = self.eval(lhs)?;
                let c = self.eval(rhs)?;
                let (n, m) = match lhs.ty.dims.as_slice() {
                    [n, m] => (*n as usize, *m as usize),
                    _ => return err("matrix product with a non-2-D left side"),
                };
                let k = match rhs.ty.dims.as_slice() {
                    [r] if *r as usize == m => None,
                    [r, k] if *r as usize == m => Some(*k as usize),
                    _ => return err("matrix product with mismatched shapes"),
                };
                // Only the variability is unified: the operands' lengths differ by design
                // (n*m and m*k components), which `unify` would reject.
                let (a, c) = if a.varying != c.varying {
                    (self.make_varying(a), self.make_varying(c))
                } else {
                    (a, c)
                };
                let a = self.float_val(a);
                let c = self.float_val(c);
                let kk = k.unwrap_or(1);
                let mut comps = vec![];
                for i in 0..n {
                    for j in 0..kk {
                        let mut acc = None;
                        for t in 0..m {
                            let x = a.comps[i * m + t];
                            let y = c.comps[t * kk + j];
                            let p = self.b.ins().fmul(x, y);
                            acc = Some(match acc {
                                None => p,
                                Some(s) => self.b.ins().fadd(s, p),
                            });
                        }
                        comps.push(acc.unwrap_or_else(|| zero(&mut self.b, Scalar::Float, a.varying)));
                    }
                }
                Ok(Val {
                    comps,
                    scalar: Scalar::Float,
                    varying: a.varying,
                })
            }
            ExprKind::SeqCount => {
                let n = self.b.ins().load(types::I32, args_flags(), self.args, 0);
                Ok(Val::one(n, Scalar::Int, false))
            }
            ExprKind::ClipFlag => {
                let on = self.iconst_here(types::I8, i64::from(!self.key.trivial_accept));
                Ok(Val::one(on, Scalar::Bool, false))
            }
        }
    }

    pub(crate) fn float_val(&mut self, v: Val) -> Val {
        if v.scalar == Scalar::Float {
            return v;
        }
        let comps = v
            .comps
            .iter()
            .map(|&c| fixed::convert(&mut self.b, v.scalar, Scalar::Float, c))
            .collect();
        Val {
            comps,
            scalar: Scalar::Float,
            varying: v.varying,
        }
    }

    /// Bring two operands to the same form and length (a single component broadcasts).
    pub(crate) fn unify(&mut self, a: Val, c: Val) -> Res<(Val, Val)> {
        let (mut a, mut c) = (a, c);
        if a.varying != c.varying {
            a = self.make_varying(a);
            c = self.make_varying(c);
        }
        if a.comps.len() != c.comps.len() {
            if a.comps.len() == 1 {
                a.comps = vec![a.comps[0]; c.comps.len()];
            } else if c.comps.len() == 1 {
                c.comps = vec![c.comps[0]; a.comps.len()];
            } else {
                return err(format!(
                    "operands of {} and {} components",
                    a.comps.len(),
                    c.comps.len()
                ));
            }
        }
        Ok((a, c))
    }

    fn binary(&mut self, op: BinOp, a: Val, c: Val) -> Res<Val> {
        // Operands share a scalar type (checker); convert defensively if they do not.
        let c = if c.scalar != a.scalar {
            Val {
                comps: c
                    .comps
                    .iter()
                    .map(|&x| fixed::convert(&mut self.b, c.scalar, a.scalar, x))
                    .collect(),
                scalar: a.scalar,
                varying: c.varying,
            }
        } else {
            c
        };
        let (a, c) = self.unify(a, c)?;
        let sc = a.scalar;
        let is_cmp = matches!(
            op,
            BinOp::Lt | BinOp::Le | BinOp::Gt | BinOp::Ge | BinOp::Eq | BinOp::Ne
        );
        let mut comps = Vec::with_capacity(a.comps.len());
        for (&x, &y) in a.comps.iter().zip(&c.comps) {
            let key = VnKey::Op(op as u8, sc, x, y);
            let v = match self.numbered(key) {
                Some(v) => v,
                None => {
                    let v = self.binop(op, sc, x, y)?;
                    self.number(key, v);
                    v
                }
            };
            comps.push(v);
        }
        let scalar = if is_cmp || matches!(op, BinOp::And | BinOp::Or) {
            Scalar::Bool
        } else {
            sc
        };
        Ok(Val {
            comps,
            scalar,
            varying: a.varying,
        })
    }

    /// Tier 0: the value `key` already has in the current block, if it was lowered there.
    /// Every key is a pure function of SSA values (or a constant), so an earlier result in
    /// the same block is the same value and dominates the use: an assignment to a local
    /// gives the local a new SSA value, and so a new key. Sharing shortens the CLIF (a
    /// triangle repeats `-orient`, `interp_data[0] * q0`, many constants) without a pass over
    /// the finished function.
    fn numbered(&self, key: VnKey) -> Option<ir::Value> {
        if !self.tier0() {
            return None;
        }
        let block = self.b.current_block()?;
        self.vn.get(block, key)
    }

    /// Record `v` as the value of `key` in the current block (tier 0; see [`Self::numbered`]).
    fn number(&mut self, key: VnKey, v: ir::Value) {
        if let (true, Some(block)) = (self.tier0(), self.b.current_block()) {
            self.vn.insert(block, key, v);
        }
    }

    /// `x * y`, or the other factor where one is the constant 1: `x * 1` is `x` for every
    /// float (NaN, infinities and signed zeros included). Transforms of unit vectors
    /// (`transform("device", "object", {1, 0, 0, 0})`, the sphere's matrix columns) have
    /// a quarter of their products by 1; `x / 1.0` is one too (`exact_reciprocal`).
    /// `tests/jit_multiply_by_one.rs`.
    pub(crate) fn fmul(&mut self, x: ir::Value, y: ir::Value) -> ir::Value {
        if float_const(self.b.func, y) == Some(1.0) {
            x
        } else if float_const(self.b.func, x) == Some(1.0) {
            y
        } else {
            self.b.ins().fmul(x, y)
        }
    }

    fn binop(&mut self, op: BinOp, sc: Scalar, x: ir::Value, y: ir::Value) -> Res<ir::Value> {
        let b = &mut self.b;
        Ok(match sc {
            Scalar::Float => match op {
                BinOp::Add => b.ins().fadd(x, y),
                BinOp::Sub => b.ins().fsub(x, y),
                BinOp::Mul => self.fmul(x, y),
                BinOp::Div => match exact_reciprocal(b.func, y) {
                    // x / 2^k and x * 2^-k round the same real number, so they are the same
                    // value for every x (NaN, infinities, zeros and subnormals included);
                    // the multiply is ~4 cycles to the division's ~11 (`vx[i] / 16.0` of
                    // the triangle's snapping, six per setup).
                    Some(r) => {
                        let r = self.fconst_like(x, r);
                        self.fmul(x, r)
                    }
                    None => b.ins().fdiv(x, y),
                },
                BinOp::Rem => {
                    // C fmodf: x - trunc(x / y) * y.
                    let q = b.ins().fdiv(x, y);
                    let t = b.ins().trunc(q);
                    let p = b.ins().fmul(t, y);
                    b.ins().fsub(x, p)
                }
                BinOp::Lt => b.ins().fcmp(FloatCC::LessThan, x, y),
                BinOp::Le => b.ins().fcmp(FloatCC::LessThanOrEqual, x, y),
                BinOp::Gt => b.ins().fcmp(FloatCC::GreaterThan, x, y),
                BinOp::Ge => b.ins().fcmp(FloatCC::GreaterThanOrEqual, x, y),
                BinOp::Eq => b.ins().fcmp(FloatCC::Equal, x, y),
                BinOp::Ne => b.ins().fcmp(FloatCC::NotEqual, x, y),
                BinOp::And | BinOp::Or => return err("logical operator on floats"),
            },
            Scalar::Int | Scalar::Fixed(_) => {
                let fmt = match sc {
                    Scalar::Fixed(f) => Some(f),
                    _ => None,
                };
                match op {
                    BinOp::Add => match fmt {
                        Some(f) => fixed::add(b, f, x, y),
                        None => b.ins().iadd(x, y),
                    },
                    BinOp::Sub => match fmt {
                        Some(f) => fixed::sub(b, f, x, y),
                        None => b.ins().isub(x, y),
                    },
                    BinOp::Mul => match fmt {
                        Some(f) => fixed::mul(b, f, x, y),
                        None => b.ins().imul(x, y),
                    },
                    BinOp::Div => match fmt {
                        Some(f) => fixed::div(b, f, x, y),
                        None => fixed::int_div_rem(b, x, y, false),
                    },
                    BinOp::Rem => match fmt {
                        Some(f) => fixed::rem(b, f, x, y),
                        None => fixed::int_div_rem(b, x, y, true),
                    },
                    BinOp::Lt => b.ins().icmp(fixed::int_cc(sc, IntCC::SignedLessThan), x, y),
                    BinOp::Le => b.ins().icmp(fixed::int_cc(sc, IntCC::SignedLessThanOrEqual), x, y),
                    BinOp::Gt => b.ins().icmp(fixed::int_cc(sc, IntCC::SignedGreaterThan), x, y),
                    BinOp::Ge => b.ins().icmp(fixed::int_cc(sc, IntCC::SignedGreaterThanOrEqual), x, y),
                    BinOp::Eq => b.ins().icmp(IntCC::Equal, x, y),
                    BinOp::Ne => b.ins().icmp(IntCC::NotEqual, x, y),
                    BinOp::And | BinOp::Or => return err("logical operator on numbers"),
                }
            }
            Scalar::Bool => match op {
                BinOp::And => b.ins().band(x, y),
                BinOp::Or => b.ins().bor(x, y),
                BinOp::Eq => b.ins().icmp(IntCC::Equal, x, y),
                BinOp::Ne => b.ins().icmp(IntCC::NotEqual, x, y),
                _ => return err("arithmetic on bools"),
            },
        })
    }

    /// Call a libm helper on a scalar or each lane of a vector.
    pub(crate) fn call_libm(&mut self, f: LibmFn, operands: &[ir::Value]) -> Res<ir::Value> {
        let fref = self.linker.libm_ref(self.b.func, f)?;
        let vec = self.b.func.dfg.value_type(operands[0]).is_vector();
        if !vec {
            let call = self.b.ins().call(fref, operands);
            return Ok(self.b.inst_results(call)[0]);
        }
        Ok(super::value::map_lanes(
            &mut self.b,
            F32X4,
            operands,
            &mut |b, lanes| {
                let call = b.ins().call(fref, lanes);
                b.inst_results(call)[0]
            },
        ))
    }

    pub(crate) fn spaces_base(&self) -> Option<u32> {
        self.layout.spaces
    }

    pub(crate) fn args_ptr(&self) -> ir::Value {
        self.args
    }
}

/// Flag `l` in a per-local table.
fn mark_local(out: &mut [bool], l: LocalId) {
    if let Some(x) = out.get_mut(l.0 as usize) {
        *x = true;
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

/// Whether `index` is a constant within `ty`'s outer fixed dimension (indexing then records
/// no error).
fn const_index_in_range(ty: &Type, index: &Expr) -> bool {
    !ty.per_seq
        && ty
            .dims
            .first()
            .is_some_and(|&n| const_int(index).is_some_and(|k| k >= 0 && k < n as i64))
}

/// Whether evaluating `e` has no effect but its value (no error record, no control flow), so
/// it may run when the language would not evaluate it (tier 0's if-conversion).
fn speculable_expr(e: &Expr) -> bool {
    match &e.kind {
        ExprKind::Const(_) | ExprKind::Local(_) | ExprKind::SeqCount | ExprKind::ClipFlag => true,
        ExprKind::Index { base, index, .. } => const_index_in_range(&base.ty, index) && speculable_expr(base),
        ExprKind::Unary { expr, .. } | ExprKind::Convert(expr) => speculable_expr(expr),
        ExprKind::Binary { lhs, rhs, .. } | ExprKind::MatMul { lhs, rhs } => {
            speculable_expr(lhs) && speculable_expr(rhs)
        }
        ExprKind::Select { cond, then, otherwise } => {
            speculable_expr(cond) && speculable_expr(then) && speculable_expr(otherwise)
        }
        ExprKind::Builtin { args, .. } => args.iter().all(speculable_expr),
        ExprKind::List(items) => items.iter().all(speculable_expr),
        ExprKind::Splat(item) => speculable_expr(item),
    }
}

/// Whether running setup statement `s` can matter to a bound run only through its value:
/// no `bound`, no primitive call, no loop (fuel), no index that may record an error. (An
/// early `return` is fine: the bound already recorded stays.)
fn quiet_stmt(f: &Function, s: &Stmt) -> bool {
    match &s.kind {
        StmtKind::Assign { place, value } => {
            // Each index of the place a constant inside its dimension.
            let Some(local) = f.locals.get(place.local.0 as usize) else {
                return false;
            };
            let mut ty = local.ty.clone();
            let in_range = place.indices.iter().all(|(index, _)| {
                let ok = const_index_in_range(&ty, index);
                if ok {
                    ty = ty.element();
                }
                ok
            });
            in_range && speculable_expr(value)
        }
        StmtKind::If { cond, then, otherwise } => {
            speculable_expr(cond) && then.iter().chain(otherwise).all(|t| quiet_stmt(f, t))
        }
        StmtKind::Return => true,
        _ => false,
    }
}

/// Whether `e` is a constant (or a literal of constants) whose every component has all bits
/// zero (so `-0.0` is not).
fn all_zero_bits(e: &Expr) -> bool {
    match &e.kind {
        ExprKind::Const(ConstValue::Float(f)) => f.to_bits() == 0,
        ExprKind::Const(ConstValue::Int(v) | ConstValue::Fixed(v)) => *v == 0,
        ExprKind::Const(ConstValue::Bool(b)) => !b,
        ExprKind::List(items) => items.iter().all(all_zero_bits),
        ExprKind::Splat(item) => all_zero_bits(item),
        // Every conversion (to interpolation data too: a broadcast) keeps zero bits zero.
        ExprKind::Convert(inner) => all_zero_bits(inner),
        _ => false,
    }
}

fn const_int(e: &Expr) -> Option<i64> {
    match &e.kind {
        ExprKind::Const(ConstValue::Int(i)) => Some(*i as i64),
        ExprKind::Unary { op: UnaryOp::Neg, expr } => const_int(expr).map(|v| -v),
        _ => None,
    }
}

/// An index site: the static length of the array it indexes (`None`: a sequence, or not
/// an array), its index and its site.
type IndexSite<'a> = (Option<u32>, &'a Expr, SiteId);

/// The static length [`Lower::index_access`] checks an index of a `ty` value against.
fn static_len_of(ty: &Type) -> Option<u32> {
    if ty.per_seq {
        None
    } else {
        ty.dims.first().copied()
    }
}

/// Every index site of `stmts` (setup statements of `f`): in places (`a[i] = ...`, the
/// local's type indexed one dimension per site) and in expressions.
fn collect_setup_index_sites<'a>(f: &'a Function, stmts: &'a [Stmt], out: &mut Vec<IndexSite<'a>>) {
    fn expr<'a>(e: &'a Expr, out: &mut Vec<IndexSite<'a>>) {
        if let ExprKind::Index { base, index, site } = &e.kind {
            out.push((static_len_of(&base.ty), index, *site));
        }
        e.for_each_child(|c| expr(c, out));
    }
    for s in stmts {
        match &s.kind {
            StmtKind::Assign { place, value } => {
                if let Some(local) = f.locals.get(place.local.0 as usize) {
                    let mut ty = local.ty.clone();
                    for (index, site) in &place.indices {
                        out.push((static_len_of(&ty), index, *site));
                        expr(index, out);
                        ty = ty.element();
                    }
                }
                expr(value, out);
            }
            StmtKind::If { cond, then, otherwise } => {
                expr(cond, out);
                collect_setup_index_sites(f, then, out);
                collect_setup_index_sites(f, otherwise, out);
            }
            StmtKind::Loop { cond, body, step, .. } => {
                if let Some(c) = cond {
                    expr(c, out);
                }
                collect_setup_index_sites(f, body, out);
                collect_setup_index_sites(f, step, out);
            }
            StmtKind::Interpolation { arms } => arms.iter().for_each(|a| collect_setup_index_sites(f, &a.body, out)),
            StmtKind::InterpolatorReturn(Some(e)) => expr(e, out),
            StmtKind::Bound(args) => args.iter().for_each(|a| expr(a, out)),
            StmtKind::CallPrimitive { args, .. } => args.iter().for_each(|a| expr(a, out)),
            StmtKind::InterpolatorReturn(None) | StmtKind::Break(_) | StmtKind::Continue(_) | StmtKind::Return => {}
        }
    }
}

/// Marks locals indexed with a non-constant index: they live in stack slots.
fn mark_dynamic_stmt(s: &Stmt, dynamic: &mut [bool]) {
    match &s.kind {
        StmtKind::Assign { place, value } => {
            for (i, _) in &place.indices {
                if const_int(i).is_none() {
                    if let Some(d) = dynamic.get_mut(place.local.0 as usize) {
                        *d = true;
                    }
                }
                mark_dynamic_expr(i, dynamic);
            }
            mark_dynamic_expr(value, dynamic);
        }
        StmtKind::If { cond, then, otherwise } => {
            mark_dynamic_expr(cond, dynamic);
            then.iter().chain(otherwise).for_each(|s| mark_dynamic_stmt(s, dynamic));
        }
        StmtKind::Loop { cond, body, step, .. } => {
            if let Some(c) = cond {
                mark_dynamic_expr(c, dynamic);
            }
            body.iter().chain(step).for_each(|s| mark_dynamic_stmt(s, dynamic));
        }
        StmtKind::Interpolation { arms } => {
            arms.iter()
                .flat_map(|a| a.body.iter())
                .for_each(|s| mark_dynamic_stmt(s, dynamic));
        }
        StmtKind::InterpolatorReturn(Some(e)) => mark_dynamic_expr(e, dynamic),
        StmtKind::Bound(es) => es.iter().for_each(|e| mark_dynamic_expr(e, dynamic)),
        StmtKind::CallPrimitive { args, .. } => args.iter().for_each(|e| mark_dynamic_expr(e, dynamic)),
        StmtKind::Break(_) | StmtKind::Continue(_) | StmtKind::Return | StmtKind::InterpolatorReturn(None) => {}
    }
}

fn mark_dynamic_expr(e: &Expr, dynamic: &mut [bool]) {
    if let ExprKind::Index { base, index, .. } = &e.kind {
        if const_int(index).is_none() {
            if let Some(d) = root_local(base).and_then(|l| dynamic.get_mut(l.0 as usize)) {
                *d = true;
            }
        }
    }
    e.for_each_child(|c| mark_dynamic_expr(c, dynamic));
}

fn root_local(e: &Expr) -> Option<LocalId> {
    match &e.kind {
        ExprKind::Local(l) => Some(*l),
        ExprKind::Index { base, .. } => root_local(base),
        _ => None,
    }
}

/// The value of a condition fixed by the variant key: `clipping()` or `!clipping()`.
fn key_constant(cond: &Expr, key: &VariantKey) -> Option<bool> {
    match &cond.kind {
        ExprKind::ClipFlag => Some(!key.trivial_accept),
        ExprKind::Unary {
            op: crate::ir::UnaryOp::Not,
            expr,
        } => key_constant(expr, key).map(|v| !v),
        _ => None,
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
