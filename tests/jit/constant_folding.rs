//! Constant folding in the unroller (src/mid/unroll.rs) follows the JIT's integer
//! semantics: wrapping add and multiply, division truncating toward zero, division and
//! remainder by zero 0, `i32::MIN / -1` wrapping.

use primflow::diag::Span;
use primflow::ir::{BinOp, ConstValue, Expr, ExprId, ExprKind, Exprs, Type, Variability};
use primflow::mid::unroll::{fold, Env};

fn int(x: &mut Exprs, v: i32) -> ExprId {
    x.alloc(
        Expr::new(ExprKind::Const(ConstValue::Int(v)), Type::int(), Variability::Uniform),
        Span::default(),
    )
}

fn bin(x: &mut Exprs, op: BinOp, a: ExprId, c: ExprId) -> ExprId {
    let ty = if matches!(
        op,
        BinOp::Lt | BinOp::Le | BinOp::Gt | BinOp::Ge | BinOp::Eq | BinOp::Ne
    ) {
        Type::bool()
    } else {
        Type::int()
    };
    x.alloc(
        Expr::new(ExprKind::Binary { op, lhs: a, rhs: c }, ty, Variability::Uniform),
        Span::default(),
    )
}

/// `op a c` folded.
fn folded(op: BinOp, a: i32, c: i32) -> Option<ConstValue> {
    let mut x = Exprs::new();
    let (a, c) = (int(&mut x, a), int(&mut x, c));
    let e = bin(&mut x, op, a, c);
    let f = fold(&mut x, e, &Env::new());
    match x[f].kind {
        ExprKind::Const(c) => Some(c),
        _ => None,
    }
}

/// Folding follows the JIT's integer semantics, edge cases included.
#[test]
fn folds_ints_like_the_jit() {
    let cases = [
        (BinOp::Add, i32::MAX, 1, i32::MIN),
        (BinOp::Mul, 65536, 65536, 0),
        (BinOp::Div, 7, -2, -3),
        (BinOp::Rem, -7, 3, -1),
        (BinOp::Div, 5, 0, 0),
        (BinOp::Rem, 5, 0, 0),
        (BinOp::Div, i32::MIN, -1, i32::MIN),
        (BinOp::Rem, i32::MIN, -1, 0),
    ];
    for (op, x, y, want) in cases {
        assert_eq!(folded(op, x, y), Some(ConstValue::Int(want)), "{op:?} {x} {y}");
    }
    assert_eq!(folded(BinOp::Lt, 2, 3), Some(ConstValue::Bool(true)));
    assert_eq!(folded(BinOp::Ge, 2, 3), Some(ConstValue::Bool(false)));
}
