//! Per-row hoisting of pixel-code terms that depend on Y alone, and the splatted copies of
//! the uniform frame, so a pixel group reads both as one folded vector memory operand.
//!
//! A group is 4 pixels of one row, so a varying expression whose only varying input is Y
//! (`b * Y` of a plane `a*X + b*Y + c`, `int(Y * 16) - int(oy * 16)`) has the same value in
//! every group of a row. [`Scope::collect_hoists`] finds, at compile time, the *maximal*
//! such subexpressions of the pixel code that contain an operation; the row prologue of
//! every pixel loop (the JIT's `Lower::row_hoists`) evaluates each once per row with the same operations the group would
//! use and stores it in the *row section* of the uniform frame; the group reads it back
//! instead of computing it. A uniform operation feeding a varying one (`int(oy * 16)`)
//! goes to the row section too, but is evaluated once per kernel run, after setup. Only the hoisted subterm moves: the sums around it stay in
//! source order, so results are bit-identical (no re-association).
//!
//! Invariants of a hoisted expression: pure (no index that may fail, no call, no division
//! of integers, no fixed point or bool arithmetic; the built-ins lowered inline — `dot`,
//! `cross`, `length`, `normalize`, `sqrt`, `min`, `clamp` ... — are pure maths and count,
//! library calls and transforms do not), its leaves are constants, Y (when the pixel code
//! never assigns Y), uniform locals in the uniform frame or parameters in the argument
//! block (neither changes while the pixel loops run), *row locals* and constant-index
//! elements of one-dimensional row locals, and it is scalar, an array of float or int
//! scalars (one component per element), or interpolation_data (one component per view
//! component). Expressions are keyed by id together with the interpolation view they were
//! collected under.
//!
//! A row local is a varying local of the pixel code assigned once, whole, by a top-level
//! statement, from a row-invariant value (`float dy = Y - sy;`): every read sees that value,
//! so `dy * g1` is a row term too, and so are `cross(gamma, d)` and `d[1] * k` of a row
//! local `d`. The row prologue evaluates such a term with the local replaced by its
//! defining expression (an element by that expression's component: the same operations
//! again, so the same bits), each local once per prologue; the group reads the stored term
//! and never the local. Only hoisting sees row locals (the carried terms of
//! [`super::affine`] keep their own notion of substitutable locals). A row local every read
//! of which is inside a row term is not assigned in the groups at all
//! ([`row_locals_unread`]).
//!
//! The uniform frame also gets a *vector section*: a slot of 16 bytes per non-bool word,
//! holding its splat, written once per kernel run. A uniform read in a group that feeds a
//! varying operation then loads the splat (`vmulps xmm, xmm, [base + off]`) instead of
//! broadcasting the scalar in every group. Only the splats some group loads are stored
//! (`Lower::drop_unread_splats`).
//!
//! The analysis is made over a [`Scope`]: the key (the views of `interpolation` arms),
//! which uniform locals stay put while the pixel loops run (in the uniform frame or the
//! argument block, see [`super::spill`]) and the row locals found so far.

use std::collections::{HashMap, HashSet};

use super::view;
use crate::abi::VariantKey;
use crate::ir::{
    BinOp, Builtin, ConstValue, Elem, ExprId, ExprKind, Function, LocalId, Scalar, StmtId, StmtKind, UnaryOp,
};

/// One hoisted expression: where its components live in the row section.
pub(crate) struct Hoist {
    pub expr: ExprId,
    /// The interpolation view it is evaluated under.
    pub view: Vec<u32>,
    /// Byte offset of its first component in the uniform frame (16 bytes per component).
    pub offset: u32,
    pub comps: u32,
    pub scalar: Scalar,
    /// A uniform operation (no Y in it): evaluated once per kernel run, after setup
    /// (`Lower::run_hoists`), rather than in every row prologue.
    pub per_run: bool,
}

