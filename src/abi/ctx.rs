//! The calling convention of a kernel: the variant key, the per-tile context
//! a kernel reads and writes, and the layout of a primitive instance's argument block.
//!
//! A kernel is `extern "C" fn(ctx: *mut TileCtx, args: *const u32)`. It touches only the
//! memory these two point at: the argument block (read-only, `ArgLayout::words` long for the
//! instance's sequence-point count) and the tile's part of the buffers the context names.
//! Pixel (x, y) of the tile is element `(y - y0) * stride + (x - x0)` from a buffer pointer
//! (and from each plane's start, `plane_stride` elements apart); pixel groups are `GROUP`
//! pixels of one row starting at `x0`, so the addressable elements are, for every row
//! `y0..y1`, the columns from `x0` to `x1` rounded up to whole groups. The runtime points
//! the buffers at the frame's own, at the tile's origin, with the frame's row stride: it
//! keeps `x0` and `stride` multiples of `GROUP` and pads the frame's rows, so a group never
//! straddles a row, two tiles never share a group, and a tile's last group (at a ragged
//! right edge) stays inside the padded row (`runtime::frame`).
//!
//! Limits: loops spend *fuel* and failures are *counted*, both deterministically, so that a
//! frame is the same bit for bit, and reports the same warnings, whatever the number of
//! threads and the tile size.
//! - Setup fuel ([`TileCtx::fuel`]): every visit of a loop head in setup code spends one
//!   unit; the setup of one invocation and the setups of the primitives it calls directly
//!   share `fuel` units (`DEFAULT_FUEL`). The loop head that finds none records `ERR_FUEL`
//!   at its loop and ends the invocation, and the invocations that called it end after
//!   the call, with `fuel` holding `-(2 + site)` (as an `i64`) of that loop
//!   ([`setup_fuel_ran_out`]); kernels do not count this error, the runner does from
//!   `fuel`. Setup code does not depend on the tile, so every invocation of one draw (its
//!   bound run and its render run in each tile) spends the same fuel and runs out, if at
//!   all, at the same loop; the runtime draws nothing of a draw whose bound run ran out
//!   (`runtime::expand`).
//! - Pixel fuel: before its pixel loops a kernel gives every pixel group
//!   `max(group_fuel_floor, pixel_fuel / groups)` units ([`TileCtx::group_fuel`]), where
//!   `groups` is the number of pixel groups of its bound rectangle in the viewport (rows
//!   times the group columns it touches, at least 1): the same in every tile. Each group
//!   starts with that many; its loops (varying or uniform) spend one unit per visit of a
//!   loop head. A group is never split between tiles, so what it computes does not depend
//!   on the tiling either. A draw's pixel loops spend at most
//!   `max(pixel_fuel, groups * group_fuel_floor)` units in all.
//!   A pixel group's loop head that finds none (0) records and counts `ERR_FUEL` at its
//!   loop, marks the group's fuel spent (-1) and leaves the loop (as `break` would, for
//!   every lane); later loop heads of the same group find it spent and leave too,
//!   recording nothing. Kernels take fuel as a signed count, so a budget must be at most
//!   `i64::MAX` (the runtime caps its options).
//! - Error counts: besides the first error (`error`, `error_site`), every run-time error
//!   but a setup loop out of fuel is counted, once per execution of the failing operation,
//!   at its [`ErrorSlot`] in `setup_counts` (setup code and what a kernel does before its
//!   setup: the stack check) or `pixel_counts` (pixel code, where one execution covers one
//!   pixel group). Both point at `count_slots(program)` `u64`s (wrapping adds).
//!
//! A third mode, `MODE_EXPAND`, serves primitives that only call other primitives (no pixel
//! code of their own, [`expands`]): the runtime runs such an instance once, its calls are
//! handed to `TileCtx::expand` instead of being made, and the recorded calls are bound,
//! binned and rendered as instances of their own (see `runtime::expand`).

use crate::ir::{for_each_stmt, Elem, FuncId, FuncKind, Function, ParamRole, Program, SiteId, StmtKind, Type};

/// Pixels per group: one f32x4 per varying value.
pub const GROUP: u32 = 4;

