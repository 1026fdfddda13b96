//! `texture` lookups: one call of `runtime::texture::primflow_texture` per pixel group,
//! with the six operands' lanes (s, t and their derivatives) stored to a stack slot and the
//! three colour channels' lanes loaded back from it.
//!
//! The texture set and the slot's texture id are the program's (`ir::Textures`, loaded by
//! the runtime before the kernel is compiled; the set outlives every kernel of the program)
//! and are constants of the code. Without a loaded set the call gets a null set and reads
//! black. A lookup of uniform operands is made on splatted lanes and gives lane 0, uniform.
//! The evaluator calls `TextureSet::sample` per lane, which is what `primflow_texture` does.

use cranelift_codegen::ir::{self, types, InstBuilder, StackSlotData, StackSlotKind};

use super::{err, Lower, Res};
use crate::jit::value::{mem_flags, Val, F32X4};

/// Bytes of the slot: 6 operand vectors, then 3 result vectors.
const SLOT_BYTES: u32 = 9 * 16;

impl<'a, 'b> Lower<'a, 'b> {
    /// `texture` of texture `slot` with wrap mode `wrap` on `vals` (s, t, Dx(s), Dx(t),
    /// Dy(s), Dy(t), float scalars).
    pub(crate) fn texture(&mut self, slot: u32, wrap: u32, vals: Vec<Val>) -> Res<Val> {
        if vals.len() != 6 || vals.iter().any(|v| v.comps.len() != 1) {
            return err("texture with operands that are not six floats");
        }
        let varying = vals.iter().any(|v| v.varying);
        let (set, id) = match self.program.textures.lookup(slot) {
            Some((set, id)) => (set as *const crate::runtime::texture::TextureSet as i64, id),
            None => (0, 0),
        };
        let stack = self
            .b
            .create_sized_stack_slot(StackSlotData::new(StackSlotKind::ExplicitSlot, SLOT_BYTES, 4));
        let base = self.slot_addr(stack);
        for (k, v) in vals.into_iter().enumerate() {
            let v = self.make_varying(v);
            self.b.ins().store(mem_flags(), v.comps[0], base, (16 * k) as i32);
        }
        let mut sig = ir::Signature::new(self.b.func.signature.call_conv);
        for ty in [types::I64, types::I32, types::I32, types::I64, types::I64] {
            sig.params.push(ir::AbiParam::new(ty));
        }
        let sig = self.b.import_signature(sig);
        let entry = self.b.ins().iconst(
            types::I64,
            crate::runtime::texture::primflow_texture as *const () as usize as i64,
        );
        let set = self.b.ins().iconst(types::I64, set);
        let id = self.b.ins().iconst(types::I32, i64::from(id));
        let wrap = self.b.ins().iconst(types::I32, i64::from(wrap));
        let out = self.b.ins().iadd_imm_u(base, 96);
        self.b.ins().call_indirect(sig, entry, &[set, id, wrap, base, out]);
        let mut comps = vec![];
        for c in 0..3 {
            let v = self.b.ins().load(F32X4, mem_flags(), base, 96 + 16 * c);
            comps.push(if varying { v } else { self.b.ins().extractlane(v, 0) });
        }
        Ok(self.fl(comps, varying))
    }
}
