//! The row loop of a pass rectangle and the group loop inside each row, packaged as one
//! control-flow construct in the style of cranelift-frontend's `Switch`: [`RowLoop::new`]
//! declares its variables, gives them their first row's values and creates its blocks;
//! [`RowLoop::emit`] fills the blocks, lowering the pixel code once per group through
//! [`Lower::pixel_group`]. [`Lower::pixel_rows`] drives it.
//!
//! Shape: rows `[ys[0], ys[1])`, and in each row groups of 4 pixels from `gs[0]`
//! (tile-aligned) while `g < gs[1]`, `UNROLL` groups per loop step. Both headers test their
//! bound and branch exit-first, so Cranelift keeps hoisting uniform work out of the loops.
//!
//! Invariants:
//! - Carried values are exact, so bit-identical to computing them afresh: the row's element
//!   index of x = 0 (`(y - y0) * stride - x0`) is an integer; its sample Y and the groups'
//!   lanes' sample X are multiples of 1/16 (the sample offsets are) below 2^15 in magnitude
//!   (images are at most 16384 pixels on a side), so exact in f32.
//! - The blocks are created in `new`, in one fixed order (rows' header, body, step; groups'
//!   header, step), so the CLIF of a kernel does not depend on what the loop bodies emit.
//! - `row_step` reads the row's values as `row_body` read them (that block dominates it), not
//!   through `use_var`: a read there would be looked up through the group loop and carried
//!   around it.

use cranelift_codegen::ir::{self, condcodes::IntCC, types, Block, InstBuilder};
use cranelift_frontend::Variable;

use super::carry::{CarryLoop, RowCarry};
use super::{Lower, PassRect, Res, UNROLL};
use crate::ir::{ExprId, Function};
use crate::jit::value::F32X4;
use crate::mid::block::Prefix;

/// The variables and blocks of one row loop and its group loop.
pub(super) struct RowLoop {
    /// The rows' end (exclusive) and the groups' end (a group starts below it).
    hi_y: ir::Value,
    hi_x: ir::Value,
    /// The first group of every row.
    gx_start: ir::Value,
    /// The element distance from one row to the next (i64).
    stride64: ir::Value,
    /// The row; its element index of pixel x = 0; its centre Y.
    y: Variable,
    row_base: Variable,
    yf: Variable,
    /// The group's first pixel; its lanes' centre X.
    gx: Variable,
    xv: Variable,
    row_hdr: Block,
    row_body: Block,
    row_next: Block,
    grp_hdr: Block,
    grp_next: Block,
}

/// What the row body read of the row's variables (valid in every block of the row).
struct Row {
    y: ir::Value,
    base: ir::Value,
    yf: ir::Value,
    /// Centre Y splatted over the lanes.
    y_f: ir::Value,
}

impl RowLoop {
    /// The loop over rows `ys` and groups `gs` (see the module doc), its variables holding
    /// the first row's values.
    pub(super) fn new(l: &mut Lower, rect: &PassRect, ys: [ir::Value; 2], gs: [ir::Value; 2]) -> RowLoop {
        let y = l.declare_var(types::I32);
        let gx = l.declare_var(types::I32);
        let xv = l.declare_var(F32X4);
        l.b.def_var(y, ys[0]);
        let row_base = l.declare_var(types::I64);
        let yf = l.declare_var(types::F32);
        let row = l.b.ins().isub(ys[0], rect.y0);
        let row64 = l.b.ins().sextend(types::I64, row);
        let base = l.b.ins().imul(row64, rect.stride64);
        let x0_64 = l.b.ins().sextend(types::I64, rect.x0);
        let base = l.b.ins().isub(base, x0_64);
        l.b.def_var(row_base, base);
        let yf0 = l.sample_coord(ys[0], super::loops::Axis::Y);
        l.b.def_var(yf, yf0);
        RowLoop {
            hi_y: ys[1],
            hi_x: gs[1],
            gx_start: gs[0],
            stride64: rect.stride64,
            y,
            row_base,
            yf,
            gx,
            xv,
            row_hdr: l.b.create_block(),
            row_body: l.b.create_block(),
            row_next: l.b.create_block(),
            grp_hdr: l.b.create_block(),
            grp_next: l.b.create_block(),
        }
    }

