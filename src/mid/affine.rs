//! Int expressions of the pixel code that are affine in the pixel column, carried along the
//! row instead of evaluated in every group (tier 1).
//!
//! Language ints wrap (two's complement), so `+`, `-`, unary `-` and `*` on ints are ring
//! operations mod 2^32. An int expression whose value at pixel column `xi` is `A*xi + R`
//! (mod 2^32), with `A` the same for every pixel of the frame and `R` the same for every
//! pixel of a row, is evaluated once per row at the row's first group and then advanced by
//! `4*A` per group (pure, so every group advances whatever its lanes): bit-identical to
//! evaluating it in each group. [`collect_carried`] finds, at compile time, the
//! *maximal* such expressions of the pixel code; the kernel run computes each one's step
//! once after setup (the JIT's `Lower::carry_steps`, into the uniform frame), each row
//! prologue its value at the first group (`Lower::carry_prologue`), and the group loop carries it
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
//! - Row-invariant int expressions ([`super::hoist`]'s definition: constants, uniform locals the
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
//! are not stored per row ([`mark_unread_in_groups`]).
//!
//! X must never be assigned in the pixel code, and pixel code that calls a primitive
//! carries nothing. Tier 0 evaluates every expression as written (it serves one frame;
//! tier 1 must be bit-identical to it, which the exactness above guarantees).

use std::collections::{HashMap, HashSet};

use super::hoist::Scope;
use crate::ir::{
    BinOp, ConstValue, Elem, Expr, ExprId, ExprKind, Exprs, Function, LocalId, ParamRole, Scalar, StmtId, StmtKind,
    UnaryOp,
};

/// One carried expression: where its per-group step lives in the uniform frame.
pub(crate) struct Carried {
    pub expr: ExprId,
    /// Byte offset of its step (`4 * A` splatted, i32x4) in the uniform frame.
    pub step_offset: u32,
    /// When the expression is affine in the row too (`A*xi + B*yi + C`, B and C the same
    /// for the kernel run): the byte offset of its row step (`B` splatted). Its value at a
    /// row's first group is then carried from row to row as well, instead of evaluated.
    pub row_step_offset: Option<u32>,
}

