//! A reference evaluator of the checked IR: what a kernel compiled from a [`Function`] for
//! a [`VariantKey`] does to a tile, computed by walking the IR instead of compiling it. It
//! is the JIT's differential oracle (`tests/jit/eval_oracle.rs`, `eval_generated.rs`): on
//! the same program, key, argument block and tile, tier 1 and [`Evaluator::run`] leave the
//! same depths, G-buffer planes, depth-write counts, run-time error counts and setup fuel,
//! and tier 0 too but where noted below.
//!
//! What it computes is what a kernel does in `MODE_RENDER` (`abi::ctx`), from the
//! primitive's body as the JIT lowers it ([`Evaluator::new`]: copies forwarded,
//! constant-trip loops unrolled, which then spend no fuel): the setup part once, with the
//! setup fuel; then, unless the setup returned or ran out of fuel, the pixel part for every
//! 4-pixel group of the pass rectangle (the last executed `bound`, clipped to the tile;
//! groups start at tile-aligned x), each group from the state the setup left, with its own
//! pixel fuel. Primitive calls are made directly (as `MODE_RENDER` makes them, not
//! recorded as `MODE_EXPAND` would), on the same tile, with the caller's key, sharing the
//! setup fuel and nesting at most `MAX_CALL_DEPTH` deep. Shared interpolators run where the
//! JIT inlines them (`interpolator_return;`), for the executing lanes. `MODE_BOUND` and
//! `MODE_EXPAND` runs are not modelled.
//!
//! It computes floats in one of two precisions ([`Precision`], [`Evaluator::with_precision`]):
//! - `F32` ([`Evaluator::new`]): the JIT's oracle, bit for bit, as the rest of this doc
//!   describes.
//! - `F64`: the f64 reference the f32 kernels' shading is measured against. Every float
//!   value is an f64 in each lane and every float operation is done in f64, in the order
//!   the JIT does it in f32: arithmetic, comparisons, conversions between float and int,
//!   fixed or bool, the component-wise built-ins, the transcendental functions (Rust's f64
//!   ones; `pow` is `powf` for every exponent), the vector built-ins, the space transforms,
//!   `faceforward`/`reflect`/`refract`, `Dx`/`Dy`/`filterwidth`, the pixel centres X and Y.
//!   Ints, bools and fixed values are computed as in `F32`. Control flow, masks, fuel and
//!   errors follow the f64 values (a comparison that goes the other way in f32 takes the
//!   other branch). F64 meets f32 only where the program's data is f32 in both modes:
//!   - float constants of the IR are f32 (the checker rounds literals, `PI` and constant
//!     conversions to f32); they are widened;
//!   - the argument block's floats (parameters, constant bindings, the space matrices) are
//!     f32 words; they are widened. A primitive call passes its float arguments exactly:
//!     the callee's block holds them rounded to f32, as the JIT's would, and the evaluator
//!     reads the f64 value it keeps beside the word (`args`);
//!   - the G-buffer planes stay f32 ([`Tile::planes`]): a `__gbuffer` read widens the
//!     plane's value, every store (`interpolator_return`, constant bindings) rounds to f32;
//!   - the depth buffer stays `fixed<32,32>`: Z is converted to it from its f64 value (the
//!     f64 product with 2^32, rounded to even and saturated), a Z read from it is the raw
//!     value in f64 (exact);
//!   - `noise`/`cellnoise` and `texture` are defined by their f32 implementations
//!     (`jit::libm`, the texture sampler): they take their operands rounded to f32 and
//!     their result is widened;
//!   - [`Outcome::bound`] is the last bound rounded to f32; the pass rectangle is computed
//!     from the f64 bound, in f64.
//!
//! Invariants:
//! - *Bit-exact values (F32).* Every component is a 32-bit word per lane (f32 bits, i32,
//!   bool 0/1, fixed raw), held zero-extended in a 64-bit lane word (`precision`); the
//!   arithmetic in `scalar` is the JIT's instruction for instruction (f32 operations in the
//!   same order, fixed point in the same 64-bit intermediates, the same saturations, the
//!   libm functions kernels call). NaN payloads are the one thing a caller should not
//!   compare: Rust and Cranelift agree on which results are NaN, not on which NaN.
//! - *The JIT's lanes.* The pixel part runs on groups of 4 lanes under the masks tier 1
//!   keeps (`alive`, `exec`, a mask and a continue mask per varying loop, the lanes that
//!   assigned Z), with the same early exits: a varying `if` skips a side no lane takes, a
//!   varying loop ends when its mask is empty, a group ends when no lane is alive. Uniform
//!   values are computed in every lane (they are equal there). So fuel is spent per group
//!   exactly as the JIT spends it, and an error is counted once per execution of the
//!   failing operation per group.
//! - *Errors.* An index out of range reads the nearest end and counts `ERR_INDEX` at its
//!   site, as the JIT checks it: a varying index when an executing lane is out of range, a
//!   uniform one of pixel code when some lane executes it (a group counts an access that
//!   fails in any of its pixels; after a varying `break`, `continue` or `return` left no
//!   lane executing, the rest of the statement list still runs and fails for none), of
//!   setup code whenever its statement runs; under the guards of the expression (the arms
//!   of `?:` and the right side of `&&`/`||` count only where taken: a varying guard
//!   needs some lane taking it). A loop head with no fuel left counts `ERR_FUEL` (setup:
//!   records it and ends the run and its callers' runs, uncounted, with `-(2 + site)` left
//!   as fuel); a call too deep counts `ERR_CALL_DEPTH`. Setup code counts into
//!   [`Outcome::setup_counts`], pixel code into [`Outcome::pixel_counts`].
//! - *No panic, no overflow, no hang.* Malformed IR or a short argument block is an
//!   [`EvalError`], never a panic; [`Evaluator::run`] evaluates on a thread of its own
//!   with a large stack and refuses nesting past [`MAX_NESTING`] levels (a checked
//!   program, within `crate::limits`, stays far below); every loop spends fuel.
//!
//! Where it differs from the JIT:
//! - In F64, every float result, and what follows from it (above).
//! - `ERR_STACK` is never recorded: locals do not live on the native stack here.
//! - [`Outcome::first_error`] is the first error in this evaluator's order: setup first,
//!   then groups row by row. The JIT's block walk visits groups in another order, so only a
//!   setup's first error is comparable.

