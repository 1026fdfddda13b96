//! Carried terms, their emission: the int expressions of the pixel code affine in the pixel
//! column ([`crate::mid::affine`] finds them and proves them exact) are evaluated once per
//! row at the row's first group and advanced by `4*A` per group instead of evaluated in
//! every group (tier 1).
//!
//! Once per kernel run, after setup, [`Lower::carry_steps`] stores each term's step per
//! group (`4 * A` splatted, and `B` for a term affine in the row too) in the uniform frame;
//! [`Lower::carry_rows_start`] evaluates, at a pixel loop's entry, the value at the first
//! group of the first row of each term affine in the row too; each row prologue
//! ([`Lower::carry_prologue`]) gives every term the loop's variant reads its value at the
//! row's first group (read from the row carry, or evaluated with X and Y bound there), the
//! group loop carries it as a loop variable like X ([`Lower::carry_advance`]), and a group
//! reads it ([`Lower::carried_value`]) instead of evaluating the expression.
//!
//! Invariants: a term is evaluated outside the groups with its substitutable locals
//! replaced by their defining values ([`Lower::eval_affine`]: the same operations the group
//! would run on the same values), so a carried value is the value the group computed, bit
//! for bit; the uniform multipliers of `A` and `B` are evaluated once per run after setup,
//! where every uniform the pixel loops read has its final value.

use std::collections::HashSet;

use cranelift_codegen::ir::{self, types, InstBuilder};

use crate::ir::{BinOp, Elem, ExprId, ExprKind, Function, LocalId, ParamRole, Scalar, UnaryOp};
use crate::mid::affine::column_leaf;

use super::super::value::{mem_flags, splat, Val, I32X4};
use super::{Lower, Res, Storage};

/// The carried values of one pixel loop (see `Lower::pixel_rows`).
#[derive(Default)]
pub(super) struct CarryLoop {
    /// Per carried expression the loop reads: its id, the variable carrying it through
    /// the groups of a row, its step's offset.
    pub group: Vec<(ExprId, cranelift_frontend::Variable, u32)>,
    /// The values at the rows' first group of the expressions also carried from row to
    /// row (see [`RowCarry`]).
    pub rows: RowCarry,
}

/// Values at a row's first group, carried from row to row in a stack slot of the pixel
/// loop: loaded in the row prologue, advanced and stored back at the row's end. In memory
/// rather than in variables: live across the group loop they were spilled anyway, and
/// the register allocator's spill and reload code around the loop cost more.
#[derive(Default, Clone)]
pub(super) struct RowCarry {
    pub slot: Option<ir::StackSlot>,
    /// Per expression: its id, its offset in `slot`, its row step's offset in the uniform
    /// frame.
    pub items: Vec<(ExprId, u32, u32)>,
}
impl<'a, 'b> Lower<'a, 'b> {
    /// Evaluate carried expression `e` (or part of one) where the pixel code would, but
    /// with its substitutable locals replaced by their values: in the row prologue, with
    /// X bound to the row's first group.
    fn eval_affine(&mut self, e_id: ExprId) -> Res<Val> {
        let e = &self.exprs()[e_id];
        match &e.kind {
            ExprKind::Local(l) => match self.affine_def(*l) {
                Some(def) => self.eval_affine(def),
                None => self.eval(e_id),
            },
            ExprKind::Unary { op: UnaryOp::Neg, expr } => {
                let v = self.eval_affine(*expr)?;
                let comps = v.comps.iter().map(|&c| self.b.ins().ineg(c)).collect();
                Ok(Val { comps, ..v })
            }
            ExprKind::Binary {
                op: op @ (BinOp::Add | BinOp::Sub | BinOp::Mul),
                lhs,
                rhs,
            } => {
                let a = self.eval_affine(*lhs)?;
                let c = self.eval_affine(*rhs)?;
                self.binary(*op, a, c)
            }
            _ => self.eval(e_id),
        }
    }

