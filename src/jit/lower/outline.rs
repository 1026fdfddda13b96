//! Tier 0 splits a kernel into two functions, compiled on two cores: its pixel loops, or
//! the second half of a large setup.
//!
//! A tier-0 compile is what a scene's first frame waits for, and Cranelift's part of it
//! grows with the function's instructions (~0.7 us per CLIF instruction on the 2-core VM;
//! docs/performance.md). A kernel is its setup (scalar, ~600 instructions for
//! screen_triangle, ~1000 for the lit sphere) and its pixel loops (~370, ~500), and at tier
//! 0 the loops read nothing of the setup but the uniform frame, other stack slots and the
//! four numbers of the pass rectangle (`spill_uniforms` has stored every uniform local the
//! pixel code reads). So tier 0 lowers the loops into a second function,
//! `pixels(ctx, args, slots, x_lo, y_lo, x_hi, y_hi)`, which the kernel calls where the
//! loops were. The kernel ends with that call, so it is finished when the lowering reaches
//! the loops ([`Lower::begin_outlined_pixels`]): the linker takes it then
//! ([`super::Linker::kernel_finished`]) and the batch ([`crate::jit`]'s `batch`) has
//! another thread compile it while this one lowers and compiles the pixel function. The
//! compile's wall time becomes the setup's lowering plus the larger of the kernel's
//! compile and the pixel function's lowering and compile.
//!
//! A kernel without pixel loops whose setup is large (NURB's tessellation, ~4 400
//! instructions in one function) is split the same way before the top-level setup
//! statement that halves it best ([`crate::mid::split`], [`Lower::begin_outlined_setup`]):
//! the second function runs the rest of the setup. Its locals are the kernel's, so the
//! SSA variables of locals both halves use are stored after the slot addresses in the
//! table and defined from there at the second function's entry; the kernel's deferred
//! errors are flushed before the call, and the second function defers its own.
//!
//! The second function is lowered by the same `Lower`, its builder swapped in at the split,
//! so every analysis and every piece of state the code after the split reads (frames,
//! hoists, the frame layout) carries over unchanged. What names a function's own entities
//! is made to mean the same in the new one:
//! - SSA `Variable`s: the second function declares the kernel's variables again, in the
//!   same order with the same types (`Lower::var_types`); the fuel and the pass rectangle's
//!   variables start from `ctx` and the parameters, the carried ones from the table, the
//!   others are never read before they are assigned (uniform locals the pixel code reads
//!   live on the stack by then) or read as zero in both forms.
//! - Stack slots: the new function starts with one empty placeholder per slot of the
//!   kernel, so slot numbers keep their meaning, and `Lower::slot_addr` gives a kernel
//!   slot's address from the `slots` table the kernel passes (word `n` the address of
//!   slot `n`, every slot of the kernel: which ones the second function reads is known only
//!   after the kernel is finished).
//! - The setup fuel goes through `ctx.fuel` around the call (the pixel loops spend their
//!   groups' fuel, from `ctx.group_fuel`); run-time errors of the pixel code are recorded
//!   and counted in `ctx` directly, as in the kernel (the setup's deferred errors are
//!   flushed before the split).
//!
//! Results are bit-identical to the single function (the same instructions on the same
//! values; `tests/jit/tier0.rs` and `tests/jit/tiers.rs` compare tiers). Tier 1 keeps one
//! function: it compiles in the background, and its optimisations work across the split.

use cranelift_codegen::entity::EntityRef;
use cranelift_codegen::ir::{self, types, AbiParam, InstBuilder, StackSlot, StackSlotData, StackSlotKind};
use cranelift_frontend::{FunctionBuilder, FunctionBuilderContext, Variable};

use super::{err, stack_check, Lower, Res, Storage};
use crate::ir::Function;
use crate::jit::value::{ctx_off, mem_flags};

