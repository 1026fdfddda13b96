//! Statements and expressions as owned trees: the form in which the checker and
//! hand-written test programs build a body before it enters a function's arenas.
//!
//! A [`Tree`] holds its operands itself, so building code can compose values freely
//! (fold a constant, wrap a conversion, clone an index) without an arena at hand.
//! Statements are generic over how they hold an expression ([`super::Form`]): a body under
//! construction is `Vec<Stmt<Tree>>`, each statement holding its trees and the statements
//! inside it. [`intern_body`] moves it into a statement and an expression arena in the
//! order of [`super::number`] and gives the IR's blocks. Nothing after the checker sees a
//! `Tree` or an owned `Stmt`.

use super::{
    BinOp, Block, Builtin, ConstValue, Expr, ExprId, ExprKind, Exprs, Form, InterpArm, LocalId, Place, SiteId, Stmt,
    StmtId, StmtKind, Stmts, Type, UnaryOp, Variability,
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

impl Form for Tree {
    type Block = Vec<Stmt<Tree>>;
}

/// A body's setup and pixel statements moved into fresh arenas, numbered as
/// [`super::number`] says.
pub struct Interned {
    pub setup: Block,
    pub pixel: Block,
    pub stmts: Stmts,
    pub exprs: Exprs,
}

/// Move `setup` then `pixel` into fresh arenas (see [`Interned`]).
pub fn intern_body(setup: Vec<Stmt<Tree>>, pixel: Vec<Stmt<Tree>>) -> Interned {
    let mut stmts = Stmts::new();
    let mut exprs = Exprs::new();
    let setup = intern_block(&mut stmts, &mut exprs, setup);
    let pixel = intern_block(&mut stmts, &mut exprs, pixel);
    Interned {
        setup,
        pixel,
        stmts,
        exprs,
    }
}

fn intern_block(stmts: &mut Stmts, x: &mut Exprs, block: Vec<Stmt<Tree>>) -> Block {
    block.into_iter().map(|s| intern_stmt(stmts, x, s)).collect()
}

/// Move `s` into the arenas: its node first, then its expressions, then the statements
/// inside it; returns its id.
fn intern_stmt(stmts: &mut Stmts, x: &mut Exprs, s: Stmt<Tree>) -> StmtId {
    let id = stmts.alloc(StmtKind::Return, s.span);
    let mut put = |t: Tree| x.intern(t);
    // Expressions first, in `for_each_expr` order: a place's indices, then the value.
    let kind = match s.kind {
        StmtKind::Assign { place, value } => {
            let indices = place.indices.into_iter().map(|(i, site)| (put(i), site)).collect();
            let place = Place {
                local: place.local,
                indices,
                span: place.span,
            };
            StmtKind::Assign {
                place,
                value: put(value),
            }
        }
        StmtKind::If { cond, then, otherwise } => {
            let cond = put(cond);
            let then = intern_block(stmts, x, then);
            StmtKind::If {
                cond,
                then,
                otherwise: intern_block(stmts, x, otherwise),
            }
        }
        StmtKind::Loop {
            id: loop_id,
            cond,
            body,
            step,
            varying,
            site,
        } => {
            let cond = cond.map(put);
            let body = intern_block(stmts, x, body);
            StmtKind::Loop {
                id: loop_id,
                cond,
                body,
                step: intern_block(stmts, x, step),
                varying,
                site,
            }
        }
        StmtKind::Break(l) => StmtKind::Break(l),
        StmtKind::Continue(l) => StmtKind::Continue(l),
        StmtKind::Return => StmtKind::Return,
        StmtKind::Interpolation { arms } => StmtKind::Interpolation {
            arms: arms
                .into_iter()
                .map(|a| InterpArm {
                    kind: a.kind,
                    body: intern_block(stmts, x, a.body),
                    span: a.span,
                })
                .collect(),
        },
        StmtKind::InterpolatorReturn(e) => StmtKind::InterpolatorReturn(e.map(put)),
        StmtKind::Bound(es) => StmtKind::Bound(es.map(put)),
        StmtKind::CallPrimitive { callee, args, site } => StmtKind::CallPrimitive {
            callee,
            args: args.into_iter().map(put).collect(),
            site,
        },
    };
    stmts[id] = kind;
    id
}
