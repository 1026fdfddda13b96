//! Int expressions of the pixel code that are affine in the pixel column, carried along the
//! row instead of evaluated in every group (tier 1).
//!
//! Language ints wrap (two's complement), so `+`, `-`, unary `-` and `*` on ints are ring
//! operations mod 2^32. An int expression whose value at pixel column `xi` is `A*xi + R`
//! (mod 2^32), with `A` the same for every pixel of the frame and `R` the same for every
//! pixel of a row, is evaluated once per row at the row's first group and then advanced by
//! `4*A` per group (pure, so every group advances whatever its lanes): bit-identical to
//! evaluating it in each group. [`Lower::collect_carried`] finds, at compile time, the
//! *maximal* such expressions of the pixel code; the kernel run computes each one's step
//! once after setup ([`Lower::carry_steps`], into the uniform frame), each row prologue its
//! value at the first group ([`Lower::carry_prologue`]), and the group loop carries it
//! as a loop variable like X (`Lower::pixel_rows`); a group reads it instead of evaluating.
//! An expression affine in the row as well (`A*xi + B*yi + C`: `int(Y * c)` leaves, with
//! the same exactness as X's) is evaluated once per pixel loop, at its first row, and its
//! value at a row's first group advanced by `B` per row ([`Carried::row_step_offset`]).
//!
//! The forms, and why each is exact:
//! - `int(X * c)` (or `int(c * X)`) with an integer constant `c`, `1 <= |c| <= 2^15`, whose
//!   odd part `m` (`c = m * 2^k`) has `|m| <= 255`. A pixel's X is `xi + 0.5` exactly, with
//!   `0 <= xi < 2^15` (the group's lanes: tile-aligned groups from the tile origin, images
//!   at most `MAX_IMAGE_SIDE` = 16384 pixels wide, plus at most 3 lanes past the edge; X is
//!   built as int -> float + 0.5 and stepped by 4.0, exact below 2^22). Then
//!   `c * X = m * (2*xi + 1) * 2^(k-1)` with `|m * (2*xi + 1)| < 2^24`: the f32 product is
//!   exact, `|c * X| < 2^31` never saturates, and truncation toward zero gives
//!   `c*xi + c/2` for even `c`, `c*xi + (c-1)/2` for odd `c > 0` and `c*xi + (c+1)/2` for
//!   odd `c < 0` (X > 0 fixes the sign): affine with `A = c`. Anything else (another
//!   constant, a float local holding X) is not treated as affine.
//! - Row-invariant int expressions (hoist.rs' definition: constants, uniform locals the
//!   pixel code never assigns, Y when never assigned), `A = 0`.
//! - `a + b`, `a - b`, `-a` of such forms; `a * u` and `u * a` where `u` is uniform (no Y,
//!   no pixel local), so `A` is the same for the whole kernel run and computed once.
//! - An int local of the pixel code assigned exactly once in the pixel code, as a whole,
//!   outside loops, interpolation arms and varying `if`s, read where that assignment
//!   dominates the read (after it in the same or an enclosing statement list): it holds the
//!   form of its value, computed where it is assigned (so the locals that value reads are
//!   the ones already defined there, and keep their values: they are assigned once too).
//!
//! A substitutable local that only carried expressions read (`sx`, `sy` of
//! screen_triangle) is not assigned in the groups at all, and the row terms of its value
//! are not stored per row (`Lower::unread_in_groups`).
//!
//! X must never be assigned in the pixel code, and pixel code that calls a primitive
//! carries nothing. Tier 0 evaluates every expression as written (it serves one frame;
//! tier 1 must be bit-identical to it, which the exactness above guarantees).

use std::collections::{HashMap, HashSet};

use cranelift_codegen::ir::{self, types, InstBuilder};

use crate::ir::{
    BinOp, ConstValue, Elem, Expr, ExprId, ExprKind, Function, LocalId, ParamRole, Scalar, Stmt, StmtKind, UnaryOp,
};

use super::super::value::{mem_flags, splat, Val, I32X4};
use super::{Lower, Res, Storage};