/// Kernel mode: only record bounds (run setup, skip pixel passes).
pub const MODE_BOUND: u32 = 0;
/// Kernel mode: render the pixels of the tile.
pub const MODE_RENDER: u32 = 1;
/// Kernel mode: run the setup once and record every primitive call it makes through
/// `TileCtx::expand` instead of making it (the tile is empty; no pixel is touched). Only run
/// on primitives for which [`expands`] holds.
pub const MODE_EXPAND: u32 = 2;

/// Run-time error codes a kernel can record (the first one wins in `TileCtx::error`; every
/// one is counted at its [`ErrorSlot`]).
pub const ERR_NONE: u32 = 0;
pub const ERR_INDEX: u32 = 1;
pub const ERR_FUEL: u32 = 2;
pub const ERR_CALL_DEPTH: u32 = 3;
/// The kernel's stack frame reached below `TileCtx::stack_limit`; its `error_site` is the
/// kernel's `FuncId` (not a `SiteId`), and the kernel returned without running.
pub const ERR_STACK: u32 = 4;

/// One tile's state, handed to every kernel invocation for that tile.
#[repr(C)]
#[derive(Debug)]
pub struct TileCtx {
    /// Tile rectangle in screen pixels: x0, y0 inclusive, x1, y1 exclusive.
    pub x0: i32,
    pub y0: i32,
    pub x1: i32,
    pub y1: i32,
    /// `MODE_BOUND` or `MODE_RENDER`.
    pub mode: u32,
    /// Row stride of every buffer, in pixels (a multiple of `GROUP`).
    pub stride: u32,
    /// Depth buffer at pixel (x0, y0), `fixed<32,32>` raw (unsigned fraction, larger is
    /// nearer), row-major.
    pub depth: *mut u32,
    /// Shading-parameter plane 0 at pixel (x0, y0); plane `p` starts `p * plane_stride`
    /// floats further, `num_planes` planes, each laid out like `depth`.
    pub gbuf: *mut f32,
    pub plane_stride: u32,
    pub num_planes: u32,
    /// Per-pixel count of depth writes at pixel (x0, y0), laid out like `depth` (only
    /// touched by kernels whose key counts writes; otherwise it points at nothing valid).
    pub write_count: *mut u32,
    /// In bound mode: union of the bounds recorded so far (xmin, ymin, xmax, ymax).
    pub bound: [f32; 4],
    /// Non-zero once `bound` holds something.
    pub bound_set: u32,
    /// First run-time error (`ERR_*`) and the `SiteId` it happened at.
    pub error: u32,
    pub error_site: u32,
    /// Setup fuel left: loop-head visits the setup code of this invocation, and of the
    /// primitives it calls directly, may still make (the pixel part has its own, see
    /// `group_fuel`); once a setup loop found none, `-(2 + site)` of that loop
    /// ([`setup_fuel_ran_out`]).
    pub fuel: u64,
    /// Depth of nested primitive calls (a call deeper than `MAX_CALL_DEPTH` is an error).
    pub call_depth: u32,
    /// Viewport size in pixels (bounds are clamped to it).
    pub width: u32,
    pub height: u32,
    /// In `MODE_EXPAND`: where a primitive call goes instead of to the callee (after the
    /// call-depth check, with `call_depth` already the callee's). `None` in the other modes;
    /// a call in `MODE_EXPAND` with `None` here is dropped.
    pub expand: Option<ExpandFn>,
    /// The recorder `expand` writes to (opaque to kernels; null outside `MODE_EXPAND`).
    pub expand_state: *mut std::ffi::c_void,
    /// The lowest address a kernel's stack frame may reach on the thread that runs it
    /// ([`thread_stack_limit`]). Every compiled kernel compares its stack pointer, after its
    /// prologue has reserved the frame and before anything is stored in it, with this and
    /// records `ERR_STACK` instead of running when the frame reaches below: a primitive's
    /// local arrays (up to 65536 floats each, any number of them, calls nested 16 deep) can
    /// outgrow any thread's stack, and without the check the frame would overrun it.
    pub stack_limit: usize,
    /// Error counts of setup code and of pixel code: `count_slots(program)` `u64`s each
    /// (they may be the same array), indexed by [`ErrorSlot::index`]. A kernel adds to
    /// them with wrapping adds (a kernel compiled at tier 0 also adds 0 where nothing
    /// failed, so both must point at memory it may write whenever it runs). Null in a
    /// context from [`TileCtx::new`]: set both before running a kernel.
    pub setup_counts: *mut u64,
    pub pixel_counts: *mut u64,
    /// The pixel fuel of this draw (`DEFAULT_PIXEL_FUEL`): shared out over the pixel groups
    /// of the kernel's bound rectangle, at least `group_fuel_floor` a group (see the module
    /// doc). Read by kernels, never written.
    pub pixel_fuel: u64,
    pub group_fuel_floor: u64,
    /// Written by a kernel whose pixel part has loops, before its pixel loops: the fuel each
    /// of its pixel groups starts with (`max(group_fuel_floor, pixel_fuel / groups)`).
    pub group_fuel: u64,
    /// Where in its pixel the pixel code evaluates: the sample's position relative to the
    /// pixel's top-left corner, in [0, 1) each way (0.5, 0.5 is the centre, where a
    /// single-sample frame evaluates). Pixel (x, y)'s `X` is `x + sample_x` and its `Y`
    /// `y + sample_y`; a multisampled frame renders each sample with its own
    /// (`runtime::samples`). Read by kernels, never written.
    pub sample_x: f32,
    pub sample_y: f32,
}

