//! Type rules of the checker: resolving written types, the arithmetic result type of two
//! scalars (including the fixed-point JOIN format), conversions and shapes.
//!
//! Everything here is pure: functions take IR types and expressions and return new ones or
//! a description of what is wrong; the caller turns that into a diagnostic with spans.
//! Invariant kept by [`convert`]: the returned expression has exactly the requested scalar
//! element and the input's shape; constant scalars are folded instead of wrapped.

use crate::ir::tree::{Tree, TreeKind};
use crate::ir::{ConstValue, Elem, FixedFormat, Scalar, Type, Variability};

/// The result format of an arithmetic operation on two fixed-point operands.
///
/// The fraction keeps the finer operand's bits and the integer part the wider operand's, so
/// neither operand loses range; when that would need more than 32 bits the fraction gives
/// way (integer bits are kept, capped at 32). The result is unsigned exactly when it has no
/// integer bits.
pub fn join_fixed(a: FixedFormat, b: FixedFormat) -> FixedFormat {
    let mut frac = a.frac.max(b.frac) as u32;
    let int = (a.int_bits().max(b.int_bits()) as u32).min(32);
    if int + frac > 32 {
        frac = 32 - int;
    }
    FixedFormat {
        bits: (int + frac) as u8,
        frac: frac as u8,
    }
}

/// The common scalar type of an arithmetic or comparison between numbers, or `None` when
/// either side is not a number (bool).
pub fn arith_scalar(a: Scalar, b: Scalar) -> Option<Scalar> {
    use Scalar::*;
    Some(match (a, b) {
        (Bool, _) | (_, Bool) => return None,
        (Int, Int) => Int,
        (Float, _) | (_, Float) => Float,
        // The int takes the fixed operand's format (saturating), so `X + 1` keeps X's
        // fraction bits; taking it as fixed<32,0> would leave no room for any.
        (Int, Fixed(f)) | (Fixed(f), Int) => Fixed(f),
        (Fixed(f), Fixed(g)) => Fixed(join_fixed(f, g)),
    })
}

pub fn is_number(s: Scalar) -> bool {
    !matches!(s, Scalar::Bool)
}

/// The scalar element of a type, if it is not interpolation data.
pub fn scalar_of(ty: &Type) -> Option<Scalar> {
    match ty.elem {
        Elem::Scalar(s) => Some(s),
        Elem::Interp => None,
    }
}

/// A readable name of a type, as the user would write it (`float[3][3]`, `fixed<32,16>`).
pub fn type_name(ty: &Type) -> String {
    let mut s = elem_name(ty.elem);
    if ty.per_seq {
        s.push_str("[]");
    }
    for d in &ty.dims {
        s.push_str(&format!("[{d}]"));
    }
    s
}

pub fn elem_name(e: Elem) -> String {
    match e {
        Elem::Interp => "interpolation_data".into(),
        Elem::Scalar(s) => scalar_name(s),
    }
}

pub fn scalar_name(s: Scalar) -> String {
    match s {
        Scalar::Float => "float".into(),
        Scalar::Int => "int".into(),
        Scalar::Bool => "bool".into(),
        Scalar::Fixed(f) => format!("fixed<{},{}>", f.bits, f.frac),
    }
}

/// Zero of a scalar type as a constant.
pub fn zero_const(s: Scalar) -> ConstValue {
    match s {
        Scalar::Float => ConstValue::Float(0.0),
        Scalar::Int => ConstValue::Int(0),
        Scalar::Bool => ConstValue::Bool(false),
        Scalar::Fixed(_) => ConstValue::Fixed(0),
    }
}

/// A constant expression of a scalar type.
pub fn const_expr(c: ConstValue, s: Scalar, span: crate::diag::Span) -> Tree {
    Tree::new(TreeKind::Const(c), Type::scalar(s), Variability::Uniform, span)
}

/// Raw bits of `v` in format `f`: rounded to nearest, saturated to the format's range.
pub fn fixed_raw(v: f64, f: FixedFormat) -> i32 {
    let (lo, hi) = f.raw_range();
    let raw = (v * f.scale()).round();
    let raw = if raw.is_nan() {
        0.0
    } else {
        raw.clamp(lo as f64, hi as f64)
    };
    raw as i64 as i32
}

