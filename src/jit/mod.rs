//! The back end: specialises IR functions for a variant key and compiles them with Cranelift.
//!
//! A [`Jit`] owns one Cranelift JIT module (host ISA from `cranelift-native`, `opt_level =
//! speed`, non-PIC) and a cache of kernels keyed by (function, variant key). Asking for a
//! kernel compiles it and every primitive it calls, for the same key, in one batch: callees
//! are declared as module functions and called directly, so a call costs no lookup at run
//! time and recursion between primitives is bounded by `TileCtx::call_depth`. A batch's
//! functions are lowered and compiled in parallel on the caller's rayon pool ([`batch`]),
//! with the same machine code as one after another.
//!
//! Files: [`lower`] turns one IR function into CLIF (the execution model is described
//! there), [`batch`] runs a batch's lowerings and compiles in parallel, [`value`] holds the
//! uniform/varying value representation and masks, [`fixed`] the integer/fixed-point
//! arithmetic and conversions, [`builtin`] the built-in functions, [`libm`] the `extern "C"`
//! math helpers kernels link against.
//!
//! Tiers ([`Tier`], [`JitOptions`]): tier 0 ([`Tier::Fast`]) compiles with regalloc2's
//! single-pass allocator, `opt_level=none`, without block-level culling and with a lighter
//! lowering (`lower::Lower::tier0`: fewer blocks and less CLIF), and with each kernel's pixel
//! loops (or the second half of a large setup without them) in a function of their own
//! that the batch compiles beside it (`lower::outline`), and a batch's callees started
//! before their caller is lowered, so a scene's first frame starts quickly; tier 1 ([`Tier::Optimised`]) is the full pipeline. A *tiered* JIT
//! ([`Jit::tiered`]) answers each new (function, key) with a tier-0 kernel at once and asks a
//! background worker thread, which owns a second JIT module, for the tier-1 kernel; later
//! requests get the tier-1 kernel once it is ready. The frame in flight switches too: a
//! tiered JIT's tier-0 kernels start by reading a word the worker fills with their tier-1
//! entry point and call that when it is set ([`Jit::tier0_forwards_to`]), so draws binned
//! with tier-0 entries, expanded calls and tier-0 kernels' calls to each other run tier-1
//! code from the moment it exists — a single long frame (the CLI renders one) gets the
//! fast start and the fast kernels. The worker does not compete with a frame blindly: a
//! [`TierUpWatch`] ([`Jit::tier_up_watch`], what `KernelSource::tier_up` hands the renderer)
//! says whether it is idle, held or compiling, and lets the renderer hold it
//! ([`TierUpWatch::hold`]) for a grace period in proportion to the frame's tier-0 compile
//! time ([`TierUpWatch::grace`], [`Jit::set_tier_up_grace`]); after that, while it compiles,
//! the renderer leaves it a thread (`runtime::tiergate`). [`Jit::stall_tier_up`] holds it
//! while reporting it compiling, for tests. Both tiers compute the same buffers bit for bit: they
//! lower the same IR with the same floating-point operations in the same order, and block
//! culling only decides which pixels run, never what they compute (`tests/jit/tiers.rs`).
//! Compiled code is never freed (cranelift-jit leaks a module's memory unless told
//! otherwise), so every entry point a JIT hands out stays callable for the life of the
//! process, beyond the `KernelSource` contract; the worker's too, after it has ended.
//!
//! Before lowering, the middle end ([`crate::mid`]) makes each function's body once
//! ([`crate::mid::body`]: whole-array copies forwarded, uniform loops with a compile-time
//! trip count unrolled when [`JitOptions::unroll_loops`]), kept per program in
//! [`SHARED_BODIES`], and plans each kernel ([`crate::mid::plan`]: one plan per function,
//! variant key and tier), which the lowering consults instead of running analyses itself.
//!
//! Compiles reuse per-thread Cranelift contexts, and each kernel's cost is recorded in wall
//! and thread CPU time ([`Jit::compile_cost`], [`CompileCost`]); [`Jit::clif`] and
//! [`Jit::disassembly`] show what a kernel is made of before and after Cranelift (the
//! latter with its count of register-allocator spills, see [`Disassembly`]).
//!
//! Run-time errors a kernel records carry a `SiteId` in `TileCtx::error_site` (an
//! `ERR_CALL_DEPTH` the site of the call it skipped), except `ERR_STACK` (every kernel,
//! and every outlined pixel function, begins by comparing its stack pointer with
//! `TileCtx::stack_limit`), which records the kernel's `FuncId`. `TileCtx::error` keeps the
//! first; every one is also counted at its `abi::ErrorSlot` (`lower::frame`).

mod batch;
mod builtin;
mod derivative;
mod fixed;
pub mod libm;
mod lower;
mod shading;
mod value;

use std::cell::RefCell;
use std::collections::{HashMap, HashSet};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{mpsc, Arc, Mutex, Weak};
use std::thread::JoinHandle;
use std::time::Instant;

use cranelift_codegen::ir::{self, types, AbiParam, UserFuncName};
use cranelift_codegen::isa::OwnedTargetIsa;
use cranelift_codegen::settings::{self, Configurable};
use cranelift_codegen::Context;
use cranelift_frontend::FunctionBuilderContext;
use cranelift_jit::{JITBuilder, JITModule};
use cranelift_module::{default_libcall_names, Linkage, Module};

use crate::abi::{ArgLayout, Kernel, KernelFn, TierUpHold, TierUpWatch, VariantKey};
use crate::ir::{FuncId, Program};
use crate::mid::Body;
use libm::LibmFn;
use lower::{Linker, Res};

/// The JIT's name for the kernel error of the ABI (what its lowering and compiling report).
pub(crate) use crate::abi::KernelError as JitError;