impl TileCtx {
    /// A context for a `width` x `height` viewport in `mode` with no tile yet: an empty
    /// rectangle, null buffers, no bound, no error, full `DEFAULT_FUEL` and the default
    /// pixel fuel, call depth 0, no expansion recorder, no error counts (null: set them).
    /// Bound and expand runs use it with counts; a render run first names its tile and
    /// buffers (`TileCtx { x0, .., ..TileCtx::new(MODE_RENDER, w, h) }`).
    pub fn new(mode: u32, width: u32, height: u32) -> TileCtx {
        TileCtx {
            x0: 0,
            y0: 0,
            x1: 0,
            y1: 0,
            mode,
            stride: GROUP,
            depth: std::ptr::null_mut(),
            gbuf: std::ptr::null_mut(),
            plane_stride: 0,
            num_planes: 0,
            write_count: std::ptr::null_mut(),
            bound: [0.0; 4],
            bound_set: 0,
            error: 0,
            error_site: 0,
            fuel: DEFAULT_FUEL,
            call_depth: 0,
            width,
            height,
            expand: None,
            expand_state: std::ptr::null_mut(),
            stack_limit: thread_stack_limit(),
            setup_counts: std::ptr::null_mut(),
            pixel_counts: std::ptr::null_mut(),
            pixel_fuel: DEFAULT_PIXEL_FUEL,
            group_fuel_floor: DEFAULT_GROUP_FUEL_FLOOR,
            group_fuel: 0,
            sample_x: 0.5,
            sample_y: 0.5,
        }
    }
}

/// The loop whose setup ran out of fuel in a run that left `fuel` in `TileCtx::fuel`, if
/// one did (see the module doc).
pub fn setup_fuel_ran_out(fuel: u64) -> Option<SiteId> {
    let fuel = fuel as i64;
    (fuel <= -2).then(|| SiteId((-(fuel + 2)) as u32))
}

/// Where a run-time error is counted (`TileCtx::setup_counts`, `TileCtx::pixel_counts`):
/// index 0 counts calls a hand-written kernel skipped for depth (its calls have no source
/// site); at a `SiteId`, `1 + 3 * site` counts index errors, `2 + 3 * site` loops out of
/// fuel and `3 + 3 * site` calls skipped for depth; `1 + 3 * sites + func` counts stack
/// errors of a function's kernel (`sites`: `Program::sites.len()`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum ErrorSlot {
    CallDepth(Option<SiteId>),
    Index(SiteId),
    Fuel(SiteId),
    Stack(FuncId),
}

impl ErrorSlot {
    /// The slot of error `code` recorded with `site` (a `SiteId`, or for `ERR_STACK` a
    /// `FuncId`; `u32::MAX` for a hand-written kernel's call); `None` for an unknown code.
    pub fn of(code: u32, site: u32) -> Option<ErrorSlot> {
        match code {
            ERR_INDEX => Some(ErrorSlot::Index(SiteId(site))),
            ERR_FUEL => Some(ErrorSlot::Fuel(SiteId(site))),
            ERR_CALL_DEPTH => Some(ErrorSlot::CallDepth((site != u32::MAX).then_some(SiteId(site)))),
            ERR_STACK => Some(ErrorSlot::Stack(FuncId(site))),
            _ => None,
        }
    }

