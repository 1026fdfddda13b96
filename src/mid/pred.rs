//! Predicates on IR nodes that the passes and the lowering both ask: constant indices,
//! speculable expressions and statements, conditions the variant key decides.
//!
//! Invariant: each answers from the node (with the key, and for statements which locals
//! live in SSA variables) alone, the same at every use, so a pass's table and the lowering
//! that consults it mean the same thing by "speculable" or "constant".

use crate::abi::VariantKey;
use crate::ir::{ConstValue, ExprId, ExprKind, Exprs, Function, LocalId, StmtId, StmtKind, Type, UnaryOp};

/// `e` as an int constant: a literal, or the negation of one.
pub(crate) fn const_int(x: &Exprs, e: ExprId) -> Option<i64> {
    match &x[e].kind {
        ExprKind::Const(ConstValue::Int(i)) => Some(*i as i64),
        ExprKind::Unary { op: UnaryOp::Neg, expr } => const_int(x, *expr).map(|v| -v),
        _ => None,
    }
}

/// Whether `index` is a constant within `ty`'s outer fixed dimension (indexing then records
/// no error).
pub(crate) fn const_index_in_range(x: &Exprs, ty: &Type, index: ExprId) -> bool {
    !ty.per_seq
        && ty
            .dims
            .first()
            .is_some_and(|&n| const_int(x, index).is_some_and(|k| k >= 0 && k < n as i64))
}

/// Whether evaluating `e` has no effect but its value (no error record, no control flow), so
/// it may run when the language would not evaluate it (tier 0's if-conversion).
pub(crate) fn speculable_expr(x: &Exprs, e: ExprId) -> bool {
    let spec = |c: &ExprId| speculable_expr(x, *c);
    match &x[e].kind {
        ExprKind::Const(_) | ExprKind::Local(_) | ExprKind::SeqCount | ExprKind::ClipFlag => true,
        ExprKind::Index { base, index, .. } => const_index_in_range(x, &x[*base].ty, *index) && spec(base),
        ExprKind::Unary { expr, .. } | ExprKind::Convert(expr) => spec(expr),
        ExprKind::Binary { lhs, rhs, .. } | ExprKind::MatMul { lhs, rhs } => spec(lhs) && spec(rhs),
        ExprKind::Select { cond, then, otherwise } => spec(cond) && spec(then) && spec(otherwise),
        ExprKind::Builtin { args, .. } => args.iter().all(spec),
        ExprKind::List(items) => items.iter().all(spec),
        ExprKind::Splat(item) => spec(item),
    }
}

/// Whether `stmts` (uniform code of `f`) only assign, from speculable expressions at
/// constant in-range indices, uniform locals kept in SSA variables (`in_vars`), under `if`s
/// the key does not decide whose conditions are speculable: running them where the language
/// would not changes nothing but those variables. `budget`: statements still allowed (each
/// one met costs one; none left answers false).
pub(crate) fn speculable_stmts(
    f: &Function,
    key: &VariantKey,
    in_vars: &dyn Fn(LocalId) -> bool,
    stmts: &[StmtId],
    budget: &mut usize,
) -> bool {
    stmts.iter().all(|&s| {
        if *budget == 0 {
            return false;
        }
        *budget -= 1;
        match &f.stmts[s] {
            StmtKind::Assign { place, value } => {
                let Some(local) = f.locals.get(place.local.0 as usize) else {
                    return false;
                };
                if !place.indices.is_empty() {
                    let mut ty = local.ty.clone();
                    for (idx, _) in &place.indices {
                        if !const_index_in_range(&f.exprs, &ty, *idx) {
                            return false;
                        }
                        ty = ty.element();
                    }
                }
                in_vars(place.local) && !local.var.is_varying() && speculable_expr(&f.exprs, *value)
            }
            StmtKind::If { cond, then, otherwise } => {
                key_constant(&f.exprs, *cond, key).is_none()
                    && speculable_expr(&f.exprs, *cond)
                    && speculable_stmts(f, key, in_vars, then, budget)
                    && speculable_stmts(f, key, in_vars, otherwise, budget)
            }
            _ => false,
        }
    })
}

/// The value of a condition fixed by the variant key: `clipping()` or `!clipping()`.
pub(crate) fn key_constant(x: &Exprs, cond: ExprId, key: &VariantKey) -> Option<bool> {
    match &x[cond].kind {
        ExprKind::ClipFlag => Some(!key.trivial_accept),
        ExprKind::Unary {
            op: crate::ir::UnaryOp::Not,
            expr,
        } => key_constant(x, *expr, key).map(|v| !v),
        _ => None,
    }
}