/// Where the second function goes (see the module doc).
#[derive(Default)]
pub(crate) struct Outline<'b> {
    /// The function the pixel loops (or the setup's second half) go to, until the lowering
    /// reaches them; `None`: the kernel is lowered as one function.
    target: Option<(&'b mut ir::Function, &'b mut FunctionBuilderContext)>,
    /// A kernel without pixel loops: the top-level setup statement its second function
    /// starts with ([`crate::mid::split`]).
    pub setup_split: Option<usize>,
    /// Slots numbered below this are the kernel's (placeholders in the second function).
    inherited: u32,
    /// In the second function: the `slots` parameter, the kernel's slot addresses.
    table: Option<ir::Value>,
    /// The kernel was split.
    pub done: bool,
}

impl<'b> Outline<'b> {
    /// Split `f`'s kernel into `target` where it pays (`None`: lower it as one function):
    /// before its pixel loops, or without any before top-level setup statement `split_at`
    /// (the plan's [`crate::mid::split::SetupSplit`]).
    pub fn new(
        target: Option<(&'b mut ir::Function, &'b mut FunctionBuilderContext)>,
        f: &Function,
        split_at: Option<usize>,
    ) -> Outline<'b> {
        let setup_split = match (&target, f.pixel.is_empty()) {
            (Some(_), true) => split_at,
            _ => None,
        };
        let wanted = !f.pixel.is_empty() || setup_split.is_some();
        Outline {
            target: target.filter(|_| wanted),
            setup_split,
            ..Default::default()
        }
    }
}

/// The pixel function's signature: `(ctx, args, slots, x_lo, y_lo, x_hi, y_hi)`.
pub(crate) fn pixel_signature(call_conv: cranelift_codegen::isa::CallConv) -> ir::Signature {
    let mut sig = ir::Signature::new(call_conv);
    for ty in [types::I64, types::I64, types::I64] {
        sig.params.push(AbiParam::new(ty));
    }
    for _ in 0..4 {
        sig.params.push(AbiParam::new(types::F32));
    }
    sig
}

/// Bytes a carried variable of type `ty` takes in the slot table (vectors 16, others 8).
fn carried_bytes(ty: ir::Type) -> u32 {
    if ty.is_vector() {
        16
    } else {
        8
    }
}

impl<'a, 'b> Lower<'a, 'b> {
    /// At the start of the render path (the current block), if there is a pixel function
    /// to lower into: finish the kernel with a call to it, hand the kernel to the linker
    /// ([`super::Linker::kernel_finished`]), and continue in the pixel function.
    pub(super) fn begin_outlined_pixels(&mut self) -> Res<()> {
        self.split_function(&[])
    }

    /// Before top-level setup statement `split` (the current block; the setup's deferred
    /// guards are resolved): finish the kernel with a call to the second function and
    /// continue in it, as [`Self::begin_outlined_pixels`] does. The SSA variables of the
    /// locals both halves use are carried through the slot table; the kernel's deferred
    /// errors are flushed first (they come before any the second half records), and the
    /// second function defers its own into its own setup exit.
    pub(super) fn begin_outlined_setup(&mut self, split: usize) -> Res<()> {
        let plan = self.plan;
        let shared = match &plan.setup_split {
            Some(s) if s.at == split => &s.shared,
            _ => return err("a setup split the plan does not have"),
        };
        let mut carried = vec![];
        for (i, st) in self.frames[0].storage.iter().enumerate() {
            if shared.get(i).copied().unwrap_or(false) {
                match st {
                    Storage::Vars(vars) => carried.extend(vars.iter().copied()),
                    Storage::Z(var) => carried.push(*var),
                    Storage::Stack(_) | Storage::Frame(_) | Storage::Args => {}
                }
            }
        }
        self.flush_errors();
        let deferring = self.setup_exit.is_some();
        self.exit = self.kernel_exit;
        self.split_function(&carried)?;
        if deferring {
            let none = self.iconst_here(types::I32, 0);
            self.b.def_var(self.pending_error, none);
            let setup_exit = self.b.create_block();
            self.setup_exit = Some(setup_exit);
            self.exit = setup_exit;
        }
        Ok(())
    }