    /// The coefficient `A` of carried expression `e` (a scalar i32; `None` for 0), with the
    /// uniform multipliers evaluated here (once per kernel run, after setup).
    fn column_coefficient(&mut self, e_id: ExprId, axis: LocalId) -> Res<Option<ir::Value>> {
        let e = &self.exprs()[e_id];
        if let Some(c) = column_leaf(self.exprs(), e_id, axis) {
            return Ok(Some(self.iconst_here(types::I32, c as i64)));
        }
        Ok(match &e.kind {
            ExprKind::Local(l) => match self.affine_def(*l) {
                Some(def) => self.column_coefficient(def, axis)?,
                None => None,
            },
            ExprKind::Unary { op: UnaryOp::Neg, expr } => {
                self.column_coefficient(*expr, axis)?.map(|a| self.b.ins().ineg(a))
            }
            ExprKind::Binary { op, lhs, rhs } => {
                let a = self.column_coefficient(*lhs, axis)?;
                let c = self.column_coefficient(*rhs, axis)?;
                match (op, a, c) {
                    (_, None, None) => None,
                    (BinOp::Add, Some(a), Some(c)) => Some(self.b.ins().iadd(a, c)),
                    (BinOp::Sub, Some(a), Some(c)) => Some(self.b.ins().isub(a, c)),
                    (BinOp::Add | BinOp::Sub, Some(a), None) => Some(a),
                    (BinOp::Add, None, Some(c)) => Some(c),
                    (BinOp::Sub, None, Some(c)) => Some(self.b.ins().ineg(c)),
                    (BinOp::Mul, Some(a), None) => {
                        let u = self.uniform_int(*rhs)?;
                        Some(self.b.ins().imul(a, u))
                    }
                    (BinOp::Mul, None, Some(c)) => {
                        let u = self.uniform_int(*lhs)?;
                        Some(self.b.ins().imul(u, c))
                    }
                    _ => return super::err("carried int expression of an unexpected shape"),
                }
            }
            _ => None,
        })
    }

    /// A uniform int multiplier's scalar value.
    fn uniform_int(&mut self, e: ExprId) -> Res<ir::Value> {
        let v = self.eval(e)?;
        match (v.varying, v.comps.as_slice()) {
            (false, &[c]) => Ok(c),
            _ => super::err("carried int expression with a varying multiplier"),
        }
    }

    /// Once per kernel run, after setup: every carried expression's step per group,
    /// `4 * A` splatted, into the uniform frame.
    pub(super) fn carry_steps(&mut self) -> Res<()> {
        let Some((fs, _)) = self.uniform_frame else {
            return Ok(());
        };
        let Some(carry) = self.plan.pixel.as_ref().map(|p| &p.carry) else {
            return Ok(());
        };
        let (Some(x), y) = (carry.x, carry.y) else {
            return Ok(());
        };
        for c in &carry.carried {
            let (expr, offset, row_offset) = (c.expr, c.step_offset, c.row_step_offset);
            let a = match self.column_coefficient(expr, x)? {
                Some(a) => a,
                None => self.iconst_here(types::I32, 0),
            };
            let step = self.b.ins().imul_imm_s(a, 4);
            let mut steps = vec![(step, offset)];
            if let (Some(row_offset), Some(y)) = (row_offset, y) {
                let b = match self.column_coefficient(expr, y)? {
                    Some(b) => b,
                    None => self.iconst_here(types::I32, 0),
                };
                steps.push((b, row_offset));
            }
            for (step, offset) in steps {
                let step = splat(&mut self.b, Scalar::Int, step);
                let addr = self.slot_addr(fs);
                self.b.ins().store(mem_flags(), step, addr, offset as i32);
            }
        }
        Ok(())
    }

