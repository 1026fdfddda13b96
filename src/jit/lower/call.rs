//! Primitive calls from setup code.
//!
//! A call builds the callee's argument block in a stack slot (the callee's `ArgLayout`:
//! its parameters, then the interpolation data of the bindings it passes on) and calls the
//! callee's kernel for the same variant key directly; in `MODE_EXPAND` it hands the block to
//! `ctx.expand` instead, and the runtime renders the call later as an instance
//! ([`Lower::record_call`]). Around a direct call the setup fuel goes through `ctx.fuel`
//! (the callee's setup spends it too; its pixel part has its own; a callee that ran out
//! ends the caller's run too) and the call depth is checked (`ERR_CALL_DEPTH`); deferred
//! setup errors are flushed before it, so the callee sees the caller's first error.

use cranelift_codegen::ir::{self, condcodes::IntCC, types, InstBuilder, StackSlotData, StackSlotKind};

use super::{err, word_of, Lower, Res};
use crate::abi::{
    interpolator_arg_words, ArgLayout, BindingKind, ParamSlot, ERR_CALL_DEPTH, MAX_CALL_DEPTH, MODE_EXPAND,
};
use crate::ir::{ExprId, FuncId, FuncKind, SiteId};
use crate::jit::value::{args_flags, ctx_off, mem_flags};
use crate::jit::JitError;

impl<'a, 'b> Lower<'a, 'b> {
    pub(super) fn call_primitive(&mut self, callee: FuncId, args: &'a [ExprId], site: SiteId) -> Res<()> {
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
                if self.exprs()[*a].ty.per_seq || self.exprs()[*a].ty.dims.is_empty() {
                    return err(format!(
                        "argument {} of the call to `{}`: a per-sequence-point parameter needs a fixed-size array argument",
                        i, cf.name
                    ));
                }
                n_seq = self.exprs()[*a].ty.dims[0];
                break;
            }
        }
        let (base, words) = self.call_arg_block(&layout, n_seq, args)?;
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
        self.record_error(ERR_CALL_DEPTH, site.0, None);
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
        // The callee's setup spends the same fuel: hand it over in `ctx.fuel` and take back
        // the rest.
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
        // A callee whose setup ran out of fuel ended its run with the fuel spent (negative,
        // see [`Self::spend_fuel`]): the caller's run ends too, leaving the fuel as it is.
        let fuel = self.b.use_var(self.fuel);
        let spent = self.b.ins().icmp_imm_s(IntCC::SignedLessThan, fuel, 0);
        let go_on = self.b.create_block();
        if self.in_dead_block() {
            self.dead_blocks.insert(go_on);
            self.b.ins().trap(ir::TrapCode::unwrap_user(1));
        } else {
            self.b.ins().brif(spent, self.exit, &[], go_on, &[]);
            self.live_targets.insert(self.exit);
        }
        self.seal_now(go_on);
        self.b.switch_to_block(go_on);
        Ok(())
    }

    /// The argument block of a primitive call in a stack slot of the caller's frame, laid
    /// out by the callee's `layout` for `n_seq` sequence points: the caller's plane table
    /// and binding data (the same key, so the same prefix), the space matrices (the
    /// caller's, or identities when it has none) and `args` evaluated in the caller.
    /// Returns the block's address and its length in words.
    fn call_arg_block(&mut self, layout: &ArgLayout, n_seq: u32, args: &'a [ExprId]) -> Res<(ir::Value, usize)> {
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
            let v = self.eval_uniform(args[i])?;
            for w in 0..total {
                let comp = match v.comps.get(w as usize) {
                    Some(&c) => word_of(&mut self.b, v.scalar, c),
                    None => self.iconst_here(types::I32, 0),
                };
                store_word(self, comp, start + w);
            }
        }
        Ok((base, words))
    }

    /// Hand the call (callee id, its kernel's address, the argument block, its length) to
    /// `ctx.expand`; nothing when that is null.
    pub(super) fn record_call(&mut self, callee: FuncId, fref: ir::FuncRef, base: ir::Value, words: usize) -> Res<()> {
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
}