    /// The error code counted here.
    pub fn code(self) -> u32 {
        match self {
            ErrorSlot::CallDepth(_) => ERR_CALL_DEPTH,
            ErrorSlot::Index(_) => ERR_INDEX,
            ErrorSlot::Fuel(_) => ERR_FUEL,
            ErrorSlot::Stack(_) => ERR_STACK,
        }
    }

    /// Its index in a count array of a program with `sites` sites.
    pub fn index(self, sites: usize) -> usize {
        match self {
            ErrorSlot::CallDepth(None) => 0,
            ErrorSlot::Index(s) => 1 + 3 * s.0 as usize,
            ErrorSlot::Fuel(s) => 2 + 3 * s.0 as usize,
            ErrorSlot::CallDepth(Some(s)) => 3 + 3 * s.0 as usize,
            ErrorSlot::Stack(f) => 1 + 3 * sites + f.0 as usize,
        }
    }

    /// The slot at `index` of a count array of a program with `sites` sites.
    pub fn at(index: usize, sites: usize) -> ErrorSlot {
        match index {
            0 => ErrorSlot::CallDepth(None),
            i if i <= 3 * sites => {
                let site = SiteId(((i - 1) / 3) as u32);
                match (i - 1) % 3 {
                    0 => ErrorSlot::Index(site),
                    1 => ErrorSlot::Fuel(site),
                    _ => ErrorSlot::CallDepth(Some(site)),
                }
            }
            i => ErrorSlot::Stack(FuncId((i - 1 - 3 * sites) as u32)),
        }
    }
}

/// Length of the error count arrays of `program`'s kernels: one slot per [`ErrorSlot`].
pub fn count_slots(program: &Program) -> usize {
    1 + 3 * program.sites.len() + program.functions.len()
}

/// Zeroed error counts for running `program`'s kernels: hand [`ErrorCounts::ptr`] to a
/// context as both `setup_counts` and `pixel_counts`, read them back with
/// [`ErrorCounts::take`].
#[derive(Clone, Debug)]
pub struct ErrorCounts {
    counts: Vec<u64>,
    sites: usize,
}

impl ErrorCounts {
    pub fn new(program: &Program) -> ErrorCounts {
        ErrorCounts {
            counts: vec![0; count_slots(program)],
            sites: program.sites.len(),
        }
    }

    pub fn ptr(&mut self) -> *mut u64 {
        self.counts.as_mut_ptr()
    }

    /// The counts that are not zero, in slot order, each reset to zero.
    pub fn take(&mut self) -> Vec<(ErrorSlot, u64)> {
        let sites = self.sites;
        self.counts
            .iter_mut()
            .enumerate()
            .filter(|(_, n)| **n != 0)
            .map(|(i, n)| (ErrorSlot::at(i, sites), std::mem::take(n)))
            .collect()
    }
}

/// Stack kept below the limit: for what kernels call that does not check (libm, the
/// runtime's call recorder), signal handlers, and the register spills a kernel may store
/// before its check (Cranelift places spill slots above the explicit ones, at the top of
/// the frame, so they land here only if the spill area itself outgrows the reserve).
const STACK_RESERVE: usize = 64 << 10;

/// The calling thread's [`TileCtx::stack_limit`]: the low end of its stack plus
/// `STACK_RESERVE`. A context must be used on the thread that made it (the runtime makes
/// one per tile task, bound run and expansion).
pub fn thread_stack_limit() -> usize {
    thread_local! {
        static LIMIT: std::cell::Cell<usize> = const { std::cell::Cell::new(0) };
    }
    LIMIT.with(|limit| {
        if limit.get() == 0 {
            limit.set(stack_low_end().saturating_add(STACK_RESERVE));
        }
        limit.get()
    })
}

