//! Expression ids: the expressions of a function live in its arena ([`super::Exprs`]),
//! and in a checked function the ids are exactly `0..Function::exprs.len()`, in pre-order:
//! the setup part, then the pixel part; statement by statement, each before the statements
//! inside it; within a statement, its expressions in the order of [`Stmt::for_each_expr`];
//! each expression before its operands. Every node is reachable and is the operand of one
//! node or the expression of one statement (a tree). Analyses key side tables by id (a
//! hash map, or a vector of `exprs.len()` entries).
//!
//! [`renumber`] restores this after a pass: the checker's body comes out of
//! [`super::tree::intern_body`] in this order, and every pass that adds, drops or copies
//! expressions (`super::forward`, `mid::unroll`) renumbers its result. The validator checks
//! it (`valid::Rule::ExprTree`).

use super::{for_each_stmt, for_each_stmt_mut, ExprId, Exprs, Function, Stmt};

/// Compact `f.exprs` into the order of the module comment: the nodes reachable from the
/// statements, moved (not copied) to their pre-order ids, the statements' ids rewritten.
/// A node reached a second time (a pass shared it) is copied, so the result is a tree.
pub fn renumber(f: &mut Function) {
    fn take(old: &mut Exprs, moved: &mut [Option<ExprId>], out: &mut Exprs, id: ExprId) -> ExprId {
        if let Some(done) = moved[id.0 as usize] {
            return out.copy_tree(done);
        }
        let span = old.span(id);
        let mut node = old.take(id);
        let new = out.alloc(super::arena::hole(), span);
        moved[id.0 as usize] = Some(new);
        node.for_each_child_mut(|c| *c = take(old, moved, out, *c));
        out[new] = node;
        new
    }
    let mut old = std::mem::take(&mut f.exprs);
    let mut moved = vec![None; old.len() as usize];
    let mut out = Exprs::with_capacity(old.len() as usize);
    for part in [&mut f.setup, &mut f.pixel] {
        for_each_stmt_mut(part, &mut |s: &mut Stmt| {
            s.for_each_expr_mut(|e| *e = take(&mut old, &mut moved, &mut out, *e))
        });
    }
    f.exprs = out;
}

/// Call `visit` on every expression of `f` reachable from its statements, in the order
/// [`renumber`] numbers them.
pub fn for_each_expr(f: &Function, visit: &mut dyn FnMut(ExprId)) {
    fn walk(x: &Exprs, e: ExprId, visit: &mut dyn FnMut(ExprId)) {
        visit(e);
        x[e].for_each_child(|c| walk(x, c, visit));
    }
    for part in [&f.setup, &f.pixel] {
        for_each_stmt(part, &mut |s| s.for_each_expr(|e| walk(&f.exprs, *e, visit)));
    }
}
