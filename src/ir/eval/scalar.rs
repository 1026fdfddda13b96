//! One component of one lane: the language's scalar arithmetic, comparisons, conversions
//! and float built-ins, exactly as the JIT computes them, and the same in f64.
//!
//! Floats are computed in a `Float` type (`super::precision`): the functions generic over
//! it are, instantiated at `f32`, the JIT's arithmetic, and at `f64` the same operations in
//! the same order in f64 ([`Precision::F64`]). The `*_lane` functions take lane words and
//! the run's precision; [`binop`] and [`convert`] are the f32 ones on 32-bit words. Ints,
//! bools and fixed values are 32-bit words whichever the precision, computed alike in
//! both: an i32, a bool (0 or 1) or a fixed value's raw bits (sign-extended for signed
//! formats, zero-extended for unsigned ones), as a kernel's lane holds them.
//!
//! In f32 each function mirrors the Cranelift sequence `jit::fixed`, `jit::builtin` or
//! `jit::lower::expr` emits for it, step by step: the same f32 operations in the same
//! order, the same 64-bit intermediates, the same saturations, Cranelift's `fmin`/`fmax`
//! (NaN in either operand gives NaN, -0 below +0) and the libm functions of `jit::libm`.
//! In f64 the transcendental functions are Rust's f64 ones (`Float::libm`) and a
//! conversion to fixed point scales and rounds the f64 value. Nothing here panics: shifts
//! and divisions are guarded as the JIT guards them.

use super::precision::{in_precision, Float, Precision};
use crate::ir::{BinOp, Builtin, FixedFormat, Scalar};
use crate::jit::libm::LibmFn;

/// The depth buffer's format.
pub const DEPTH: FixedFormat = FixedFormat { bits: 32, frac: 32 };

/// Cranelift's `fmin`: NaN if either operand is, and -0 below +0.
pub fn fmin(a: f32, b: f32) -> f32 {
    fmin_in(a, b)
}

/// Cranelift's `fmax`: NaN if either operand is, and +0 above -0.
pub fn fmax(a: f32, b: f32) -> f32 {
    fmax_in(a, b)
}

/// Cranelift's `fmin` in `F`.
pub(crate) fn fmin_in<F: Float>(a: F, b: F) -> F {
    if a.is_nan() || b.is_nan() {
        F::from_f32(f32::NAN)
    } else if a == b {
        if a.is_sign_negative() {
            a
        } else {
            b
        }
    } else if a < b {
        a
    } else {
        b
    }
}

/// Cranelift's `fmax` in `F`.
pub(crate) fn fmax_in<F: Float>(a: F, b: F) -> F {
    if a.is_nan() || b.is_nan() {
        F::from_f32(f32::NAN)
    } else if a == b {
        if a.is_sign_negative() {
            b
        } else {
            a
        }
    } else if a > b {
        a
    } else {
        b
    }
}

/// A raw word widened to i64 as the format reads it (`fixed::widen`).
fn widen(fmt: FixedFormat, v: u32) -> i64 {
    if fmt.is_unsigned() {
        i64::from(v)
    } else {
        i64::from(v as i32)
    }
}

/// Clamp into the format's raw range and narrow (`fixed::saturate64`).
fn saturate64(fmt: FixedFormat, v: i64) -> u32 {
    let (lo, hi) = fmt.raw_range();
    v.clamp(lo, hi) as u32
}

/// Wrap a raw word to the format's bits (`fixed::wrap`).
pub(super) fn wrap(fmt: FixedFormat, v: u32) -> u32 {
    if fmt.bits >= 32 {
        return v;
    }
    let shift = 32 - u32::from(fmt.bits);
    if fmt.is_unsigned() {
        v & ((1u32 << fmt.bits) - 1)
    } else {
        (((v << shift) as i32) >> shift) as u32
    }
}

fn fixed_mul(fmt: FixedFormat, x: u32, y: u32) -> u32 {
    let p = widen(fmt, x).wrapping_mul(widen(fmt, y));
    let s = if fmt.is_unsigned() {
        ((p as u64) >> fmt.frac) as i64
    } else {
        p >> fmt.frac
    };
    wrap(fmt, s as u32)
}

