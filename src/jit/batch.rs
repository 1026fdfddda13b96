//! Lowering and compiling a batch's functions in parallel, on the caller's rayon pool.
//!
//! A batch is a root kernel and every not-yet-compiled primitive it reaches (see
//! `Jit::compile_batch`). Which functions those are is only known for sure by lowering: a
//! callee is found when its caller's lowering asks for it. So each function is one task
//! that lowers it and compiles the CLIF to machine code with Cranelift
//! (`Context::compile`), and a lowering queues the task of each callee the moment it first
//! asks for it ([`BatchWork::start`]); at tier 0 a task first queues those of every
//! primitive its function's IR calls, so they do not wait for the caller's lowering to
//! reach the calls (a call the variant never lowers costs a compile nobody uses).
//! The calling thread runs the root's task itself: the root is the largest function of
//! every batch in the library (nurb_surface is 90 % of its batch's CLIF), so it gets a
//! thread from the start and keeps it from lowering to machine code, while idle threads of
//! the pool take the queued callees (the global pool's, when the caller is in none). Then
//! the calling thread takes whatever no other thread has started: it only ever waits for
//! work in progress elsewhere, never for a pool too busy to start it. A batch of one
//! function never leaves the calling thread, and in a one-thread pool the tasks run one
//! after another. At tier 0 a kernel's lowering also makes a second function, its pixel
//! loops or the second half of a large setup (`lower::outline`), and the kernel is finished
//! before the second function is lowered: its compile is queued as a task of its own then,
//! so another thread compiles it while the lowering's thread lowers and compiles the second
//! function. For that thread to be there in
//! time, a tier-0 batch starts with a pool job that waits for tasks until the calling
//! thread is done ([`BatchWork::help`]).
//!
//! Nothing here touches the JIT module: declaring functions needs it mutably and numbers
//! them in the order the serial lowering met them, and the machine code must not depend on
//! which thread finished first. So a lowering refers to a callee by a placeholder name
//! ([`CALLEE_NAMESPACE`], the callee's `FuncId`) and records the callees in the order it
//! asked for them; the calling thread then replays the serial order, declaring as the
//! serial lowering did, and resolves the placeholders in the relocations
//! ([`CompiledFunction::relocs_for`]). Machine code does not depend on a callee's name, only
//! on its signature and on whether it is colocated, which the placeholder import shares with
//! the real one, so every function's bytes are those a serial compile gives.

use std::collections::{HashMap, HashSet, VecDeque};
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::Instant;

use cranelift_codegen::ir::{self, UserExternalName, UserFuncName};
use cranelift_codegen::isa::OwnedTargetIsa;
use cranelift_codegen::Context;
use cranelift_module::{FuncId as ModuleFuncId, ModuleReloc, ModuleRelocTarget};

use super::libm::LibmFn;
use super::lower::{self, Linker, Res};
use super::{give_back_context, kernel_signature, libm_signature, take_context, Bodies, CacheKey, Kernel, Tier};
use super::{JitError, SPARE_BUILDER_CONTEXTS};
use crate::abi::{ArgLayout, VariantKey};
use crate::ir::{FuncId, Program, StmtKind};

/// The namespace of the placeholder names a batch's lowerings give callees (index: the
/// callee's `FuncId`); the module's own names are namespace 0.
const CALLEE_NAMESPACE: u32 = 2;

/// The namespace of the placeholder name a kernel's lowering gives its outlined pixel
/// function (index: the kernel's `FuncId`; see `lower::outline`).
const PIXELS_NAMESPACE: u32 = 3;

/// Stands for the function's own module `FuncId` in relocations to an offset inside it,
/// until the function is declared. (`u32::MAX` is the entity types' reserved value, which
/// `FuncId::from_u32` rejects in debug builds.)
const OWN_ID_PLACEHOLDER: u32 = u32::MAX - 1;

