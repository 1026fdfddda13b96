//! Compile-time constants: parameter defaults and array dimensions.
//!
//! A constant expression is built from literals, `PI`, unary minus and `!`, the arithmetic
//! operators and `{...}` lists. It is evaluated in f64/i64 ([`ConstTree`]), then shaped and
//! converted to the declared type by [`flatten_to`], which gives the flattened components an
//! [`ir::Param::default`](crate::ir::Param) stores.

use crate::diag::Span;
use crate::ir::tree::{Tree, TreeKind};
use crate::ir::{ConstValue, Elem, Scalar, Type, Variability};
use crate::syntax::ast;

use super::types;

#[derive(Clone, Debug, PartialEq)]
pub enum ConstTree {
    Int(i64),
    Float(f64),
    Bool(bool),
    List(Vec<ConstTree>, Span),
}

/// Evaluate a constant expression; `Err` holds the span of the first part that is not
/// constant (or divides an int by zero) and why.
pub fn eval(e: &ast::Expr) -> Result<ConstTree, (Span, &'static str)> {
    use ast::ExprKind as K;
    match &e.kind {
        K::Int(v) => Ok(ConstTree::Int(*v)),
        K::Float(v) => Ok(ConstTree::Float(*v)),
        K::Bool(b) => Ok(ConstTree::Bool(*b)),
        K::Name(id) if id.name == "PI" => Ok(ConstTree::Float(std::f64::consts::PI)),
        K::List(items) => {
            let mut out = vec![];
            for it in items {
                out.push(eval(it)?);
            }
            Ok(ConstTree::List(out, e.span))
        }
        K::Unary { op, expr } => match (op, eval(expr)?) {
            (ast::UnaryOp::Neg, ConstTree::Int(v)) => Ok(ConstTree::Int(v.wrapping_neg())),
            (ast::UnaryOp::Neg, ConstTree::Float(v)) => Ok(ConstTree::Float(-v)),
            (ast::UnaryOp::Not, ConstTree::Bool(b)) => Ok(ConstTree::Bool(!b)),
            _ => Err((e.span, "this operator does not apply to this constant")),
        },
        K::Binary { op, lhs, rhs } => {
            let (a, b) = (eval(lhs)?, eval(rhs)?);
            use ast::BinOp::*;
            match (a, b) {
                (ConstTree::Int(a), ConstTree::Int(b)) => match op {
                    Add => Ok(ConstTree::Int(a.wrapping_add(b))),
                    Sub => Ok(ConstTree::Int(a.wrapping_sub(b))),
                    Mul => Ok(ConstTree::Int(a.wrapping_mul(b))),
                    Div | Rem if b == 0 => Err((rhs.span, "division by zero in a constant")),
                    Div => Ok(ConstTree::Int(a.wrapping_div(b))),
                    Rem => Ok(ConstTree::Int(a.wrapping_rem(b))),
                    _ => Err((e.span, "only arithmetic is allowed in a constant")),
                },
                (a, b) => {
                    let (Some(x), Some(y)) = (as_f64(&a), as_f64(&b)) else {
                        return Err((e.span, "only arithmetic on numbers is allowed in a constant"));
                    };
                    match op {
                        Add => Ok(ConstTree::Float(x + y)),
                        Sub => Ok(ConstTree::Float(x - y)),
                        Mul => Ok(ConstTree::Float(x * y)),
                        Div => Ok(ConstTree::Float(x / y)),
                        Rem => Ok(ConstTree::Float(x % y)),
                        _ => Err((e.span, "only arithmetic is allowed in a constant")),
                    }
                }
            }
        }
        _ => Err((e.span, "not a constant expression")),
    }
}

fn as_f64(c: &ConstTree) -> Option<f64> {
    match c {
        ConstTree::Int(v) => Some(*v as f64),
        ConstTree::Float(v) => Some(*v),
        _ => None,
    }
}

/// Shape `c` to `ty` (a scalar broadcasts over an aggregate) and convert each component to
/// the type's scalar. Interpolation data has no constants.
pub fn flatten_to(c: &ConstTree, ty: &Type) -> Result<Vec<ConstValue>, String> {
    let Elem::Scalar(s) = ty.elem else {
        return Err("interpolation data has no constant values".into());
    };
    let mut out = vec![];
    flatten_dims(c, &ty.dims, s, &mut out)?;
    Ok(out)
}

fn flatten_dims(c: &ConstTree, dims: &[u32], s: Scalar, out: &mut Vec<ConstValue>) -> Result<(), String> {
    match (c, dims.first()) {
        (ConstTree::List(items, _), Some(&n)) => {
            if items.len() != n as usize {
                return Err(format!("expected {n} elements, found {}", items.len()));
            }
            for it in items {
                flatten_dims(it, &dims[1..], s, out)?;
            }
            Ok(())
        }
        (ConstTree::List(items, _), None) => Err(format!("expected a single value, found a list of {}", items.len())),
        (scalar, _) => {
            let v = scalar_const(scalar, s)?;
            let count: u32 = dims.iter().product();
            out.extend(std::iter::repeat_n(v, count as usize));
            Ok(())
        }
    }
}

fn scalar_const(c: &ConstTree, s: Scalar) -> Result<ConstValue, String> {
    let (v, from) = match c {
        ConstTree::Int(v) => (
            ConstValue::Int((*v).clamp(i32::MIN as i64, i32::MAX as i64) as i32),
            Scalar::Int,
        ),
        ConstTree::Float(v) => (ConstValue::Float(*v as f32), Scalar::Float),
        ConstTree::Bool(b) => (ConstValue::Bool(*b), Scalar::Bool),
        ConstTree::List(..) => return Err("expected a single value, found a list".into()),
    };
    // Float to int/fixed goes through f64 for rounding of large values.
    if let (ConstTree::Float(x), Scalar::Fixed(f)) = (c, s) {
        return Ok(ConstValue::Fixed(types::fixed_raw(*x, f)));
    }
    types::convert_const(v, from, s).ok_or_else(|| {
        format!(
            "a {} constant cannot be converted to {}",
            types::scalar_name(from),
            types::scalar_name(s)
        )
    })
}

/// The expression for flattened constant components of `ty` (nested lists for arrays).
pub fn const_to_expr(values: &[ConstValue], ty: &Type, span: Span) -> Tree {
    let Elem::Scalar(s) = ty.elem else {
        // Callers only store defaults of scalar-element types.
        return types::const_expr(ConstValue::Float(0.0), Scalar::Float, span);
    };
    build(values, &ty.dims, s, span)
}

fn build(values: &[ConstValue], dims: &[u32], s: Scalar, span: Span) -> Tree {
    match dims.first() {
        None => types::const_expr(values.first().copied().unwrap_or(types::zero_const(s)), s, span),
        Some(&n) => {
            let stride: usize = dims[1..].iter().product::<u32>() as usize;
            let items = (0..n as usize)
                .map(|i| {
                    let lo = (i * stride).min(values.len());
                    let hi = ((i + 1) * stride).min(values.len());
                    build(&values[lo..hi], &dims[1..], s, span)
                })
                .collect();
            Tree::new(
                TreeKind::List(items),
                Type::array(Elem::Scalar(s), dims.to_vec()),
                Variability::Uniform,
                span,
            )
        }
    }
}