/// One carried expression: where its per-group step lives in the uniform frame.
pub(super) struct Carried<'a> {
    pub expr: &'a Expr,
    /// Byte offset of its step (`4 * A` splatted, i32x4) in the uniform frame.
    pub step_offset: u32,
    /// When the expression is affine in the row too (`A*xi + B*yi + C`, B and C the same
    /// for the kernel run): the byte offset of its row step (`B` splatted). Its value at a
    /// row's first group is then carried from row to row as well, instead of evaluated.
    pub row_step_offset: Option<u32>,
}

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

/// How an int expression depends on the pixel column.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Form {
    /// Uniform: no Y, no pixel local (row_invariant without Y); may multiply an affine form.
    Uniform,
    /// The same in every group of a row (A = 0).
    Row,
    /// `A*xi + R`, A the same for the kernel run.
    Affine,
}

/// The analysis' state while walking the pixel code.
struct Walk<'a> {
    x: LocalId,
    y: Option<LocalId>,
    /// Y when it is a float the pixel code never assigns (`int(Y * c)` leaves).
    y_float: Option<LocalId>,
    assigned: HashSet<LocalId>,
    /// Locals assigned exactly once in the pixel code, as a whole.
    single: HashSet<LocalId>,
    /// Substitutable locals: their value, its form, and whether it is affine in the row
    /// too (see [`Carried::row_step_offset`]), at the assignment.
    defs: HashMap<LocalId, (&'a Expr, Form, bool)>,
    /// The substitutable locals in the order of their assignments.
    def_order: Vec<LocalId>,
    /// Substitutable locals read by themselves (not inside a carried expression).
    bare: HashSet<LocalId>,
}

fn int_scalar(e: &Expr) -> bool {
    e.ty.dims.is_empty() && !e.ty.per_seq && e.ty.elem == Elem::Scalar(Scalar::Int)
}

/// `c` if `e` is a float constant with an integer value of the exactness condition in the
/// module comment (`1 <= |c| <= 2^15`, odd part at most 255 in magnitude).
fn exact_scale(e: &Expr) -> Option<i32> {
    let c = match &e.kind {
        ExprKind::Const(ConstValue::Float(c)) => *c as f64,
        ExprKind::Convert(inner) => match inner.kind {
            ExprKind::Const(ConstValue::Int(i)) if e.ty.elem == Elem::Scalar(Scalar::Float) => i as f64,
            _ => return None,
        },
        _ => return None,
    };
    if !c.is_finite() || c.trunc() != c || c == 0.0 || c.abs() > 32768.0 {
        return None;
    }
    let c = c as i32;
    let odd = c >> c.trailing_zeros();
    (odd.unsigned_abs() <= 255).then_some(c)
}

/// `c` if `e` is `int(X * c)` or `int(c * X)` with `c` exact (see [`exact_scale`]).
fn column_leaf(e: &Expr, x: LocalId) -> Option<i32> {
    let ExprKind::Convert(inner) = &e.kind else { return None };
    if !int_scalar(e) || inner.ty.elem != Elem::Scalar(Scalar::Float) || !inner.ty.dims.is_empty() {
        return None;
    }
    let ExprKind::Binary {
        op: BinOp::Mul,
        lhs,
        rhs,
    } = &inner.kind
    else {
        return None;
    };
    let is_x = |e: &Expr| matches!(e.kind, ExprKind::Local(l) if l == x);
    if is_x(lhs) {
        exact_scale(rhs)
    } else if is_x(rhs) {
        exact_scale(lhs)
    } else {
        None
    }
}

