//! The pixel part's loops: passes, the block walk, rows and 4-pixel groups.
//!
//! In bound mode the pixel part records the viewport unless a bound ran, and returns. In
//! render mode (at tier 0 in a function of its own the kernel calls, see
//! [`super::outline`]) [`Lower::pixel_loops`] loops rows, then 4-pixel groups
//! ([`Lower::pixel_group`]) of the pass rectangle clipped to the tile (a
//! [`super::rows::RowLoop`]; groups start at tile-aligned x; lanes outside start dead),
//! `UNROLL` groups per loop step. Loop headers branch exit-first so Cranelift keeps
//! hoisting uniform work out of them. Uniform locals move to the uniform frame first (see
//! [`super::spill`]) and the G-buffer plane addresses are computed once (see
//! [`super::planes`]).
//!
//! When the pixel part opens with coverage tests (`if (c) return;`), the rectangle is
//! walked in blocks instead: first the whole rectangle as one block, and only when that is
//! neither dead nor passing, blocks of `BLOCK_W` x `BLOCK_H` pixels; [`super::block`]
//! evaluates the tests over each block with interval arithmetic (their uniform and Y-only
//! terms once per block row) and skips blocks no lane survives, and runs blocks every lane
//! passes with a variant of the pixel code without those tests; consecutive pass blocks of
//! a block row run as one span, the others run the full code. Per row, the pixel terms
//! that depend on Y alone are evaluated once ([`crate::mid::hoist`]); X steps by 4.0 per group;
//! only the groups at the rectangle's ends build a lane mask (the others start all ones).
//! Tier 1 first decides up to two uniform `if`s of the pixel code whose conditions no group
//! can change, once per draw, and lowers the loops once per side ([`crate::mid::unswitch`]
//! plans the copies, [`Lower::unswitched_loops`] emits them).
//! Z is written back at the end of a group for the lanes that assigned it.
//!
//! Fuel: when the pixel code has loops ([`crate::mid::pixel_code_has_loops`]), the kernel stores the
//! fuel each group gets in `ctx.group_fuel` before the loops (`Lower::store_group_fuel`:
//! the draw's `ctx.pixel_fuel` over the groups of its bound rectangle, at least
//! `ctx.group_fuel_floor`; see `abi::ctx`), and every group starts by loading it into the
//! group's fuel variable, which its loops spend ([`Lower::spend_fuel`]). The setup's fuel
//! (`ctx.fuel`) is not touched by the pixel part.

use cranelift_codegen::ir::{self, condcodes::FloatCC, condcodes::IntCC, types, Block, InstBuilder};
use cranelift_frontend::Variable;

use super::rows::RowLoop;
use super::walk::BlockWalk;
use super::{elem_scalar, err, Lower, PassRect, PixelState, Res, Storage, ALL_LANE_BITS, DEPTH_FORMAT};
use crate::abi::{BindingKind, MODE_BOUND};
use crate::ir::{Elem, Function, ParamRole, Scalar, StmtKind};
use crate::jit::fixed;
use crate::jit::value::{args_flags, ctx_off, mask_const, mem_flags, zero, F32X4, I32X4};
use crate::mid::block::Prefix;
use crate::mid::unswitch::Loops;

/// A screen axis, for [`Lower::sample_offset`].
#[derive(Clone, Copy)]
pub(super) enum Axis {
    X,
    Y,
}