    /// Bind X to `x_f` and Y to `y_f` (vectors of lane centres) for an evaluation outside
    /// the groups.
    fn bind_xy(&mut self, f: &'a Function, x_f: ir::Value, y_f: ir::Value) {
        for (role, v) in [(ParamRole::X, x_f), (ParamRole::Y, y_f)] {
            let Some(p) = f.param_by_role(role) else { continue };
            let i = p.local.0 as usize;
            if let (Storage::Vars(vs), Elem::Scalar(sc)) = (&self.frames[0].storage[i], f.local(p.local).ty.elem) {
                let var = vs[0];
                let v = super::fixed::convert(&mut self.b, Scalar::Float, sc, v);
                self.b.def_var(var, v);
            }
        }
    }

    /// The carried expressions a pixel loop's variant reads (`only`; `None`: all).
    fn carried_in(&self, only: Option<&HashSet<ExprId>>) -> Vec<(ExprId, u32, Option<u32>)> {
        let (Some(p), Some(_)) = (&self.plan.pixel, self.uniform_frame) else {
            return vec![];
        };
        p.carry
            .carried
            .iter()
            .filter(|c| only.is_none_or(|set| set.contains(&c.expr)))
            .map(|c| (c.expr, c.step_offset, c.row_step_offset))
            .collect()
    }

    /// Evaluate carried `expr` outside the groups (X and Y bound), as one i32x4 vector.
    fn eval_carried(&mut self, expr: ExprId) -> Res<ir::Value> {
        let v = self.eval_affine(expr)?;
        let v = self.make_varying(v);
        match v.comps.as_slice() {
            [c] => Ok(*c),
            _ => super::err("carried int expression with several components"),
        }
    }

    /// Entry of a pixel loop (rows from `y0`, groups from `g0`): the value at the first
    /// group of the first row of every carried expression that is affine in the row too,
    /// in variables the row prologue reads and `carry_next_row` advances. Returns
    /// (id, row variable, row step offset) per such expression.
    pub(super) fn carry_rows_start(
        &mut self,
        f: &'a Function,
        g0: ir::Value,
        y0: ir::Value,
        only: Option<&HashSet<ExprId>>,
    ) -> Res<RowCarry> {
        let picked: Vec<(ExprId, u32)> = self
            .carried_in(only)
            .into_iter()
            .filter_map(|(e, _, row)| row.map(|r| (e, r)))
            .collect();
        if picked.is_empty() {
            return Ok(RowCarry::default());
        }
        let slot = self.b.create_sized_stack_slot(ir::StackSlotData::new(
            ir::StackSlotKind::ExplicitSlot,
            16 * picked.len() as u32,
            4,
        ));
        let x0_f = self.lane_centres(g0);
        let yf = self.sample_coord(y0, super::loops::Axis::Y);
        let y0_f = self.b.ins().splat(super::F32X4, yf);
        self.bind_xy(f, x0_f, y0_f);
        // The hoisted uniform operations are already in the frame; the row terms are not.
        let addr = self.uniform_frame.map(|(fs, _)| self.slot_addr(fs));
        self.prologue_frame = addr.map(|a| (a, false));
        let mut out = RowCarry {
            slot: Some(slot),
            items: vec![],
        };
        for (i, (expr, row_offset)) in picked.into_iter().enumerate() {
            let v = self.eval_carried(expr);
            let v = match v {
                Ok(v) => v,
                Err(e) => {
                    self.prologue_frame = None;
                    return Err(e);
                }
            };
            let at = 16 * i as u32;
            let addr = self.slot_addr(slot);
            self.b.ins().store(mem_flags(), v, addr, at as i32);
            out.items.push((expr, at, row_offset));
        }
        self.prologue_frame = None;
        Ok(out)
    }