impl<'a, 'b> Lower<'a, 'b> {
    /// The maximal carried expressions of `f`'s pixel code (see the module comment), their
    /// steps at offsets from `first_offset` (16 bytes each), and the substitutable locals.
    pub(super) fn collect_carried(&mut self, f: &'a Function, first_offset: u32) -> Vec<Carried<'a>> {
        let mut assigned = HashSet::new();
        super::block::assigned_locals(&f.pixel, &mut assigned);
        let Some(x) = f.param_by_role(ParamRole::X).map(|p| p.local) else {
            return vec![];
        };
        let x_float = f.local(x).ty.elem == Elem::Scalar(Scalar::Float) && f.local(x).ty.dims.is_empty();
        if !x_float || assigned.contains(&x) || calls_primitive(&f.pixel) {
            return vec![];
        }
        let y = f
            .param_by_role(ParamRole::Y)
            .map(|p| p.local)
            .filter(|l| !assigned.contains(l));
        let y_float = y.filter(|&l| f.local(l).ty.elem == Elem::Scalar(Scalar::Float) && f.local(l).ty.dims.is_empty());
        let mut counts: HashMap<LocalId, (u32, bool)> = HashMap::new();
        crate::ir::for_each_assign(&f.pixel, &mut |place, _| {
            let c = counts.entry(place.local).or_insert((0, true));
            c.0 += 1;
            c.1 &= place.indices.is_empty();
        });
        let params: HashSet<LocalId> = f.params.iter().map(|p| p.local).collect();
        let single = counts
            .into_iter()
            .filter(|(l, (n, whole))| {
                *n == 1
                    && *whole
                    && !params.contains(l)
                    && f.locals.get(l.0 as usize).is_some_and(|local| {
                        local.ty.dims.is_empty() && !local.ty.per_seq && local.ty.elem == Elem::Scalar(Scalar::Int)
                    })
            })
            .map(|(l, _)| l)
            .collect();
        let mut w = Walk {
            x,
            y,
            y_float,
            assigned,
            single,
            defs: HashMap::new(),
            def_order: vec![],
            bare: HashSet::new(),
        };
        let mut found = vec![];
        let mut visible = HashSet::new();
        self.carry_stmts(f, &f.pixel, true, &mut visible, &mut w, &mut found);
        // An affine local read by itself (`v` in `v <= w`) is carried as its value: the
        // group's assignment then reads the carried value.
        for l in &w.def_order {
            let Some(&(value, form, plane)) = w.defs.get(l) else {
                continue;
            };
            if form == Form::Affine
                && w.bare.contains(l)
                && !matches!(value.kind, ExprKind::Local(_) | ExprKind::Const(_))
            {
                found.push((value, plane));
            }
        }
        self.affine_x = Some(x);
        self.affine_y = y_float;
        let mut next = first_offset;
        let carried: Vec<Carried<'a>> = found
            .into_iter()
            .map(|(expr, rows)| {
                let step_offset = next;
                next += 16;
                let row_step_offset = rows.then(|| {
                    next += 16;
                    next - 16
                });
                Carried {
                    expr,
                    step_offset,
                    row_step_offset,
                }
            })
            .collect();
        self.affine_defs = w.defs.iter().map(|(l, (e, _, _))| (*l, *e)).collect();
        // A substitutable local every read of which is inside a carried expression is never
        // read by a group (`sy` of screen_triangle).
        self.unread_in_groups.clear();
        self.unstored_terms.clear();
        self.mark_unread_in_groups(
            f,
            carried.iter().map(|c| c.expr),
            w.def_order
                .iter()
                .filter_map(|l| w.defs.get(l).map(|&(value, _, _)| (*l, value))),
        );
        carried
    }

    /// Of `locals` (each with the value the terms substitute for it), mark those whose every
    /// read in `f`'s pixel code is inside one of `terms`: no group reads them, so their
    /// assignment is not lowered there, and the row terms only their values use are not
    /// stored per row. Shared by the carried terms (above) and the row terms (`hoist`).
    pub(super) fn mark_unread_in_groups<'e>(
        &mut self,
        f: &Function,
        terms: impl IntoIterator<Item = &'e Expr>,
        locals: impl IntoIterator<Item = (LocalId, &'e Expr)>,
    ) {
        let mut all_reads = HashMap::new();
        count_stmt_reads(&f.pixel, &mut all_reads);
        let mut term_reads = HashMap::new();
        for t in terms {
            count_reads(t, &mut term_reads);
        }
        for (l, value) in locals {
            if all_reads.get(&l) == term_reads.get(&l) {
                self.unread_in_groups.insert(l);
                super::block::expr_keys(value, &mut self.unstored_terms);
            }
        }
    }

    /// Walk `stmts` in order; `straight`: not under a varying `if` (assignments here are
    /// seen by every lane that reaches the reads after them).
    fn carry_stmts(
        &self,
        f: &'a Function,
        stmts: &'a [Stmt],
        straight: bool,
        visible: &mut HashSet<LocalId>,
        w: &mut Walk<'a>,
        out: &mut Vec<(&'a Expr, bool)>,
    ) {
        for s in stmts {
            match &s.kind {
                StmtKind::Assign { place, value } => {
                    for (i, _) in &place.indices {
                        self.carry_expr(f, i, visible, w, out);
                    }
                    let form = if straight && w.single.contains(&place.local) {
                        self.form(f, value, visible, w)
                    } else {
                        None
                    };
                    match form {
                        // Its reads are carried (or evaluated) instead; the value itself is
                        // evaluated where it is assigned only if something else reads it.
                        Some(form) => {
                            let plane = self.plane(f, value, visible, w);
                            w.defs.insert(place.local, (value, form, plane));
                            w.def_order.push(place.local);
                            visible.insert(place.local);
                        }
                        None => self.carry_expr(f, value, visible, w, out),
                    }
                }
                StmtKind::If { cond, then, otherwise } => {
                    self.carry_expr(f, cond, visible, w, out);
                    let straight = straight && !cond.var.is_varying();
                    for side in [then, otherwise] {
                        let mut inner = visible.clone();
                        self.carry_stmts(f, side, straight, &mut inner, w, out);
                    }
                }
                // Loop bodies, interpolation arms and the rest are left as they are.
                _ => {}
            }
        }
    }

    /// Record the maximal affine subexpressions of `e` in `out`.
    fn carry_expr(
        &self,
        f: &'a Function,
        e: &'a Expr,
        visible: &HashSet<LocalId>,
        w: &mut Walk<'a>,
        out: &mut Vec<(&'a Expr, bool)>,
    ) {
        if let ExprKind::Local(l) = e.kind {
            if visible.contains(&l) {
                w.bare.insert(l);
            }
            return;
        }
        if !matches!(e.kind, ExprKind::Local(_) | ExprKind::Const(_))
            && self.form(f, e, visible, w) == Some(Form::Affine)
        {
            out.push((e, self.plane(f, e, visible, w)));
            return;
        }
        let mut children = vec![];
        e.for_each_child(|c| children.push(c));
        for c in children {
            self.carry_expr(f, c, visible, w, out);
        }
    }

    /// The form of int expression `e` where the locals in `visible` hold their definitions.
    fn form(&self, f: &Function, e: &Expr, visible: &HashSet<LocalId>, w: &Walk<'a>) -> Option<Form> {
        if !int_scalar(e) {
            return None;
        }
        if self.row_invariant(f, e, None, &w.assigned) {
            return Some(Form::Uniform);
        }
        if self.row_invariant(f, e, w.y, &w.assigned) {
            return Some(Form::Row);
        }
        if column_leaf(e, w.x).is_some() {
            return Some(Form::Affine);
        }
        match &e.kind {
            ExprKind::Local(l) if visible.contains(l) => match w.defs.get(l)?.1 {
                // A uniform value through a local is only known in the group: not a
                // multiplier computed once per run.
                Form::Uniform | Form::Row => Some(Form::Row),
                Form::Affine => Some(Form::Affine),
            },
            ExprKind::Unary { op: UnaryOp::Neg, expr } => match self.form(f, expr, visible, w)? {
                Form::Affine => Some(Form::Affine),
                _ => Some(Form::Row),
            },
            ExprKind::Binary { op, lhs, rhs } => {
                let a = self.form(f, lhs, visible, w)?;
                let c = self.form(f, rhs, visible, w)?;
                match op {
                    BinOp::Add | BinOp::Sub if a == Form::Affine || c == Form::Affine => Some(Form::Affine),
                    BinOp::Mul => match (a, c) {
                        (Form::Affine, Form::Uniform) | (Form::Uniform, Form::Affine) => Some(Form::Affine),
                        (Form::Affine, _) | (_, Form::Affine) => None,
                        _ => Some(Form::Row),
                    },
                    BinOp::Add | BinOp::Sub => Some(Form::Row),
                    _ => None,
                }
            }
            _ => None,
        }
    }

    /// `e` is `A*xi + B*yi + C` with A, B and C the same for the kernel run: built from
    /// `int(X * c)` and `int(Y * c)` leaves (the same exactness), uniform values and
    /// locals of that form, by `+`, `-`, unary `-` and products by uniform values.
    fn plane(&self, f: &Function, e: &Expr, visible: &HashSet<LocalId>, w: &Walk<'a>) -> bool {
        if !int_scalar(e) {
            return false;
        }
        if self.row_invariant(f, e, None, &w.assigned)
            || column_leaf(e, w.x).is_some()
            || w.y_float.is_some_and(|y| column_leaf(e, y).is_some())
        {
            return true;
        }
        match &e.kind {
            ExprKind::Local(l) => visible.contains(l) && w.defs.get(l).is_some_and(|d| d.2),
            ExprKind::Unary { op: UnaryOp::Neg, expr } => self.plane(f, expr, visible, w),
            ExprKind::Binary {
                op: BinOp::Add | BinOp::Sub,
                lhs,
                rhs,
            } => self.plane(f, lhs, visible, w) && self.plane(f, rhs, visible, w),
            ExprKind::Binary {
                op: BinOp::Mul,
                lhs,
                rhs,
            } => {
                let uniform = |e: &Expr| self.row_invariant(f, e, None, &w.assigned);
                (uniform(lhs) && self.plane(f, rhs, visible, w)) || (uniform(rhs) && self.plane(f, lhs, visible, w))
            }
            _ => false,
        }
    }

    /// Evaluate carried expression `e` (or part of one) where the pixel code would, but
    /// with its substitutable locals replaced by their values: in the row prologue, with
    /// X bound to the row's first group.
    fn eval_affine(&mut self, e: &'a Expr) -> Res<Val> {
        match &e.kind {
            ExprKind::Local(l) => match self.affine_defs.get(l) {
                Some(&def) => self.eval_affine(def),
                None => self.eval(e),
            },
            ExprKind::Unary { op: UnaryOp::Neg, expr } => {
                let v = self.eval_affine(expr)?;
                let comps = v.comps.iter().map(|&c| self.b.ins().ineg(c)).collect();
                Ok(Val { comps, ..v })
            }
            ExprKind::Binary {
                op: op @ (BinOp::Add | BinOp::Sub | BinOp::Mul),
                lhs,
                rhs,
            } => {
                let a = self.eval_affine(lhs)?;
                let c = self.eval_affine(rhs)?;
                self.binary(*op, a, c)
            }
            _ => self.eval(e),
        }
    }

    /// The coefficient `A` of carried expression `e` (a scalar i32; `None` for 0), with the
    /// uniform multipliers evaluated here (once per kernel run, after setup).
    fn column_coefficient(&mut self, e: &'a Expr, axis: LocalId) -> Res<Option<ir::Value>> {
        if let Some(c) = column_leaf(e, axis) {
            return Ok(Some(self.iconst_here(types::I32, c as i64)));
        }
        Ok(match &e.kind {
            ExprKind::Local(l) => match self.affine_defs.get(l) {
                Some(&def) => self.column_coefficient(def, axis)?,
                None => None,
            },
            ExprKind::Unary { op: UnaryOp::Neg, expr } => {
                self.column_coefficient(expr, axis)?.map(|a| self.b.ins().ineg(a))
            }
            ExprKind::Binary { op, lhs, rhs } => {
                let a = self.column_coefficient(lhs, axis)?;
                let c = self.column_coefficient(rhs, axis)?;
                match (op, a, c) {
                    (_, None, None) => None,
                    (BinOp::Add, Some(a), Some(c)) => Some(self.b.ins().iadd(a, c)),
                    (BinOp::Sub, Some(a), Some(c)) => Some(self.b.ins().isub(a, c)),
                    (BinOp::Add | BinOp::Sub, Some(a), None) => Some(a),
                    (BinOp::Add, None, Some(c)) => Some(c),
                    (BinOp::Sub, None, Some(c)) => Some(self.b.ins().ineg(c)),
                    (BinOp::Mul, Some(a), None) => {
                        let u = self.uniform_int(rhs)?;
                        Some(self.b.ins().imul(a, u))
                    }
                    (BinOp::Mul, None, Some(c)) => {
                        let u = self.uniform_int(lhs)?;
                        Some(self.b.ins().imul(u, c))
                    }
                    _ => return super::err("carried int expression of an unexpected shape"),
                }
            }
            _ => None,
        })
    }

    /// A uniform int multiplier's scalar value.
    fn uniform_int(&mut self, e: &'a Expr) -> Res<ir::Value> {
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
        let (Some(x), y) = (self.affine_x, self.affine_y) else {
            return Ok(());
        };
        for k in 0..self.carried.len() {
            let c = &self.carried[k];
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
    fn carried_in(&self, only: Option<&HashSet<ExprId>>) -> Vec<(&'a Expr, u32, Option<u32>)> {
        if self.uniform_frame.is_none() {
            return vec![];
        }
        self.carried
            .iter()
            .filter(|c| only.is_none_or(|set| set.contains(&c.expr.id)))
            .map(|c| (c.expr, c.step_offset, c.row_step_offset))
            .collect()
    }

    /// Evaluate carried `expr` outside the groups (X and Y bound), as one i32x4 vector.
    fn eval_carried(&mut self, expr: &'a Expr) -> Res<ir::Value> {
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
        let picked: Vec<(&'a Expr, u32)> = self
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
        let yf = self.b.ins().fcvt_from_sint(types::F32, y0);
        let half = self.f32const_here(0.5);
        let yf = self.b.ins().fadd(yf, half);
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
            out.items.push((expr.id, at, row_offset));
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
            let v = match (rows.slot, rows.items.iter().find(|r| r.0 == expr.id)) {
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
            out.group.push((expr.id, var, offset));
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

    /// In a group: the carried value of `e`, if `e` is carried by the loop being lowered.
    pub(super) fn carried_value(&self, e: &'a Expr) -> Option<Val> {
        if self.carry_now.is_empty() || self.pix.is_none() || self.frames.len() != 1 {
            return None;
        }
        let &(_, v) = self.carry_now.iter().find(|(k, _)| *k == e.id)?;
        Some(Val {
            comps: vec![v],
            scalar: Scalar::Int,
            varying: true,
        })
    }
}

/// The pixel code renders another primitive somewhere (its X is this one's: not carried).
fn calls_primitive(stmts: &[Stmt]) -> bool {
    stmts.iter().any(|s| match &s.kind {
        StmtKind::CallPrimitive { .. } => true,
        StmtKind::If { then, otherwise, .. } => calls_primitive(then) || calls_primitive(otherwise),
        StmtKind::Loop { body, step, .. } => calls_primitive(body) || calls_primitive(step),
        StmtKind::Interpolation { arms } => arms.iter().any(|a| calls_primitive(&a.body)),
        _ => false,
    })
}

/// Count the reads of each local in `e` (every `Local` node).
fn count_reads(e: &Expr, out: &mut HashMap<LocalId, u32>) {
    if let ExprKind::Local(l) = e.kind {
        *out.entry(l).or_insert(0) += 1;
    }
    e.for_each_child(|c| count_reads(c, out));
}

/// Count the reads of each local in every expression of `stmts`.
fn count_stmt_reads(stmts: &[Stmt], out: &mut HashMap<LocalId, u32>) {
    for s in stmts {
        match &s.kind {
            StmtKind::Assign { place, value } => {
                for (i, _) in &place.indices {
                    count_reads(i, out);
                }
                count_reads(value, out);
            }
            StmtKind::If { cond, then, otherwise } => {
                count_reads(cond, out);
                count_stmt_reads(then, out);
                count_stmt_reads(otherwise, out);
            }
            StmtKind::Loop { cond, body, step, .. } => {
                if let Some(c) = cond {
                    count_reads(c, out);
                }
                count_stmt_reads(body, out);
                count_stmt_reads(step, out);
            }
            StmtKind::Interpolation { arms } => arms.iter().for_each(|a| count_stmt_reads(&a.body, out)),
            StmtKind::InterpolatorReturn(Some(e)) => count_reads(e, out),
            StmtKind::Bound(es) => es.iter().for_each(|e| count_reads(e, out)),
            StmtKind::CallPrimitive { args, .. } => args.iter().for_each(|e| count_reads(e, out)),
            StmtKind::InterpolatorReturn(None) | StmtKind::Break(_) | StmtKind::Continue(_) | StmtKind::Return => {}
        }
    }
}