fn fixed_div(fmt: FixedFormat, x: u32, y: u32) -> u32 {
    let a = widen(fmt, x);
    let c = widen(fmt, y);
    let (lo, hi) = fmt.raw_range();
    if c == 0 {
        return if a == 0 {
            0
        } else if a < 0 {
            lo as u32
        } else {
            hi as u32
        };
    }
    let num = a.wrapping_shl(u32::from(fmt.frac));
    if fmt.is_unsigned() {
        // A u64 quotient, clamped unsigned (`fixed::div`).
        return ((num as u64) / (c as u64)).min(hi as u64) as u32;
    }
    saturate64(fmt, num.wrapping_div(c))
}

fn fixed_rem(fmt: FixedFormat, x: u32, y: u32) -> u32 {
    let a = widen(fmt, x);
    let c = widen(fmt, y);
    if c == 0 {
        return 0;
    }
    let r = if fmt.is_unsigned() {
        ((a as u64) % (c as u64)) as i64
    } else {
        a.wrapping_rem(c)
    };
    r as u32
}

fn int_div_rem(x: u32, y: u32, rem: bool) -> u32 {
    let a = i64::from(x as i32);
    let c = i64::from(y as i32);
    if c == 0 {
        return 0;
    }
    let r = if rem { a.wrapping_rem(c) } else { a.wrapping_div(c) };
    r as u32
}

fn fixed_to_fixed(from: FixedFormat, to: FixedFormat, v: u32) -> u32 {
    let w = widen(from, v);
    let diff = i64::from(to.frac) - i64::from(from.frac);
    let w = if diff > 0 {
        let shifted = w.wrapping_shl(diff as u32);
        if shifted >> diff == w {
            shifted
        } else if w < 0 {
            i64::MIN
        } else {
            i64::MAX
        }
    } else if diff < 0 {
        w >> (-diff)
    } else {
        w
    };
    saturate64(to, w)
}

fn float_to_fixed<F: Float>(fmt: FixedFormat, x: F) -> u32 {
    let scaled = x * F::from_f64(fmt.scale());
    // `as` saturates and takes NaN to 0, as `fcvt_to_sint_sat` does.
    saturate64(fmt, scaled.round_ties_even().to_i64())
}

/// Convert one word from `from` to `to` (`fixed::convert`), in f32.
pub fn convert(from: Scalar, to: Scalar, v: u32) -> u32 {
    convert_in::<f32>(from, to, u64::from(v)) as u32
}

/// Convert lane word `v` from `from` to `to` in precision `p`.
pub(crate) fn convert_lane(p: Precision, from: Scalar, to: Scalar, v: u64) -> u64 {
    in_precision!(p, F => convert_in::<F>(from, to, v))
}

/// Convert lane word `v` from `from` to `to`, floats in `F`.
fn convert_in<F: Float>(from: Scalar, to: Scalar, v: u64) -> u64 {
    // Every word but a float's is 32 bits.
    let i = v as u32;
    u64::from(match (from, to) {
        (a, c) if a == c => return v,
        (Scalar::Float, Scalar::Int) => F::from_word(v).to_i32() as u32,
        (Scalar::Float, Scalar::Bool) => u32::from(F::from_word(v) != F::ZERO),
        (Scalar::Float, Scalar::Fixed(fmt)) => float_to_fixed(fmt, F::from_word(v)),
        (Scalar::Int, Scalar::Float) => return F::from_i32(i as i32).word(),
        (Scalar::Int | Scalar::Fixed(_), Scalar::Bool) => u32::from(i != 0),
        (Scalar::Int, Scalar::Fixed(fmt)) => fixed_to_fixed(FixedFormat { bits: 32, frac: 0 }, fmt, i),
        (Scalar::Bool, _) => return convert_in::<F>(Scalar::Int, to, v & 1),
        (Scalar::Fixed(fmt), Scalar::Float) => {
            let x = if fmt.is_unsigned() {
                F::from_u32(i)
            } else {
                F::from_i32(i as i32)
            };
            return (x * F::from_f64(1.0f64 / fmt.scale())).word();
        }
        (Scalar::Fixed(fmt), Scalar::Int) => {
            if fmt.is_unsigned() {
                0
            } else {
                ((i as i32) >> fmt.frac.min(31)) as u32
            }
        }
        (Scalar::Fixed(a), Scalar::Fixed(c)) => fixed_to_fixed(a, c, i),
        _ => return v,
    })
}