mod args;
mod derivative;
mod expr;
pub mod observe;
mod precision;
pub mod scalar;
mod shading;
mod stmt;

pub use observe::{Event, Observer};
pub use precision::Precision;

use std::rc::Rc;

use crate::abi::{
    count_slots, ArgLayout, BindingKind, ErrorSlot, ParamSlot, VariantKey, DEFAULT_FUEL, DEFAULT_GROUP_FUEL_FLOOR,
    DEFAULT_PIXEL_FUEL, GROUP,
};
use crate::ir::{for_each_assign, FuncId, FuncKind, Function, ParamRole, Program};
use args::ArgBlock;
use observe::Watch;
use precision::{in_precision, Float};

/// Recursion levels (statements, expressions, calls together) [`Evaluator::run`] evaluates before it
/// refuses with [`EvalError::Unsupported`]: a checked program nests at most ~1100 levels per
/// primitive (`crate::limits`), 17 primitives deep.
pub const MAX_NESTING: usize = 1 << 15;

/// Stack of the thread [`Evaluator::run`] evaluates on: [`MAX_NESTING`] levels of at most ~2 KiB.
const EVAL_STACK: usize = 128 << 20;

/// One component per lane, as lane words: a float of the run's precision, or a 32-bit word
/// (i32, bool 0/1, fixed raw) zero-extended (`precision`).
pub(crate) type Lanes = [u64; 4];
/// Which of a group's 4 lanes a mask holds.
pub(crate) type Mask = [bool; 4];

const NONE: Mask = [false; 4];
const ALL: Mask = [true; 4];

fn any(m: Mask) -> bool {
    m.iter().any(|&b| b)
}

fn and(a: Mask, b: Mask) -> Mask {
    std::array::from_fn(|l| a[l] && b[l])
}

/// A tile the evaluator draws into, laid out as a kernel's tile (`abi::ctx`): pixel (x, y)
/// is element `(y - y0) * stride + (x - x0)` of `depth`, `writes` and of each of the
/// `planes` planes (`plane_stride` floats apart).
#[derive(Clone, Debug, PartialEq)]
pub struct Tile {
    /// The rectangle: x0, y0 inclusive, x1, y1 exclusive.
    pub x0: i32,
    pub y0: i32,
    pub x1: i32,
    pub y1: i32,
    /// Row stride in pixels, a multiple of 4 and at least `x1 - x0` rounded up to one.
    pub stride: usize,
    /// Depth buffer, `fixed<32,32>` raw, larger is nearer.
    pub depth: Vec<u32>,
    /// Depth writes per pixel (the JIT's `write_count` of a key that counts them).
    pub writes: Vec<u32>,
    /// G-buffer planes, one after another: f32 in both precisions.
    pub planes: Vec<f32>,
    pub plane_stride: usize,
    pub num_planes: usize,
    /// The viewport (bounds and the pixel fuel's share are taken in it).
    pub width: u32,
    pub height: u32,
}