/// What compiling one kernel cost (see [`Jit::compile_cost`]).
///
/// Wall time counts whatever else the machine runs meanwhile (on a loaded 2-core machine,
/// the background tier-1 thread and other processes can double it); thread CPU time counts
/// only the compiling threads' own work, so it is the figure to compare between runs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CompileCost {
    /// Lowering and compiling this kernel (callees excluded): wall time, microseconds
    /// (the same figure as [`Kernel::compile_micros`]).
    pub wall_micros: u64,
    /// The same, in the CPU time of the threads that did it, microseconds.
    pub cpu_micros: u64,
    /// The part of `cpu_micros` spent in Cranelift (`Context::compile`: instruction
    /// selection, register allocation, emission); the rest is ours (preparing the body,
    /// range analysis, lowering to CLIF, linking). Cranelift's cost grows with the CLIF, so
    /// this is the floor no front-end work can go under without emitting less code.
    pub codegen_cpu_micros: u64,
    /// Instructions in the kernel's CLIF as handed to Cranelift.
    pub clif_insts: u64,
    /// The whole batch this kernel was compiled in (itself, the callees compiled with it,
    /// unrolling, linking and making the code executable): the CPU time of every thread
    /// that worked on it, summed, microseconds. The functions of a batch are compiled in
    /// parallel, so this is more than `batch_wall_micros` on a machine with idle cores.
    pub batch_cpu_micros: u64,
    /// The whole batch, wall time, microseconds: what its caller waited for.
    pub batch_wall_micros: u64,
}

/// The calling thread's CPU time in microseconds (Linux `CLOCK_THREAD_CPUTIME_ID`; elsewhere
/// 0, so CPU figures read 0). Unlike wall time it does not grow while the thread waits for a
/// core.
pub fn thread_cpu_micros() -> u64 {
    #[cfg(target_os = "linux")]
    {
        #[repr(C)]
        struct Timespec {
            tv_sec: i64,
            tv_nsec: i64,
        }
        extern "C" {
            fn clock_gettime(clock: i32, tp: *mut Timespec) -> i32;
        }
        const CLOCK_THREAD_CPUTIME_ID: i32 = 3;
        let mut t = Timespec { tv_sec: 0, tv_nsec: 0 };
        // SAFETY: `t` is a valid, writable timespec for the duration of the call.
        if unsafe { clock_gettime(CLOCK_THREAD_CPUTIME_ID, &mut t) } != 0 {
            return 0;
        }
        t.tv_sec as u64 * 1_000_000 + t.tv_nsec as u64 / 1000
    }
    #[cfg(not(target_os = "linux"))]
    {
        0
    }
}

fn jit_err(what: &str, e: impl std::fmt::Display) -> JitError {
    JitError {
        message: format!("{what}: {e}"),
    }
}

type CacheKey = (FuncId, VariantKey);

/// A fault for tests of `Jit::compile_batch_caught`: once set, compiling the function of
/// this name at tier 1 panics, as a bug of the JIT or of Cranelift would.
#[doc(hidden)]
pub static PANIC_AT_TIER_1: std::sync::OnceLock<String> = std::sync::OnceLock::new();