/// The lowest address of the calling thread's stack, from pthread (glibc reads the main
/// thread's from its mapping and its rlimit, a spawned thread's from its attributes).
#[cfg(target_os = "linux")]
fn stack_low_end() -> usize {
    // SAFETY: `attr` is initialised by pthread_getattr_np before it is read and destroyed
    // once; `addr` and `size` are plain out-parameters.
    unsafe {
        let mut attr: libc::pthread_attr_t = std::mem::zeroed();
        if libc::pthread_getattr_np(libc::pthread_self(), &mut attr) != 0 {
            return stack_low_end_guess();
        }
        let mut addr: *mut libc::c_void = std::ptr::null_mut();
        let mut size: libc::size_t = 0;
        let ok = libc::pthread_attr_getstack(&attr, &mut addr, &mut size) == 0;
        libc::pthread_attr_destroy(&mut attr);
        if ok && !addr.is_null() {
            addr as usize
        } else {
            stack_low_end_guess()
        }
    }
}

#[cfg(not(target_os = "linux"))]
fn stack_low_end() -> usize {
    stack_low_end_guess()
}

/// Without the thread's attributes: assume 512 KiB below the current frame (a thread's
/// stack is at least 2 MiB where Rust spawns it, and this runs near its top).
fn stack_low_end_guess() -> usize {
    let here = 0u8;
    (std::ptr::addr_of!(here) as usize).saturating_sub(512 << 10)
}

pub const MAX_CALL_DEPTH: u32 = 16;
/// Setup fuel of one invocation (`TileCtx::fuel`): under a second of an endless setup
/// loop, which runs in a draw's bound run only (see the module doc).
pub const DEFAULT_FUEL: u64 = 1 << 28;
/// Pixel fuel of one draw (`TileCtx::pixel_fuel`): a second or two of one core's time in an
/// endless pixel loop, at any image size up to `2^29 / DEFAULT_GROUP_FUEL_FLOOR` groups
/// (2 Mpixels); larger bound rectangles get the floor per group.
pub const DEFAULT_PIXEL_FUEL: u64 = 1 << 29;
/// The least fuel a pixel group gets (`TileCtx::group_fuel_floor`): a per-pixel loop of up
/// to ~1000 iterations never runs out, whatever the image size.
pub const DEFAULT_GROUP_FUEL_FLOOR: u64 = 1 << 10;

/// The signature of every compiled kernel.
pub type KernelFn = unsafe extern "C" fn(ctx: *mut TileCtx, args: *const u32);

/// `FuncId` value a native (hand-written) kernel passes to [`ExpandFn`] when it does not
/// know the callee's function: the call is then rendered as it is, never expanded further.
pub const CALLEE_UNKNOWN: u32 = u32::MAX;

/// Records one primitive call made in `MODE_EXPAND`: `ctx` the caller's context (its
/// `call_depth` is the callee's), `callee` the callee's `FuncId` (or [`CALLEE_UNKNOWN`]),
/// `entry` the callee's kernel for the caller's key, `args` the argument block the call
/// built, `words` long (`ArgLayout::words` of the callee for the block's word 0). The
/// callee is not run; the recorder copies the block before it returns.
pub type ExpandFn =
    unsafe extern "C" fn(ctx: *mut TileCtx, callee: u32, entry: Option<KernelFn>, args: *const u32, words: u32);

/// Whether the runtime expands instances of `func`: a primitive with no pixel part of its own
/// whose setup calls primitives. Everything such a primitive draws, it draws through its
/// calls, so running it once in `MODE_EXPAND` and rendering the recorded calls in its place
/// (in call order) draws the same pixels as running it in every tile. An unknown id is
/// `false`.
pub fn expands(program: &Program, func: FuncId) -> bool {
    fn calls(f: &Function) -> bool {
        let mut found = false;
        for_each_stmt(&f.stmts, &f.setup, &mut |_, s| {
            found |= matches!(s, StmtKind::CallPrimitive { .. })
        });
        found
    }
    program
        .functions
        .get(func.0 as usize)
        .is_some_and(|f| f.kind == FuncKind::Primitive && f.pixel.is_empty() && calls(f))
}

