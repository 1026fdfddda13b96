//! Tier 0's pixel loops as a function of their own, compiled on another core.
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
//! The pixel function is lowered by the same `Lower`, its builder swapped in at the split,
//! so every analysis and every piece of state the pixel code reads (frames, hoists, the
//! frame layout) carries over unchanged. What names a function's own entities is made to
//! mean the same in the new one:
//! - SSA `Variable`s: the pixel function declares the kernel's variables again, in the
//!   same order with the same types (`Lower::var_types`); the fuel and the pass rectangle's
//!   variables start from `ctx` and the parameters, the others are never read before they
//!   are assigned (uniform locals the pixel code reads live on the stack by then).
//! - Stack slots: the new function starts with one empty placeholder per slot of the
//!   kernel, so slot numbers keep their meaning, and `Lower::slot_addr` gives a kernel
//!   slot's address from the `slots` table the kernel passes (word `n` the address of
//!   slot `n`, every slot of the kernel: which ones the pixel code reads is known only
//!   after the kernel is finished).
//! - The fuel goes through `ctx.fuel` around the call; run-time errors of the pixel code
//!   go to `ctx` directly, as in the kernel (the setup's deferred errors are flushed
//!   before the split).
//!
//! Results are bit-identical to the single function (the same instructions on the same
//! values; `tests/jit_tier0.rs` and `tests/jit_tiers.rs` compare tiers). Tier 1 keeps one
//! function: it compiles in the background, and its optimisations work across the split.

use cranelift_codegen::ir::{self, types, AbiParam, InstBuilder, StackSlot, StackSlotData, StackSlotKind};
use cranelift_frontend::{FunctionBuilder, FunctionBuilderContext};

use super::{stack_check, Lower, Res};
use crate::jit::value::{ctx_off, mem_flags};

/// Where the pixel function goes (see the module doc).
#[derive(Default)]
pub(crate) struct Outline<'b> {
    /// The function the pixel loops go to, until the lowering reaches them; `None`: the
    /// kernel is lowered as one function.
    target: Option<(&'b mut ir::Function, &'b mut FunctionBuilderContext)>,
    /// Slots numbered below this are the kernel's (placeholders in the pixel function).
    inherited: u32,
    /// In the pixel function: the `slots` parameter, the kernel's slot addresses.
    table: Option<ir::Value>,
    /// The pixel loops were outlined.
    pub done: bool,
}

impl<'b> Outline<'b> {
    /// Outline into `target` (`None`: lower the kernel as one function).
    pub fn new(target: Option<(&'b mut ir::Function, &'b mut FunctionBuilderContext)>) -> Outline<'b> {
        Outline {
            target,
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

impl<'a, 'b> Lower<'a, 'b> {
    /// At the start of the render path (the current block), if there is a pixel function
    /// to lower into: finish the kernel with a call to it, hand the kernel to the linker
    /// ([`super::Linker::kernel_finished`]), and continue in the pixel function.
    pub(super) fn begin_outlined_pixels(&mut self) -> Res<()> {
        let Some((func, fctx)) = self.outline.target.take() else {
            return Ok(());
        };
        // The kernel: every slot's address in the table (three for screen_triangle and
        // the sphere; which ones the pixel code reads is known only after lowering it),
        // the fuel through `ctx`, the call, and the kernel's end.
        let inherited = self.b.func.sized_stack_slots.len() as u32;
        let table =
            self.b
                .create_sized_stack_slot(StackSlotData::new(StackSlotKind::ExplicitSlot, 8 * inherited.max(1), 3));
        let table_addr = self.slot_addr(table);
        for n in 0..inherited {
            let addr = self.slot_addr(StackSlot::from_u32(n));
            self.b.ins().store(mem_flags(), addr, table_addr, 8 * n as i32);
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

        // The pixel function, lowered by this `Lower` from here on.
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
        self.dead_blocks.clear();
        self.live_targets.clear();
        self.sealed_early.clear();
        self.vn.forget();
        self.outline.inherited = inherited;
        self.outline.table = Some(params[2]);
        stack_check(&mut self.b, self.ctx, self.func_id);
        for (k, &p) in params[3..7].iter().enumerate() {
            self.b.def_var(self.bound_vars[k], p);
        }
        let fuel = self.load_ctx(types::I64, ctx_off::FUEL);
        self.b.def_var(self.fuel, fuel);
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