/// The carried terms of a primitive's pixel code (empty at tier 0, and when the pixel code
/// has no X it never assigns, or calls a primitive).
#[derive(Default)]
pub(crate) struct Carry {
    pub carried: Vec<Carried>,
    /// Substitutable locals (see the module comment), by their single defining value.
    pub defs: HashMap<LocalId, ExprId>,
    /// The primitive's X, when the pixel code was walked.
    pub x: Option<LocalId>,
    /// The primitive's Y when carried terms may be affine in the row too.
    pub y: Option<LocalId>,
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
struct Walk<'s> {
    x: LocalId,
    y: Option<LocalId>,
    /// Y when it is a float the pixel code never assigns (`int(Y * c)` leaves).
    y_float: Option<LocalId>,
    assigned: &'s HashSet<LocalId>,
    /// Locals assigned exactly once in the pixel code, as a whole.
    single: HashSet<LocalId>,
    /// Substitutable locals: their value, its form, and whether it is affine in the row
    /// too (see [`Carried::row_step_offset`]), at the assignment.
    defs: HashMap<LocalId, (ExprId, Form, bool)>,
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
fn exact_scale(x: &Exprs, e_id: ExprId) -> Option<i32> {
    let e = &x[e_id];
    let c = match &e.kind {
        ExprKind::Const(ConstValue::Float(c)) => *c as f64,
        ExprKind::Convert(inner) => match x[*inner].kind {
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
pub(crate) fn column_leaf(exprs: &Exprs, e_id: ExprId, x: LocalId) -> Option<i32> {
    let e = &exprs[e_id];
    let ExprKind::Convert(inner) = e.kind else { return None };
    let inner = &exprs[inner];
    if !int_scalar(e) || inner.ty.elem != Elem::Scalar(Scalar::Float) || !inner.ty.dims.is_empty() {
        return None;
    }
    let ExprKind::Binary {
        op: BinOp::Mul,
        lhs,
        rhs,
    } = inner.kind
    else {
        return None;
    };
    let is_x = |e: ExprId| matches!(exprs[e].kind, ExprKind::Local(l) if l == x);
    if is_x(lhs) {
        exact_scale(exprs, rhs)
    } else if is_x(rhs) {
        exact_scale(exprs, lhs)
    } else {
        None
    }
}

/// The carried terms of `f`'s pixel code (see the module comment), their steps at offsets
/// from `first_offset` (16 bytes each), and the substitutable locals; `assigned`: the locals
/// the pixel code assigns. The substitutable locals no group reads go to `unread`, their
/// values' expressions to `unstored` (see [`mark_unread_in_groups`]).
pub(crate) fn collect_carried(
    scope: &Scope<'_>,
    f: &Function,
    assigned: &HashSet<LocalId>,
    first_offset: u32,
    unread: &mut HashSet<LocalId>,
    unstored: &mut HashSet<ExprId>,
) -> Carry {
    scope.collect_carried(f, assigned, first_offset, unread, unstored)
}

/// Of `locals` (each with the value the terms substitute for it), mark in `unread` those
/// whose every read in `f`'s pixel code is inside one of `terms`: no group reads them, so
/// their assignment is not lowered there, and the row terms only their values use (marked
/// in `unstored`) are not stored per row. Shared by the carried terms and the row terms
/// ([`super::hoist::row_locals_unread`]).
pub(crate) fn mark_unread_in_groups(
    f: &Function,
    terms: impl IntoIterator<Item = ExprId>,
    locals: impl IntoIterator<Item = (LocalId, ExprId)>,
    unread: &mut HashSet<LocalId>,
    unstored: &mut HashSet<ExprId>,
) {
    let mut all_reads = HashMap::new();
    count_stmt_reads(f, &f.pixel, &mut all_reads);
    let mut term_reads = HashMap::new();
    for t in terms {
        count_reads(&f.exprs, t, &mut term_reads);
    }
    for (l, value) in locals {
        if all_reads.get(&l) == term_reads.get(&l) {
            unread.insert(l);
            super::block::expr_keys(&f.exprs, value, unstored);
        }
    }
}

impl Scope<'_> {
    /// See [`collect_carried`].
    fn collect_carried(
        &self,
        f: &Function,
        assigned: &HashSet<LocalId>,
        first_offset: u32,
        unread: &mut HashSet<LocalId>,
        unstored: &mut HashSet<ExprId>,
    ) -> Carry {
        let Some(x) = f.param_by_role(ParamRole::X).map(|p| p.local) else {
            return Carry::default();
        };
        let x_float = f.local(x).ty.elem == Elem::Scalar(Scalar::Float) && f.local(x).ty.dims.is_empty();
        if !x_float || assigned.contains(&x) || calls_primitive(f, &f.pixel) {
            return Carry::default();
        }
        let y = f
            .param_by_role(ParamRole::Y)
            .map(|p| p.local)
            .filter(|l| !assigned.contains(l));
        let y_float = y.filter(|&l| f.local(l).ty.elem == Elem::Scalar(Scalar::Float) && f.local(l).ty.dims.is_empty());
        let mut counts: HashMap<LocalId, (u32, bool)> = HashMap::new();
        crate::ir::for_each_assign(&f.stmts, &f.pixel, &mut |place, _| {
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
                && !matches!(f.exprs[value].kind, ExprKind::Local(_) | ExprKind::Const(_))
            {
                found.push((value, plane));
            }
        }
        let mut next = first_offset;
        let carried: Vec<Carried> = found
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
        let defs = w.defs.iter().map(|(l, (e, _, _))| (*l, *e)).collect();
        // A substitutable local every read of which is inside a carried expression is never
        // read by a group (`sy` of screen_triangle).
        mark_unread_in_groups(
            f,
            carried.iter().map(|c| c.expr),
            w.def_order
                .iter()
                .filter_map(|l| w.defs.get(l).map(|&(value, _, _)| (*l, value))),
            unread,
            unstored,
        );
        Carry {
            carried,
            defs,
            x: Some(x),
            y: y_float,
        }
    }

    /// Walk `stmts` in order; `straight`: not under a varying `if` (assignments here are
    /// seen by every lane that reaches the reads after them).
    fn carry_stmts(
        &self,
        f: &Function,
        stmts: &[StmtId],
        straight: bool,
        visible: &mut HashSet<LocalId>,
        w: &mut Walk<'_>,
        out: &mut Vec<(ExprId, bool)>,
    ) {
        for &s in stmts {
            match &f.stmts[s] {
                StmtKind::Assign { place, value } => {
                    for (i, _) in &place.indices {
                        self.carry_expr(f, *i, visible, w, out);
                    }
                    let form = if straight && w.single.contains(&place.local) {
                        self.form(f, *value, visible, w)
                    } else {
                        None
                    };
                    match form {
                        // Its reads are carried (or evaluated) instead; the value itself is
                        // evaluated where it is assigned only if something else reads it.
                        Some(form) => {
                            let plane = self.plane(f, *value, visible, w);
                            w.defs.insert(place.local, (*value, form, plane));
                            w.def_order.push(place.local);
                            visible.insert(place.local);
                        }
                        None => self.carry_expr(f, *value, visible, w, out),
                    }
                }
                StmtKind::If { cond, then, otherwise } => {
                    self.carry_expr(f, *cond, visible, w, out);
                    let straight = straight && !f.exprs[*cond].var.is_varying();
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
        f: &Function,
        e_id: ExprId,
        visible: &HashSet<LocalId>,
        w: &mut Walk<'_>,
        out: &mut Vec<(ExprId, bool)>,
    ) {
        let e = &f.exprs[e_id];
        if let ExprKind::Local(l) = e.kind {
            if visible.contains(&l) {
                w.bare.insert(l);
            }
            return;
        }
        if !matches!(e.kind, ExprKind::Local(_) | ExprKind::Const(_))
            && self.form(f, e_id, visible, w) == Some(Form::Affine)
        {
            out.push((e_id, self.plane(f, e_id, visible, w)));
            return;
        }
        let mut children = vec![];
        e.for_each_child(|c| children.push(c));
        for c in children {
            self.carry_expr(f, c, visible, w, out);
        }
    }

    /// The form of int expression `e` where the locals in `visible` hold their definitions.
    fn form(&self, f: &Function, e_id: ExprId, visible: &HashSet<LocalId>, w: &Walk<'_>) -> Option<Form> {
        let e = &f.exprs[e_id];
        if !int_scalar(e) {
            return None;
        }
        if self.row_invariant(f, e_id, None, w.assigned) {
            return Some(Form::Uniform);
        }
        if self.row_invariant(f, e_id, w.y, w.assigned) {
            return Some(Form::Row);
        }
        if column_leaf(&f.exprs, e_id, w.x).is_some() {
            return Some(Form::Affine);
        }
        match &e.kind {
            ExprKind::Local(l) if visible.contains(l) => match w.defs.get(l)?.1 {
                // A uniform value through a local is only known in the group: not a
                // multiplier computed once per run.
                Form::Uniform | Form::Row => Some(Form::Row),
                Form::Affine => Some(Form::Affine),
            },
            ExprKind::Unary { op: UnaryOp::Neg, expr } => match self.form(f, *expr, visible, w)? {
                Form::Affine => Some(Form::Affine),
                _ => Some(Form::Row),
            },
            ExprKind::Binary { op, lhs, rhs } => {
                let a = self.form(f, *lhs, visible, w)?;
                let c = self.form(f, *rhs, visible, w)?;
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
    fn plane(&self, f: &Function, e_id: ExprId, visible: &HashSet<LocalId>, w: &Walk<'_>) -> bool {
        let e = &f.exprs[e_id];
        if !int_scalar(e) {
            return false;
        }
        if self.row_invariant(f, e_id, None, w.assigned)
            || column_leaf(&f.exprs, e_id, w.x).is_some()
            || w.y_float.is_some_and(|y| column_leaf(&f.exprs, e_id, y).is_some())
        {
            return true;
        }
        match &e.kind {
            ExprKind::Local(l) => visible.contains(l) && w.defs.get(l).is_some_and(|d| d.2),
            ExprKind::Unary { op: UnaryOp::Neg, expr } => self.plane(f, *expr, visible, w),
            ExprKind::Binary {
                op: BinOp::Add | BinOp::Sub,
                lhs,
                rhs,
            } => self.plane(f, *lhs, visible, w) && self.plane(f, *rhs, visible, w),
            ExprKind::Binary {
                op: BinOp::Mul,
                lhs,
                rhs,
            } => {
                let uniform = |e: ExprId| self.row_invariant(f, e, None, w.assigned);
                (uniform(*lhs) && self.plane(f, *rhs, visible, w)) || (uniform(*rhs) && self.plane(f, *lhs, visible, w))
            }
            _ => false,
        }
    }
}

/// The pixel code renders another primitive somewhere (its X is this one's: not carried).
fn calls_primitive(f: &Function, stmts: &[StmtId]) -> bool {
    let mut found = false;
    crate::ir::for_each_stmt(&f.stmts, stmts, &mut |_, s| {
        found |= matches!(s, StmtKind::CallPrimitive { .. })
    });
    found
}

/// Count the reads of each local in `e` (every `Local` node).
fn count_reads(x: &Exprs, e: ExprId, out: &mut HashMap<LocalId, u32>) {
    x.for_each_local(e, &mut |l| *out.entry(l).or_insert(0) += 1);
}

/// Count the reads of each local in every expression of `stmts`.
fn count_stmt_reads(f: &Function, stmts: &[StmtId], out: &mut HashMap<LocalId, u32>) {
    crate::ir::for_each_stmt(&f.stmts, stmts, &mut |_, s| {
        s.for_each_expr(|e| count_reads(&f.exprs, *e, out))
    });
}