impl Tile {
    /// A tile of `w` x `h` pixels at (x0, y0) in a `width` x `height` viewport, depth 0
    /// (farthest), `planes` planes of zeros.
    pub fn new(x0: i32, y0: i32, w: usize, h: usize, planes: usize, width: u32, height: u32) -> Tile {
        let stride = w.div_ceil(GROUP as usize) * GROUP as usize;
        Tile {
            x0,
            y0,
            x1: x0 + w as i32,
            y1: y0 + h as i32,
            stride,
            depth: vec![0; stride * h],
            writes: vec![0; stride * h],
            planes: vec![0.0; stride * h * planes],
            plane_stride: stride * h,
            num_planes: planes,
            width,
            height,
        }
    }

    /// The element index of pixel (x, y), if the buffers hold it.
    pub fn index(&self, x: i32, y: i32) -> Option<usize> {
        let (dx, dy) = (x.checked_sub(self.x0)?, y.checked_sub(self.y0)?);
        let (dx, dy) = (usize::try_from(dx).ok()?, usize::try_from(dy).ok()?);
        (dx < self.stride && dy < (self.y1 - self.y0).max(0) as usize).then(|| dy * self.stride + dx)
    }
}

/// The fuel a run gets (`TileCtx::fuel`, `pixel_fuel`, `group_fuel_floor`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Budget {
    pub setup_fuel: u64,
    pub pixel_fuel: u64,
    pub group_fuel_floor: u64,
}

impl Default for Budget {
    fn default() -> Budget {
        Budget {
            setup_fuel: DEFAULT_FUEL,
            pixel_fuel: DEFAULT_PIXEL_FUEL,
            group_fuel_floor: DEFAULT_GROUP_FUEL_FLOOR,
        }
    }
}

/// What a run did besides drawing into the tile.
#[derive(Clone, Debug, PartialEq)]
pub struct Outcome {
    /// Error counts of setup code and of pixel code, `abi::count_slots(program)` each,
    /// indexed by [`ErrorSlot::index`].
    pub setup_counts: Vec<u64>,
    pub pixel_counts: Vec<u64>,
    /// The first error recorded (`TileCtx::error`, `error_site`), and whether setup code
    /// recorded it (see the module doc).
    pub first_error: Option<(u32, u32)>,
    pub first_error_in_setup: bool,
    /// The setup fuel left (`TileCtx::fuel`): `-(2 + site)` as an i64 when a setup loop
    /// ran out (`abi::setup_fuel_ran_out`).
    pub fuel: u64,
    /// The last `bound` the primitive's own setup executed (its pass rectangle before
    /// clipping), if any; rounded to f32 in F64.
    pub bound: Option<[f32; 4]>,
}

impl Outcome {
    /// The nonzero counts of setup and pixel code together, in slot order.
    pub fn errors(&self, program: &Program) -> Vec<(ErrorSlot, u64)> {
        let sites = program.sites.len();
        self.setup_counts
            .iter()
            .zip(&self.pixel_counts)
            .enumerate()
            .filter(|(_, (a, b))| **a + **b != 0)
            .map(|(i, (a, b))| (ErrorSlot::at(i, sites), a.wrapping_add(*b)))
            .collect()
    }
}

/// Why a run could not be evaluated.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum EvalError {
    /// The IR or the argument block breaks a rule the JIT relies on (it would refuse to
    /// compile it, or read outside the block).
    Malformed(String),
    /// Deeper than [`MAX_NESTING`], or larger than the evaluator handles.
    Unsupported(String),
}

impl std::fmt::Display for EvalError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            EvalError::Malformed(m) => write!(f, "malformed: {m}"),
            EvalError::Unsupported(m) => write!(f, "unsupported: {m}"),
        }
    }
}

impl std::error::Error for EvalError {}

pub(crate) type Res<T> = Result<T, EvalError>;

pub(crate) fn malformed<T>(m: impl Into<String>) -> Res<T> {
    Err(EvalError::Malformed(m.into()))
}

/// The evaluator of one program: its primitives' bodies as the JIT lowers them
/// (`mid::body`: whole-array copies forwarded, and with `unroll_loops` as in
/// `JitOptions::unroll_loops`, constant-trip loops unrolled, which then spend no fuel).
/// Shared interpolators run as checked, as the JIT inlines them. Floats are computed in
/// `precision` (see the module doc).
pub struct Evaluator<'p> {
    program: &'p Program,
    bodies: Vec<Option<Function>>,
    precision: Precision,
}