impl<'a, 'b> Lower<'a, 'b> {
    /// The pixel loops (render mode) or the viewport bound (bound mode).
    /// `pending_return`: a condition on which the kernel ends, left by [`Self::setup_stmts`].
    pub(super) fn pixel_passes(&mut self, f: &'a Function, pending_return: Option<ir::Value>) -> Res<()> {
        // Tier 0 stores the uniform frame here, before the bound/render branch, in the
        // block that computed its values: they then die in that block instead of living
        // into the render block, where the single-pass allocator would reload each one
        // after spilling it at the block's end. (Bound mode stores a frame it does not
        // read: a few dozen stores, once per primitive.)
        let early_frame = self.tier0();
        if early_frame {
            self.spill_uniforms(f)?;
        }
        // After the frame stores (stores to the kernel's own stack only), so the values
        // they store die in the block that computed them.
        if let Some(p) = pending_return {
            self.return_if(p);
        }
        let mode = self.load_ctx(types::I32, ctx_off::MODE);
        let is_bound = self.b.ins().icmp_imm_s(IntCC::Equal, mode, MODE_BOUND as i64);
        let bound_blk = self.b.create_block();
        let render_blk = self.b.create_block();
        self.b.ins().brif(is_bound, bound_blk, &[], render_blk, &[]);

        // Bound mode: no `bound` ran, so the primitive may cover the whole viewport.
        self.b.switch_to_block(bound_blk);
        let has = self.b.use_var(self.has_bound);
        // Tier 0: a `bound` among the setup's top-level statements runs on every path
        // that gets here (`has` is 1), so the viewport union is not emitted.
        let always_bound = f.setup.iter().any(|&s| matches!(f.stmts[s], StmtKind::Bound(_)));
        if self.tier0() && always_bound {
            self.b.ins().jump(self.exit, &[]);
        } else {
            let vp_blk = self.b.create_block();
            self.b.ins().brif(has, self.exit, &[], vp_blk, &[]);
            self.b.switch_to_block(vp_blk);
            let w = self.load_ctx(types::I32, ctx_off::WIDTH);
            let h = self.load_ctx(types::I32, ctx_off::HEIGHT);
            let wf = self.b.ins().fcvt_from_uint(types::F32, w);
            let hf = self.b.ins().fcvt_from_uint(types::F32, h);
            let z = self.f32const_here(0.0);
            self.union_bound([z, z, wf, hf], None);
            self.b.ins().jump(self.exit, &[]);
        }

        self.b.switch_to_block(render_blk);
        if !early_frame {
            self.spill_uniforms(f)?;
        }
        // Tier 0: from here on into the pixel function, if there is one (see [`outline`]).
        self.begin_outlined_pixels()?;
        self.run_hoists()?;
        self.carry_steps()?;
        self.plane_table();
        let x0 = self.load_ctx(types::I32, ctx_off::X0);
        let y0 = self.load_ctx(types::I32, ctx_off::Y0);
        let x1 = self.load_ctx(types::I32, ctx_off::X1);
        let y1 = self.load_ctx(types::I32, ctx_off::Y1);
        let bx = [
            self.b.use_var(self.bound_vars[0]),
            self.b.use_var(self.bound_vars[1]),
            self.b.use_var(self.bound_vars[2]),
            self.b.use_var(self.bound_vars[3]),
        ];
        self.group_fuel_used = crate::mid::pixel_code_has_loops(self.program, f, self.key);
        if self.group_fuel_used {
            self.store_group_fuel(bx);
        }
        let (sx, sy) = (self.sample_offset(Axis::X), self.sample_offset(Axis::Y));
        let (lo_x, hi_x) = self.pass_range(bx[0], bx[2], x0, x1, sx);
        let (lo_y, hi_y) = self.pass_range(bx[1], bx[3], y0, y1, sy);
        // Any NaN component: the pass rectangle is empty.
        let n1 = self.b.ins().fcmp(FloatCC::Unordered, bx[0], bx[1]);
        let n2 = self.b.ins().fcmp(FloatCC::Unordered, bx[2], bx[3]);
        let nan = self.b.ins().bor(n1, n2);
        let hi_y = self.b.ins().select(nan, lo_y, hi_y);

        let stride = self.load_ctx(types::I32, ctx_off::STRIDE);
        let stride64 = self.b.ins().uextend(types::I64, stride);
        // Groups start at tile-aligned x.
        let off = self.b.ins().isub(lo_x, x0);
        let off = self.b.ins().band_imm_s(off, !3i64);
        let gx_start = self.b.ins().iadd(x0, off);
        let width = self.b.ins().isub(hi_x, lo_x);
        let lim = self.b.ins().iadd_imm_s(width, -3);
        let zero_i = self.iconst_here(types::I32, 0);
        let interior_lim = self.b.ins().smax(lim, zero_i);
        // lo_x and hi_x as f32x4 splats in the uniform frame, for the groups at either end
        // of a row (`pixel_group`).
        let Some((fs, _)) = self.uniform_frame else {
            return err("uniform frame missing");
        };
        let addr = self.slot_addr(fs);
        for (k, v) in [lo_x, hi_x].into_iter().enumerate() {
            let f = self.b.ins().fcvt_from_sint(types::F32, v);
            let fv = self.b.ins().splat(F32X4, f);
            self.b
                .ins()
                .store(mem_flags(), fv, addr, (self.x_range_at + 16 * k as u32) as i32);
        }
        let rect = PassRect {
            x0,
            y0,
            lo_x,
            stride64,
            interior_lim,
        };
        let loops_done = self.b.create_block();
        // One copy of the loops per combination of the uniform conditions decided before
        // them (tier 1; see [`crate::mid::unswitch`]).
        let copies = &self.pixel_plan()?.loops;
        self.unswitched_loops(copies, 0, &mut |l: &mut Self| {
            l.pixel_loops(f, &rect, [lo_y, hi_y], [gx_start, hi_x], loops_done)
        })?;
        self.b.switch_to_block(loops_done);
        Ok(())
    }