fn is_unsigned(sc: Scalar) -> bool {
    matches!(sc, Scalar::Fixed(f) if f.is_unsigned())
}

/// An integer order comparison in `sc`'s order (unsigned for unsigned fixed formats).
fn int_order(sc: Scalar, x: u32, y: u32) -> std::cmp::Ordering {
    if is_unsigned(sc) {
        x.cmp(&y)
    } else {
        (x as i32).cmp(&(y as i32))
    }
}

/// `x op y` in scalar type `sc`, in f32 (comparisons and `&&`/`||` give a bool word);
/// `None` for an operator the type does not have (the IR validator rules it out).
pub fn binop(op: BinOp, sc: Scalar, x: u32, y: u32) -> Option<u32> {
    binop_in::<f32>(op, sc, u64::from(x), u64::from(y)).map(|w| w as u32)
}

/// `x op y` on lane words in precision `p` (see [`binop`]).
pub(crate) fn binop_lane(p: Precision, op: BinOp, sc: Scalar, x: u64, y: u64) -> Option<u64> {
    in_precision!(p, F => binop_in::<F>(op, sc, x, y))
}

fn binop_in<F: Float>(op: BinOp, sc: Scalar, x: u64, y: u64) -> Option<u64> {
    use std::cmp::Ordering::{Greater, Less};
    if sc == Scalar::Float {
        let (a, b) = (F::from_word(x), F::from_word(y));
        return Some(match op {
            BinOp::Add => (a + b).word(),
            BinOp::Sub => (a - b).word(),
            BinOp::Mul => (a * b).word(),
            BinOp::Div => (a / b).word(),
            // C fmodf as the JIT writes it: x - trunc(x / y) * y.
            BinOp::Rem => (a - (a / b).trunc() * b).word(),
            BinOp::Lt => u64::from(a < b),
            BinOp::Le => u64::from(a <= b),
            BinOp::Gt => u64::from(a > b),
            BinOp::Ge => u64::from(a >= b),
            BinOp::Eq => u64::from(a == b),
            BinOp::Ne => u64::from(a != b),
            BinOp::And | BinOp::Or => return None,
        });
    }
    let (x, y) = (x as u32, y as u32);
    Some(u64::from(match sc {
        Scalar::Float => return None,
        Scalar::Int | Scalar::Fixed(_) => {
            let fmt = match sc {
                Scalar::Fixed(f) => Some(f),
                _ => None,
            };
            match (op, fmt) {
                (BinOp::Add, Some(f)) => wrap(f, x.wrapping_add(y)),
                (BinOp::Add, None) => x.wrapping_add(y),
                (BinOp::Sub, Some(f)) => wrap(f, x.wrapping_sub(y)),
                (BinOp::Sub, None) => x.wrapping_sub(y),
                (BinOp::Mul, Some(f)) => fixed_mul(f, x, y),
                (BinOp::Mul, None) => x.wrapping_mul(y),
                (BinOp::Div, Some(f)) => fixed_div(f, x, y),
                (BinOp::Div, None) => int_div_rem(x, y, false),
                (BinOp::Rem, Some(f)) => fixed_rem(f, x, y),
                (BinOp::Rem, None) => int_div_rem(x, y, true),
                (BinOp::Lt, _) => u32::from(int_order(sc, x, y) == Less),
                (BinOp::Le, _) => u32::from(int_order(sc, x, y) != Greater),
                (BinOp::Gt, _) => u32::from(int_order(sc, x, y) == Greater),
                (BinOp::Ge, _) => u32::from(int_order(sc, x, y) != Less),
                (BinOp::Eq, _) => u32::from(x == y),
                (BinOp::Ne, _) => u32::from(x != y),
                (BinOp::And | BinOp::Or, _) => return None,
            }
        }
        Scalar::Bool => match op {
            BinOp::And => x & y,
            BinOp::Or => x | y,
            BinOp::Eq => u32::from(x == y),
            BinOp::Ne => u32::from(x != y),
            _ => return None,
        },
    }))
}

