//! Interpolation data, interpolation arms, shared interpolators and the G-buffer planes.
//!
//! Interpolation data is specialised away: an interpolation_data value is just the float
//! components of the current *view* (all Kind-bound components outside an `interpolation`
//! arm, the arm's kind's inside; [`crate::mid::view::arm_view`]). An arm the variant key gives
//! nothing to do is not lowered. Shared interpolators are inlined at a bare
//! `interpolator_return;` as a one-trip masked loop whose `return` is a break
//! ([`Lower::inline_interpolator`]).
//!
//! G-buffer planes: each binding component of the key is a plane of the tile; their base
//! addresses are computed once per kernel run into a table ([`Lower::plane_table`]).
//! Invariant: every G-buffer store goes to a plane below `ctx.num_planes`; a store to
//! another plane goes to a scratch slot, branch-free, and stores blend with the old value
//! for the executing lanes only ([`Lower::store_planes`]).

use cranelift_codegen::ir::{self, condcodes::IntCC, types, InstBuilder, StackSlotData, StackSlotKind};

use super::{elem_scalar, err, ArmInfo, LoopCtx, Lower, Res, Storage, ALL_LANE_BITS, DEPTH_FORMAT};
use crate::abi::{interpolator_arg_words, type_words, BindingKind, KernelWarning, ParamSlot};
use crate::ir::{Elem, ExprId, FuncKind, ParamRole, Scalar};
use crate::jit::fixed;
use crate::jit::value::{args_flags, blend, ctx_off, mask_const, mem_flags, zero, Val, F32X4, I32X4};
use crate::mid::view;