/// One function of a batch, lowered and compiled.
pub(super) struct CompiledFunction {
    /// The kernel's machine code (where tier 0 outlined its pixel loops, compiled by a task
    /// of its own and put here when the batch ends).
    pub machine: MachineCode,
    /// Tier 0: the kernel's outlined pixel function (see `lower::outline`), which its
    /// machine code calls.
    pub pixels: Option<MachineCode>,
    pub layout: ArgLayout,
    pub warnings: Vec<crate::abi::KernelWarning>,
    /// A tiered JIT's upgrade word, which the code reads (see `super::UpgradeWord`).
    pub upgrade: Option<&'static AtomicUsize>,
    /// Lowering and compiling it (and the kernel compiled apart from its outlined pixel
    /// function, on whichever thread compiled that): wall time and CPU time, microseconds.
    pub wall_micros: u64,
    pub cpu_micros: u64,
    started: Instant,
}

impl MachineCode {
    /// The relocations with names resolved: `own`, this function's module id, `callee`,
    /// each callee's, and `pixels`, the outlined pixel function's (all declared by now).
    pub fn relocs_for(
        &self,
        own: ModuleFuncId,
        callee: impl Fn(FuncId) -> Option<ModuleFuncId>,
        pixels: Option<ModuleFuncId>,
    ) -> Result<Vec<ModuleReloc>, JitError> {
        self.relocs
            .iter()
            .map(|r| {
                let name = match r.name {
                    ModuleRelocTarget::User {
                        namespace: PIXELS_NAMESPACE,
                        ..
                    } => {
                        let id = pixels.ok_or_else(|| JitError {
                            message: "pixel function not declared".into(),
                        })?;
                        ModuleRelocTarget::user(0, id.as_u32())
                    }
                    ModuleRelocTarget::User {
                        namespace: CALLEE_NAMESPACE,
                        index,
                    } => {
                        let id = callee(FuncId(index)).ok_or_else(|| JitError {
                            message: format!("callee {index} not declared"),
                        })?;
                        ModuleRelocTarget::user(0, id.as_u32())
                    }
                    ModuleRelocTarget::FunctionOffset(_, offset) => ModuleRelocTarget::FunctionOffset(own, offset),
                    ref other => other.clone(),
                };
                Ok(ModuleReloc { name, ..r.clone() })
            })
            .collect()
    }
}

/// What Cranelift made of one lowered function.
#[derive(Default)]
pub(super) struct MachineCode {
    /// The machine code (its relocations not applied).
    pub code: Vec<u8>,
    pub alignment: u64,
    /// Relocations with placeholder names (see [`CompiledFunction::relocs_for`]).
    relocs: Vec<ModuleReloc>,
    /// Thread CPU time of Cranelift's `Context::compile`, microseconds.
    pub codegen_cpu_micros: u64,
    /// Instructions of the CLIF compiled.
    pub clif_insts: u64,
}

/// Why a function of a batch has no machine code. A lowering error ends the serial batch
/// where it happens; a compile error only after every function is lowered.
pub(super) enum Failure {
    Lowering(JitError),
    Compiling(JitError),
}

/// Closes a batch's queue when dropped (see [`BatchWork::help`]).
struct CloseOnDrop<'w, 'j>(&'w BatchWork<'j>);

impl Drop for CloseOnDrop<'_, '_> {
    fn drop(&mut self) {
        self.0.queue.lock().unwrap_or_else(|e| e.into_inner()).closed = true;
        self.0.queued.notify_all();
    }
}

/// A kernel compiled apart from its lowering (tier 0, pixel loops outlined).
struct CompiledApart {
    code: Result<MachineCode, Failure>,
    /// When its compile ended, and its thread's CPU time, microseconds.
    done: Instant,
    cpu_micros: u64,
}

/// A batch's queued tasks no thread has taken yet, first queued first.
#[derive(Default)]
struct Queue {
    tasks: VecDeque<Task>,
    /// The calling thread has run out of work: the helper leaves (see [`BatchWork::help`]).
    closed: bool,
}