/// What row invariance is judged against (see the module comment).
pub(crate) struct Scope<'s> {
    pub key: &'s VariantKey,
    /// The key's interpolated components (the view outside `interpolation` arms).
    pub n_interp: u32,
    /// Per local of the primitive: a uniform value that stays put while the pixel loops run
    /// (a word of the uniform frame, or a parameter in the argument block).
    pub resident: &'s [bool],
    /// The row locals, once found ([`Self::collect_row_locals`]).
    pub row_locals: HashMap<LocalId, ExprId>,
}

/// `f`'s Y parameter unless the pixel code assigns it (`assigned`; then nothing is
/// row-invariant through Y).
fn unassigned_y(f: &Function, assigned: &HashSet<LocalId>) -> Option<LocalId> {
    f.param_by_role(crate::ir::ParamRole::Y)
        .map(|p| p.local)
        .filter(|l| !assigned.contains(l))
}

/// Row locals whose every read is inside a row term (`along` of the sphere, read only by
/// the terms `dot(along, along)` and `dot(along, along_x)`): the terms substitute the
/// local's value, so no group reads the local. Its assignment is left out of the groups
/// and its own value not stored per row, as for the locals only carried terms read
/// (marked in `unread` and `unstored`, see [`super::affine::mark_unread_in_groups`]).
pub(crate) fn row_locals_unread<'a>(
    f: &Function,
    hoists: &[Hoist],
    rows: &HashMap<LocalId, ExprId>,
    unread: &mut HashSet<LocalId>,
    unstored: &mut HashSet<ExprId>,
) {
    // Each term once, whatever the views it was collected under.
    let mut counted = HashSet::new();
    let terms: Vec<ExprId> = hoists
        .iter()
        .filter(|h| !h.per_run && counted.insert(h.expr))
        .map(|h| h.expr)
        .collect();
    let locals: Vec<(LocalId, ExprId)> = rows.iter().map(|(&l, &v)| (l, v)).collect();
    super::affine::mark_unread_in_groups(f, terms, locals, unread, unstored);
}