impl<'a, 'b> Lower<'a, 'b> {
    pub(super) fn kind_offsets(&self) -> Vec<(usize, u32, u32)> {
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

    pub(super) fn global_offset(&self, binding: usize) -> u32 {
        self.key.bindings[..binding].iter().map(|b| b.components).sum()
    }

    pub(super) fn interpolation(&mut self, arms: &'a [crate::ir::InterpArm]) -> Res<()> {
        // In setup code the construct only computes (figure 8: interpolation data of new
        // vertices); `interpolator_return` there is refused by `interpolator_return` itself.
        let named = view::named_kinds(arms);
        for arm in arms {
            let Some((view, bindings)) = view::arm_view(self.key, &named, arm) else {
                continue;
            };
            for &bi in &bindings {
                self.served_by[bi] = Some((arm.kind.clone(), arm.span));
            }
            let saved_view = std::mem::replace(&mut self.view, view);
            let saved_arm = self.arm.replace(ArmInfo { bindings });
            let r = self.stmts(&arm.body);
            self.view = saved_view;
            self.arm = saved_arm;
            r?;
        }
        Ok(())
    }

    /// Store a varying f32x4 into G-buffer component `g` (global binding component index)
    /// for the executing lanes; planes at or past `ctx.num_planes` are not written.
    pub(super) fn store_plane(&mut self, g: u32, v: ir::Value) {
        self.store_planes(&[(g, v)]);
    }

    /// Store several components for the executing lanes, with one test for the common case:
    /// when every lane executes and every plane of the key exists (`plane_table`), each
    /// store is a plain vector store. Otherwise each is load + blend + store to its plane's
    /// address, or to a scratch slot for a plane the frame does not have (branch-free, so
    /// values shared by several stores, like a perspective divisor, are computed once).
    /// Same memory contents either way: a full mask blends nothing from the old value.
    pub(super) fn store_planes(&mut self, stores: &[(u32, ir::Value)]) {
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
    pub(super) fn blended_plane_stores(
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
    pub(super) fn plane_table(&mut self) {
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

    /// `__gbuffer(plane, X, Y)`: plane `plane` (a uniform float, converted saturating) at
    /// the group's pixels. A plane not below `ctx.num_planes` loads from the scratch slot
    /// and reads as 0, so the load stays inside the buffers.
    pub(crate) fn gbuffer_read(&mut self, plane: &Val) -> Res<Val> {
        let Some(tile_idx) = self.pix.as_ref().map(|p| p.tile_idx) else {
            return err("`__gbuffer` outside per-pixel code");
        };
        if plane.varying || plane.comps.len() != 1 {
            return err("`__gbuffer` of a varying plane");
        }
        let k = self.b.ins().fcvt_to_uint_sat(types::I32, plane.comps[0]);
        let num = self.load_ctx(types::I32, ctx_off::NUM_PLANES);
        let valid = self.b.ins().icmp(IntCC::UnsignedLessThan, k, num);
        let pstride = self.load_ctx(types::I32, ctx_off::PLANE_STRIDE);
        let ps64 = self.b.ins().uextend(types::I64, pstride);
        let k64 = self.b.ins().uextend(types::I64, k);
        let start = self.b.ins().imul(k64, ps64);
        let elem = self.b.ins().iadd(start, tile_idx);
        let bytes = self.b.ins().ishl_imm_u(elem, 2);
        let gbuf = self.load_ctx(types::I64, ctx_off::GBUF);
        let real = self.b.ins().iadd(gbuf, bytes);
        let dummy = self.slot_addr(self.scratch);
        let addr = self.b.ins().select(valid, real, dummy);
        let loaded = self.b.ins().load(F32X4, mem_flags(), addr, 0);
        let zeros = zero(&mut self.b, Scalar::Float, true);
        let v = self.b.ins().select(valid, loaded, zeros);
        Ok(Val {
            comps: vec![v],
            scalar: Scalar::Float,
            varying: true,
        })
    }

    pub(super) fn interpolator_return(&mut self, e: Option<ExprId>) -> Res<()> {
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
                    let func = self.frame().func;
                    let name = &func.name;
                    self.warnings.push(KernelWarning {
                        binding: bi,
                        message: format!(
                            "interpolator `{name}` returns {} components for shading parameter {{param}} of {comps}; it is not stored",
                            v.comps.len(),
                        ),
                        span: func.exprs.span(e),
                        label: format!("{} components", v.comps.len()),
                    });
                }
            }
            return self.leave_interpolator();
        }
        match e {
            Some(e) => self.store_kind_bindings(e),
            None => self.run_shared_and_constants(),
        }
    }

    pub(super) fn float_varying(&mut self, v: Val) -> Val {
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

    pub(super) fn store_kind_bindings(&mut self, e_id: ExprId) -> Res<()> {
        let e = &self.exprs()[e_id];
        let is_interp = e.ty.elem == Elem::Interp && e.ty.dims.is_empty();
        let v = self.eval(e_id)?;
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
                let span = self.frame().func.exprs.span(e_id);
                self.warnings.push(KernelWarning {
                    binding: bi,
                    message: format!(
                        "`{fname}`: the `interpolator_return` value has {} components, shading parameter {{param}} has {comps}; it is not stored",
                        v.comps.len()
                    ),
                    span,
                    label: format!("{} components", v.comps.len()),
                });
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

    pub(super) fn run_shared_and_constants(&mut self) -> Res<()> {
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

    pub(super) fn inline_interpolator(&mut self, bi: usize, name: &str) -> Res<()> {
        let span = self.frame().func.span;
        let Some(id) = self.program.find(name) else {
            self.warnings.push(KernelWarning {
                binding: bi,
                message: format!(
                    "shared interpolator `{name}` of shading parameter {{param}} does not exist; it is not written"
                ),
                span,
                label: "in this primitive".into(),
            });
            return Ok(());
        };
        let f = self.program.func(id);
        if f.kind != FuncKind::Interpolator {
            self.warnings.push(KernelWarning {
                binding: bi,
                message: format!("`{name}`, bound to shading parameter {{param}}, is a primitive, not a shared interpolator; it is not written"),
                span,
                label: "in this primitive".into(),
            });
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
        let frame = self.make_frame(f, id, slots, at, Some(bi))?;
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
}