/// A tier-0 kernel of a tiered JIT and the word its code reads on entry: 0 until the worker
/// stores the kernel's tier-1 entry point there (see `lower::lower_kernel`). The words are
/// leaked on purpose, like the code that reads them (compiled code is never freed).
type UpgradeWord = (CacheKey, &'static AtomicUsize);

pub use crate::mid::Tier;

/// How a [`Jit`] compiles.
#[derive(Clone, Debug)]
pub struct JitOptions {
    pub tier: Tier,
    /// Unroll uniform loops with a compile-time trip count before lowering (see
    /// [`crate::mid::unroll`]).
    pub unroll_loops: bool,
}

impl Default for JitOptions {
    fn default() -> JitOptions {
        JitOptions {
            tier: Tier::Optimised,
            unroll_loops: true,
        }
    }
}

/// Kernel bodies as lowered ([`crate::mid::body`]: forwarded, then unrolled when
/// unrolling), by function, made on first use. A body does not depend on the variant key
/// or the tier, so every variant, both tiers and every JIT sharing the body reuse it and
/// the analyses it keeps.
type Bodies = Arc<Mutex<HashMap<FuncId, Arc<Body>>>>;

/// `func`'s body as lowered, from `bodies` (made and kept there on first use).
/// Made outside the lock: a batch's functions are lowered in parallel (`batch`), and the
/// root's body (1-2 ms for nurb_surface) must not hold up its callees'.
fn body_of(bodies: &Bodies, program: &Program, unroll_loops: bool, func: FuncId) -> Arc<Body> {
    let lock = || bodies.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(body) = lock().get(&func) {
        return body.clone();
    }
    let body = Arc::new(crate::mid::body(program, func, unroll_loops));
    // Another thread may have made it meanwhile: the first one stays.
    lock().entry(func).or_insert(body).clone()
}

/// The bodies of every live program, per unrolling setting, shared by all the JITs of that
/// program in the process: a body does not depend on the variant key or the tier, so a
/// fresh JIT (the bench makes one per workload, a renderer one per scene) and the tier-1
/// worker reuse what an earlier one unrolled (~9% of a tier-0 compile of screen_triangle).
/// Entries of dropped programs are removed on the next lookup; an entry is only matched
/// while its program is alive, so a new program at a freed address cannot see it.
static SHARED_BODIES: Mutex<Vec<(Weak<Program>, bool, Bodies)>> = Mutex::new(Vec::new());

/// `program`'s shared bodies for the unrolling setting `unroll` (see [`SHARED_BODIES`]).
fn shared_bodies(program: &Arc<Program>, unroll: bool) -> Bodies {
    let mut all = SHARED_BODIES.lock().unwrap_or_else(|e| e.into_inner());
    all.retain(|(p, _, _)| p.strong_count() > 0);
    if let Some((_, _, bodies)) = all
        .iter()
        .find(|(p, u, _)| *u == unroll && std::ptr::eq(p.as_ptr(), Arc::as_ptr(program)))
    {
        return bodies.clone();
    }
    let bodies = Bodies::default();
    all.push((Arc::downgrade(program), unroll, bodies.clone()));
    bodies
}

/// Owns the JIT module (the code memory) and the kernel cache for one program.
pub struct Jit {
    program: Arc<Program>,
    /// Kernel bodies as lowered, shared with the tier-1 worker and every other JIT of the
    /// program (see [`SHARED_BODIES`]).
    bodies: Bodies,
    options: JitOptions,
    /// The background tier-1 compiler of a tiered JIT.
    tier_up: Option<TierUp>,
    isa: OwnedTargetIsa,
    module: JITModule,
    cache: HashMap<CacheKey, Arc<Kernel>>,
    /// Every kernel declared in the module (defined ones are in `cache`).
    declared: HashMap<CacheKey, cranelift_module::FuncId>,
    libm: HashMap<LibmFn, cranelift_module::FuncId>,
    /// Kernels that failed to compile, with their error (asking again gives it again).
    failed: HashMap<CacheKey, JitError>,
    /// What each kernel in `cache` cost to compile.
    costs: HashMap<CacheKey, CompileCost>,
    /// Tiered JITs: each tier-0 kernel's upgrade word (see [`UpgradeWord`]).
    upgrade_words: HashMap<CacheKey, &'static AtomicUsize>,
    next_name: u32,
}

thread_local! {
    /// Cranelift contexts and function-builder contexts kept between compiles on this
    /// thread, so each compile reuses their buffers (the function's tables, the CFG and
    /// dominator tree, the register allocator's state) instead of growing new ones: that
    /// allocation was a visible part of a tier-0 compile. Every JIT on the thread shares
    /// them (the tier-1 worker thread has its own).
    static SPARE_CONTEXTS: RefCell<Vec<Context>> = const { RefCell::new(Vec::new()) };
    static SPARE_BUILDER_CONTEXTS: RefCell<Vec<FunctionBuilderContext>> = const { RefCell::new(Vec::new()) };
}

/// Spare contexts kept per thread (a batch rarely compiles more functions at once).
const MAX_SPARE_CONTEXTS: usize = 4;

/// A kernel's machine code after register allocation (see [`Jit::disassembly`]).
#[derive(Clone, Debug)]
pub struct Disassembly {
    /// Cranelift's listing: one line per machine instruction, labels per block.
    pub text: String,
    /// Lines that store a value to a register-allocator spill slot or load one back.
    pub spill_lines: usize,
    /// Machine instruction lines (labels and unwind directives not counted).
    pub inst_lines: usize,
}

impl Disassembly {
    /// Count `text`'s instructions and spill moves. Stack addresses print as
    /// `<offset:1>+0xN(%rsp)` from the start of the frame's slot area, where the function's
    /// own stack slots come first (`explicit_bytes`) and the allocator's spill slots after.
    fn new(text: String, explicit_bytes: u32) -> Disassembly {
        let mut spill_lines = 0;
        let mut inst_lines = 0;
        for line in text.lines() {
            let l = line.trim_start();
            if l.is_empty() || l.ends_with(':') || l.starts_with("unwind ") {
                continue;
            }
            inst_lines += 1;
            let spill = line.split("<offset:1>+0x").skip(1).any(|rest| {
                let hex: String = rest.chars().take_while(|c| c.is_ascii_hexdigit()).collect();
                u32::from_str_radix(&hex, 16).is_ok_and(|off| off >= explicit_bytes)
            });
            spill_lines += spill as usize;
        }
        Disassembly {
            text,
            spill_lines,
            inst_lines,
        }
    }
}

/// A cleared Cranelift context, reused if this thread has one.
fn take_context() -> Context {
    SPARE_CONTEXTS
        .with(|spare| spare.borrow_mut().pop())
        .unwrap_or_else(Context::new)
}

/// Keep `ctx` (cleared) for the next compile on this thread.
fn give_back_context(mut ctx: Context) {
    ctx.clear();
    SPARE_CONTEXTS.with(|spare| {
        let mut spare = spare.borrow_mut();
        if spare.len() < MAX_SPARE_CONTEXTS {
            spare.push(ctx);
        }
    });
}

/// The host ISA with the flags kernels of `tier` are compiled with.
fn host_isa(tier: Tier) -> Result<OwnedTargetIsa, JitError> {
    let mut flags = settings::builder();
    // Tier 0 skips the e-graph pass (a third of its compile time); lowering still drops
    // unused pure instructions, and no pass at either level changes a float result.
    let opt = if tier == Tier::Fast { "none" } else { "speed" };
    flags.set("opt_level", opt).map_err(|e| jit_err("opt_level", e))?;
    if tier == Tier::Fast {
        flags
            .set("regalloc_algorithm", "single_pass")
            .map_err(|e| jit_err("regalloc_algorithm", e))?;
    }
    // cranelift-jit needs non-PIC code (JITBuilder::with_isa does not set it).
    flags.set("is_pic", "false").map_err(|e| jit_err("is_pic", e))?;
    // The verifier costs ~30% compile time; keep it for debug builds, where tests run.
    let verify = if cfg!(debug_assertions) { "true" } else { "false" };
    flags
        .set("enable_verifier", verify)
        .map_err(|e| jit_err("enable_verifier", e))?;
    let builder = cranelift_native::builder().map_err(|e| jit_err("host ISA", e))?;
    builder
        .finish(settings::Flags::new(flags))
        .map_err(|e| jit_err("host ISA", e))
}

fn kernel_signature(isa: &OwnedTargetIsa) -> ir::Signature {
    let mut sig = ir::Signature::new(isa.default_call_conv());
    sig.params.push(AbiParam::new(types::I64));
    sig.params.push(AbiParam::new(types::I64));
    sig
}

fn libm_signature(isa: &OwnedTargetIsa, f: LibmFn) -> ir::Signature {
    let mut sig = ir::Signature::new(isa.default_call_conv());
    for _ in 0..f.arity() {
        sig.params.push(AbiParam::new(types::F32));
    }
    sig.returns.push(AbiParam::new(types::F32));
    sig
}

/// Links nothing: imports by placeholder names, for printing CLIF without compiling.
struct PrintLinker<'j> {
    isa: &'j OwnedTargetIsa,
}