    /// The pixel loops over the pass rectangle (rows `ys`, groups from `gs[0]`, tile-aligned,
    /// to `gs[1]`): plain rows, or the block walk when the pixel code opens with guards.
    /// Ends by jumping to `loops_done`; lowered as the copy `self.copy`, under the conditions
    /// in `self.unswitched`.
    pub(super) fn pixel_loops(
        &mut self,
        f: &'a Function,
        rect: &PassRect,
        ys: [ir::Value; 2],
        gs: [ir::Value; 2],
        loops_done: Block,
    ) -> Res<()> {
        let [lo_y, hi_y] = ys;
        let [gx_start, hi_x] = gs;
        let lo_x = rect.lo_x;
        let Some(copy) = self.copy else {
            return err("pixel loops outside a planned copy");
        };
        let Some(prefix) = &copy.prefix else {
            return self.pixel_rows(f, rect, [lo_y, hi_y], [gx_start, hi_x], None, loops_done);
        };

        // The block walk (see [`super::walk`]): blocks of BLOCK_W x BLOCK_H pixels, the
        // pass variant over spans of passing blocks, the full code over the others.
        let walk = BlockWalk::new(self, [lo_y, hi_y], [gx_start, hi_x], lo_x, loops_done);
        walk.emit(self, f, rect, prefix)
    }

    /// Rows [ys[0], ys[1]) x groups starting at gs[0] (tile-aligned) up to gs[1], `UNROLL`
    /// groups per loop step; lanes outside the pass rectangle start dead. `pass` selects the
    /// pass variant of the pixel code. Ends by jumping to `done`.
    pub(super) fn pixel_rows(
        &mut self,
        f: &'a Function,
        rect: &PassRect,
        ys: [ir::Value; 2],
        gs: [ir::Value; 2],
        pass: Option<(&Prefix, &[bool])>,
        done: Block,
    ) -> Res<()> {
        let first_block = self.b.func.dfg.num_blocks();
        // The row terms this variant reads (a pass span drops guards, and their terms).
        // So does a copy of the loops for decided conditions (their untaken sides).
        // Which guards a pass span drops is the block evaluation's answer (`decidable`), so
        // its expressions are asked for here.
        let pass_exprs;
        let used_exprs = match (pass, self.copy) {
            (Some((prefix, decidable)), Some(copy)) => {
                pass_exprs = crate::mid::block::pass_exprs(
                    f,
                    &prefix.stmts,
                    &f.pixel[prefix.len..],
                    decidable,
                    &copy.rest_live,
                    &self.unswitched,
                );
                Some(&pass_exprs)
            }
            (Some(_), None) => return err("a pass span outside a planned copy"),
            (None, copy) => copy.and_then(|c| c.full_exprs.as_ref()),
        };
        let rows = RowLoop::new(self, rect, ys, gs);
        let row_carry = self.carry_rows_start(f, gs[0], ys[0], used_exprs)?;
        rows.emit(self, f, rect, used_exprs, &row_carry, pass, done)?;
        self.seal_blocks_from(first_block);
        Ok(())
    }

