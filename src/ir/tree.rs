//! Expressions as owned trees: the form in which the checker and hand-written test
//! programs build a body before it enters a function's arena.
//!
//! A [`Tree`] holds its operands itself, so building code can compose values freely
//! (fold a constant, wrap a conversion, clone an index) without an arena at hand.
//! Statements are generic over how they hold an expression, so a body under construction
//! is `Vec<Stmt<Tree>>`; [`intern_body`] moves it into an arena in the order of
//! [`super::number`] and gives the IR's `Vec<Stmt>`. Nothing after the checker sees a
//! `Tree`.

use super::{
    BinOp, Builtin, ConstValue, Expr, ExprId, ExprKind, Exprs, LocalId, SiteId, Stmt, Type, UnaryOp, Variability,
};
use crate::diag::Span;

/// An expression with its operands inline; see [`ExprKind`] for what each kind means.
#[derive(Clone, Debug, PartialEq)]
pub struct Tree {
    pub kind: TreeKind,
    pub ty: Type,
    pub var: Variability,
    pub span: Span,
}

/// [`ExprKind`] with owned operands.
#[derive(Clone, Debug, PartialEq)]
pub enum TreeKind {
    Const(ConstValue),
    Local(LocalId),
    Index {
        base: Box<Tree>,
        index: Box<Tree>,
        site: SiteId,
    },
    Unary {
        op: UnaryOp,
        expr: Box<Tree>,
    },
    Binary {
        op: BinOp,
        lhs: Box<Tree>,
        rhs: Box<Tree>,
    },
    Convert(Box<Tree>),
    Select {
        cond: Box<Tree>,
        then: Box<Tree>,
        otherwise: Box<Tree>,
    },
    Builtin {
        func: Builtin,
        args: Vec<Tree>,
    },
    List(Vec<Tree>),
    Splat(Box<Tree>),
    MatMul {
        lhs: Box<Tree>,
        rhs: Box<Tree>,
    },
    SeqCount,
    ClipFlag,
}

impl Tree {
    pub fn new(kind: TreeKind, ty: Type, var: Variability, span: Span) -> Tree {
        Tree { kind, ty, var, span }
    }
}

impl Exprs {
    /// Move `t` into the arena, each node before its operands; returns the root's id.
    pub fn intern(&mut self, t: Tree) -> ExprId {
        let root = self.alloc(super::arena::hole(), t.span);
        let mut one = |x: Box<Tree>| self.intern(*x);
        let kind = match t.kind {
            TreeKind::Const(c) => ExprKind::Const(c),
            TreeKind::Local(l) => ExprKind::Local(l),
            TreeKind::Index { base, index, site } => {
                let base = one(base);
                ExprKind::Index {
                    base,
                    index: one(index),
                    site,
                }
            }
            TreeKind::Unary { op, expr } => ExprKind::Unary { op, expr: one(expr) },
            TreeKind::Binary { op, lhs, rhs } => {
                let lhs = one(lhs);
                ExprKind::Binary { op, lhs, rhs: one(rhs) }
            }
            TreeKind::Convert(x) => ExprKind::Convert(one(x)),
            TreeKind::Select { cond, then, otherwise } => {
                let cond = one(cond);
                let then = one(then);
                ExprKind::Select {
                    cond,
                    then,
                    otherwise: one(otherwise),
                }
            }
            TreeKind::Builtin { func, args } => ExprKind::Builtin {
                func,
                args: args.into_iter().map(|a| self.intern(a)).collect(),
            },
            TreeKind::List(items) => ExprKind::List(items.into_iter().map(|a| self.intern(a)).collect()),
            TreeKind::Splat(x) => ExprKind::Splat(one(x)),
            TreeKind::MatMul { lhs, rhs } => {
                let lhs = one(lhs);
                ExprKind::MatMul { lhs, rhs: one(rhs) }
            }
            TreeKind::SeqCount => ExprKind::SeqCount,
            TreeKind::ClipFlag => ExprKind::ClipFlag,
        };
        self[root] = Expr::new(kind, t.ty, t.var);
        root
    }
}

/// A body's setup and pixel statements moved into a fresh arena, numbered as
/// [`super::number`] says: `(setup, pixel, arena)`.
pub fn intern_body(setup: Vec<Stmt<Tree>>, pixel: Vec<Stmt<Tree>>) -> (Vec<Stmt>, Vec<Stmt>, Exprs) {
    let mut exprs = Exprs::new();
    let mut put = |t: Tree| exprs.intern(t);
    let setup = setup.into_iter().map(|s| s.map_exprs(&mut put)).collect();
    let pixel = pixel.into_iter().map(|s| s.map_exprs(&mut put)).collect();
    (setup, pixel, exprs)
}
