//! The two arenas of a [`super::Function`], both an [`Arena`]: [`Stmts`], every statement
//! node indexed by [`StmtId`], and [`Exprs`], every expression node indexed by [`ExprId`];
//! each keeps its nodes' spans in a side table of the same length.
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

use std::marker::PhantomData;

use super::{Expr, ExprId, LocalId, StmtId, StmtKind};
use crate::diag::Span;

/// A handle type of an [`Arena`]: a dense index.
pub trait Id: Copy {
    fn from_index(i: u32) -> Self;
    fn index(self) -> usize;
}

impl Id for ExprId {
    fn from_index(i: u32) -> ExprId {
        ExprId(i)
    }
    fn index(self) -> usize {
        self.0 as usize
    }
}

impl Id for StmtId {
    fn from_index(i: u32) -> StmtId {
        StmtId(i)
    }
    fn index(self) -> usize {
        self.0 as usize
    }
}

/// Nodes of type `T` addressed by handles `I`, each node's span in a side table of the same
/// length.
#[derive(Clone, Debug, PartialEq)]
pub struct Arena<I, T> {
    nodes: Vec<T>,
    /// The span of each node, indexed like `nodes`.
    spans: Vec<Span>,
    id: PhantomData<I>,
}

/// Every expression node of a function, by [`ExprId`].
pub type Exprs = Arena<ExprId, Expr>;
/// Every statement node of a function, by [`StmtId`].
pub type Stmts = Arena<StmtId, StmtKind>;

impl<I, T> Default for Arena<I, T> {
    fn default() -> Self {
        Arena {
            nodes: Vec::new(),
            spans: Vec::new(),
            id: PhantomData,
        }
    }
}

impl<I: Id, T> Arena<I, T> {
    pub fn new() -> Self {
        Self::default()
    }

    pub fn with_capacity(n: usize) -> Self {
        Arena {
            nodes: Vec::with_capacity(n),
            spans: Vec::with_capacity(n),
            id: PhantomData,
        }
    }

    /// Number of nodes: their ids are `0..len`.
    pub fn len(&self) -> u32 {
        self.nodes.len() as u32
    }

    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// Add `node` (whose operands or blocks name nodes already in the arena, or added
    /// before it is read) and return its id.
    pub fn alloc(&mut self, node: T, span: Span) -> I {
        self.nodes.push(node);
        self.spans.push(span);
        I::from_index(self.nodes.len() as u32 - 1)
    }

    pub fn get(&self, id: I) -> Option<&T> {
        self.nodes.get(id.index())
    }

    /// The source span of `id`.
    pub fn span(&self, id: I) -> Span {
        self.spans[id.index()]
    }

    /// Every node with its id, in id order.
    pub fn iter(&self) -> impl Iterator<Item = (I, &T)> {
        self.nodes.iter().enumerate().map(|(i, n)| (I::from_index(i as u32), n))
    }

    /// Put `node`, with `span`, in the place of node `id` (whose operands or blocks are then
    /// no longer its own).
    pub fn replace(&mut self, id: I, node: T, span: Span) {
        self.nodes[id.index()] = node;
        self.spans[id.index()] = span;
    }

    /// Take the node `id` out, leaving `hole` in its place.
    fn take_leaving(&mut self, id: I, hole: T) -> T {
        std::mem::replace(&mut self.nodes[id.index()], hole)
    }
}

impl<I: Id, T> Index<I> for Arena<I, T> {
    type Output = T;
    fn index(&self, id: I) -> &T {
        &self.nodes[id.index()]
    }
}

impl<I: Id, T> IndexMut<I> for Arena<I, T> {
    fn index_mut(&mut self, id: I) -> &mut T {
        &mut self.nodes[id.index()]
    }
}

impl Exprs {
    /// A copy of the tree rooted at `id`, its nodes allocated afresh in pre-order (the
    /// copy shares no node with the original); returns the copy's root.
    pub fn copy_tree(&mut self, id: ExprId) -> ExprId {
        let root = self.alloc(self[id].clone(), self.span(id));
        let mut node = self.take(root);
        node.for_each_child_mut(|c| *c = self.copy_tree(*c));
        self[root] = node;
        root
    }

    /// Take the node `id` out, leaving a placeholder.
    pub(super) fn take(&mut self, id: ExprId) -> Expr {
        self.take_leaving(id, hole())
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

impl Stmts {
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
        self.take_leaving(id, StmtKind::Return)
    }
}
