//! One component of one lane: the language's scalar arithmetic, comparisons, conversions
//! and float built-ins, on raw 32-bit words, exactly as the JIT computes them.
//!
//! A word holds an f32's bits, an i32, a bool (0 or 1) or a fixed value's raw bits
//! (sign-extended for signed formats, zero-extended for unsigned ones), as a kernel's lane
//! does. Each function here mirrors the Cranelift sequence `jit::fixed`, `jit::builtin` or
//! `jit::lower::expr` emits for it, step by step: the same f32 operations in the same
//! order, the same 64-bit intermediates, the same saturations, Cranelift's `fmin`/`fmax`
//! (NaN in either operand gives NaN, -0 below +0) and the libm functions of `jit::libm`.
//! Nothing here panics: shifts and divisions are guarded as the JIT guards them.

use crate::ir::{BinOp, Builtin, FixedFormat, Scalar};
use crate::jit::libm::LibmFn;

/// The depth buffer's format.
pub const DEPTH: FixedFormat = FixedFormat { bits: 32, frac: 32 };

fn f(w: u32) -> f32 {
    f32::from_bits(w)
}

fn w(x: f32) -> u32 {
    x.to_bits()
}

/// Cranelift's `fmin`: NaN if either operand is, and -0 below +0.
pub fn fmin(a: f32, b: f32) -> f32 {
    if a.is_nan() || b.is_nan() {
        f32::NAN
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

/// Cranelift's `fmax`: NaN if either operand is, and +0 above -0.
pub fn fmax(a: f32, b: f32) -> f32 {
    if a.is_nan() || b.is_nan() {
        f32::NAN
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

fn float_to_fixed(fmt: FixedFormat, v: u32) -> u32 {
    let scaled = f(v) * fmt.scale() as f32;
    // `as` saturates and takes NaN to 0, as `fcvt_to_sint_sat` does.
    saturate64(fmt, scaled.round_ties_even() as i64)
}

/// Convert one word from `from` to `to` (`fixed::convert`).
pub fn convert(from: Scalar, to: Scalar, v: u32) -> u32 {
    match (from, to) {
        (a, c) if a == c => v,
        (Scalar::Float, Scalar::Int) => f(v) as i32 as u32,
        (Scalar::Float, Scalar::Bool) => u32::from(f(v) != 0.0),
        (Scalar::Float, Scalar::Fixed(fmt)) => float_to_fixed(fmt, v),
        (Scalar::Int, Scalar::Float) => w(v as i32 as f32),
        (Scalar::Int | Scalar::Fixed(_), Scalar::Bool) => u32::from(v != 0),
        (Scalar::Int, Scalar::Fixed(fmt)) => fixed_to_fixed(FixedFormat { bits: 32, frac: 0 }, fmt, v),
        (Scalar::Bool, _) => convert(Scalar::Int, to, v & 1),
        (Scalar::Fixed(fmt), Scalar::Float) => {
            let x = if fmt.is_unsigned() { v as f32 } else { v as i32 as f32 };
            w(x * (1.0f64 / fmt.scale()) as f32)
        }
        (Scalar::Fixed(fmt), Scalar::Int) => {
            if fmt.is_unsigned() {
                0
            } else {
                ((v as i32) >> fmt.frac.min(31)) as u32
            }
        }
        (Scalar::Fixed(a), Scalar::Fixed(c)) => fixed_to_fixed(a, c, v),
        _ => v,
    }
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

/// `x op y` in scalar type `sc` (comparisons and `&&`/`||` give a bool word); `None` for an
/// operator the type does not have (the IR validator rules it out).
pub fn binop(op: BinOp, sc: Scalar, x: u32, y: u32) -> Option<u32> {
    use std::cmp::Ordering::{Greater, Less};
    Some(match sc {
        Scalar::Float => {
            let (a, b) = (f(x), f(y));
            match op {
                BinOp::Add => w(a + b),
                BinOp::Sub => w(a - b),
                BinOp::Mul => w(a * b),
                BinOp::Div => w(a / b),
                // C fmodf as the JIT writes it: x - trunc(x / y) * y.
                BinOp::Rem => w(a - (a / b).trunc() * b),
                BinOp::Lt => u32::from(a < b),
                BinOp::Le => u32::from(a <= b),
                BinOp::Gt => u32::from(a > b),
                BinOp::Ge => u32::from(a >= b),
                BinOp::Eq => u32::from(a == b),
                BinOp::Ne => u32::from(a != b),
                BinOp::And | BinOp::Or => return None,
            }
        }
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
    })
}

/// `-x` in `sc`.
pub(super) fn neg(sc: Scalar, x: u32) -> u32 {
    match sc {
        Scalar::Float => x ^ 0x8000_0000,
        Scalar::Fixed(f) => wrap(f, x.wrapping_neg()),
        _ => x.wrapping_neg(),
    }
}

/// Integer and fixed `abs`, `min`, `max`, `clamp` (`jit::builtin`'s `int_builtin`): in the
/// type, unsigned formats compared unsigned; `abs` does not wrap.
pub(super) fn int_builtin(func: Builtin, sc: Scalar, a: &[u32]) -> u32 {
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
    let arg = |i: usize| a.get(i).copied().unwrap_or(0);
    match func {
        Builtin::Abs if unsigned => arg(0),
        Builtin::Abs => (arg(0) as i32).wrapping_abs() as u32,
        Builtin::Min => min(arg(0), arg(1)),
        Builtin::Max => max(arg(0), arg(1)),
        _ => min(max(arg(0), arg(1)), arg(2)),
    }
}

/// One component of a float built-in of one to three float operands (the component-wise
/// ones); `None` for the others.
pub(super) fn float_builtin(func: Builtin, a: &[u32]) -> Option<u32> {
    let arg = |i: usize| f(a.get(i).copied().unwrap_or(0));
    let (x, y, z) = (arg(0), arg(1), arg(2));
    let libm = |l: LibmFn| Some(w(l.apply(&[x, y])));
    Some(w(match func {
        Builtin::Sqrt => x.sqrt(),
        Builtin::Abs => f(a.first().copied().unwrap_or(0) & 0x7fff_ffff),
        Builtin::Floor => x.floor(),
        Builtin::Ceil => x.ceil(),
        Builtin::Round => x.round_ties_even(),
        Builtin::Sign => {
            if x > 0.0 {
                1.0
            } else if x < 0.0 {
                -1.0
            } else {
                0.0
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
        Builtin::Min => fmin(x, y),
        Builtin::Max => fmax(x, y),
        // step(edge, x) = x < edge ? 0 : 1
        Builtin::Step => {
            if y < x {
                0.0
            } else {
                1.0
            }
        }
        Builtin::Clamp => fmin(fmax(x, y), z),
        Builtin::Mix => x + (y - x) * z,
        Builtin::Smoothstep => {
            let t = (z - x) / (y - x);
            let t = fmin(fmax(t, 0.0), 1.0);
            (t * t) * (3.0 - 2.0 * t)
        }
        _ => return None,
    }))
}

/// The most operands a built-in takes ([`Builtin::arities`]).
pub(super) fn arity(func: Builtin) -> usize {
    func.arities().1
}