impl PrintLinker<'_> {
    fn import(&self, func: &mut ir::Function, index: u32, sig: ir::Signature) -> ir::FuncRef {
        batch::import_function(func, ir::UserExternalName { namespace: 0, index }, sig, false)
    }
}

impl Linker for PrintLinker<'_> {
    fn kernel_ref(&mut self, func: &mut ir::Function, callee: FuncId) -> Res<ir::FuncRef> {
        Ok(self.import(func, callee.0, kernel_signature(self.isa)))
    }
    fn libm_ref(&mut self, func: &mut ir::Function, f: LibmFn) -> Res<ir::FuncRef> {
        let index = 1_000_000 + LibmFn::ALL.iter().position(|&g| g == f).unwrap_or(0) as u32;
        Ok(self.import(func, index, libm_signature(self.isa, f)))
    }
    fn pixel_ref(&mut self, func: &mut ir::Function, sig: ir::Signature) -> Res<ir::FuncRef> {
        Ok(self.import(func, PRINTED_PIXEL_INDEX, sig))
    }
}

/// The name printed CLIF gives a kernel's outlined pixel function (`u0:2000000`).
const PRINTED_PIXEL_INDEX: u32 = 2_000_000;

/// What the tier-1 worker has finished, shared with the JIT that feeds it; recorded under the
/// watch's lock (`TierUpWatch::finish_request`), so a kernel is here by the time its request
/// stops being pending.
#[derive(Default)]
struct TierUpResults {
    ready: HashMap<CacheKey, Arc<Kernel>>,
    /// What each kernel in `ready` cost the worker to compile.
    costs: HashMap<CacheKey, CompileCost>,
    /// Tier-1 compile failures (the tier-0 kernel stays in use).
    failed: HashMap<CacheKey, JitError>,
}

/// The background tier-1 compiler: a thread owning an optimising [`Jit`].
struct TierUp {
    requests: Option<mpsc::Sender<(CacheKey, Vec<UpgradeWord>)>>,
    watch: TierUpWatch,
    results: Arc<Mutex<TierUpResults>>,
    worker: Option<JoinHandle<()>>,
}

impl TierUp {
    /// `bodies`: the feeding JIT's kernel bodies, shared.
    fn start(program: Arc<Program>, bodies: Bodies, unroll_loops: bool) -> Result<TierUp, JitError> {
        let options = JitOptions {
            tier: Tier::Optimised,
            unroll_loops,
        };
        let watch = TierUpWatch::new();
        let results: Arc<Mutex<TierUpResults>> = Arc::default();
        let (tx, rx) = mpsc::channel::<(CacheKey, Vec<UpgradeWord>)>();
        let (shared, finished) = (watch.clone(), results.clone());
        let worker = std::thread::Builder::new()
            .name("primflow-tier1".into())
            .spawn(move || {
                // At the render threads' priority: the frame in flight switches to what this
                // compiles (a worker at nice 10 starved behind two render threads, so a long
                // first frame ran on tier-0 code to its end).
                // Built on the worker so the first frame does not wait for a second ISA, and
                // at the first request the worker may start on, so a frame that holds it
                // (`TierUpWatch::hold`) has the cores to itself.
                let mut built: Option<Result<Jit, JitError>> = None;
                // Its batches compile on one thread, function after function (a one-thread
                // pool; see `batch`): a frame leaves the worker one core (`runtime::tiergate`).
                let mut one_thread: Option<Result<rayon::ThreadPool, rayon::ThreadPoolBuildError>> = None;
                // Ends when the feeding JIT drops its sender.
                while let Ok(((func, key), words)) = rx.recv() {
                    shared.wait_while_held();
                    let jit = built.get_or_insert_with(|| Jit::build(program.clone(), bodies.clone(), options.clone()));
                    let pool = one_thread.get_or_insert_with(|| {
                        rayon::ThreadPoolBuilder::new()
                            .num_threads(1)
                            .thread_name(|_| "primflow-tier1-compile".into())
                            .build()
                    });
                    let result = match (&mut *jit, pool) {
                        (Ok(jit), Ok(pool)) => pool.install(|| jit.kernel(func, &key)),
                        (Err(e), _) => Err(e.clone()),
                        (_, Err(e)) => Err(jit_err("starting the tier-1 compiler's pool", e)),
                    };
                    // The tier-0 kernels of the request's batch switch to their tier-1 twins
                    // (this batch compiled them, or an earlier one did).
                    if let (Ok(jit), Ok(_)) = (&jit, &result) {
                        for (ck, word) in &words {
                            if let Some(k) = jit.cache.get(ck) {
                                word.store(k.entry as usize, Ordering::Release);
                            }
                        }
                    }
                    shared.finish_request(|| {
                        let mut st = finished.lock().unwrap_or_else(|e| e.into_inner());
                        match result {
                            Ok(k) => {
                                if let Some(cost) = jit.as_ref().ok().and_then(|j| j.compile_cost(func, &key)) {
                                    st.costs.insert((func, key.clone()), cost);
                                }
                                st.ready.insert((func, key), k);
                            }
                            Err(e) => {
                                st.failed.insert((func, key), e);
                            }
                        }
                    });
                }
            })
            .map_err(|e| jit_err("starting the tier-1 compiler thread", e))?;
        Ok(TierUp {
            requests: Some(tx),
            watch,
            results,
            worker: Some(worker),
        })
    }