/// A batch's unit of work.
enum Task {
    /// Lower and compile this function.
    Lower(FuncId),
    /// Compile this kernel, lowered into the context (its pixel loops outlined, their
    /// function lowered and compiled by the kernel's task).
    CompileKernel(FuncId, Box<Context>),
}

/// What a batch's task made of one function.
pub(super) struct Outcome {
    /// The kernels its lowering asked for, in order, repeats included (the serial lowering
    /// declared them in this order).
    pub callees: Vec<FuncId>,
    pub result: Result<CompiledFunction, Failure>,
}

/// What a batch's tasks share: what they read from the JIT and what they hand back.
pub(super) struct BatchWork<'j> {
    program: &'j Program,
    bodies: &'j Bodies,
    unroll_loops: bool,
    isa: &'j OwnedTargetIsa,
    libm: &'j HashMap<LibmFn, ModuleFuncId>,
    key: &'j VariantKey,
    tier: Tier,
    /// A tiered JIT: each kernel reads an upgrade word.
    tiered: bool,
    /// Kernels compiled by earlier batches (not compiled again).
    compiled: &'j HashMap<CacheKey, Arc<Kernel>>,
    /// Functions whose task has been queued.
    started: Mutex<HashSet<FuncId>>,
    queue: Mutex<Queue>,
    /// Signalled when a task is queued and when the queue is closed (see [`Self::help`]).
    queued: Condvar,
    outcomes: Mutex<HashMap<FuncId, Outcome>>,
    /// Kernels compiled apart from their lowering, by kernel.
    compiled_apart: Mutex<HashMap<FuncId, CompiledApart>>,
    /// Thread CPU time of every task, microseconds.
    cpu_micros: AtomicU64,
}