    /// Row prologue of a pixel loop (after the row hoists): bind X to the row's first group
    /// (`x0_f`) and Y to the row (`y_f`); every carried expression the loop's variant reads
    /// gets its value at the first group, read from its row variable (`rows`, from
    /// [`Self::carry_rows_start`]) or evaluated here.
    pub(super) fn carry_prologue(
        &mut self,
        f: &'a Function,
        x0_f: ir::Value,
        y_f: ir::Value,
        only: Option<&HashSet<ExprId>>,
        rows: &RowCarry,
    ) -> Res<CarryLoop> {
        let picked = self.carried_in(only);
        let mut out = CarryLoop::default();
        if picked.is_empty() {
            return Ok(out);
        }
        if picked.len() > rows.items.len() {
            self.bind_xy(f, x0_f, y_f);
        }
        out.rows = rows.clone();
        // Only the hoisted uniform operations are read back: a row term is in the frame
        // only when the loop's variant reads it, which a substituted local's definition
        // (evaluated here) need not be.
        let addr = self.uniform_frame.map(|(fs, _)| self.slot_addr(fs));
        self.prologue_frame = addr.map(|a| (a, false));
        for (expr, offset, _) in picked {
            let v = match (rows.slot, rows.items.iter().find(|r| r.0 == expr)) {
                (Some(slot), Some(&(_, at, _))) => {
                    let addr = self.slot_addr(slot);
                    Ok(self.b.ins().load(I32X4, mem_flags(), addr, at as i32))
                }
                _ => self.eval_carried(expr),
            };
            let v = match v {
                Ok(v) => v,
                Err(e) => {
                    self.prologue_frame = None;
                    return Err(e);
                }
            };
            let var = self.declare_var(I32X4);
            self.b.def_var(var, v);
            out.group.push((expr, var, offset));
        }
        self.prologue_frame = None;
        Ok(out)
    }

    /// Advance carried values by `groups` groups: `v + groups * step` per carried value.
    pub(super) fn carry_advance(&mut self, vals: &mut [ir::Value], carry: &CarryLoop, groups: u32) {
        let Some((fs, _)) = self.uniform_frame else { return };
        if carry.group.is_empty() || groups == 0 {
            return;
        }
        let addr = self.slot_addr(fs);
        for (v, &(_, _, off)) in vals.iter_mut().zip(&carry.group) {
            // Not `can_move`: hoisted out of the loop the steps were spilled and reloaded;
            // here each load folds into its add.
            let step = self.b.ins().load(I32X4, mem_flags(), addr, off as i32);
            for _ in 0..groups {
                *v = self.b.ins().iadd(*v, step);
            }
        }
    }

    /// End of a row: advance the values at the rows' first group by one row.
    pub(super) fn carry_next_row(&mut self, carry: &CarryLoop) {
        let (Some((fs, _)), Some(slot)) = (self.uniform_frame, carry.rows.slot) else {
            return;
        };
        let addr = self.slot_addr(fs);
        let row_addr = self.slot_addr(slot);
        for &(_, at, off) in &carry.rows.items {
            let v = self.b.ins().load(I32X4, mem_flags(), row_addr, at as i32);
            let step = self.b.ins().load(I32X4, mem_flags(), addr, off as i32);
            let next = self.b.ins().iadd(v, step);
            self.b.ins().store(mem_flags(), next, row_addr, at as i32);
        }
    }

    /// The value a substitutable local of the carried terms stands for (see
    /// [`crate::mid::affine`]).
    fn affine_def(&self, l: LocalId) -> Option<ExprId> {
        self.plan.pixel.as_ref()?.carry.defs.get(&l).copied()
    }

    /// In a group: the carried value of `e`, if `e` is carried by the loop being lowered.
    pub(super) fn carried_value(&self, e: ExprId) -> Option<Val> {
        if self.carry_now.is_empty() || self.pix.is_none() || self.frames.len() != 1 {
            return None;
        }
        let &(_, v) = self.carry_now.iter().find(|(k, _)| *k == e)?;
        Some(Val {
            comps: vec![v],
            scalar: Scalar::Int,
            varying: true,
        })
    }
}