    /// Finish the kernel with a call to the second function and continue lowering into it
    /// (see the module doc); `carried`: variables whose values go along in the slot table.
    fn split_function(&mut self, carried: &[Variable]) -> Res<()> {
        let Some((func, fctx)) = self.outline.target.take() else {
            return Ok(());
        };
        // The kernel: every slot's address in the table (three for screen_triangle and
        // the sphere; which ones the second function reads is known only after lowering
        // it), then the carried values, the fuel through `ctx`, the call, and the
        // kernel's end.
        let inherited = self.b.func.sized_stack_slots.len() as u32;
        // Each carried variable with its type and its offset in the table.
        let mut table_bytes = 8 * inherited;
        let carried: Vec<(Variable, ir::Type, i32)> = carried
            .iter()
            .map(|&v| {
                let ty = self.var_types[v.index()];
                let at = table_bytes;
                table_bytes += carried_bytes(ty);
                (v, ty, at as i32)
            })
            .collect();
        let table =
            self.b
                .create_sized_stack_slot(StackSlotData::new(StackSlotKind::ExplicitSlot, table_bytes.max(8), 3));
        let table_addr = self.slot_addr(table);
        for n in 0..inherited {
            let addr = self.slot_addr(StackSlot::from_u32(n));
            self.b.ins().store(mem_flags(), addr, table_addr, 8 * n as i32);
        }
        for &(var, _, at) in &carried {
            let v = self.b.use_var(var);
            self.b.ins().store(mem_flags(), v, table_addr, at);
        }
        let fuel = self.b.use_var(self.fuel);
        self.store_ctx(fuel, ctx_off::FUEL);
        let sig = pixel_signature(self.b.func.signature.call_conv);
        let fref = self.linker.pixel_ref(self.b.func, sig)?;
        let mut call_args = vec![self.ctx, self.args, table_addr];
        for k in 0..4 {
            call_args.push(self.b.use_var(self.bound_vars[k]));
        }
        self.b.ins().call(fref, &call_args);
        let fuel = self.load_ctx(types::I64, ctx_off::FUEL);
        self.b.def_var(self.fuel, fuel);
        self.finish_function();
        self.b.seal_all_blocks();
        self.count_stack_error();

        // The second function, lowered by this `Lower` from here on.
        func.signature = pixel_signature(self.b.func.signature.call_conv);
        for _ in 0..inherited {
            func.create_sized_stack_slot(StackSlotData::new(StackSlotKind::ExplicitSlot, 0, 0));
        }
        let mut b = FunctionBuilder::new(func, fctx);
        let entry = b.create_block();
        b.append_block_params_for_function_params(entry);
        b.switch_to_block(entry);
        b.seal_block(entry);
        for &ty in &self.var_types {
            b.declare_var(ty);
        }
        let params = b.block_params(entry).to_vec();
        let kernel = std::mem::replace(&mut self.b, b);
        self.linker.kernel_finished(kernel.func);
        // If the linker took the function, `finalize` checks the builder's own state (every
        // block sealed and filled) and clears it for the next function; Cranelift's
        // verifier checks the function itself when it is compiled (debug builds).
        kernel.finalize(self.frontend);
        self.ctx = params[0];
        self.args = params[1];
        self.exit = self.b.create_block();
        self.kernel_exit = self.exit;
        self.dead_blocks.clear();
        self.live_targets.clear();
        self.sealed_early.clear();
        self.vn.forget();
        self.outline.inherited = inherited;
        self.outline.table = Some(params[2]);
        self.stack_count = Some(stack_check(&mut self.b, self.ctx, self.func_id));
        for (k, &p) in params[3..7].iter().enumerate() {
            self.b.def_var(self.bound_vars[k], p);
        }
        let fuel = self.load_ctx(types::I64, ctx_off::FUEL);
        self.b.def_var(self.fuel, fuel);
        for &(var, ty, at) in &carried {
            let v = self.b.ins().load(ty, mem_flags(), params[2], at);
            self.b.def_var(var, v);
        }
        self.outline.done = true;
        Ok(())
    }

    /// The address of kernel slot `slot` in the pixel function (`None` elsewhere, and for
    /// the pixel function's own slots): the word the kernel stored in the slot table.
    pub(super) fn inherited_slot_addr(&mut self, slot: ir::StackSlot) -> Option<ir::Value> {
        let table = self.outline.table.filter(|_| slot.as_u32() < self.outline.inherited)?;
        Some(
            self.b
                .ins()
                .load(types::I64, mem_flags(), table, 8 * slot.as_u32() as i32),
        )
    }
}
