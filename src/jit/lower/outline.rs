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
//! loops were, and the batch ([`crate::jit`]'s `batch`) compiles the two at once: the
//! compile's wall time becomes the lowering plus the larger of the two.
//!
//! The pixel function is lowered by the same `Lower`, its builder swapped in at the split
//! ([`Lower::begin_outlined_pixels`]) and out again at the end
//! ([`Lower::end_outlined_pixels`]), so every analysis and every piece of state the pixel
//! code reads (frames, hoists, the frame layout) carries over unchanged. What names a
//! function's own entities is made to mean the same in the new one:
//! - SSA `Variable`s: the pixel function declares the kernel's variables again, in the
//!   same order with the same types (`Lower::var_types`); the fuel and the pass rectangle's
//!   variables start from `ctx` and the parameters, the others are never read before they
//!   are assigned (uniform locals the pixel code reads live on the stack by then).
//! - Stack slots: the new function starts with one empty placeholder per slot of the
//!   kernel, so slot numbers keep their meaning, and `Lower::slot_addr` gives a kernel
//!   slot's address from the `slots` table the kernel passes (one word per slot the
//!   pixel code addressed, filled by the kernel right before the call).
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

/// Where the pixel function goes and what the split swapped out (see the module doc).
#[derive(Default)]
pub(crate) struct Outline<'b> {
    /// The function the pixel loops go to, until the lowering reaches them; `None`: the
    /// kernel is lowered as one function.
    target: Option<(&'b mut ir::Function, &'b mut FunctionBuilderContext)>,
    /// While the pixel function is lowered: the kernel's builder and its entities.
    kernel: Option<KernelSide<'b>>,
    /// Slots numbered below this are the kernel's (placeholders in the pixel function).
    inherited: u32,
    /// In the pixel function: the `slots` parameter, and the kernel slots addressed so
    /// far, in table order.
    table: Option<ir::Value>,
    table_slots: Vec<StackSlot>,
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

/// The kernel's side of the split, kept while the pixel function is lowered.
struct KernelSide<'b> {
    b: FunctionBuilder<'b>,
    ctx: ir::Value,
    args: ir::Value,
    exit: ir::Block,
    dead_blocks: std::collections::HashSet<ir::Block>,
    live_targets: std::collections::HashSet<ir::Block>,
    sealed_early: std::collections::HashSet<ir::Block>,
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
    /// At the start of the render path (the current block): continue in the pixel
    /// function, if there is one to lower into. The kernel's block is left as it is until
    /// [`Self::end_outlined_pixels`] calls the function from it.
    pub(super) fn begin_outlined_pixels(&mut self) -> bool {
        let Some((func, fctx)) = self.outline.target.take() else {
            return false;
        };
        func.signature = pixel_signature(self.b.func.signature.call_conv);
        let inherited = self.b.func.sized_stack_slots.len() as u32;
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
        let kernel_b = std::mem::replace(&mut self.b, b);
        let exit = self.b.create_block();
        self.outline.kernel = Some(KernelSide {
            b: kernel_b,
            ctx: std::mem::replace(&mut self.ctx, params[0]),
            args: std::mem::replace(&mut self.args, params[1]),
            exit: std::mem::replace(&mut self.exit, exit),
            dead_blocks: std::mem::take(&mut self.dead_blocks),
            live_targets: std::mem::take(&mut self.live_targets),
            sealed_early: std::mem::take(&mut self.sealed_early),
        });
        self.vn.forget();
        self.outline.inherited = inherited;
        self.outline.table = Some(params[2]);
        stack_check(&mut self.b, self.ctx, self.func_id);
        for (k, &p) in params[3..7].iter().enumerate() {
            self.b.def_var(self.bound_vars[k], p);
        }
        let fuel = self.load_ctx(types::I64, ctx_off::FUEL);
        self.b.def_var(self.fuel, fuel);
        true
    }

    /// The address of kernel slot `slot` in the pixel function (`None` elsewhere, and for
    /// the pixel function's own slots): the word the kernel stored in the slot table.
    pub(super) fn inherited_slot_addr(&mut self, slot: StackSlot) -> Option<ir::Value> {
        let table = self.outline.table.filter(|_| slot.as_u32() < self.outline.inherited)?;
        let pos = match self.outline.table_slots.iter().position(|&s| s == slot) {
            Some(pos) => pos,
            None => {
                self.outline.table_slots.push(slot);
                self.outline.table_slots.len() - 1
            }
        };
        Some(self.b.ins().load(types::I64, mem_flags(), table, 8 * pos as i32))
    }

    /// At the end of the pixel loops (the current block of the pixel function): return
    /// from it, go back to the kernel, and call the function from the block the split
    /// left it in, with the slot table filled and the fuel in `ctx`. The kernel continues
    /// in that block.
    pub(super) fn end_outlined_pixels(&mut self) -> Res<()> {
        let Some(side) = self.outline.kernel.take() else {
            return super::err("pixel function not begun");
        };
        self.b.ins().jump(self.exit, &[]);
        self.return_at_exit();
        self.b.seal_all_blocks();
        let pixel_b = std::mem::replace(&mut self.b, side.b);
        pixel_b.finalize(self.frontend);
        self.ctx = side.ctx;
        self.args = side.args;
        self.exit = side.exit;
        self.dead_blocks = side.dead_blocks;
        self.live_targets = side.live_targets;
        self.sealed_early = side.sealed_early;
        self.vn.forget();
        self.outline.table = None;

        let slots = std::mem::take(&mut self.outline.table_slots);
        let table = self.b.create_sized_stack_slot(StackSlotData::new(
            StackSlotKind::ExplicitSlot,
            8 * slots.len().max(1) as u32,
            3,
        ));
        let table_addr = self.slot_addr(table);
        for (pos, &slot) in slots.iter().enumerate() {
            let addr = self.slot_addr(slot);
            self.b.ins().store(mem_flags(), addr, table_addr, 8 * pos as i32);
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
        self.outline.done = true;
        Ok(())
    }
}