/// What a native kernel does where its primitive's source calls another primitive, as the
/// JIT's call does: bump `call_depth` (past `MAX_CALL_DEPTH` the call is skipped, and
/// `ERR_CALL_DEPTH` recorded and counted in `setup_counts`), then in `MODE_EXPAND` hand the call to `ctx.expand` (as
/// [`CALLEE_UNKNOWN`]: rendered as recorded), in the other modes run `entry` on `args`.
///
/// # Safety
/// `ctx` is a valid context the caller owns for the call, and `args` a complete argument
/// block of `entry`'s primitive under the caller's key.
pub unsafe fn call_primitive(ctx: *mut TileCtx, entry: KernelFn, args: &[u32]) {
    // SAFETY: the caller's contract.
    let c = unsafe { &mut *ctx };
    let depth = c.call_depth.wrapping_add(1);
    c.call_depth = depth;
    if depth > MAX_CALL_DEPTH {
        if c.error == ERR_NONE {
            c.error = ERR_CALL_DEPTH;
            c.error_site = u32::MAX;
        }
        if !c.setup_counts.is_null() {
            let at = ErrorSlot::CallDepth(None).index(0);
            // SAFETY: the context's counts hold every slot of the program (`TileCtx`), and
            // a hand-written kernel's call-depth slot is the first.
            unsafe { *c.setup_counts.add(at) = (*c.setup_counts.add(at)).wrapping_add(1) };
        }
    } else if c.mode == MODE_EXPAND {
        if let Some(record) = c.expand {
            // SAFETY: `record` is the runtime's recorder for this context; `args` is
            // `args.len()` words long.
            unsafe { record(ctx, CALLEE_UNKNOWN, Some(entry), args.as_ptr(), args.len() as u32) };
        }
    } else {
        // SAFETY: the caller's contract.
        unsafe { entry(ctx, args.as_ptr()) };
    }
    // SAFETY: as above (`c` is not used across the calls, which may write the context).
    let c = unsafe { &mut *ctx };
    c.call_depth = c.call_depth.wrapping_sub(1);
}

/// How one shading parameter of a primitive instance gets its value.
#[derive(Clone, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum BindingKind {
    /// A per-sequence-point kind handled by the primitive's `interpolation` arms:
    /// `linear`, `perspective_linear`, or any other kind name a primitive defines.
    Kind(String),
    /// A shared interpolator (by name), evaluated by `default: interpolator_return;`.
    Shared(String),
    /// One value for the whole primitive, written by `default: interpolator_return;`.
    Constant,
}

#[derive(Clone, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Binding {
    pub kind: BindingKind,
    /// Float components of the parameter (1 for float, 3 for color, ...).
    pub components: u32,
}

/// Everything about a scene that changes a primitive's code. A kernel is compiled once per
/// (primitive, key) and reused for every instance with that key.
#[derive(Clone, Debug, Default, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct VariantKey {
    /// The instance's shading parameters in order. The interpolation-data components are
    /// the `Kind` bindings' components, concatenated in this order.
    pub bindings: Vec<Binding>,
    /// Count depth writes per pixel in `TileCtx::write_count` (tests and tools).
    pub count_writes: bool,
    /// The instance was trivially accepted by the geometry pipeline (seed 002: the OR of its
    /// clip codes, after the runtime's own clipping, has no near-plane bit): the language's
    /// `clipping()` is constant `false` and the kernel is compiled without the clip path.
    /// `false` (the default) keeps the clipping code, which is always correct.
    pub trivial_accept: bool,
}

impl VariantKey {
    /// Total per-sequence-point (interpolation data) components.
    pub fn interp_components(&self) -> u32 {
        self.bindings
            .iter()
            .filter(|b| matches!(b.kind, BindingKind::Kind(_)))
            .map(|b| b.components)
            .sum()
    }
    /// Indices (into the interpolation data) of the components of kind `kind`.
    pub fn components_of_kind(&self, kind: &str) -> Vec<u32> {
        let mut out = vec![];
        let mut at = 0;
        for b in &self.bindings {
            if let BindingKind::Kind(k) = &b.kind {
                if k == kind {
                    out.extend(at..at + b.components);
                }
                at += b.components;
            }
        }
        out
    }
    /// Total components of all bindings (= entries of the plane table).
    pub fn total_components(&self) -> u32 {
        self.bindings.iter().map(|b| b.components).sum()
    }
}