impl<'p> Evaluator<'p> {
    /// The JIT's oracle: floats in f32, bit for bit as kernels compute them.
    pub fn new(program: &'p Program, unroll_loops: bool) -> Evaluator<'p> {
        Evaluator::with_precision(program, unroll_loops, Precision::F32)
    }

    /// An evaluator computing floats in `precision`.
    pub fn with_precision(program: &'p Program, unroll_loops: bool, precision: Precision) -> Evaluator<'p> {
        let bodies = (0..program.functions.len())
            .map(|i| {
                let id = FuncId(i as u32);
                (program.func(id).kind == FuncKind::Primitive)
                    .then(|| crate::mid::body(program, id, unroll_loops).function)
            })
            .collect();
        Evaluator {
            program,
            bodies,
            precision,
        }
    }

    /// The precision it computes floats in.
    pub fn precision(&self) -> Precision {
        self.precision
    }

    /// Run primitive `func` for `key` on the argument block `args` (laid out by
    /// `abi::ArgLayout`, as the runtime builds it) into `tile`, as a kernel in
    /// `MODE_RENDER` would with `budget`: see the module doc.
    pub fn run(
        &self,
        func: FuncId,
        key: &VariantKey,
        args: &[u32],
        tile: &mut Tile,
        budget: Budget,
    ) -> Result<Outcome, EvalError> {
        self.run_watched(func, key, args, tile, budget, None)
    }

    /// [`Evaluator::run`], reporting to `observer` what it does for pixel (x, y) of the
    /// tile (see [`observe`]).
    #[allow(clippy::too_many_arguments)]
    pub fn run_observed(
        &self,
        func: FuncId,
        key: &VariantKey,
        args: &[u32],
        tile: &mut Tile,
        budget: Budget,
        pixel: (i32, i32),
        observer: &mut dyn Observer,
    ) -> Result<Outcome, EvalError> {
        let watch = Watch {
            observer,
            x: pixel.0,
            y: pixel.1,
        };
        self.run_watched(func, key, args, tile, budget, Some(watch))
    }

    fn run_watched<'t>(
        &self,
        func: FuncId,
        key: &VariantKey,
        args: &[u32],
        tile: &'t mut Tile,
        budget: Budget,
        watch: Option<Watch<'t>>,
    ) -> Result<Outcome, EvalError> {
        std::thread::scope(|s| {
            let worker = std::thread::Builder::new()
                .name("ir-eval".into())
                .stack_size(EVAL_STACK)
                .spawn_scoped(s, || run_here(self, func, key, args, tile, budget, watch));
            match worker {
                Ok(handle) => handle
                    .join()
                    .unwrap_or_else(|_| Err(EvalError::Unsupported("the evaluator panicked".into()))),
                Err(e) => Err(EvalError::Unsupported(format!("no evaluator thread: {e}"))),
            }
        })
    }
}

fn run_here<'t>(
    evaluator: &Evaluator,
    func: FuncId,
    key: &VariantKey,
    args: &[u32],
    tile: &'t mut Tile,
    budget: Budget,
    watch: Option<Watch<'t>>,
) -> Result<Outcome, EvalError> {
    if !tile.stride.is_multiple_of(GROUP as usize) || tile.x1 < tile.x0 || tile.y1 < tile.y0 {
        return malformed("tile stride not a multiple of the group or negative extent");
    }
    let rows = (tile.y1 - tile.y0) as usize;
    let cols = (tile.x1 - tile.x0) as usize;
    if tile.stride < cols
        || tile.depth.len() < tile.stride * rows
        || tile.writes.len() < tile.stride * rows
        || tile.plane_stride < tile.stride * rows
        || tile.planes.len() < tile.plane_stride * tile.num_planes
    {
        return malformed("tile buffers smaller than the tile");
    }
    let (program, precision) = (evaluator.program, evaluator.precision);
    let slots = count_slots(program);
    let mut m = Machine {
        program,
        bodies: &evaluator.bodies,
        precision,
        key,
        n_interp: key.interp_components(),
        tile,
        budget,
        out: Outcome {
            setup_counts: vec![0; slots],
            pixel_counts: vec![0; slots],
            first_error: None,
            first_error_in_setup: false,
            fuel: budget.setup_fuel,
            bound: None,
        },
        fuel: budget.setup_fuel as i64,
        call_depth: 0,
        frames: vec![],
        kernels: vec![],
        loops: vec![],
        exec: ALL,
        guard: true,
        pix: None,
        view: (0..key.interp_components()).collect(),
        arm: None,
        nesting: 0,
        watch,
    };
    let bound = m.invoke(func, Rc::new(ArgBlock::new(args.to_vec())))?;
    m.out.fuel = m.fuel as u64;
    m.out.bound = bound.map(|b| b.map(|w| precision.to_f32(w)));
    Ok(m.out)
}

