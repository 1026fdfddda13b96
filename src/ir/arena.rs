//! The two arenas of a [`super::Function`]: [`Stmts`], every statement node indexed by
//! [`StmtId`], and [`Exprs`], every expression node indexed by [`ExprId`]; each keeps its
//! nodes' spans in a side table of the same length.
//!
//! A statement node ([`StmtKind`]) holds the ids of its expressions and the blocks of
//! statement ids inside it; an expression node's operands are ids of other nodes of the
//! expression arena. Both arenas store trees: each statement is in exactly one block (the
//! setup or pixel part, or a block of one statement), each expression node is the operand
//! of exactly one node or the expression of exactly one statement, so a pass that rewrites
//! a statement or an expression may change its nodes in place. In a checked function the
//! ids of each arena are also exactly `0..len` in pre-order and no node is unreachable
//! ([`super::number`]); a pass that allocates nodes (a copy, a folded constant) or drops
//! or moves them restores that with [`super::number::renumber`].

use std::ops::{Index, IndexMut};

use super::{Expr, ExprId, LocalId, StmtId, StmtKind};
use crate::diag::Span;

#[derive(Clone, Debug, Default, PartialEq)]
pub struct Exprs {
    nodes: Vec<Expr>,
    /// The span of each node, indexed like `nodes`.
    spans: Vec<Span>,
}

impl Exprs {
    pub fn new() -> Exprs {
        Exprs::default()
    }

    pub fn with_capacity(n: usize) -> Exprs {
        Exprs {
            nodes: Vec::with_capacity(n),
            spans: Vec::with_capacity(n),
        }
    }

    /// Number of nodes: their ids are `0..len`.
    pub fn len(&self) -> u32 {
        self.nodes.len() as u32
    }

    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// Add `e` (whose operands are already in the arena, or are added before it is read)
    /// and return its id.
    pub fn alloc(&mut self, e: Expr, span: Span) -> ExprId {
        self.nodes.push(e);
        self.spans.push(span);
        ExprId(self.nodes.len() as u32 - 1)
    }

    pub fn get(&self, id: ExprId) -> Option<&Expr> {
        self.nodes.get(id.0 as usize)
    }

    /// The source span of `id`.
    pub fn span(&self, id: ExprId) -> Span {
        self.spans[id.0 as usize]
    }

    /// Every node with its id, in id order.
    pub fn iter(&self) -> impl Iterator<Item = (ExprId, &Expr)> {
        self.nodes.iter().enumerate().map(|(i, e)| (ExprId(i as u32), e))
    }

    /// A copy of the tree rooted at `id`, its nodes allocated afresh in pre-order (the
    /// copy shares no node with the original); returns the copy's root.
    pub fn copy_tree(&mut self, id: ExprId) -> ExprId {
        let root = self.alloc(self[id].clone(), self.span(id));
        let mut node = self.take(root);
        node.for_each_child_mut(|c| *c = self.copy_tree(*c));
        self[root] = node;
        root
    }

    /// Put `e`, with `span`, in the place of node `id` (whose operands are then no longer
    /// its operands).
    pub fn replace(&mut self, id: ExprId, e: Expr, span: Span) {
        self.nodes[id.0 as usize] = e;
        self.spans[id.0 as usize] = span;
    }

    /// Take the node `id` out, leaving a placeholder.
    pub(super) fn take(&mut self, id: ExprId) -> Expr {
        std::mem::replace(&mut self.nodes[id.0 as usize], hole())
    }

    /// Call `f` on every local the tree at `id` reads (once per occurrence).
    pub fn for_each_local(&self, id: ExprId, f: &mut dyn FnMut(LocalId)) {
        let e = &self[id];
        if let super::ExprKind::Local(l) = e.kind {
            f(l);
        }
        e.for_each_child(|c| self.for_each_local(c, f));
    }

    /// Whether the tree at `id` reads a local for which `pred` holds.
    pub fn reads_any(&self, id: ExprId, pred: &dyn Fn(LocalId) -> bool) -> bool {
        let mut found = false;
        self.for_each_local(id, &mut |l| found |= pred(l));
        found
    }
}

/// A node standing in for one being moved.
pub(super) fn hole() -> Expr {
    Expr::new(
        super::ExprKind::Const(super::ConstValue::Int(0)),
        super::Type::int(),
        super::Variability::Uniform,
    )
}

impl Index<ExprId> for Exprs {
    type Output = Expr;
    fn index(&self, id: ExprId) -> &Expr {
        &self.nodes[id.0 as usize]
    }
}

impl IndexMut<ExprId> for Exprs {
    fn index_mut(&mut self, id: ExprId) -> &mut Expr {
        &mut self.nodes[id.0 as usize]
    }
}

/// The statements of a function: [`StmtKind`] nodes by [`StmtId`], spans beside them.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Stmts {
    nodes: Vec<StmtKind>,
    /// The span of each node, indexed like `nodes`.
    spans: Vec<Span>,
}

impl Stmts {
    pub fn new() -> Stmts {
        Stmts::default()
    }

    pub fn with_capacity(n: usize) -> Stmts {
        Stmts {
            nodes: Vec::with_capacity(n),
            spans: Vec::with_capacity(n),
        }
    }

    /// Number of nodes: their ids are `0..len`.
    pub fn len(&self) -> u32 {
        self.nodes.len() as u32
    }

    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// Add `s` (whose blocks name statements already in the arena, or added before it is
    /// read) and return its id.
    pub fn alloc(&mut self, s: StmtKind, span: Span) -> StmtId {
        self.nodes.push(s);
        self.spans.push(span);
        StmtId(self.nodes.len() as u32 - 1)
    }

    pub fn get(&self, id: StmtId) -> Option<&StmtKind> {
        self.nodes.get(id.0 as usize)
    }

    /// The source span of `id`.
    pub fn span(&self, id: StmtId) -> Span {
        self.spans[id.0 as usize]
    }

    /// Every node with its id, in id order.
    pub fn iter(&self) -> impl Iterator<Item = (StmtId, &StmtKind)> {
        self.nodes.iter().enumerate().map(|(i, s)| (StmtId(i as u32), s))
    }

    /// A copy of statement `id` with the statements inside it and all their expressions,
    /// allocated afresh in pre-order in `self` and `x` (the copy shares no node with the
    /// original); returns the copy's id.
    pub fn copy_tree(&mut self, x: &mut Exprs, id: StmtId) -> StmtId {
        let root = self.alloc(self[id].clone(), self.span(id));
        let mut node = self.take(root);
        node.for_each_expr_mut(|e| *e = x.copy_tree(*e));
        node.for_each_block_mut(|b| b.iter_mut().for_each(|s| *s = self.copy_tree(x, *s)));
        self[root] = node;
        root
    }

    /// Take the node `id` out, leaving a placeholder (a `Return`).
    pub fn take(&mut self, id: StmtId) -> StmtKind {
        std::mem::replace(&mut self.nodes[id.0 as usize], StmtKind::Return)
    }
}

impl Index<StmtId> for Stmts {
    type Output = StmtKind;
    fn index(&self, id: StmtId) -> &StmtKind {
        &self.nodes[id.0 as usize]
    }
}

impl IndexMut<StmtId> for Stmts {
    fn index_mut(&mut self, id: StmtId) -> &mut StmtKind {
        &mut self.nodes[id.0 as usize]
    }
}