    fn ready(&self, ck: &CacheKey) -> Option<Arc<Kernel>> {
        let st = self.results.lock().unwrap_or_else(|e| e.into_inner());
        st.ready.get(ck).cloned()
    }

    fn cost(&self, ck: &CacheKey) -> Option<CompileCost> {
        let st = self.results.lock().unwrap_or_else(|e| e.into_inner());
        st.costs.get(ck).copied()
    }

    fn request(&self, ck: CacheKey, words: Vec<UpgradeWord>) {
        let Some(tx) = &self.requests else { return };
        self.watch.count_request(|| tx.send((ck, words)).is_ok());
    }

    fn wait(&self) {
        self.watch.wait_idle();
    }
}

impl Drop for TierUp {
    fn drop(&mut self) {
        // Closing the channel ends the worker after its current compile; a hold outliving
        // the JIT must not keep it (and this join) waiting.
        self.requests = None;
        self.watch.close();
        if let Some(w) = self.worker.take() {
            let _ = w.join();
        }
    }
}

impl Jit {
    /// An optimising (tier-1) JIT with loop unrolling: the default.
    pub fn new(program: Arc<Program>) -> Result<Jit, JitError> {
        Jit::with_options(program, JitOptions::default())
    }

    /// A JIT that compiles every kernel at `tier` (no tiering up): the tests comparing
    /// tiers use it.
    pub fn at_tier(program: Arc<Program>, tier: Tier) -> Result<Jit, JitError> {
        Jit::with_options(
            program,
            JitOptions {
                tier,
                ..JitOptions::default()
            },
        )
    }

    /// A tiered JIT: tier-0 kernels at once, tier-1 kernels compiled in the background and
    /// handed out once ready (see the module doc).
    pub fn tiered(program: Arc<Program>) -> Result<Jit, JitError> {
        let mut jit = Jit::with_options(
            program.clone(),
            JitOptions {
                tier: Tier::Fast,
                ..JitOptions::default()
            },
        )?;
        jit.tier_up = Some(TierUp::start(program, jit.bodies.clone(), jit.options.unroll_loops)?);
        Ok(jit)
    }

    /// The tier-1 entry point the tier-0 kernel for (`func`, `key`) now forwards to, once
    /// the worker has compiled it (tiered JITs only; see `lower::lower_kernel`).
    pub fn tier0_forwards_to(&self, func: FuncId, key: &VariantKey) -> Option<KernelFn> {
        let word = self.upgrade_word(func, key)?.load(Ordering::Acquire);
        // SAFETY: the worker stores only entry points of finalized kernels with the kernel
        // signature (`KernelFn`); 0 means none yet.
        (word != 0).then(|| unsafe { std::mem::transmute::<usize, KernelFn>(word) })
    }