impl<'j> BatchWork<'j> {
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        program: &'j Program,
        bodies: &'j Bodies,
        unroll_loops: bool,
        isa: &'j OwnedTargetIsa,
        libm: &'j HashMap<LibmFn, ModuleFuncId>,
        key: &'j VariantKey,
        tier: Tier,
        tiered: bool,
        compiled: &'j HashMap<CacheKey, Arc<Kernel>>,
    ) -> BatchWork<'j> {
        BatchWork {
            program,
            bodies,
            unroll_loops,
            isa,
            libm,
            key,
            tier,
            tiered,
            compiled,
            started: Mutex::default(),
            queue: Mutex::default(),
            queued: Condvar::new(),
            outcomes: Mutex::default(),
            compiled_apart: Mutex::default(),
            cpu_micros: AtomicU64::new(0),
        }
    }

    /// Lower and compile `root` (on this thread) and every not-yet-compiled function it
    /// reaches (on the current rayon pool, the global one outside any, and on this thread);
    /// returns each function's outcome and the CPU time of every task.
    pub fn run(self, root: FuncId) -> (HashMap<FuncId, Outcome>, u64) {
        self.started.lock().unwrap_or_else(|e| e.into_inner()).insert(root);
        rayon::in_place_scope(|s| {
            if self.tier == Tier::Fast && rayon::current_num_threads() > 1 {
                s.spawn(|s| self.help(s));
            }
            // Set on the way out, a panic's too: the scope waits for the helper.
            let _close = CloseOnDrop(&self);
            self.lower_and_compile(s, root);
            while self.take_one(s) {}
        });
        let mut outcomes = self.outcomes.into_inner().unwrap_or_else(|e| e.into_inner());
        let mut apart = self.compiled_apart.into_inner().unwrap_or_else(|e| e.into_inner());
        for (&f, outcome) in outcomes.iter_mut() {
            let Ok(c) = &mut outcome.result else { continue };
            if c.pixels.is_none() {
                continue;
            }
            match apart.remove(&f) {
                Some(CompiledApart {
                    code: Ok(code),
                    done,
                    cpu_micros,
                }) => {
                    c.machine = code;
                    c.cpu_micros += cpu_micros;
                    c.wall_micros = c.wall_micros.max(done.duration_since(c.started).as_micros() as u64);
                }
                Some(CompiledApart { code: Err(e), .. }) => outcome.result = Err(e),
                None => {
                    outcome.result = Err(Failure::Compiling(JitError {
                        message: format!("`{}`: kernel not compiled", self.program.func(f).name),
                    }))
                }
            }
        }
        (outcomes, self.cpu_micros.into_inner())
    }

    /// Queue `f`'s task, and a pool job to take one, unless it has been queued or `f` is
    /// compiled already.
    fn start<'s>(&'s self, scope: &rayon::Scope<'s>, f: FuncId) {
        if self.compiled.contains_key(&(f, self.key.clone())) {
            return;
        }
        if self.started.lock().unwrap_or_else(|e| e.into_inner()).insert(f) {
            self.queue(scope, Task::Lower(f));
        }
    }

    /// Queue `task`, and a pool job to take one.
    fn queue<'s>(&'s self, scope: &rayon::Scope<'s>, task: Task) {
        self.queue
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .tasks
            .push_back(task);
        self.queued.notify_one();
        scope.spawn(move |s| {
            self.take_one(s);
        });
    }

    /// Tier 0's helper: from the start of the batch, a pool thread waits for tasks and runs
    /// them until the calling thread is out of work. A kernel is queued when the lowering
    /// reaches its pixel loops (`lower::outline`), a few hundred microseconds before the
    /// calling thread is done with the pixel function; a pool thread woken only then
    /// mostly started after the calling thread had taken the task itself (measured on the
    /// 2-core VM when the pixel function was the queued one: the compile's wall time
    /// equalled the calling thread's CPU time).
    fn help<'s>(&'s self, scope: &rayon::Scope<'s>) {
        let mut queue = self.queue.lock().unwrap_or_else(|e| e.into_inner());
        loop {
            if let Some(task) = queue.tasks.pop_front() {
                drop(queue);
                self.run_task(scope, task);
                queue = self.queue.lock().unwrap_or_else(|e| e.into_inner());
            } else if queue.closed {
                return;
            } else {
                queue = self.queued.wait(queue).unwrap_or_else(|e| e.into_inner());
            }
        }
    }

    /// Run the first queued task, if any is left; whether there was one.
    fn take_one<'s>(&'s self, scope: &rayon::Scope<'s>) -> bool {
        let next = self.queue.lock().unwrap_or_else(|e| e.into_inner()).tasks.pop_front();
        next.map(|task| self.run_task(scope, task)).is_some()
    }

    fn run_task<'s>(&'s self, scope: &rayon::Scope<'s>, task: Task) {
        match task {
            Task::Lower(f) => self.lower_and_compile(scope, f),
            Task::CompileKernel(f, ctx) => self.compile_apart(f, ctx),
        }
    }

    /// Compile kernel `f` (lowered into `ctx`; its pixel loops outlined).
    fn compile_apart(&self, f: FuncId, mut ctx: Box<Context>) {
        let started_cpu = super::thread_cpu_micros();
        let code = self.compile(f, &mut ctx);
        give_back_context(*ctx);
        let cpu = super::thread_cpu_micros().saturating_sub(started_cpu);
        self.cpu_micros.fetch_add(cpu, Ordering::Relaxed);
        self.compiled_apart.lock().unwrap_or_else(|e| e.into_inner()).insert(
            f,
            CompiledApart {
                code,
                done: Instant::now(),
                cpu_micros: cpu,
            },
        );
    }

    /// `f`'s task: lower it (starting its callees' tasks), then compile it.
    fn lower_and_compile<'s>(&'s self, scope: &rayon::Scope<'s>, f: FuncId) {
        let (started, started_cpu) = (Instant::now(), super::thread_cpu_micros());
        if self.tier == Tier::Fast {
            // The helper lowers and compiles the callees while this thread lowers their
            // caller, instead of when the lowering reaches the calls (NURB's are at the end
            // of its setup). A callee the variant does not reach is compiled for nothing:
            // its outcome is left unused (`Jit::compile_batch` walks from the root).
            let func = self.program.func(f);
            for stmts in [&func.setup, &func.pixel] {
                crate::ir::for_each_stmt(&func.stmts, stmts, &mut |_, s| {
                    if let StmtKind::CallPrimitive { callee, .. } = *s {
                        self.start(scope, callee);
                    }
                });
            }
        }
        let mut linker = BatchLinker {
            work: self,
            scope,
            func: f,
            callees: vec![],
        };
        let upgrade: Option<&'static AtomicUsize> = self.tiered.then(|| &*Box::leak(Box::new(AtomicUsize::new(0))));
        let mut ctx = take_context();
        let mut pixels = take_context();
        let lowered = self.lower(f, &mut ctx.func, &mut pixels.func, &mut linker, upgrade);
        let callees = linker.callees;
        // Outlined: the kernel was queued (`BatchLinker::kernel_finished`), this thread
        // compiles the pixel function; the kernel's code joins it when the batch ends.
        let result = lowered.map_err(Failure::Lowering).and_then(|lowered| {
            let (machine, pixels) = match lowered.2 {
                true => (MachineCode::default(), Some(self.compile(f, &mut pixels)?)),
                false => (self.compile(f, &mut ctx)?, None),
            };
            Ok((lowered, machine, pixels))
        });
        give_back_context(ctx);
        give_back_context(pixels);
        let cpu = super::thread_cpu_micros().saturating_sub(started_cpu);
        self.cpu_micros.fetch_add(cpu, Ordering::Relaxed);
        let result = result.map(|((layout, warnings, _), machine, pixels)| CompiledFunction {
            machine,
            pixels,
            layout,
            warnings,
            upgrade,
            wall_micros: started.elapsed().as_micros() as u64,
            cpu_micros: cpu,
            started,
        });
        let outcome = Outcome { callees, result };
        self.outcomes
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .insert(f, outcome);
    }

    /// Compile `ctx`'s function (`f` lowered): its machine code, alignment and relocations
    /// (with placeholder names).
    fn compile(&self, f: FuncId, ctx: &mut Context) -> Result<MachineCode, Failure> {
        let failed = |detail: String| {
            Failure::Compiling(JitError {
                message: format!("compiling `{}`: {detail}", self.program.func(f).name),
            })
        };
        let layout = &ctx.func.layout;
        let clif_insts = layout.blocks().map(|b| layout.block_insts(b).count() as u64).sum();
        let started_cpu = super::thread_cpu_micros();
        let compiled = ctx.compile(&**self.isa, &mut Default::default());
        let codegen_cpu_micros = super::thread_cpu_micros().saturating_sub(started_cpu);
        if let Err(e) = compiled {
            return Err(failed(format!("{:?}", e.inner)));
        }
        let code = ctx
            .compiled_code()
            .ok_or_else(|| failed("no code after compiling".into()))?;
        let placeholder = ModuleFuncId::from_u32(OWN_ID_PLACEHOLDER);
        let relocs = code
            .buffer
            .relocs()
            .iter()
            .map(|r| ModuleReloc::from_mach_reloc(r, &ctx.func, placeholder))
            .collect();
        Ok(MachineCode {
            code: code.code_buffer().to_vec(),
            alignment: code.buffer.alignment as u64,
            relocs,
            codegen_cpu_micros,
            clif_insts,
        })
    }

    /// Lower `f` into `func` (and its pixel loops into `pixels`, where tier 0 outlines
    /// them): its argument layout, the lowering's warnings and whether `pixels` was used.
    fn lower(
        &self,
        f: FuncId,
        func: &mut ir::Function,
        pixels: &mut ir::Function,
        linker: &mut BatchLinker,
        upgrade: Option<&'static AtomicUsize>,
    ) -> Res<(ArgLayout, Vec<crate::abi::KernelWarning>, bool)> {
        let layout = ArgLayout::new(self.program, f, self.key);
        let body = super::body_of(self.bodies, self.program, self.unroll_loops, f);
        let plan = crate::mid::plan(self.program, f, &body, self.key, self.tier)?;
        func.signature = kernel_signature(self.isa);
        func.name = UserFuncName::user(0, f.0);
        pixels.name = UserFuncName::user(PIXELS_NAMESPACE, f.0);
        let [mut fctx, mut pctx] = SPARE_BUILDER_CONTEXTS.with(|spare| {
            let mut spare = spare.borrow_mut();
            [spare.pop().unwrap_or_default(), spare.pop().unwrap_or_default()]
        });
        let lowered = lower::lower_kernel(
            self.program,
            &plan,
            self.key,
            &layout,
            func,
            &mut fctx,
            Some((pixels, &mut pctx)),
            linker,
            self.isa.frontend_config(),
            upgrade.map(|w| w as *const AtomicUsize),
        );
        // A lowering error leaves the builder contexts mid-function; the next kernel must
        // not inherit them, so only clean ones are kept.
        if lowered.is_ok() {
            SPARE_BUILDER_CONTEXTS.with(|spare| spare.borrow_mut().extend([fctx, pctx]));
        }
        let lowered = lowered?;
        Ok((layout, lowered.warnings, lowered.outlined))
    }
}