    /// Seal every block created since block number `first`: a finished loop nest whose
    /// blocks no later code jumps into.
    ///
    /// Why: a variable read after the loops (the block walk's span bounds, read when a
    /// span is flushed) is looked up through the loop blocks. Unsealed, each loop header
    /// on the way gets a speculative block parameter that the frontend cannot prove
    /// redundant later, so the value was carried (and spilled and reloaded) through every
    /// pixel group. Sealed, the lookup sees all predecessors and drops the parameter.
    pub(super) fn seal_blocks_from(&mut self, first: usize) {
        for i in first..self.b.func.dfg.num_blocks() {
            let block = Block::from_u32(i as u32);
            if !self.sealed_early.contains(&block) {
                self.b.seal_block(block);
            }
        }
    }

    /// The pixel code for the group of 4 pixels starting at `g` (lane centres `xy_f`;
    /// `row_base` is the element index of x = 0 in the group's row); ends by jumping to
    /// `next`.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn pixel_group(
        &mut self,
        f: &'a Function,
        rect: &PassRect,
        g: ir::Value,
        row_base: ir::Value,
        xy_f: [ir::Value; 2],
        pass: Option<(&Prefix, &[bool])>,
        next: Block,
    ) -> Res<()> {
        let [x_f, y_f] = xy_f;
        let group_end = self.b.create_block();
        let g64 = self.b.ins().sextend(types::I64, g);
        let tile_idx = self.b.ins().iadd(row_base, g64);
        let frame_base = self.uniform_frame.map(|(_, ptr_slot)| {
            let pa = self.slot_addr(ptr_slot);
            self.b.ins().load(types::I64, mem_flags(), pa, 0)
        });
        // Lane i is live when lo_x <= g + i < hi_x, i.e. lo_x < X < hi_x for its centre X
        // (integers below 2^22 and their half-integer centres are exact in f32). The bounds'
        // splats are read from the frame: two compares with memory operands. (Splats of the
        // group-relative bounds cost 13 instructions a group; splats kept in registers
        // across the loops cost the fill workload's groups 4 % in spills.)
        let Some(base) = frame_base else {
            return err("uniform frame missing");
        };
        let mask = self.group_lane_mask(rect, g, x_f, base, next);
        let alive = self.declare_var(I32X4);
        let exec = self.declare_var(I32X4);
        let z_written = self.declare_var(I32X4);
        self.b.def_var(alive, mask);
        self.b.def_var(exec, mask);
        let none_mask = mask_const(&mut self.b, false);
        self.b.def_var(z_written, none_mask);
        let needs_depth = f.param_by_role(ParamRole::Z).is_some()
            || self
                .key
                .bindings
                .iter()
                .any(|b| matches!(b.kind, BindingKind::Shared(_)));
        let z_raw = if needs_depth {
            let addr = self.tile_addr(ctx_off::DEPTH, tile_idx);
            Some(self.b.ins().load(I32X4, mem_flags(), addr, 0))
        } else {
            None
        };
        self.pix = Some(PixelState {
            alive,
            exec,
            z_written,
            group_end,
            tile_idx,
            x_f,
            y_f,
            frame_base,
            z_raw,
            varying_depth: 0,
        });
        self.bind_pixel_params(f, x_f, y_f, z_raw);
        if self.group_fuel_used {
            let fuel = self.load_ctx(types::I64, ctx_off::GROUP_FUEL);
            self.b.def_var(self.group_fuel, fuel);
        }
        for r in 0..self.group_resets.len() {
            let (init, work, bytes) = self.group_resets[r];
            self.copy_slot(init, work, bytes);
        }
        if self.flat {
            self.flat_group_locals(f)?;
        }
        // Guard facts hold within one group body only (not in row prologues).
        self.guard_facts.clear();
        match pass {
            None => self.stmts(&f.pixel)?,
            Some((prefix, decidable)) => {
                let Some(copy) = self.copy else {
                    return err("a pass span outside a planned copy");
                };
                self.prefix_without_guards(&prefix.stmts, &prefix.stmts, decidable, &copy.rest_live)?;
                self.stmts(&f.pixel[prefix.len..])?;
            }
        }
        self.guard_facts.clear();
        self.b.ins().jump(group_end, &[]);

        self.end_group(f, group_end, z_written, z_raw, tile_idx, next)?;
        self.pix = None;
        Ok(())
    }

    /// The lanes of the group starting at `g` that lie inside the pass rectangle, as the
    /// group's first block sees them. Tier 1 branches: an interior group starts all ones
    /// and a group with no live lane goes to `next`; flat (tier 0) code always computes the
    /// mask. `base`: the uniform frame's address.
    fn group_lane_mask(
        &mut self,
        rect: &PassRect,
        g: ir::Value,
        x_f: ir::Value,
        base: ir::Value,
        next: Block,
    ) -> ir::Value {
        if self.flat {
            // Flat pixel code: every group computes its lane mask, in the block it starts
            // in (no branch, so no block boundary). A group with no live lane (only when
            // the pass is empty in x) then runs for no lane, which changes nothing there.
            self.edge_lane_mask(base, x_f)
        } else {
            let grp_run = self.b.create_block();
            let mask = self.b.append_block_param(grp_run, I32X4);
            let edge = self.b.create_block();
            // Lanes outside [lo_x, hi_x) start dead. Only a group at either end of the
            // rectangle has such lanes: one unsigned compare tells the others apart.
            let d = self.b.ins().isub(g, rect.lo_x);
            let interior = self.b.ins().icmp(IntCC::UnsignedLessThan, d, rect.interior_lim);
            let all = mask_const(&mut self.b, true);
            self.b.ins().brif(interior, grp_run, &[all.into()], edge, &[]);

            self.b.switch_to_block(edge);
            let edge_mask = self.edge_lane_mask(base, x_f);
            let any = self.b.ins().vany_true(edge_mask);
            let none = self.b.ins().icmp_imm_s(IntCC::Equal, any, 0);
            self.b.ins().brif(none, next, &[], grp_run, &[edge_mask.into()]);

            self.b.switch_to_block(grp_run);
            mask
        }
    }

    /// `lo_x <= X < hi_x` per lane (X = x + a sample offset in [0, 1), so exactly the pixels x
    /// in `lo_x..hi_x`), the bounds' splats read from the uniform frame at `base`.
    fn edge_lane_mask(&mut self, base: ir::Value, x_f: ir::Value) -> ir::Value {
        let [lo, hi] = [0, 16].map(|k| {
            self.b
                .ins()
                .load(F32X4, args_flags(), base, (self.x_range_at + k) as i32)
        });
        let ge = self.b.ins().fcmp(FloatCC::GreaterThanOrEqual, x_f, lo);
        let lt = self.b.ins().fcmp(FloatCC::LessThan, x_f, hi);
        self.b.ins().band(ge, lt)
    }

    /// Bind the primitive's X, Y, Z in its declared types (Z from the depth buffer's raw
    /// values, when loaded).
    fn bind_pixel_params(&mut self, f: &'a Function, x_f: ir::Value, y_f: ir::Value, z_raw: Option<ir::Value>) {
        for (i, p) in f.params.iter().enumerate() {
            let local = f.local(p.local);
            let Elem::Scalar(sc) = local.ty.elem else { continue };
            let (src, from) = match p.role {
                ParamRole::X => (x_f, Scalar::Float),
                ParamRole::Y => (y_f, Scalar::Float),
                ParamRole::Z => match z_raw {
                    Some(z) => (z, Scalar::Fixed(DEPTH_FORMAT)),
                    None => continue,
                },
                _ => continue,
            };
            let v = fixed::convert(&mut self.b, from, sc, src);
            match &self.frames[0].storage[i] {
                Storage::Vars(vs) => {
                    let var = vs[0];
                    self.b.def_var(var, v)
                }
                Storage::Z(var) => {
                    let var = *var;
                    self.b.def_var(var, v)
                }
                _ => {}
            }
        }
    }

    /// Fill the group's end block `group_end`: write Z back for the lanes that assigned it
    /// (`z_written`), then go on at `next`. Nothing else writes the depth buffer during the
    /// group, so the depth loaded at its start (`z_raw`) is the old value to blend with;
    /// when every lane assigned Z it is a plain store.
    fn end_group(
        &mut self,
        f: &'a Function,
        group_end: Block,
        z_written: Variable,
        z_raw: Option<ir::Value>,
        tile_idx: ir::Value,
        next: Block,
    ) -> Res<()> {
        self.b.switch_to_block(group_end);
        if let (Some(zp), Some(z_old)) = (f.param_by_role(ParamRole::Z), z_raw) {
            let zi = f.params.iter().position(|p| p.role == ParamRole::Z).unwrap_or(0);
            let zsc = match f.local(zp.local).ty.elem {
                Elem::Scalar(s) => s,
                Elem::Interp => Scalar::Float,
            };
            let zvar = match &self.frames[0].storage[zi] {
                Storage::Z(v) => *v,
                _ => return err("Z parameter without storage"),
            };
            let written = self.b.use_var(z_written);
            if self.tier0() {
                // Tier 0: one blended store, whatever the lanes (no blocks for the all and
                // none cases). The depth loaded at the group's start is still the buffer's
                // value, so unwritten lanes store back what they hold.
                self.store_depth(zvar, zsc, Some((written, z_old)), tile_idx);
                self.count_writes(written, tile_idx);
                self.b.ins().jump(next, &[]);
                return Ok(());
            }
            // The written lanes' bits (`vmovmskps`): all four and none are compares of one
            // integer, cheaper than `vall_true` and `vany_true` on the vector.
            let bits = self.b.ins().vhigh_bits(types::I32, written);
            let all = self.b.ins().icmp_imm_s(IntCC::Equal, bits, ALL_LANE_BITS);
            let full_blk = self.b.create_block();
            let part_blk = self.b.create_block();
            let blend_blk = self.b.create_block();
            let stored = self.b.create_block();
            self.b.ins().brif(all, full_blk, &[], part_blk, &[]);

            self.b.switch_to_block(full_blk);
            self.store_depth(zvar, zsc, None, tile_idx);
            self.b.ins().jump(stored, &[]);

            self.b.switch_to_block(part_blk);
            let none = self.b.ins().icmp_imm_s(IntCC::Equal, bits, 0);
            self.b.ins().brif(none, next, &[], blend_blk, &[]);
            self.b.switch_to_block(blend_blk);
            self.store_depth(zvar, zsc, Some((written, z_old)), tile_idx);
            self.b.ins().jump(stored, &[]);

            self.b.switch_to_block(stored);
            self.count_writes(written, tile_idx);
        }
        self.b.ins().jump(next, &[]);
        Ok(())
    }

    /// Store the group's Z (`zvar`, of scalar type `zsc`) to the depth buffer as
    /// `fixed<32,32>` raw: in every lane, or with `blend = (written, old)` only in the
    /// `written` lanes, the others keeping `old`.
    pub(super) fn store_depth(
        &mut self,
        zvar: Variable,
        zsc: Scalar,
        blend: Option<(ir::Value, ir::Value)>,
        tile_idx: ir::Value,
    ) {
        let zval = self.b.use_var(zvar);
        let raw = fixed::convert(&mut self.b, zsc, Scalar::Fixed(DEPTH_FORMAT), zval);
        let addr = self.tile_addr(ctx_off::DEPTH, tile_idx);
        let new = match blend {
            Some((written, old)) => self.b.ins().blendv(written, raw, old),
            None => raw,
        };
        self.b.ins().store(mem_flags(), new, addr, 0);
    }

    /// Add one to the write count of the `written` lanes (when the key counts writes).
    pub(super) fn count_writes(&mut self, written: ir::Value, tile_idx: ir::Value) {
        if !self.key.count_writes {
            return;
        }
        let caddr = self.tile_addr(ctx_off::WRITE_COUNT, tile_idx);
        let old = self.b.ins().load(I32X4, mem_flags(), caddr, 0);
        // Written lanes are -1: subtracting adds one.
        let new = self.b.ins().isub(old, written);
        self.b.ins().store(mem_flags(), new, caddr, 0);
    }

    /// Flat pixel code, at the start of a group: every varying local the pixel code
    /// assigns starts the group as zero.
    ///
    /// Why: flat code assigns such locals under masks (a declaration inside a uniform `if`
    /// run as a masked one blends), which reads the old value: left undefined, that is the
    /// previous group's, carried through the group and row loops as block parameters the
    /// single-pass allocator moves and spills at every loop edge. No lane reads what an
    /// earlier group left (a local is declared, so assigned, before any read of it in the
    /// same group), so the values the pixels see are the same.
    pub(super) fn flat_group_locals(&mut self, f: &'a Function) -> Res<()> {
        let mut zeros: std::collections::HashMap<Scalar, ir::Value> = std::collections::HashMap::new();
        for &i in &self.pixel_plan()?.zeroed {
            let Storage::Vars(vars) = &self.frames[0].storage[i] else {
                continue;
            };
            let vars = vars.clone();
            let sc = elem_scalar(&f.locals[i].ty);
            let z = *zeros.entry(sc).or_insert_with(|| zero(&mut self.b, sc, true));
            for v in vars {
                self.b.def_var(v, z);
            }
        }
        Ok(())
    }

    /// Store the fuel each pixel group of this draw starts with in `ctx.group_fuel`:
    /// `max(ctx.group_fuel_floor, ctx.pixel_fuel / groups)`, where `groups` is the number of
    /// pixel groups of the bound rectangle `bx` in the viewport (its pixels whose samples
    /// lie in the bound, as [`Self::pass_range`] takes them, clamped to `ctx.width` x
    /// `ctx.height`: rows times the group columns those pixels touch, at least 1). It
    /// depends on neither the tile nor the order tiles run in.
    fn store_group_fuel(&mut self, bx: [ir::Value; 4]) {
        let zero = self.iconst_here(types::I32, 0);
        let w = self.load_ctx(types::I32, ctx_off::WIDTH);
        let h = self.load_ctx(types::I32, ctx_off::HEIGHT);
        let (sx, sy) = (self.sample_offset(Axis::X), self.sample_offset(Axis::Y));
        let (lo_x, hi_x) = self.pass_range(bx[0], bx[2], zero, w, sx);
        let (lo_y, hi_y) = self.pass_range(bx[1], bx[3], zero, h, sy);
        // Groups start at multiples of 4 (tiles start at them too).
        let end = self.b.ins().iadd_imm_s(hi_x, 3);
        let end = self.b.ins().ushr_imm_u(end, 2);
        let start = self.b.ins().ushr_imm_u(lo_x, 2);
        let cols = self.b.ins().isub(end, start);
        let rows = self.b.ins().isub(hi_y, lo_y);
        let cols = self.b.ins().uextend(types::I64, cols);
        let rows = self.b.ins().uextend(types::I64, rows);
        let groups = self.b.ins().imul(rows, cols);
        let one = self.iconst_here(types::I64, 1);
        let groups = self.b.ins().umax(groups, one);
        let budget = self.load_ctx(types::I64, ctx_off::PIXEL_FUEL);
        let share = self.b.ins().udiv(budget, groups);
        let floor = self.load_ctx(types::I64, ctx_off::GROUP_FUEL_FLOOR);
        let fuel = self.b.ins().umax(share, floor);
        self.store_ctx(fuel, ctx_off::GROUP_FUEL);
    }

    /// Pixels [lo, hi) of the tile range [t0, t1) whose sample positions (`x + offset`,
    /// `offset` the context's [`Self::sample_offset`] along this axis) lie in [bmin, bmax].
    /// Clamped in float first so huge or infinite bounds cannot overflow the conversion.
    pub(super) fn pass_range(
        &mut self,
        bmin: ir::Value,
        bmax: ir::Value,
        t0: ir::Value,
        t1: ir::Value,
        offset: ir::Value,
    ) -> (ir::Value, ir::Value) {
        let t0f = self.b.ins().fcvt_from_sint(types::F32, t0);
        let t1f = self.b.ins().fcvt_from_sint(types::F32, t1);
        let one = self.f32const_here(1.0);
        let lo = self.b.ins().fsub(bmin, offset);
        let lo = self.b.ins().ceil(lo);
        let lo = self.b.ins().fmax(lo, t0f);
        let lo = self.b.ins().fmin(lo, t1f);
        let hi = self.b.ins().fsub(bmax, offset);
        let hi = self.b.ins().floor(hi);
        let hi = self.b.ins().fadd(hi, one);
        let hi = self.b.ins().fmax(hi, t0f);
        let hi = self.b.ins().fmin(hi, t1f);
        // NaN converts to 0 here; the caller empties the rectangle for NaN bounds.
        let lo_i = self.b.ins().fcvt_to_sint_sat(types::I32, lo);
        let hi_i = self.b.ins().fcvt_to_sint_sat(types::I32, hi);
        let hi_i = self.b.ins().smax(hi_i, lo_i);
        (lo_i, hi_i)
    }

    /// X of the lanes of the group starting at `g`: the pixels' sample positions (int ->
    /// float, + the sample's offset, as the pixel's X is defined).
    pub(super) fn lane_centres(&mut self, g: ir::Value) -> ir::Value {
        let g0 = self.b.ins().splat(I32X4, g);
        let iota = self.iota();
        let px0 = self.b.ins().iadd(g0, iota);
        let pxf = self.b.ins().fcvt_from_sint(F32X4, px0);
        let offset = self.sample_offset(Axis::X);
        let offsetv = self.b.ins().splat(F32X4, offset);
        self.b.ins().fadd(pxf, offsetv)
    }

    /// Where in its pixel the pixel code evaluates along `axis` (`TileCtx::sample_x` or
    /// `sample_y`: 0.5 at the centre), loaded from the context. Pixel `i`'s coordinate is
    /// `i + offset` (int -> float, then one add) wherever a kernel computes one, so that
    /// every computation of it is bit-identical. The offsets are multiples of 1/16, so `i +
    /// offset` and the loops' carried `+ 1` and `+ 4` steps are exact below 2^19.
    pub(super) fn sample_offset(&mut self, axis: Axis) -> ir::Value {
        let at = match axis {
            Axis::X => ctx_off::SAMPLE_X,
            Axis::Y => ctx_off::SAMPLE_Y,
        };
        // Read-only: the runtime sets it before the call; loads of it merge.
        self.b.ins().load(types::F32, args_flags(), self.ctx, at)
    }

    /// Pixel row or column `i`'s coordinate at the sample: `i + sample_offset(axis)`.
    pub(super) fn sample_coord(&mut self, i: ir::Value, axis: Axis) -> ir::Value {
        let f = self.b.ins().fcvt_from_sint(types::F32, i);
        let offset = self.sample_offset(axis);
        self.b.ins().fadd(f, offset)
    }

    pub(super) fn iota(&mut self) -> ir::Value {
        let mut bytes = vec![];
        for i in 0..4u32 {
            bytes.extend_from_slice(&i.to_le_bytes());
        }
        let c = self.b.func.dfg.constants.insert(bytes.into());
        self.b.ins().vconst(I32X4, c)
    }

    /// Address of element `idx` (i64) of the tile buffer whose pointer is at `ptr_off` in ctx.
    pub(super) fn tile_addr(&mut self, ptr_off: i32, idx: ir::Value) -> ir::Value {
        // The context's buffer pointers never change while a kernel runs (the runtime sets
        // them before the call; kernels write only the error, bound, fuel and call-depth
        // fields): loaded as read-only, the group loop's two loads of the depth pointer
        // merge and leave the loop instead of reloading the context pointer every group.
        let base = self.b.ins().load(types::I64, args_flags(), self.ctx, ptr_off);
        let bytes = self.b.ins().ishl_imm_u(idx, 2);
        self.b.ins().iadd(base, bytes)
    }

    /// Lower the copies of the pixel loops `copies` plans (`loops` lowers one copy, the one
    /// in `self.copy`; every copy ends by jumping to the block the caller continues in): a
    /// decided condition is evaluated once, in the current block, and each side's dispatch
    /// block goes on with the copies for that side. `depth`: conditions decided on the way.
    pub(super) fn unswitched_loops(
        &mut self,
        copies: &'a Loops,
        depth: usize,
        loops: &mut dyn FnMut(&mut Self) -> Res<()>,
    ) -> Res<()> {
        let (cond, sides) = match copies {
            Loops::Copy(copy) => {
                self.copy = Some(copy);
                let r = loops(self);
                self.copy = None;
                return r;
            }
            Loops::Split { cond, sides } => (*cond, sides),
        };
        let c = self.eval_uniform(cond)?;
        let c = fixed::convert(&mut self.b, c.scalar, Scalar::Bool, c.comps[0]);
        let blocks: [Block; 2] = [self.b.create_block(), self.b.create_block()];
        self.b.ins().brif(c, blocks[0], &[], blocks[1], &[]);
        for ((block, on), side) in blocks.into_iter().zip([true, false]).zip(sides.iter()) {
            self.b.switch_to_block(block);
            if depth == 0 {
                self.store_deferred_frame(cond, on);
            }
            self.unswitched.insert(cond, on);
            let r = self.unswitched_loops(side, depth + 1, loops);
            self.unswitched.remove(&cond);
            r?;
        }
        Ok(())
    }
}
