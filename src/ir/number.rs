//! Expression ids: each expression of a function has an [`ExprId`] of its own, and the ids
//! are exactly `0..Function::exprs`, in pre-order: the setup part, then the pixel part;
//! statement by statement, each before the statements inside it; within a statement, its
//! expressions in the order of [`Stmt::for_each_expr`]; each expression before its
//! operands. Analyses key side tables by id (a hash map, or a vector of `exprs` entries).
//!
//! [`renumber`] assigns them. The checker runs it on every function it lowers, and so does
//! every pass that adds, drops or copies expressions (`super::forward`,
//! `mid::unroll`); an expression built elsewhere has [`ExprId::UNSET`] until then. The
//! validator checks the ids (`valid::Rule::ExprIdsDense`).

use super::{for_each_stmt, for_each_stmt_mut, Expr, ExprId, Function, Stmt};

/// Number `f`'s expressions (see the module comment) and set `f.exprs`.
pub fn renumber(f: &mut Function) {
    fn number(e: &mut Expr, next: &mut u32) {
        e.id = ExprId(*next);
        *next += 1;
        e.for_each_child_mut(|c| number(c, next));
    }
    let mut next = 0;
    for part in [&mut f.setup, &mut f.pixel] {
        for_each_stmt_mut(part, &mut |s: &mut Stmt| s.for_each_expr_mut(|e| number(e, &mut next)));
    }
    f.exprs = next;
}

/// Call `visit` on every expression of `f`, in the order [`renumber`] numbers them.
pub fn for_each_expr<'f>(f: &'f Function, visit: &mut dyn FnMut(&'f Expr)) {
    fn walk<'f>(e: &'f Expr, visit: &mut dyn FnMut(&'f Expr)) {
        visit(e);
        e.for_each_child(|c| walk(c, visit));
    }
    for part in [&f.setup, &f.pixel] {
        for_each_stmt(part, &mut |s| s.for_each_expr(|e| walk(e, visit)));
    }
}
