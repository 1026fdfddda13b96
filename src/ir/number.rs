//! Statement and expression ids: the statements and expressions of a function live in its
//! arenas ([`super::Stmts`], [`super::Exprs`]), and in a checked function the ids of each
//! are exactly `0..len`, in one pre-order walk: the setup part, then the pixel part;
//! statement by statement, each before the statements inside it (its blocks in the order
//! of [`StmtKind::for_each_block`]); within a statement, its expressions in the order of
//! [`StmtKind::for_each_expr`], before the statements inside it; each expression before
//! its operands. Every node is reachable; each statement is in exactly one block and each
//! expression is the operand of one node or the expression of one statement (trees).
//! Analyses key side tables by id (a hash map, or a vector of `len` entries).
//!
//! [`renumber`] restores this after a pass: the checker's body comes out of
//! [`super::tree::intern_body`] in this order, and every pass that adds, drops, moves or
//! copies statements or expressions (`super::split`, `super::forward`, `mid::unroll`)
//! renumbers its result. The validator checks it (`valid::Rule::StmtTree`,
//! `valid::Rule::ExprTree`).

use super::{for_each_stmt, ExprId, Exprs, Function, StmtId, StmtKind, Stmts};

/// Compact `f.stmts` and `f.exprs` into the order of the module comment: the nodes
/// reachable from `f.setup` and `f.pixel`, moved (not copied) to their pre-order ids, the
/// blocks' and statements' ids rewritten. A node reached a second time (a pass shared it)
/// is copied, so the result is a tree.
pub fn renumber(f: &mut Function) {
    let old_stmts = std::mem::take(&mut f.stmts);
    let old_exprs = std::mem::take(&mut f.exprs);
    let mut r = Renumber {
        moved_stmts: vec![None; old_stmts.len() as usize],
        moved_exprs: vec![None; old_exprs.len() as usize],
        stmts: Stmts::with_capacity(old_stmts.len() as usize),
        exprs: Exprs::with_capacity(old_exprs.len() as usize),
        old_stmts,
        old_exprs,
    };
    for part in [&mut f.setup, &mut f.pixel] {
        part.iter_mut().for_each(|s| *s = r.stmt(*s));
    }
    f.stmts = r.stmts;
    f.exprs = r.exprs;
}

/// The old arenas being emptied into the new ones.
struct Renumber {
    old_stmts: Stmts,
    old_exprs: Exprs,
    /// Each old node's new id, once moved.
    moved_stmts: Vec<Option<StmtId>>,
    moved_exprs: Vec<Option<ExprId>>,
    stmts: Stmts,
    exprs: Exprs,
}

impl Renumber {
    fn stmt(&mut self, id: StmtId) -> StmtId {
        if let Some(done) = self.moved_stmts[id.0 as usize] {
            return self.stmts.copy_tree(&mut self.exprs, done);
        }
        let span = self.old_stmts.span(id);
        let mut node = self.old_stmts.take(id);
        let new = self.stmts.alloc(StmtKind::Return, span);
        self.moved_stmts[id.0 as usize] = Some(new);
        node.for_each_expr_mut(|e| *e = self.expr(*e));
        node.for_each_block_mut(|b| b.iter_mut().for_each(|s| *s = self.stmt(*s)));
        self.stmts[new] = node;
        new
    }

    fn expr(&mut self, id: ExprId) -> ExprId {
        if let Some(done) = self.moved_exprs[id.0 as usize] {
            return self.exprs.copy_tree(done);
        }
        let span = self.old_exprs.span(id);
        let mut node = self.old_exprs.take(id);
        let new = self.exprs.alloc(super::arena::hole(), span);
        self.moved_exprs[id.0 as usize] = Some(new);
        node.for_each_child_mut(|c| *c = self.expr(*c));
        self.exprs[new] = node;
        new
    }
}

/// Call `visit` on every expression of `f` reachable from its statements, in the order
/// [`renumber`] numbers them.
pub fn for_each_expr(f: &Function, visit: &mut dyn FnMut(ExprId)) {
    fn walk(x: &Exprs, e: ExprId, visit: &mut dyn FnMut(ExprId)) {
        visit(e);
        x[e].for_each_child(|c| walk(x, c, visit));
    }
    for part in [&f.setup, &f.pixel] {
        for_each_stmt(&f.stmts, part, &mut |_, s| {
            s.for_each_expr(|e| walk(&f.exprs, *e, visit))
        });
    }
}