/// Import `name` into `func` as the module's `declare_func_in_func` does for a function
/// declared with `sig` (`colocated`: its linkage is local to the module).
pub(super) fn import_function(
    func: &mut ir::Function,
    name: UserExternalName,
    sig: ir::Signature,
    colocated: bool,
) -> ir::FuncRef {
    let signature = func.import_signature(sig);
    let name = func.declare_imported_user_function(name);
    func.import_function(ir::ExtFuncData {
        name: ir::ExternalName::user(name),
        signature,
        colocated,
        patchable: false,
    })
}

/// Links a batch's lowering: callees by placeholder name (their tasks started on first
/// use), libm helpers by their module ids.
struct BatchLinker<'s, 'r> {
    work: &'s BatchWork<'s>,
    scope: &'r rayon::Scope<'s>,
    /// The function being lowered.
    func: FuncId,
    callees: Vec<FuncId>,
}

impl Linker for BatchLinker<'_, '_> {
    fn kernel_ref(&mut self, func: &mut ir::Function, callee: FuncId) -> Res<ir::FuncRef> {
        self.callees.push(callee);
        self.work.start(self.scope, callee);
        let name = UserExternalName {
            namespace: CALLEE_NAMESPACE,
            index: callee.0,
        };
        // Kernels are declared `Linkage::Local`: colocated.
        Ok(import_function(func, name, kernel_signature(self.work.isa), true))
    }

    fn libm_ref(&mut self, func: &mut ir::Function, f: LibmFn) -> Res<ir::FuncRef> {
        let id = self.work.libm.get(&f).ok_or_else(|| JitError {
            message: format!("libm function {f:?} not declared"),
        })?;
        let name = UserExternalName {
            namespace: 0,
            index: id.as_u32(),
        };
        // Imported (`Linkage::Import`): not colocated.
        Ok(import_function(func, name, libm_signature(self.work.isa, f), false))
    }

    fn pixel_ref(&mut self, func: &mut ir::Function, sig: ir::Signature) -> Res<ir::FuncRef> {
        let name = UserExternalName {
            namespace: PIXELS_NAMESPACE,
            index: self.func.0,
        };
        // Declared `Linkage::Local` with its kernel: colocated.
        Ok(import_function(func, name, sig, true))
    }

    fn kernel_finished(&mut self, func: &mut ir::Function) {
        let mut ctx = Box::new(take_context());
        std::mem::swap(&mut ctx.func, func);
        self.work.queue(self.scope, Task::CompileKernel(self.func, ctx));
    }
}