/// Where each part of a primitive instance's argument block lives, in 32-bit words.
///
/// ```text
/// word 0                  n_seq (number of sequence points; the runtime passes at least 1
///                         element for every per-sequence-point parameter, zero-filled)
/// plane_table             one G-buffer plane index per binding component, binding order
/// binding_data[b]         Constant: its components; Shared: the interpolator's
///                         per-primitive parameters (flattened, declaration order)
/// spaces                  if the primitive uses transform(): 6 matrices of 16 floats,
///                         row-major: device_from_object, device_from_world,
///                         device_from_lighting, object_from_device, world_from_device,
///                         lighting_from_device
/// params[i]               each PerPrimitive / InterpData (sized) parameter, flattened
/// --- then, at run-time offsets ---
/// seq params              each PerSequencePoint parameter (and a per-seq InterpData):
///                         max(n_seq,1) * element words, in declaration order
/// ```
/// Floats are f32 bits, ints i32, bools 0/1, fixed values their raw bits; an
/// interpolation_data element is `interp_components` floats.
#[derive(Clone, Debug, PartialEq)]
pub struct ArgLayout {
    pub plane_table: u32,
    /// Offset of each binding's data (`None` for `Kind` bindings, which have none).
    pub binding_data: Vec<Option<u32>>,
    pub spaces: Option<u32>,
    /// For each parameter of the function (by index): where it lives.
    pub params: Vec<ParamSlot>,
    /// Words before the per-sequence-point part.
    pub fixed_words: u32,
    /// Words per sequence point over all per-sequence-point parameters.
    pub seq_words: u32,
}

#[derive(Clone, Debug, PartialEq)]
pub enum ParamSlot {
    /// X, Y or Z: bound from the pixel, not stored.
    Pixel,
    /// At a fixed word offset, `words` long.
    Fixed { offset: u32, words: u32 },
    /// Per sequence point: starts at `fixed_words + max(n_seq,1) * seq_offset`,
    /// `words` per element.
    Seq { seq_offset: u32, words: u32 },
}

/// Words one value of type `ty` takes (per-sequence-point dimension excluded).
pub fn type_words(ty: &Type, interp_components: u32) -> u32 {
    let per = match ty.elem {
        Elem::Scalar(_) => 1,
        Elem::Interp => interp_components,
    };
    per * ty.fixed_len()
}

impl ArgLayout {
    /// The layout of `func`'s arguments under `key`. Shared interpolators named by the key
    /// are looked up in `program`; an unknown one takes no words (the runtime rejects such
    /// a key before it gets here).
    pub fn new(program: &Program, func: FuncId, key: &VariantKey) -> ArgLayout {
        let f = program.func(func);
        let n_interp = key.interp_components();
        let mut at = 1u32;
        let plane_table = at;
        at += key.total_components();
        let mut binding_data = vec![];
        for b in &key.bindings {
            match &b.kind {
                BindingKind::Kind(_) => binding_data.push(None),
                BindingKind::Constant => {
                    binding_data.push(Some(at));
                    at += b.components;
                }
                BindingKind::Shared(name) => {
                    binding_data.push(Some(at));
                    if let Some(id) = program.find(name) {
                        at += interpolator_arg_words(program, id);
                    }
                }
            }
        }
        let spaces = if f.uses_spaces {
            let s = at;
            at += 6 * 16;
            Some(s)
        } else {
            None
        };
        let mut params = vec![];
        let mut seq_words = 0;
        for p in &f.params {
            let ty = &f.local(p.local).ty;
            let words = type_words(ty, n_interp);
            params.push(match p.role {
                ParamRole::X | ParamRole::Y | ParamRole::Z => ParamSlot::Pixel,
                _ if ty.per_seq => {
                    let s = ParamSlot::Seq {
                        seq_offset: seq_words,
                        words,
                    };
                    seq_words += words;
                    s
                }
                _ => {
                    let s = ParamSlot::Fixed { offset: at, words };
                    at += words;
                    s
                }
            });
        }
        ArgLayout {
            plane_table,
            binding_data,
            spaces,
            params,
            fixed_words: at,
            seq_words,
        }
    }

    /// Total words for an instance with `n_seq` sequence points.
    pub fn words(&self, n_seq: u32) -> usize {
        self.fixed_words as usize + n_seq.max(1) as usize * self.seq_words as usize
    }
}

/// Words of a shared interpolator's per-primitive parameters (X, Y, Z excluded).
pub fn interpolator_arg_words(program: &Program, id: FuncId) -> u32 {
    let f = program.func(id);
    f.params
        .iter()
        .filter(|p| !matches!(p.role, ParamRole::X | ParamRole::Y | ParamRole::Z))
        .map(|p| type_words(&f.local(p.local).ty, 0))
        .sum()
}