    /// Emit the loops from the current block and end by jumping to `done`. `used`: the row
    /// terms this copy of the pixel code reads (all when `None`); `row_carry`: the carried
    /// terms' values at the first row ([`Lower::carry_rows_start`]); `pass`: lower the pass
    /// variant of the pixel code.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn emit<'a>(
        self,
        l: &mut Lower<'a, '_>,
        f: &'a Function,
        rect: &PassRect,
        used: Option<&std::collections::HashSet<ExprId>>,
        row_carry: &RowCarry,
        pass: Option<(&Prefix, &[bool])>,
        done: Block,
    ) -> Res<()> {
        l.b.ins().jump(self.row_hdr, &[]);
        l.b.switch_to_block(self.row_hdr);
        let y = l.b.use_var(self.y);
        let finished = l.b.ins().icmp(IntCC::SignedGreaterThanOrEqual, y, self.hi_y);
        l.b.ins().brif(finished, done, &[], self.row_body, &[]);

        l.b.switch_to_block(self.row_body);
        let y = l.b.use_var(self.y);
        let base = l.b.use_var(self.row_base);
        let yf = l.b.use_var(self.yf);
        let y_f = l.b.ins().splat(F32X4, yf);
        let row = Row { y, base, yf, y_f };
        l.row_hoists(f, y_f, used)?;
        l.b.def_var(self.gx, self.gx_start);
        let x0_f = l.lane_centres(self.gx_start);
        l.b.def_var(self.xv, x0_f);
        // Int terms affine in the column: their value at the first group, carried (see
        // [`super::carry`]); after the row hoists, which define Y's variable the same way.
        let carry = l.carry_prologue(f, x0_f, y_f, used, row_carry)?;
        l.b.ins().jump(self.grp_hdr, &[]);

        self.groups(l, f, rect, &row, &carry, pass)?;
        self.group_step(l, &carry);
        self.row_step(l, &row, &carry);
        Ok(())
    }

    /// The group loop's header and its `UNROLL` group bodies, the last jumping to the step.
    fn groups<'a>(
        &self,
        l: &mut Lower<'a, '_>,
        f: &'a Function,
        rect: &PassRect,
        row: &Row,
        carry: &CarryLoop,
        pass: Option<(&Prefix, &[bool])>,
    ) -> Res<()> {
        l.b.switch_to_block(self.grp_hdr);
        let g = l.b.use_var(self.gx);
        let finished = l.b.ins().icmp(IntCC::SignedGreaterThanOrEqual, g, self.hi_x);
        let first = l.b.create_block();
        l.b.ins().brif(finished, self.row_next, &[], first, &[]);
        l.b.switch_to_block(first);
        for k in 0..UNROLL {
            let next = if k + 1 == UNROLL {
                self.grp_next
            } else {
                l.b.create_block()
            };
            let g = l.b.use_var(self.gx);
            let g = l.b.ins().iadd_imm_s(g, 4 * k as i64);
            let x_f = l.b.use_var(self.xv);
            let x_f = if k == 0 { x_f } else { add_splat(l, x_f, 4.0 * k as f32) };
            let mut vals: Vec<ir::Value> = carry.group.iter().map(|c| l.b.use_var(c.1)).collect();
            l.carry_advance(&mut vals, carry, k);
            l.carry_now = carry.group.iter().zip(&vals).map(|(c, &v)| (c.0, v)).collect();
            let lowered = l.pixel_group(f, rect, g, row.base, [x_f, row.y_f], pass, next);
            l.carry_now.clear();
            lowered?;
            if k + 1 != UNROLL {
                l.b.switch_to_block(next);
            }
        }
        Ok(())
    }

    /// Advance the group variables and the carried terms by `UNROLL` groups; back to the
    /// group header.
    fn group_step(&self, l: &mut Lower, carry: &CarryLoop) {
        l.b.switch_to_block(self.grp_next);
        let g = l.b.use_var(self.gx);
        let g = l.b.ins().iadd_imm_s(g, 4 * UNROLL as i64);
        l.b.def_var(self.gx, g);
        let x_f = l.b.use_var(self.xv);
        let x_f = add_splat(l, x_f, 4.0 * UNROLL as f32);
        l.b.def_var(self.xv, x_f);
        let mut vals: Vec<ir::Value> = carry.group.iter().map(|c| l.b.use_var(c.1)).collect();
        l.carry_advance(&mut vals, carry, UNROLL);
        for (c, v) in carry.group.iter().zip(vals) {
            l.b.def_var(c.1, v);
        }
        l.b.ins().jump(self.grp_hdr, &[]);
    }

    /// Advance the row variables and the row-carried terms by one row; back to the row
    /// header.
    fn row_step(&self, l: &mut Lower, row: &Row, carry: &CarryLoop) {
        l.b.switch_to_block(self.row_next);
        let y = l.b.ins().iadd_imm_s(row.y, 1);
        l.b.def_var(self.y, y);
        let base = l.b.ins().iadd(row.base, self.stride64);
        l.b.def_var(self.row_base, base);
        let one = l.f32const_here(1.0);
        let yf = l.b.ins().fadd(row.yf, one);
        l.b.def_var(self.yf, yf);
        l.carry_next_row(carry);
        l.b.ins().jump(self.row_hdr, &[]);
    }
}

/// `v + splat(c)` over f32x4 lanes.
fn add_splat(l: &mut Lower, v: ir::Value, c: f32) -> ir::Value {
    let step = l.f32const_here(c);
    let step = l.b.ins().splat(F32X4, step);
    l.b.ins().fadd(v, step)
}