    /// The upgrade word of the tier-0 kernel for (`func`, `key`) (tiered JITs only): the
    /// entry its code forwards to, 0 for none. For tests that store a stand-in entry there.
    #[doc(hidden)]
    pub fn upgrade_word(&self, func: FuncId, key: &VariantKey) -> Option<&'static AtomicUsize> {
        self.upgrade_words.get(&(func, key.clone())).copied()
    }

    /// Let the tier-1 worker go without waiting for it, for a process about to exit (dropping
    /// a tiered JIT waits for the compile in progress, so that it does not run on into what the
    /// caller does next): the worker ends after its current compile on its own.
    pub fn detach_tier_up(&mut self) {
        if let Some(mut t) = self.tier_up.take() {
            t.requests = None;
            t.worker = None;
        }
    }

    /// A watch on the background tier-1 compiler (tiered JITs only): the renderer asks it
    /// whether a compile is pending, to leave the worker a core meanwhile.
    pub fn tier_up_watch(&self) -> Option<TierUpWatch> {
        let t = self.tier_up.as_ref()?;
        Some(t.watch.clone())
    }

    /// Stall the tier-1 worker (tiered JITs only): until the returned guard drops it starts
    /// no compile, so every compile requested meanwhile stays pending, while
    /// [`TierUpWatch::activity`] reports it compiling, as a compile that long would. For
    /// tests and measurements of what runs while tier 1 is on its way.
    pub fn stall_tier_up(&self) -> Option<TierUpHold> {
        Some(self.tier_up_watch()?.add_hold(true))
    }

    /// How long a renderer keeps this tiered JIT's worker from starting a compile after a
    /// frame's kernels are compiled, per unit of time compiling them took (default
    /// [`DEFAULT_TIER_UP_GRACE`]; see [`TierUpWatch::grace`]): a frame shorter than that
    /// runs on every thread with the worker out of the way; a longer one then leaves the
    /// worker a thread (`runtime::tiergate`). A negative or NaN factor counts as 0. No-op if
    /// not tiered.
    ///
    /// [`DEFAULT_TIER_UP_GRACE`]: crate::abi::DEFAULT_TIER_UP_GRACE
    pub fn set_tier_up_grace(&mut self, per_compile: f64) {
        if let Some(t) = &self.tier_up {
            let factor = if per_compile >= 0.0 { per_compile } else { 0.0 };
            t.watch.set_grace_per_compile(factor);
        }
    }

    /// Wait until every tier-1 compile requested so far has finished (no-op if not tiered).
    /// A hold without a deadline ([`Jit::stall_tier_up`], [`TierUpWatch::hold`]) kept alive
    /// meanwhile makes this wait until it drops.
    pub fn wait_for_tier_up(&self) {
        if let Some(t) = &self.tier_up {
            t.wait();
        }
    }

    /// The tier-1 kernel of (func, key), if a tiered JIT has it ready.
    pub fn tier_up_kernel(&self, func: FuncId, key: &VariantKey) -> Option<Arc<Kernel>> {
        self.tier_up.as_ref()?.ready(&(func, key.clone()))
    }

    /// What compiling this JIT's own kernel for (func, key) cost (tier 0 in a tiered JIT), if
    /// it compiled one.
    pub fn compile_cost(&self, func: FuncId, key: &VariantKey) -> Option<CompileCost> {
        self.costs.get(&(func, key.clone())).copied()
    }

    /// What the background tier-1 compile of (func, key) cost, once it is ready.
    pub fn tier_up_compile_cost(&self, func: FuncId, key: &VariantKey) -> Option<CompileCost> {
        self.tier_up.as_ref()?.cost(&(func, key.clone()))
    }

    pub fn options(&self) -> &JitOptions {
        &self.options
    }

    pub fn with_options(program: Arc<Program>, options: JitOptions) -> Result<Jit, JitError> {
        let bodies = shared_bodies(&program, options.unroll_loops);
        Jit::build(program, bodies, options)
    }

    /// `func`'s body as lowered (see `bodies`).
    fn body(&self, func: FuncId) -> Arc<Body> {
        body_of(&self.bodies, &self.program, self.options.unroll_loops, func)
    }

    fn build(program: Arc<Program>, bodies: Bodies, options: JitOptions) -> Result<Jit, JitError> {
        let isa = host_isa(options.tier)?;
        let mut builder = JITBuilder::with_isa(isa.clone(), default_libcall_names());
        for f in LibmFn::ALL {
            builder.symbol(f.symbol(), f.address());
        }
        let mut module = JITModule::new(builder);
        let mut libm = HashMap::new();
        for f in LibmFn::ALL {
            let id = module
                .declare_function(f.symbol(), Linkage::Import, &libm_signature(&isa, f))
                .map_err(|e| jit_err("declare libm", e))?;
            libm.insert(f, id);
        }
        Ok(Jit {
            program,
            bodies,
            options,
            tier_up: None,
            isa,
            module,
            cache: HashMap::new(),
            declared: HashMap::new(),
            libm,
            failed: HashMap::new(),
            costs: HashMap::new(),
            upgrade_words: HashMap::new(),
            next_name: 0,
        })
    }

    pub fn program(&self) -> &Arc<Program> {
        &self.program
    }

    fn check_func(&self, func: FuncId) -> Result<(), JitError> {
        if (func.0 as usize) < self.program.functions.len() {
            Ok(())
        } else {
            Err(JitError {
                message: format!("no function with id {}", func.0),
            })
        }
    }

    /// The kernel for `func` under `key`, compiled on first use and cached. Primitives it
    /// calls are compiled for the same key.
    /// A tiered JIT returns the tier-1 kernel once it is ready, the tier-0 one before.
    pub fn kernel(&mut self, func: FuncId, key: &VariantKey) -> Result<Arc<Kernel>, JitError> {
        self.check_func(func)?;
        let ck = (func, key.clone());
        if let Some(t) = &self.tier_up {
            if let Some(k) = t.ready(&ck) {
                return Ok(k);
            }
        }
        if let Some(k) = self.cache.get(&ck) {
            return Ok(k.clone());
        }
        if let Some(e) = self.failed.get(&ck) {
            return Err(e.clone());
        }
        match self.compile_batch_caught(func, key) {
            Ok(words) => {
                if let Some(t) = &self.tier_up {
                    t.request(ck.clone(), words);
                }
                self.cache.get(&ck).cloned().ok_or_else(|| JitError {
                    message: "kernel missing after compilation".into(),
                })
            }
            Err(e) => {
                self.failed.insert(ck, e.clone());
                Err(e)
            }
        }
    }

    /// [`Self::compile_batch`], with a panic turned into an error for `root`. A panic there
    /// is a bug of ours or of Cranelift's (every program that checks must compile; a
    /// `float a[65535]` once panicked the SSA builder), but it must not end the render, and
    /// a tier-1 worker must not die of it: its compile would stay pending for ever, so
    /// waits for it would hang and every later frame would leave it a core.
    fn compile_batch_caught(&mut self, root: FuncId, key: &VariantKey) -> Result<Vec<UpgradeWord>, JitError> {
        let caught = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            let injected = PANIC_AT_TIER_1.get() == Some(&self.program.func(root).name);
            if injected && self.options.tier == Tier::Optimised {
                panic!("a panic for a test");
            }
            self.compile_batch(root, key)
        }));
        caught.unwrap_or_else(|payload| {
            let what = payload
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_default();
            Err(JitError {
                message: format!(
                    "internal compiler error while compiling `{}`: {what}",
                    self.program.func(root).name
                ),
            })
        })
    }

    /// Compile `root` and every not-yet-compiled primitive it reaches under `key`; in a
    /// tiered JIT, the upgrade words of the kernels compiled.
    ///
    /// The functions are lowered and compiled in parallel on the caller's rayon pool
    /// ([`batch`]); then this thread declares and defines them in the order a serial
    /// lowering meets them (depth first from the root, each callee declared where it is first
    /// asked for), so names, module ids and the code's layout do not depend on which thread
    /// finished first. A batch with a function that fails to lower or to compile defines
    /// nothing and reports the error the serial order meets first: the first lowering error,
    /// else the first compile error.
    fn compile_batch(&mut self, root: FuncId, key: &VariantKey) -> Result<Vec<UpgradeWord>, JitError> {
        let (batch_started, batch_cpu) = (Instant::now(), thread_cpu_micros());
        let program = self.program.clone();
        if !self.declared.contains_key(&(root, key.clone())) {
            self.declare_kernel(root, key)?;
        }
        let work = batch::BatchWork::new(
            &program,
            &self.bodies,
            self.options.unroll_loops,
            &self.isa,
            &self.libm,
            key,
            self.options.tier,
            self.tier_up.is_some(),
            &self.cache,
        );
        let tasks_started_cpu = thread_cpu_micros();
        let (mut outcomes, tasks_cpu) = work.run(root);
        // What this thread spent meanwhile is in `tasks_cpu` (the tasks it ran) or waiting.
        let waiting_cpu = thread_cpu_micros().saturating_sub(tasks_started_cpu);
        let mut batch = vec![];
        let mut queued = HashSet::from([root]);
        let mut pending = vec![root];
        while let Some(f) = pending.pop() {
            let outcome = outcomes.remove(&f).ok_or_else(|| JitError {
                message: format!("`{}` was not lowered with its batch", program.func(f).name),
            })?;
            for &callee in &outcome.callees {
                let ck = (callee, key.clone());
                if !self.declared.contains_key(&ck) {
                    self.declare_kernel(callee, key)?;
                }
                // Declared by a batch that failed, a callee still needs its body.
                if !self.cache.contains_key(&ck) && queued.insert(callee) {
                    pending.push(callee);
                }
            }
            match outcome.result {
                Err(batch::Failure::Lowering(e)) => return Err(e),
                result => batch.push((f, result)),
            }
        }
        let mut compiled = vec![];
        for (f, result) in batch {
            match result {
                Ok(c) => compiled.push((f, c)),
                Err(batch::Failure::Compiling(e) | batch::Failure::Lowering(e)) => return Err(e),
            }
        }
        let mut defined = vec![];
        let mut words = vec![];
        for (f, c) in compiled {
            let (started, started_cpu) = (Instant::now(), thread_cpu_micros());
            let ck = (f, key.clone());
            let id = self.declared.get(&ck).copied().ok_or_else(|| JitError {
                message: format!("`{}` was not declared with its batch", program.func(f).name),
            })?;
            let pixels = match &c.pixels {
                Some(code) => Some(self.define_pixels(f, &key, id, code)?),
                None => None,
            };
            let callee = |callee| self.declared.get(&(callee, key.clone())).copied();
            let relocs = c.machine.relocs_for(id, callee, pixels)?;
            self.module
                .define_function_bytes(id, c.machine.alignment, &c.machine.code, &relocs)
                .map_err(|e| JitError {
                    message: format!("compiling `{}`: {e}", program.func(f).name),
                })?;
            if let Some(w) = c.upgrade {
                self.upgrade_words.insert(ck.clone(), w);
                words.push((ck, w));
            }
            let pixels = c.pixels.as_ref();
            let cost = CompileCost {
                wall_micros: c.wall_micros + started.elapsed().as_micros() as u64,
                cpu_micros: c.cpu_micros + thread_cpu_micros().saturating_sub(started_cpu),
                codegen_cpu_micros: c.machine.codegen_cpu_micros + pixels.map_or(0, |p| p.codegen_cpu_micros),
                clif_insts: c.machine.clif_insts + pixels.map_or(0, |p| p.clif_insts),
                ..CompileCost::default()
            };
            defined.push((f, id, c.layout, c.warnings, cost));
        }
        self.module
            .finalize_definitions()
            .map_err(|e| jit_err("finalize kernels", e))?;
        let own_cpu = thread_cpu_micros()
            .saturating_sub(batch_cpu)
            .saturating_sub(waiting_cpu);
        let batch_cpu = own_cpu + tasks_cpu;
        let batch_wall = batch_started.elapsed().as_micros() as u64;
        for (f, id, layout, warnings, cost) in defined {
            let ptr = self.module.get_finalized_function(id);
            // SAFETY: the function was defined with the kernel signature
            // (ctx: i64, args: i64) -> () in the host's default C calling convention, which is
            // `KernelFn`'s ABI; the code lives as long as `self.module`.
            let entry = unsafe { std::mem::transmute::<*const u8, KernelFn>(ptr) };
            self.cache.insert(
                (f, key.clone()),
                Arc::new(Kernel {
                    func: f,
                    key: key.clone(),
                    entry,
                    layout,
                    compile_micros: cost.wall_micros,
                    warnings,
                }),
            );
            self.costs.insert(
                (f, key.clone()),
                CompileCost {
                    batch_cpu_micros: batch_cpu,
                    batch_wall_micros: batch_wall,
                    ..cost
                },
            );
        }
        Ok(words)
    }

    /// Declare and define the second function of `func`'s kernel (module id `kernel`; see
    /// `lower::outline`), named after the kernel with `_pixels` (its pixel loops) or
    /// `_rest` (the rest of a setup split in two); the second function's module id. It
    /// calls the primitives the kernel calls, declared with the batch for `key`.
    fn define_pixels(
        &mut self,
        func: FuncId,
        key: &VariantKey,
        kernel: cranelift_module::FuncId,
        code: &batch::MachineCode,
    ) -> Result<cranelift_module::FuncId, JitError> {
        let name = self
            .module
            .declarations()
            .get_function_decl(kernel)
            .linkage_name(kernel);
        let part = if self.program.func(func).pixel.is_empty() {
            "rest"
        } else {
            "pixels"
        };
        let name = format!("{name}_{part}");
        let sig = lower::pixel_signature(self.isa.default_call_conv());
        let id = self
            .module
            .declare_function(&name, Linkage::Local, &sig)
            .map_err(|e| jit_err("declare pixel function", e))?;
        let callee = |callee| self.declared.get(&(callee, key.clone())).copied();
        let relocs = code.relocs_for(id, callee, None)?;
        self.module
            .define_function_bytes(id, code.alignment, &code.code, &relocs)
            .map_err(|e| JitError {
                message: format!("compiling `{}`'s second function: {e}", self.program.func(func).name),
            })?;
        Ok(id)
    }

    /// Declare the kernel for (`func`, `key`) in the module as `pf_<primitive>_t<tier>_<n>`
    /// (unique by the number `next_name` gives). The name is what profilers show: with
    /// `PERF_BUILDID_DIR` set, cranelift-jit lists every kernel in `/tmp/perf-<pid>.map`
    /// (docs/performance.md, "Profiling kernels").
    fn declare_kernel(&mut self, func: FuncId, key: &VariantKey) -> Result<(), JitError> {
        let prim = &self.program.func(func).name;
        let tier = match self.options.tier {
            Tier::Fast => 0,
            Tier::Optimised => 1,
        };
        let name = format!(
            "pf_{}_t{tier}_{}",
            prim.replace(|c: char| !c.is_ascii_alphanumeric(), "_"),
            self.next_name
        );
        self.next_name += 1;
        let id = self
            .module
            .declare_function(&name, Linkage::Local, &kernel_signature(&self.isa))
            .map_err(|e| jit_err("declare kernel", e))?;
        self.declared.insert((func, key.clone()), id);
        Ok(())
    }

    /// The Cranelift IR text of `func` specialised for `key` (for `check --emit clif`): the
    /// kernel, and after it its outlined pixel function where tier 0 made one.
    pub fn clif(&self, func: FuncId, key: &VariantKey) -> Result<String, JitError> {
        let (kernel, pixels) = self.lower_for_print(func, key)?;
        let mut text = kernel.display().to_string();
        if let Some(p) = pixels {
            text.push('\n');
            text.push_str(&p.display().to_string());
        }
        Ok(text)
    }

    /// `func` lowered for `key` into a CLIF function of its own (and its outlined pixel
    /// function, if any), calls to other primitives left as declarations (for [`Jit::clif`]
    /// and [`Jit::disassembly`]).
    fn lower_for_print(
        &self,
        func: FuncId,
        key: &VariantKey,
    ) -> Result<(ir::Function, Option<ir::Function>), JitError> {
        self.check_func(func)?;
        let layout = ArgLayout::new(&self.program, func, key);
        let mut f = ir::Function::with_name_signature(UserFuncName::user(0, func.0), kernel_signature(&self.isa));
        let mut fctx = FunctionBuilderContext::new();
        let mut pf = ir::Function::with_name_signature(
            UserFuncName::user(0, PRINTED_PIXEL_INDEX),
            ir::Signature::new(self.isa.default_call_conv()),
        );
        let mut pfctx = FunctionBuilderContext::new();
        let mut linker = PrintLinker { isa: &self.isa };
        let body = self.body(func);
        let plan = crate::mid::plan(&self.program, func, &body, key, self.options.tier)?;
        let lowered = lower::lower_kernel(
            &self.program,
            &plan,
            key,
            &layout,
            &mut f,
            &mut fctx,
            Some((&mut pf, &mut pfctx)),
            &mut linker,
            self.isa.frontend_config(),
            // The shape a tiered JIT compiles, with a word no worker ever fills.
            self.tier_up.as_ref().map(|_| {
                static PRINTED_ONLY: AtomicUsize = AtomicUsize::new(0);
                &PRINTED_ONLY as *const AtomicUsize
            }),
        )?;
        Ok((f, lowered.outlined.then_some(pf)))
    }

    /// The machine code of `func` specialised for `key` as Cranelift prints it after register
    /// allocation (this JIT's tier and flags; the kernel is compiled but not installed).
    /// With it, the count of the register allocator's spill and reload instructions (tier 0's
    /// single-pass allocator spills much; see `examples/compile_probe.rs`'s `disasm=FILE`).
    pub fn disassembly(&self, func: FuncId, key: &VariantKey) -> Result<Disassembly, JitError> {
        let (kernel, pixels) = self.lower_for_print(func, key)?;
        let mut all = self.disassemble(func, kernel)?;
        if let Some(p) = pixels {
            let p = self.disassemble(func, p)?;
            all.text.push('\n');
            all.text.push_str(&p.text);
            all.spill_lines += p.spill_lines;
            all.inst_lines += p.inst_lines;
        }
        Ok(all)
    }

    /// Compile `f` (lowered from `func`) and take its listing.
    fn disassemble(&self, func: FuncId, f: ir::Function) -> Result<Disassembly, JitError> {
        let mut ctx = Context::for_function(f);
        // The slot area's layout as Cranelift computes it (`FrameLayout`): each explicit slot
        // aligned to max(its alignment, a word), then the spill slots.
        let explicit_bytes = ctx.func.sized_stack_slots.values().fold(0u32, |end, slot| {
            let align = (1u32 << slot.align_shift).max(8);
            end.next_multiple_of(align) + slot.size
        });
        let explicit_bytes = explicit_bytes.next_multiple_of(8);
        ctx.set_disasm(true);
        let code = ctx.compile(&*self.isa, &mut Default::default()).map_err(|e| JitError {
            message: format!("compiling `{}`: {:?}", self.program.func(func).name, e.inner),
        })?;
        Ok(Disassembly::new(code.vcode.clone().unwrap_or_default(), explicit_bytes))
    }

    /// The target ISA, the flags it was built with and the vector width kernels use.
    pub fn isa_summary(&self) -> String {
        let flags = self.isa.isa_flags();
        let flag = |name: &str| {
            flags
                .iter()
                .find(|v| v.name == name)
                .and_then(|v| v.as_bool())
                .unwrap_or(false)
        };
        let tiers = match (self.options.tier, self.tier_up.is_some()) {
            (_, true) => {
                "tiered (tier 0: single_pass regalloc, opt_level=none; tier 1 in the background: opt_level=speed)"
            }
            (Tier::Fast, false) => "tier 0 (single_pass regalloc, opt_level=none)",
            (Tier::Optimised, false) => "opt_level=speed",
        };
        format!(
            "{} {tiers} has_sse41={} has_avx={} has_avx2={} has_fma={} has_avx512f={}; \
             4 pixels per group (f32x4)",
            self.isa.triple(),
            flag("has_sse41"),
            flag("has_avx"),
            flag("has_avx2"),
            flag("has_fma"),
            flag("has_avx512f"),
        )
    }
}