/// One function being evaluated: the primitive of a kernel run, or a shared interpolator
/// run inside it.
pub(crate) struct Frame<'p> {
    pub func: &'p Function,
    /// The argument block its parameters are read from (an interpolator's: its kernel's).
    pub args: Rc<ArgBlock>,
    pub slots: Vec<ParamSlot>,
    pub fixed_words: u32,
    /// Every local's components (parameters read from `args` have none).
    pub locals: Vec<Vec<Lanes>>,
    /// The shading parameter a shared interpolator computes (`None`: a primitive).
    pub interp_binding: Option<usize>,
}

/// One kernel run in progress: its primitive's frame and argument layout, its pass bound
/// (float lane words).
pub(crate) struct Kernel {
    pub frame: usize,
    pub layout: Rc<ArgLayout>,
    pub bound: Option<Lanes>,
}

/// A loop being run: uniform loops jump (`mask` is `None`), varying ones and the one-trip
/// loop around an interpolator keep lane masks.
pub(crate) struct LoopCtx {
    pub frame: usize,
    pub id: Option<crate::ir::LoopId>,
    pub mask: Option<Mask>,
    pub cont: Mask,
}

/// The pixel group being run.
pub(crate) struct Pix {
    pub alive: Mask,
    pub z_written: Mask,
    /// Lane 0's column, the row.
    pub gx: i32,
    pub y: i32,
    /// Lane centres as float lane words, and the depth the group started with (when it
    /// reads one: raw, zero-extended).
    pub x_f: Lanes,
    pub y_f: Lanes,
    pub z_raw: Option<Lanes>,
    /// The group's fuel (`-1`: spent and reported).
    pub fuel: i64,
    /// Varying constructs entered (an assignment at 0 writes every lane).
    pub depth: u32,
}

/// How a statement ended: on to the next, or a jump out of the statements around it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Flow {
    Normal,
    Break(crate::ir::LoopId),
    Continue(crate::ir::LoopId),
    /// Setup: the run ends.
    Return,
    /// Pixel code: no lane is left alive.
    GroupEnd,
    /// Setup: out of setup fuel; this run and its callers' end.
    FuelOut,
}

pub(crate) struct Machine<'p, 't> {
    pub program: &'p Program,
    /// What float lane words hold and float arithmetic computes in.
    pub precision: Precision,
    /// The primitives' bodies as lowered (`None` for interpolators).
    pub bodies: &'p [Option<Function>],
    pub key: &'p VariantKey,
    pub n_interp: u32,
    pub tile: &'t mut Tile,
    pub budget: Budget,
    pub out: Outcome,
    /// Setup fuel (`TileCtx::fuel` as the kernels read it).
    pub fuel: i64,
    pub call_depth: u32,
    pub frames: Vec<Frame<'p>>,
    pub kernels: Vec<Kernel>,
    pub loops: Vec<LoopCtx>,
    /// The lanes the current statement runs for (all four in setup code).
    pub exec: Mask,
    /// Every guard around the expression being evaluated lets its errors count (an arm
    /// of `?:` taken, for a varying condition by some executing lane).
    pub guard: bool,
    pub pix: Option<Pix>,
    /// The interpolation-data components visible (`mid::view`).
    pub view: Vec<u32>,
    /// The bindings of the `interpolation` arm being run.
    pub arm: Option<Vec<usize>>,
    pub nesting: usize,
    /// The pixel being watched and its observer (`run_observed`).
    pub watch: Option<Watch<'t>>,
}