/// `-x` in `sc`, on a lane word in precision `p` (a float's sign flipped, as `fneg`).
pub(super) fn neg_lane(p: Precision, sc: Scalar, x: u64) -> u64 {
    match sc {
        Scalar::Float => in_precision!(p, F => (-F::from_word(x)).word()),
        Scalar::Fixed(f) => u64::from(wrap(f, (x as u32).wrapping_neg())),
        _ => u64::from((x as u32).wrapping_neg()),
    }
}

/// Integer and fixed `abs`, `min`, `max`, `clamp` (`jit::builtin`'s `int_builtin`) of lane
/// words: in the type, unsigned formats compared unsigned; `abs` does not wrap.
pub(super) fn int_builtin(func: Builtin, sc: Scalar, a: &[u64]) -> u64 {
    let unsigned = is_unsigned(sc);
    let min = |x: u32, y: u32| {
        if unsigned {
            x.min(y)
        } else {
            (x as i32).min(y as i32) as u32
        }
    };
    let max = |x: u32, y: u32| {
        if unsigned {
            x.max(y)
        } else {
            (x as i32).max(y as i32) as u32
        }
    };
    let arg = |i: usize| a.get(i).copied().unwrap_or(0) as u32;
    u64::from(match func {
        Builtin::Abs if unsigned => arg(0),
        Builtin::Abs => (arg(0) as i32).wrapping_abs() as u32,
        Builtin::Min => min(arg(0), arg(1)),
        Builtin::Max => max(arg(0), arg(1)),
        _ => min(max(arg(0), arg(1)), arg(2)),
    })
}

/// One component of a float built-in of one to three float operands (the component-wise
/// ones), on lane words of `F`; `None` for the others.
pub(super) fn float_builtin<F: Float>(func: Builtin, a: &[u64]) -> Option<u64> {
    let arg = |i: usize| F::from_word(a.get(i).copied().unwrap_or(0));
    let (x, y, z) = (arg(0), arg(1), arg(2));
    let libm = |l: LibmFn| Some(F::libm(l, x, y).word());
    let c = F::from_f32;
    Some(
        match func {
            Builtin::Sqrt => x.sqrt(),
            // Clears the sign bit, as the JIT's `fabs`.
            Builtin::Abs => x.abs(),
            Builtin::Floor => x.floor(),
            Builtin::Ceil => x.ceil(),
            Builtin::Round => x.round_ties_even(),
            Builtin::Sign => {
                if x > F::ZERO {
                    F::ONE
                } else if x < F::ZERO {
                    -F::ONE
                } else {
                    F::ZERO
                }
            }
            Builtin::Sin => return libm(LibmFn::Sin),
            Builtin::Cos => return libm(LibmFn::Cos),
            Builtin::Tan => return libm(LibmFn::Tan),
            Builtin::Asin => return libm(LibmFn::Asin),
            Builtin::Acos => return libm(LibmFn::Acos),
            Builtin::Atan => return libm(LibmFn::Atan),
            Builtin::Exp => return libm(LibmFn::Exp),
            Builtin::Log => return libm(LibmFn::Log),
            Builtin::Atan2 => return libm(LibmFn::Atan2),
            Builtin::Pow => return libm(LibmFn::Pow),
            Builtin::Min => fmin_in(x, y),
            Builtin::Max => fmax_in(x, y),
            // step(edge, x) = x < edge ? 0 : 1
            Builtin::Step => {
                if y < x {
                    F::ZERO
                } else {
                    F::ONE
                }
            }
            Builtin::Clamp => fmin_in(fmax_in(x, y), z),
            Builtin::Mix => x + (y - x) * z,
            Builtin::Smoothstep => {
                let t = (z - x) / (y - x);
                let t = fmin_in(fmax_in(t, F::ZERO), F::ONE);
                (t * t) * (c(3.0) - c(2.0) * t)
            }
            _ => return None,
        }
        .word(),
    )
}

/// The most operands a built-in takes ([`Builtin::arities`]).
pub(super) fn arity(func: Builtin) -> usize {
    func.arities().1
}