impl Scope<'_> {
    /// The row locals of `f`'s pixel code (see the module comment), each with its defining
    /// expression; a row local's value may read earlier ones. `assigned`: the locals the
    /// pixel code assigns.
    pub(crate) fn collect_row_locals(&self, f: &Function, assigned: &HashSet<LocalId>) -> HashMap<LocalId, ExprId> {
        let y = unassigned_y(f, assigned);
        let mut pixel_assignments: HashMap<LocalId, u32> = HashMap::new();
        crate::ir::for_each_assign(&f.stmts, &f.pixel, &mut |place, _| {
            *pixel_assignments.entry(place.local).or_default() += 1;
        });
        let mut setup_assigned = HashSet::new();
        super::block::assigned_locals(f, &f.setup, &mut setup_assigned);
        let params: HashSet<LocalId> = f.params.iter().map(|p| p.local).collect();
        let mut rows = HashMap::new();
        for &s in &f.pixel {
            let StmtKind::Assign { place, value } = &f.stmts[s] else {
                continue;
            };
            let l = place.local;
            let Some(local) = f.locals.get(l.0 as usize) else {
                continue;
            };
            let candidate = place.indices.is_empty()
                && local.var.is_varying()
                && !local.ty.per_seq
                && matches!(local.ty.elem, Elem::Scalar(Scalar::Float | Scalar::Int))
                && pixel_assignments.get(&l) == Some(&1)
                && !setup_assigned.contains(&l)
                && !params.contains(&l);
            if candidate && self.row_invariant_in(f, *value, y, assigned, Some(&rows)) {
                rows.insert(l, *value);
            }
        }
        rows
    }

    /// The maximal row-invariant varying subexpressions of `f`'s pixel code, in the order
    /// met, with the view each is lowered under; offsets start at `first_offset`.
    /// `assigned`: the locals the pixel code assigns.
    pub(crate) fn collect_hoists(&self, f: &Function, assigned: &HashSet<LocalId>, first_offset: u32) -> Vec<Hoist> {
        let y = unassigned_y(f, assigned);
        let mut out = vec![];
        let view: Vec<u32> = (0..self.n_interp).collect();
        let mut next = first_offset;
        self.hoists_in(f, &f.pixel, &view, y, assigned, &mut out, &mut next);
        out
    }

    #[allow(clippy::too_many_arguments)]
    fn hoists_in(
        &self,
        f: &Function,
        stmts: &[StmtId],
        view: &[u32],
        y: Option<LocalId>,
        assigned: &HashSet<LocalId>,
        out: &mut Vec<Hoist>,
        next: &mut u32,
    ) {
        for &s in stmts {
            match &f.stmts[s] {
                StmtKind::Assign { value, .. } => self.hoists_expr(f, *value, view, y, assigned, out, next),
                StmtKind::If { cond, then, otherwise } => {
                    self.hoists_expr(f, *cond, view, y, assigned, out, next);
                    self.hoists_in(f, then, view, y, assigned, out, next);
                    self.hoists_in(f, otherwise, view, y, assigned, out, next);
                }
                StmtKind::Interpolation { arms } => {
                    let named = view::named_kinds(arms);
                    for arm in arms {
                        if let Some((arm_view, _)) = view::arm_view(self.key, &named, arm) {
                            self.hoists_in(f, &arm.body, &arm_view, y, assigned, out, next);
                        }
                    }
                }
                StmtKind::InterpolatorReturn(Some(e)) => self.hoists_expr(f, *e, view, y, assigned, out, next),
                // Loop bodies run a data-dependent number of times per group; their terms
                // are left where they are.
                _ => {}
            }
        }
    }

    #[allow(clippy::too_many_arguments)]
    fn hoists_expr(
        &self,
        f: &Function,
        e_id: ExprId,
        view: &[u32],
        y: Option<LocalId>,
        assigned: &HashSet<LocalId>,
        out: &mut Vec<Hoist>,
        next: &mut u32,
    ) {
        let e = &f.exprs[e_id];
        let has_op = !matches!(e.kind, ExprKind::Local(_) | ExprKind::Const(_) | ExprKind::Index { .. });
        let rows = Some(&self.row_locals);
        if e.var.is_varying() && has_op && !e.ty.per_seq && self.row_invariant_in(f, e_id, y, assigned, rows) {
            let elements: u32 = e.ty.dims.iter().product();
            let (comps, scalar) = match e.ty.elem {
                Elem::Interp if e.ty.dims.is_empty() => (view.len() as u32, Scalar::Float),
                Elem::Scalar(s @ (Scalar::Float | Scalar::Int)) => (elements, s),
                _ => (0, Scalar::Bool),
            };
            if comps > 0 {
                out.push(Hoist {
                    expr: e_id,
                    view: view.to_vec(),
                    offset: *next,
                    comps,
                    scalar,
                    per_run: false,
                });
                *next += 16 * comps;
                // Its uniform operations are evaluated once per run too, so the row
                // prologue reads them (`int(oy * 16)` of `int(Y * 16) - int(oy * 16)`).
                self.per_run_inside(f, e_id, view, y, assigned, out, next);
                return;
            }
        }
        match &e.kind {
            ExprKind::Unary { expr, .. } | ExprKind::Convert(expr) => {
                self.hoists_expr(f, *expr, view, y, assigned, out, next)
            }
            ExprKind::Binary { op, lhs, rhs } => {
                // A uniform operand of a varying operation is splatted in every group; when
                // it is itself an operation (`int(ox * 16)` in `int(X * 16) - int(ox * 16)`)
                // it is also recomputed there. Evaluate it once per kernel run instead (the
                // same scalar operations, then the splat the group would make).
                let splats_operand = e.var.is_varying()
                    && matches!(
                        op,
                        BinOp::Add | BinOp::Sub | BinOp::Mul | BinOp::Lt | BinOp::Le | BinOp::Gt | BinOp::Ge
                    );
                for side in [lhs, rhs] {
                    if splats_operand && self.uniform_operation(f, *side, y, assigned) {
                        push_per_run(f, *side, view, out, next);
                    } else {
                        self.hoists_expr(f, *side, view, y, assigned, out, next);
                    }
                }
            }
            ExprKind::Select { cond, then, otherwise } => {
                self.hoists_expr(f, *cond, view, y, assigned, out, next);
                // A uniform operation as an arm of a varying select (`-handedness` in
                // `w < 0 ? -handedness : handedness`) is splatted and recomputed in every
                // group: once per kernel run instead, as for a binary operator's operand.
                for arm in [then, otherwise] {
                    if e.var.is_varying() && self.uniform_operation(f, *arm, y, assigned) {
                        push_per_run(f, *arm, view, out, next);
                    } else {
                        self.hoists_expr(f, *arm, view, y, assigned, out, next);
                    }
                }
            }
            ExprKind::Builtin { args, .. } => {
                // Likewise a uniform operation as an argument of a varying built-in
                // (`clamp(v, lo * 2, hi)`).
                for a in args {
                    if e.var.is_varying() && self.uniform_operation(f, *a, y, assigned) {
                        push_per_run(f, *a, view, out, next);
                    } else {
                        self.hoists_expr(f, *a, view, y, assigned, out, next);
                    }
                }
            }
            _ => {}
        }
    }

    /// Inside row term `e`: the uniform operations that are operands of its varying
    /// operations, as per-run hoists (what `hoists_expr` does outside row terms).
    #[allow(clippy::too_many_arguments)]
    fn per_run_inside(
        &self,
        f: &Function,
        e_id: ExprId,
        view: &[u32],
        y: Option<LocalId>,
        assigned: &HashSet<LocalId>,
        out: &mut Vec<Hoist>,
        next: &mut u32,
    ) {
        let e = &f.exprs[e_id];
        match &e.kind {
            ExprKind::Unary { expr, .. } | ExprKind::Convert(expr) => {
                self.per_run_inside(f, *expr, view, y, assigned, out, next)
            }
            ExprKind::Binary { op, lhs, rhs } => {
                let splats_operand = e.var.is_varying() && matches!(op, BinOp::Add | BinOp::Sub | BinOp::Mul);
                for side in [lhs, rhs] {
                    if splats_operand && self.uniform_operation(f, *side, y, assigned) {
                        push_per_run(f, *side, view, out, next);
                    } else {
                        self.per_run_inside(f, *side, view, y, assigned, out, next);
                    }
                }
            }
            _ => {}
        }
    }

    /// `e` is a uniform float or int scalar computed by an operation from frame words,
    /// arguments and constants only (hoistable like a row term; no Y in it).
    fn uniform_operation(&self, f: &Function, e_id: ExprId, y: Option<LocalId>, assigned: &HashSet<LocalId>) -> bool {
        let e = &f.exprs[e_id];
        !e.var.is_varying()
            && !matches!(e.kind, ExprKind::Local(_) | ExprKind::Const(_) | ExprKind::Index { .. })
            && e.ty.dims.is_empty()
            && !e.ty.per_seq
            && matches!(e.ty.elem, Elem::Scalar(Scalar::Float | Scalar::Int))
            && self.row_invariant(f, e_id, y, assigned)
    }

    /// `e` has the same value in every group of a row (see the module comment), without
    /// row locals (the carried terms' test).
    pub(crate) fn row_invariant(
        &self,
        f: &Function,
        e: ExprId,
        y: Option<LocalId>,
        assigned: &HashSet<LocalId>,
    ) -> bool {
        self.row_invariant_in(f, e, y, assigned, None)
    }

    /// [`Self::row_invariant`], reading the row locals in `rows` as row-invariant leaves;
    /// with them, arrays of float or int scalars count as plain values too (their
    /// operations are component-wise).
    fn row_invariant_in(
        &self,
        f: &Function,
        e_id: ExprId,
        y: Option<LocalId>,
        assigned: &HashSet<LocalId>,
        rows: Option<&HashMap<LocalId, ExprId>>,
    ) -> bool {
        let e = &f.exprs[e_id];
        let plain = |t: &crate::ir::Type| {
            !t.per_seq
                && if t.dims.is_empty() {
                    matches!(t.elem, Elem::Interp | Elem::Scalar(Scalar::Float | Scalar::Int))
                } else {
                    rows.is_some() && matches!(t.elem, Elem::Scalar(Scalar::Float | Scalar::Int))
                }
        };
        match &e.kind {
            ExprKind::Const(ConstValue::Float(_) | ConstValue::Int(_)) => true,
            ExprKind::Local(l) => {
                if Some(*l) == y || rows.is_some_and(|r| r.contains_key(l)) {
                    return true;
                }
                let Some(local) = f.locals.get(l.0 as usize) else {
                    return false;
                };
                !local.var.is_varying()
                    && !assigned.contains(l)
                    && !local.ty.per_seq
                    && self.resident.get(l.0 as usize).copied().unwrap_or(false)
            }
            ExprKind::Index { base, index, .. } => {
                let in_range = match (
                    &f.exprs[*index].kind,
                    f.exprs[*base].ty.per_seq,
                    f.exprs[*base].ty.dims.first(),
                ) {
                    (ExprKind::Const(ConstValue::Int(k)), false, Some(&len)) => *k >= 0 && (*k as i64) < len as i64,
                    _ => false,
                };
                let ExprKind::Local(l) = f.exprs[*base].kind else {
                    return false;
                };
                // An element of a one-dimensional row local: the prologue substitutes the
                // local's value and takes the element (`Lower::row_local_element`).
                let row_element =
                    f.exprs[*base].ty.dims.len() == 1 && plain(&e.ty) && rows.is_some_and(|r| r.contains_key(&l));
                in_range && (row_element || self.row_invariant(f, *base, y, assigned))
            }
            ExprKind::Builtin { func, args } => {
                // Pure maths lowered inline, on float or int scalars and arrays: the same
                // operations in the prologue as in a group. Library calls and transforms
                // stay in the groups.
                let inline = matches!(
                    func,
                    Builtin::Sqrt
                        | Builtin::Abs
                        | Builtin::Min
                        | Builtin::Max
                        | Builtin::Clamp
                        | Builtin::Floor
                        | Builtin::Ceil
                        | Builtin::Round
                        | Builtin::Sign
                        | Builtin::Mix
                        | Builtin::Step
                        | Builtin::Smoothstep
                        | Builtin::Dot
                        | Builtin::Cross
                        | Builtin::Length
                        | Builtin::Normalize
                        | Builtin::Distance
                );
                let scalars = |t: &crate::ir::Type| plain(t) && matches!(t.elem, Elem::Scalar(_));
                inline
                    && scalars(&e.ty)
                    && args
                        .iter()
                        .all(|a| scalars(&f.exprs[*a].ty) && self.row_invariant_in(f, *a, y, assigned, rows))
            }
            ExprKind::Unary { op: UnaryOp::Neg, expr } => {
                plain(&e.ty) && self.row_invariant_in(f, *expr, y, assigned, rows)
            }
            ExprKind::Convert(expr) => {
                plain(&e.ty) && plain(&f.exprs[*expr].ty) && self.row_invariant_in(f, *expr, y, assigned, rows)
            }
            ExprKind::Binary { op, lhs, rhs } => {
                let float = matches!(e.ty.elem, Elem::Interp | Elem::Scalar(Scalar::Float));
                let op_ok = matches!(op, BinOp::Add | BinOp::Sub | BinOp::Mul) || (*op == BinOp::Div && float);
                op_ok
                    && plain(&e.ty)
                    && plain(&f.exprs[*lhs].ty)
                    && plain(&f.exprs[*rhs].ty)
                    && self.row_invariant_in(f, *lhs, y, assigned, rows)
                    && self.row_invariant_in(f, *rhs, y, assigned, rows)
            }
            _ => false,
        }
    }
}

/// Record the uniform operation `side` as a per-run hoist at `next` (a scalar one; others
/// are left where they are).
fn push_per_run(f: &Function, side_id: ExprId, view: &[u32], out: &mut Vec<Hoist>, next: &mut u32) {
    let side = &f.exprs[side_id];
    let Elem::Scalar(scalar) = side.ty.elem else {
        return;
    };
    out.push(Hoist {
        expr: side_id,
        view: view.to_vec(),
        offset: *next,
        comps: 1,
        scalar,
        per_run: true,
    });
    *next += 16;
}