/// The numeric value of a constant (bool as 0/1), given its scalar type.
pub fn const_value_f64(c: ConstValue, s: Scalar) -> f64 {
    match (c, s) {
        (ConstValue::Float(v), _) => v as f64,
        (ConstValue::Int(v), _) => v as f64,
        (ConstValue::Bool(b), _) => b as i32 as f64,
        (ConstValue::Fixed(raw), Scalar::Fixed(f)) => {
            let raw = if f.is_unsigned() { raw as u32 as f64 } else { raw as f64 };
            raw / f.scale()
        }
        (ConstValue::Fixed(raw), _) => raw as f64,
    }
}

/// A constant converted to another scalar type with the IR's `Convert` semantics
/// (float to int truncates and saturates, to fixed rounds and saturates). `None` for
/// conversions between bool and numbers, which `Convert` does not do.
pub fn convert_const(c: ConstValue, from: Scalar, to: Scalar) -> Option<ConstValue> {
    if from == to {
        return Some(c);
    }
    if matches!(from, Scalar::Bool) || matches!(to, Scalar::Bool) {
        return None;
    }
    let v = const_value_f64(c, from);
    Some(match to {
        Scalar::Float => ConstValue::Float(v as f32),
        Scalar::Int => {
            let t = v.trunc();
            let t = if t.is_nan() {
                0.0
            } else {
                t.clamp(i32::MIN as f64, i32::MAX as f64)
            };
            ConstValue::Int(t as i32)
        }
        Scalar::Fixed(f) => ConstValue::Fixed(fixed_raw(v, f)),
        Scalar::Bool => unreachable_bool(),
    })
}

/// What converting a constant to a fixed format loses, when it loses its meaning (W0006).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FixedLoss {
    /// Outside the format's range by more than one step: it becomes the nearest end.
    Saturates { value: f64, result: f64 },
    /// Not zero, but nearer to zero than half a step: it becomes 0.
    Vanishes { value: f64 },
}

/// How constant `c` of scalar `from` fares converted to `f` ([`convert_const`]'s rounding
/// and saturation), if it loses its meaning. A value one step past the top (`1` as
/// `fixed<32,32>`, the depth buffer's largest value) is taken as meant.
pub fn fixed_loss(c: ConstValue, from: Scalar, f: FixedFormat) -> Option<FixedLoss> {
    if from == Scalar::Fixed(f) || from == Scalar::Bool {
        return None;
    }
    let value = const_value_f64(c, from);
    if !value.is_finite() {
        return None;
    }
    let result = const_value_f64(ConstValue::Fixed(fixed_raw(value, f)), Scalar::Fixed(f));
    if (value - result).abs() > 1.0 / f.scale() {
        Some(FixedLoss::Saturates { value, result })
    } else if value != 0.0 && result == 0.0 {
        Some(FixedLoss::Vanishes { value })
    } else {
        None
    }
}

// Kept out of line so `convert_const` reads as the table it is; the bool case is excluded
// by the early return above.
fn unreachable_bool() -> ConstValue {
    ConstValue::Bool(false)
}

/// Convert the elements of `e` to scalar `to`, keeping its shape. Constants are folded.
/// The caller has checked that the conversion is allowed (numbers to numbers, or to the
/// same scalar; a float scalar to interpolation data).
pub fn convert(e: Tree, to: Scalar) -> Tree {
    match e.ty.elem {
        Elem::Scalar(s) if s == to => e,
        Elem::Scalar(s) => {
            if let TreeKind::Const(c) = e.kind {
                if let Some(c2) = convert_const(c, s, to) {
                    return Tree::new(TreeKind::Const(c2), Type::scalar(to), e.var, e.span);
                }
            }
            let ty = Type {
                elem: Elem::Scalar(to),
                dims: e.ty.dims.clone(),
                per_seq: e.ty.per_seq,
            };
            let (var, span) = (e.var, e.span);
            Tree::new(TreeKind::Convert(Box::new(e)), ty, var, span)
        }
        Elem::Interp => e,
    }
}

/// Whether a value of scalar `from` may be implicitly converted to `to` (assignment,
/// initialisation, arguments): numbers convert among themselves, bool only from bool.
pub fn implicitly_converts(from: Scalar, to: Scalar) -> bool {
    from == to || (is_number(from) && is_number(to))
}