impl<'p> Machine<'p, '_> {
    /// One level deeper of recursion, refused past [`MAX_NESTING`].
    pub(crate) fn enter(&mut self) -> Res<()> {
        self.nesting += 1;
        if self.nesting > MAX_NESTING {
            return Err(EvalError::Unsupported(format!(
                "nested deeper than {MAX_NESTING} levels"
            )));
        }
        Ok(())
    }

    pub(crate) fn leave(&mut self) {
        self.nesting -= 1;
    }

    /// The watched pixel's lane if the code running now runs for it: setup code runs for
    /// every pixel (lane 0 holds its uniform values), pixel code for the executing lanes of
    /// the group being run. `None` when nothing is watched.
    pub(crate) fn watched_lane(&self) -> Option<usize> {
        let w = self.watch.as_ref()?;
        match &self.pix {
            None => Some(0),
            Some(p) => self.lane_of(w, p).filter(|&l| self.exec[l]),
        }
    }

    /// The watched pixel's lane in group `p`, executing or not.
    fn lane_of(&self, w: &Watch, p: &Pix) -> Option<usize> {
        let l = usize::try_from(w.x.checked_sub(p.gx)?).ok()?;
        (p.y == w.y && l < GROUP as usize).then_some(l)
    }

    /// Report `event` to the observer, if there is one.
    pub(crate) fn notify(&mut self, event: Event<'_>) {
        if let Some(w) = &mut self.watch {
            w.observer.event(event);
        }
    }

    pub(crate) fn frame(&self) -> Res<&Frame<'p>> {
        match self.frames.last() {
            Some(f) => Ok(f),
            None => malformed("no function being evaluated"),
        }
    }

    /// The expression arena of the function being evaluated: the one every `ExprId` the
    /// statements at hand hold refers to.
    pub(crate) fn exprs(&self) -> &'p crate::ir::Exprs {
        let f: &'p Function = self.frames.last().expect("a frame is pushed while evaluating").func;
        &f.exprs
    }

    /// The statement arena of the function running in the innermost frame.
    pub(crate) fn stmt_nodes(&self) -> &'p crate::ir::Stmts {
        let f: &'p Function = self.frames.last().expect("a frame is pushed while evaluating").func;
        &f.stmts
    }

    pub(crate) fn kernel(&self) -> Res<&Kernel> {
        match self.kernels.last() {
            Some(k) => Ok(k),
            None => malformed("no kernel run"),
        }
    }

    /// Record error `code` at `site`: counted (unless `count` is false) in the setup or
    /// pixel counts, and kept as the first error if it is.
    pub(crate) fn record(&mut self, code: u32, site: u32, count: bool) -> Res<()> {
        if count {
            let Some(slot) = ErrorSlot::of(code, site) else {
                return malformed(format!("error code {code}"));
            };
            let at = slot.index(self.program.sites.len());
            let counts = if self.pix.is_some() {
                &mut self.out.pixel_counts
            } else {
                &mut self.out.setup_counts
            };
            match counts.get_mut(at) {
                Some(n) => *n = n.wrapping_add(1),
                None => return malformed(format!("error site {site} out of the program's sites")),
            }
        }
        if self.out.first_error.is_none() {
            self.out.first_error = Some((code, site));
            self.out.first_error_in_setup = self.pix.is_none();
        }
        Ok(())
    }

    /// One kernel run of primitive `func` on `args`: its setup, then its pixel passes.
    /// Returns the last bound its setup executed (float lane words).
    pub(crate) fn invoke(&mut self, func: FuncId, args: Rc<ArgBlock>) -> Res<Option<Lanes>> {
        let program = self.program;
        let Some(Some(f)) = self.bodies.get(func.0 as usize) else {
            return malformed(format!("no primitive {}", func.0));
        };
        let layout = ArgLayout::new(program, func, self.key);
        let n_seq = args.n_seq();
        if args.len() < layout.words(n_seq) {
            return malformed(format!("argument block of `{}` shorter than its layout", f.name));
        }
        let frame = self.new_frame(f, args, layout.params.clone(), layout.fixed_words, None)?;
        let saved_exec = std::mem::replace(&mut self.exec, ALL);
        let saved_view = std::mem::replace(&mut self.view, (0..self.n_interp).collect());
        let saved_arm = self.arm.take();
        self.frames.push(frame);
        self.kernels.push(Kernel {
            frame: self.frames.len() - 1,
            layout: Rc::new(layout),
            bound: None,
        });
        let depth = self.call_depth;
        self.notify(Event::KernelStart { func: f, depth });
        let r = self.run_kernel(f);
        self.notify(Event::KernelEnd { func: f, depth });
        let bound = self.kernels.pop().and_then(|k| k.bound);
        self.frames.pop();
        self.exec = saved_exec;
        self.view = saved_view;
        self.arm = saved_arm;
        r.map(|()| bound)
    }

    fn run_kernel(&mut self, f: &'p Function) -> Res<()> {
        match self.stmts(&f.setup)? {
            Flow::Normal => {}
            Flow::Return | Flow::FuelOut => return Ok(()),
            other => return malformed(format!("setup ended by {other:?}")),
        }
        if f.pixel.is_empty() {
            return Ok(());
        }
        self.pixel_passes(f)
    }

    /// A frame for `f` with zeroed locals.
    pub(crate) fn new_frame(
        &self,
        f: &'p Function,
        args: Rc<ArgBlock>,
        slots: Vec<ParamSlot>,
        fixed_words: u32,
        interp_binding: Option<usize>,
    ) -> Res<Frame<'p>> {
        let mut locals = Vec::with_capacity(f.locals.len());
        for (i, local) in f.locals.iter().enumerate() {
            let role = f.params.iter().find(|p| p.local.0 as usize == i).map(|p| p.role);
            let words = match role {
                Some(ParamRole::X | ParamRole::Y | ParamRole::Z) => 1,
                Some(_) => 0,
                None if local.ty.per_seq => return malformed(format!("local `{}` per sequence point", local.name)),
                None => crate::abi::type_words(&local.ty, self.n_interp) as usize,
            };
            if words > 1 << 24 {
                return Err(EvalError::Unsupported(format!(
                    "local `{}` of {words} words",
                    local.name
                )));
            }
            locals.push(vec![[0; 4]; words]);
        }
        if slots.len() != f.params.len() {
            return malformed(format!("`{}`: {} parameter slots", f.name, slots.len()));
        }
        Ok(Frame {
            func: f,
            args,
            slots,
            fixed_words,
            locals,
            interp_binding,
        })
    }

    /// The pixel passes of the kernel on top (render mode): every group of the pass
    /// rectangle in the tile, each from the state the setup left.
    fn pixel_passes(&mut self, f: &'p Function) -> Res<()> {
        let p = self.precision;
        let b = match self.kernel()?.bound {
            Some(b) => b,
            None => [f32::NEG_INFINITY, f32::NEG_INFINITY, f32::INFINITY, f32::INFINITY].map(|x| p.from_f32(x)),
        };
        let group_fuel = if crate::mid::pixel_code_has_loops(self.program, f, self.key) {
            let (w, h) = (self.tile.width as i32, self.tile.height as i32);
            let (lo_x, hi_x) = pass_range(p, b[0], b[2], 0, w);
            let (lo_y, hi_y) = pass_range(p, b[1], b[3], 0, h);
            let cols = ((hi_x as u32).wrapping_add(3) >> 2).wrapping_sub(lo_x as u32 >> 2);
            let rows = (hi_y as u32).wrapping_sub(lo_y as u32);
            let groups = (u64::from(rows).wrapping_mul(u64::from(cols))).max(1);
            (self.budget.pixel_fuel / groups).max(self.budget.group_fuel_floor) as i64
        } else {
            0
        };
        let (x0, y0, x1, y1) = (self.tile.x0, self.tile.y0, self.tile.x1, self.tile.y1);
        let (lo_x, hi_x) = pass_range(p, b[0], b[2], x0, x1);
        let (lo_y, mut hi_y) = pass_range(p, b[1], b[3], y0, y1);
        if b.iter().any(|&v| p.is_nan(v)) {
            hi_y = lo_y;
        }
        let gx_start = x0 + ((lo_x - x0) & !3);
        // The locals the pixel part assigns start every group with their setup values.
        let fi = self.kernel()?.frame;
        let mut assigned = vec![false; f.locals.len()];
        for_each_assign(&f.stmts, &f.pixel, &mut |p, _| {
            if let Some(a) = assigned.get_mut(p.local.0 as usize) {
                *a = true;
            }
        });
        let snapshot: Vec<(usize, Vec<Lanes>)> = assigned
            .iter()
            .enumerate()
            .filter(|(_, a)| **a)
            .map(|(i, _)| (i, self.frames[fi].locals[i].clone()))
            .collect();
        for y in lo_y..hi_y {
            let mut g = gx_start;
            while g < hi_x {
                let mask: Mask = std::array::from_fn(|l| (lo_x..hi_x).contains(&(g + l as i32)));
                if any(mask) {
                    for (i, v) in &snapshot {
                        self.frames[fi].locals[*i].clone_from(v);
                    }
                    self.group(f, g, y, mask, group_fuel)?;
                }
                g += GROUP as i32;
            }
        }
        Ok(())
    }

    /// The pixel part for the group whose lane 0 is at (gx, y), lanes `mask` live.
    fn group(&mut self, f: &'p Function, gx: i32, y: i32, mask: Mask, fuel: i64) -> Res<()> {
        let needs_depth = f.param_by_role(ParamRole::Z).is_some()
            || self
                .key
                .bindings
                .iter()
                .any(|b| matches!(b.kind, BindingKind::Shared(_)));
        let z_raw = needs_depth.then(|| {
            std::array::from_fn(|l| {
                self.tile
                    .index(gx + l as i32, y)
                    .and_then(|i| self.tile.depth.get(i).copied())
                    .map_or(0, u64::from)
            })
        });
        // Pixel centres: n + 0.5, exact in both precisions.
        let (x_f, y_f): (Lanes, Lanes) = in_precision!(self.precision, F => {
            let centre = |n: i32| (F::from_i32(n) + F::from_f32(0.5)).word();
            (std::array::from_fn(|l| centre(gx + l as i32)), [centre(y); 4])
        });
        self.pix = Some(Pix {
            alive: mask,
            z_written: NONE,
            gx,
            y,
            x_f,
            y_f,
            z_raw,
            fuel,
            depth: 0,
        });
        self.exec = mask;
        let fi = self.kernel()?.frame;
        self.bind_pixel_params(fi, x_f, y_f, z_raw, None)?;
        let watched = self.watched_lane();
        if watched.is_some() {
            self.notify(Event::PixelStart);
        }
        let flow = self.stmts(&f.pixel);
        let pix = self.pix.take();
        self.exec = ALL;
        if let (Some(l), Some(p)) = (watched, &pix) {
            self.notify(Event::PixelEnd { alive: p.alive[l] });
        }
        match flow? {
            Flow::Normal | Flow::GroupEnd => {}
            other => return malformed(format!("pixel part ended by {other:?}")),
        }
        let (Some(pix), Some(zp)) = (pix, f.param_by_role(ParamRole::Z)) else {
            return Ok(());
        };
        let zsc = expr::elem_scalar(&f.local(zp.local).ty);
        let z = self.frames[fi].locals[zp.local.0 as usize]
            .first()
            .copied()
            .unwrap_or([0; 4]);
        for (l, &zl) in z.iter().enumerate() {
            if !pix.z_written[l] {
                continue;
            }
            let Some(i) = self.tile.index(gx + l as i32, y) else {
                return malformed("a lane outside the tile wrote Z");
            };
            let before = self.tile.depth[i];
            self.tile.depth[i] =
                scalar::convert_lane(self.precision, zsc, crate::ir::Scalar::Fixed(scalar::DEPTH), zl) as u32;
            self.tile.writes[i] = self.tile.writes[i].wrapping_add(1);
            if watched == Some(l) {
                let after = self.tile.depth[i];
                self.notify(Event::Depth { before, after });
            }
        }
        Ok(())
    }

    /// Set frame `fi`'s X, Y, Z parameters from the group's lane centres and depth (`z`:
    /// a value of another frame's Z, with its scalar type, instead of the depth buffer's).
    pub(crate) fn bind_pixel_params(
        &mut self,
        fi: usize,
        x_f: Lanes,
        y_f: Lanes,
        z_raw: Option<Lanes>,
        z: Option<(Lanes, crate::ir::Scalar)>,
    ) -> Res<()> {
        use crate::ir::Scalar;
        let f = self.frames[fi].func;
        for p in &f.params {
            let crate::ir::Elem::Scalar(sc) = f.local(p.local).ty.elem else {
                continue;
            };
            let (src, from) = match p.role {
                ParamRole::X => (x_f, Scalar::Float),
                ParamRole::Y => (y_f, Scalar::Float),
                ParamRole::Z => match (z, z_raw) {
                    (Some((v, zsc)), _) => (v, zsc),
                    (None, Some(raw)) => (raw, Scalar::Fixed(scalar::DEPTH)),
                    (None, None) if self.frames[fi].interp_binding.is_some() => ([0; 4], Scalar::Float),
                    (None, None) => continue,
                },
                _ => continue,
            };
            let v = src.map(|w| scalar::convert_lane(self.precision, from, sc, w));
            match self.frames[fi]
                .locals
                .get_mut(p.local.0 as usize)
                .and_then(|l| l.first_mut())
            {
                Some(slot) => *slot = v,
                None => return malformed("pixel parameter without storage"),
            }
        }
        Ok(())
    }
}

/// Pixels [lo, hi) of the range [t0, t1) whose centres lie in [bmin, bmax] (float lane
/// words of precision `p`; `Lower::pass_range`: clamped in float first, NaN to 0).
fn pass_range(p: Precision, bmin: u64, bmax: u64, t0: i32, t1: i32) -> (i32, i32) {
    in_precision!(p, F => pass_range_in::<F>(F::from_word(bmin), F::from_word(bmax), t0, t1))
}

fn pass_range_in<F: Float>(bmin: F, bmax: F, t0: i32, t1: i32) -> (i32, i32) {
    let (t0f, t1f) = (F::from_i32(t0), F::from_i32(t1));
    let half = F::from_f32(0.5);
    let lo = scalar::fmin_in(scalar::fmax_in((bmin - half).ceil(), t0f), t1f);
    let hi = scalar::fmin_in(scalar::fmax_in((bmax - half).floor() + F::ONE, t0f), t1f);
    let (lo_i, hi_i) = (lo.to_i32(), hi.to_i32());
    (lo_i, hi_i.max(lo_i))
}
