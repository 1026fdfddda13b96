//! Integer and fixed-point arithmetic and every scalar conversion, for one component in
//! either form (scalar `i32`/`f32`/`i8`, or a 4-lane vector).
//!
//! Semantics (the language's documented rules; none of these can trap):
//! - int: wrapping i32; `/` and `%` by zero give 0; `i32::MIN / -1` gives `i32::MIN`.
//! - `fixed<B,F>`: raw i32 holding a B-bit two's complement value (an unsigned fraction when
//!   F == B). add/sub/neg/mul wrap to B bits; mul = (a*b as i64) >> F; div = (a << F) / b in
//!   i64, saturated to the raw range, and b == 0 gives the format's max (min if a < 0, 0 if
//!   a == 0); rem is the i64 remainder of the raws (0 for b == 0).
//! - conversions saturate: float -> int truncates (NaN -> 0), float -> fixed rounds to nearest
//!   (NaN -> 0), fixed -> fixed shifts by the fraction difference, fixed -> int floors.
//!
//! Work that needs 64-bit intermediates (fixed mul/div, some conversions) runs lane by lane
//! on vectors; everything else stays in vector instructions.

use cranelift_codegen::ir::{self, condcodes::FloatCC, condcodes::IntCC, types, InstBuilder};
use cranelift_frontend::FunctionBuilder;

use super::value::{map_lanes, F32X4, I32X4};
use crate::ir::{FixedFormat, Scalar};

fn is_vec(b: &FunctionBuilder, v: ir::Value) -> bool {
    b.func.dfg.value_type(v).is_vector()
}

/// An i32 constant in the form of `like` (scalar or splatted).
fn i32_like(b: &mut FunctionBuilder, like: ir::Value, n: i64) -> ir::Value {
    let c = b.ins().iconst(types::I32, n as i32 as i64);
    if is_vec(b, like) {
        b.ins().splat(I32X4, c)
    } else {
        c
    }
}

fn f32_like(b: &mut FunctionBuilder, like: ir::Value, x: f32) -> ir::Value {
    let c = b.ins().f32const(x);
    if is_vec(b, like) {
        b.ins().splat(F32X4, c)
    } else {
        c
    }
}

/// x86 `maxps x, y` on `f32x4`: `y < x ? x : y`, so NaN in either gives `y`. Written as the
/// select Cranelift's x64 backend matches to one `maxps` (Cranelift's `fmax` expands to
/// IEEE NaN and signed-zero handling instead).
fn max_ps(b: &mut FunctionBuilder, x: ir::Value, y: ir::Value) -> ir::Value {
    let less = b.ins().fcmp(FloatCC::LessThan, y, x);
    let mask = super::value::to_f32x4(b, less);
    b.ins().bitselect(mask, x, y)
}

/// x86 `minps x, y` on `f32x4`: `x < y ? x : y`, so NaN in either gives `y` (the select
/// Cranelift's x64 backend matches to one `minps`, as [`max_ps`]).
fn min_ps(b: &mut FunctionBuilder, x: ir::Value, y: ir::Value) -> ir::Value {
    let less = b.ins().fcmp(FloatCC::LessThan, x, y);
    let mask = super::value::to_f32x4(b, less);
    b.ins().bitselect(mask, x, y)
}

/// Run a scalar i32 -> i32 computation on a scalar or on each lane of a vector.
fn per_lane(
    b: &mut FunctionBuilder,
    operands: &[ir::Value],
    out_vec_ty: ir::Type,
    f: &mut dyn FnMut(&mut FunctionBuilder, &[ir::Value]) -> ir::Value,
) -> ir::Value {
    if is_vec(b, operands[0]) {
        map_lanes(b, out_vec_ty, operands, f)
    } else {
        f(b, operands)
    }
}

/// Wrap a raw i32 (scalar or vector) to the format's B bits.
pub fn wrap(b: &mut FunctionBuilder, fmt: FixedFormat, v: ir::Value) -> ir::Value {
    if fmt.bits >= 32 {
        return v;
    }
    let shift = 32 - fmt.bits as i64;
    if fmt.is_unsigned() {
        let mask = i32_like(b, v, (1i64 << fmt.bits) - 1);
        b.ins().band(v, mask)
    } else {
        let up = b.ins().ishl_imm_u(v, shift);
        b.ins().sshr_imm_u(up, shift)
    }
}

/// Widen a scalar raw i32 to i64 as the format reads it.
fn widen(b: &mut FunctionBuilder, fmt: FixedFormat, v: ir::Value) -> ir::Value {
    if fmt.is_unsigned() {
        b.ins().uextend(types::I64, v)
    } else {
        b.ins().sextend(types::I64, v)
    }
}

/// Clamp a scalar i64 into the format's raw range and narrow it.
fn saturate64(b: &mut FunctionBuilder, fmt: FixedFormat, v: ir::Value) -> ir::Value {
    let (lo, hi) = fmt.raw_range();
    let lo = b.ins().iconst(types::I64, lo);
    let hi = b.ins().iconst(types::I64, hi);
    let v = b.ins().smax(v, lo);
    let v = b.ins().smin(v, hi);
    b.ins().ireduce(types::I32, v)
}

pub fn add(b: &mut FunctionBuilder, fmt: FixedFormat, x: ir::Value, y: ir::Value) -> ir::Value {
    let s = b.ins().iadd(x, y);
    wrap(b, fmt, s)
}

pub fn sub(b: &mut FunctionBuilder, fmt: FixedFormat, x: ir::Value, y: ir::Value) -> ir::Value {
    let s = b.ins().isub(x, y);
    wrap(b, fmt, s)
}

pub fn neg(b: &mut FunctionBuilder, fmt: FixedFormat, x: ir::Value) -> ir::Value {
    let s = b.ins().ineg(x);
    wrap(b, fmt, s)
}

pub fn mul(b: &mut FunctionBuilder, fmt: FixedFormat, x: ir::Value, y: ir::Value) -> ir::Value {
    per_lane(b, &[x, y], I32X4, &mut |b, v| {
        let a = widen(b, fmt, v[0]);
        let c = widen(b, fmt, v[1]);
        // For unsigned formats the u64 product fits; imul gives its low 64 bits exactly.
        let p = b.ins().imul(a, c);
        let f = fmt.frac as i64;
        let s = if fmt.is_unsigned() {
            b.ins().ushr_imm_u(p, f)
        } else {
            b.ins().sshr_imm_u(p, f)
        };
        let r = b.ins().ireduce(types::I32, s);
        wrap(b, fmt, r)
    })
}

pub fn div(b: &mut FunctionBuilder, fmt: FixedFormat, x: ir::Value, y: ir::Value) -> ir::Value {
    per_lane(b, &[x, y], I32X4, &mut |b, v| {
        let a = widen(b, fmt, v[0]);
        let c = widen(b, fmt, v[1]);
        // |a| < 2^32 and F <= 32: the shifted numerator fits i64 (signed formats have F <= 31)
        // or u64 (unsigned formats, divided unsigned).
        let num = b.ins().ishl_imm_u(a, fmt.frac as i64);
        let is_zero = b.ins().icmp_imm_s(IntCC::Equal, c, 0);
        let one = b.ins().iconst(types::I64, 1);
        let den = b.ins().select(is_zero, one, c);
        let sat = if fmt.is_unsigned() {
            // A u64 quotient (up to 2^64 - 1 for fixed<32,32>): clamped unsigned, since read
            // signed one of 2^63 or more would be negative and clamp to 0.
            let q = b.ins().udiv(num, den);
            let hi = b.ins().iconst(types::I64, fmt.raw_range().1);
            let q = b.ins().umin(q, hi);
            b.ins().ireduce(types::I32, q)
        } else {
            let q = b.ins().sdiv(num, den);
            saturate64(b, fmt, q)
        };
        let (lo, hi) = fmt.raw_range();
        let min = b.ins().iconst(types::I32, lo as i32 as i64);
        let max = b.ins().iconst(types::I32, hi as i32 as i64);
        let zero = b.ins().iconst(types::I32, 0);
        let a_zero = b.ins().icmp_imm_s(IntCC::Equal, a, 0);
        let a_neg = b.ins().icmp_imm_s(IntCC::SignedLessThan, a, 0);
        let by_zero = b.ins().select(a_neg, min, max);
        let by_zero = b.ins().select(a_zero, zero, by_zero);
        b.ins().select(is_zero, by_zero, sat)
    })
}

pub fn rem(b: &mut FunctionBuilder, fmt: FixedFormat, x: ir::Value, y: ir::Value) -> ir::Value {
    per_lane(b, &[x, y], I32X4, &mut |b, v| {
        let a = widen(b, fmt, v[0]);
        let c = widen(b, fmt, v[1]);
        let is_zero = b.ins().icmp_imm_s(IntCC::Equal, c, 0);
        let one = b.ins().iconst(types::I64, 1);
        let den = b.ins().select(is_zero, one, c);
        let r = if fmt.is_unsigned() {
            b.ins().urem(a, den)
        } else {
            b.ins().srem(a, den)
        };
        let r = b.ins().ireduce(types::I32, r);
        let zero = b.ins().iconst(types::I32, 0);
        b.ins().select(is_zero, zero, r)
    })
}

/// Integer `/` (`rem == false`) or `%`: never traps (see the module doc).
pub fn int_div_rem(b: &mut FunctionBuilder, x: ir::Value, y: ir::Value, rem: bool) -> ir::Value {
    per_lane(b, &[x, y], I32X4, &mut |b, v| {
        // In i64, i32::MIN / -1 cannot overflow; narrowing wraps it back to i32::MIN.
        let a = b.ins().sextend(types::I64, v[0]);
        let c = b.ins().sextend(types::I64, v[1]);
        let is_zero = b.ins().icmp_imm_s(IntCC::Equal, c, 0);
        let one = b.ins().iconst(types::I64, 1);
        let den = b.ins().select(is_zero, one, c);
        let r = if rem {
            b.ins().srem(a, den)
        } else {
            b.ins().sdiv(a, den)
        };
        let r = b.ins().ireduce(types::I32, r);
        let zero = b.ins().iconst(types::I32, 0);
        b.ins().select(is_zero, zero, r)
    })
}

/// The condition code for an integer comparison in this scalar type's order.
pub fn int_cc(scalar: Scalar, signed_cc: IntCC) -> IntCC {
    match scalar {
        Scalar::Fixed(f) if f.is_unsigned() => signed_cc.unsigned(),
        _ => signed_cc,
    }
}

/// Rounded, saturated `f32x4` (already scaled, integral or not) to raw u32 lanes; NaN -> 0.
/// Used for `fixed<32,32>` and for storing depth.
pub fn f32x4_to_u32_sat(b: &mut FunctionBuilder, scaled: ir::Value) -> ir::Value {
    let r = b.ins().nearest(scaled);
    let two31 = f32_like(b, r, 2147483648.0);
    if cfg!(target_arch = "x86_64") {
        // Eight instructions after the rounding, as the hand-written kernel's `depth_raw4`
        // but saturating below 0 and for NaN too. `cvttps2dq` gives i32::MIN for NaN and
        // lanes >= 2^31; `maxps(x, 0)` gives 0 for NaN (its second operand) and x < 0.
        // low: r in [0, 2^31) exactly, i32::MIN (the top bit) for r >= 2^31, 0 otherwise.
        //
        // `maxps(r, 0)` and then [`rounded_nonneg_to_u32_sat`] is six and gives the same
        // values, but measured worse: with `0.0` used once instead of twice, regalloc2
        // spilled it in sphere's pixel loop and reloaded it at its four other uses there
        // (sphere +1.1 % JIT instructions per frame).
        let zero = f32_like(b, r, 0.0);
        let low = max_ps(b, r, zero);
        let low = b.ins().x86_cvtt2dq(I32X4, low);
        // high: r - 2^31 (exact) for r in [2^31, 2^32), i32::MIN for r >= 2^32 (and +inf),
        // 0 otherwise; the arithmetic shift turns i32::MIN into all ones (u32::MAX).
        let shifted = b.ins().fsub(r, two31);
        let high = max_ps(b, shifted, zero);
        let high = b.ins().x86_cvtt2dq(I32X4, high);
        let high_sign = b.ins().sshr_imm_u(high, 31);
        let high = b.ins().bor(high, high_sign);
        return b.ins().bor(low, high);
    }
    let big = b.ins().fcmp(FloatCC::GreaterThanOrEqual, r, two31);
    let lo = b.ins().fcvt_to_sint_sat(I32X4, r);
    let zero = i32_like(b, lo, 0);
    let lo = b.ins().smax(lo, zero);
    // r >= 2^31: r - 2^31 is exact; flipping the sign bit adds 2^31 back in u32.
    let shifted = b.ins().fsub(r, two31);
    let hi = b.ins().fcvt_to_sint_sat(I32X4, shifted);
    let sign = i32_like(b, hi, i32::MIN as i64);
    let hi = b.ins().bxor(hi, sign);
    b.ins().bitselect(big, hi, lo)
}

/// x86_64: `r`, rounded to an integer (`nearest`), not NaN and not below -0.0, to raw u32
/// lanes saturated at u32::MAX, in five instructions. For every such r this equals
/// [`f32x4_to_u32_sat`]'s result (checked for every f32 input against a scratch model of
/// the x86 instructions).
///
/// Why it is exact, with `low = cvttps2dq(r)` and
/// `high = cvttps2dq(minps(r - 2^32, -1.0))`, the result `pmaxsd(low, high)` (signed):
/// - r in [0, 2^31): `low` = r exactly (>= 0). r - 2^32 is below -2^31 before rounding, so
///   rounded it is <= -2^31 (rounding is monotone, -2^31 is an f32) and `high` is i32::MIN
///   (exact or out of range); the max is r.
/// - r in [2^31, 2^32): `low` = i32::MIN (out of range). r - 2^32 is exact (Sterbenz: r is
///   within a factor two of 2^32) and in [-2^31, -256] (the f32 below 2^32 is 2^32 - 256),
///   so `minps` keeps it and `high` = r - 2^32, which is r as a u32; it is >= i32::MIN.
/// - r >= 2^32, +inf included: r - 2^32 >= 0 (or +inf), `minps` gives -1.0, `high` = -1 =
///   u32::MAX; `low` = i32::MIN; the max is u32::MAX, the saturation.
/// - r = -0.0: `low` = 0, `high` = i32::MIN: 0.
///
/// NaN would give u32::MAX (minps returns its second operand) and r <= -1 a negative `low`:
/// callers exclude both by a bound (`maxps(r, 0)` first would too).
fn rounded_nonneg_to_u32_sat(b: &mut FunctionBuilder, r: ir::Value) -> ir::Value {
    let two32 = f32_like(b, r, 4294967296.0);
    let minus_one = f32_like(b, r, -1.0);
    let low = b.ins().x86_cvtt2dq(I32X4, r);
    let below = b.ins().fsub(r, two32);
    let below = min_ps(b, below, minus_one);
    let high = b.ins().x86_cvtt2dq(I32X4, below);
    b.ins().smax(low, high)
}

/// Convert one component from `from` to `to` (scalar or vector form preserved).
pub fn convert(b: &mut FunctionBuilder, from: Scalar, to: Scalar, v: ir::Value) -> ir::Value {
    let vec = is_vec(b, v);
    let int_ty = if vec { I32X4 } else { types::I32 };
    let float_ty = if vec { F32X4 } else { types::F32 };
    match (from, to) {
        (a, c) if a == c => v,
        (Scalar::Float, Scalar::Int) => b.ins().fcvt_to_sint_sat(int_ty, v),
        (Scalar::Float, Scalar::Bool) => {
            let z = f32_like(b, v, 0.0);
            b.ins().fcmp(FloatCC::NotEqual, v, z)
        }
        (Scalar::Float, Scalar::Fixed(fmt)) => float_to_fixed(b, fmt, v),
        (Scalar::Int, Scalar::Float) => b.ins().fcvt_from_sint(float_ty, v),
        (Scalar::Int | Scalar::Fixed(_), Scalar::Bool) => {
            let z = i32_like(b, v, 0);
            b.ins().icmp(IntCC::NotEqual, v, z)
        }
        (Scalar::Int, Scalar::Fixed(fmt)) => fixed_to_fixed(b, FixedFormat { bits: 32, frac: 0 }, fmt, v),
        (Scalar::Bool, _) => {
            // 0/1 as int first.
            let as_int = if vec {
                let one = i32_like(b, v, 1);
                b.ins().band(v, one)
            } else {
                b.ins().uextend(types::I32, v)
            };
            convert(b, Scalar::Int, to, as_int)
        }
        (Scalar::Fixed(fmt), Scalar::Float) => {
            let f = if fmt.is_unsigned() {
                b.ins().fcvt_from_uint(float_ty, v)
            } else {
                b.ins().fcvt_from_sint(float_ty, v)
            };
            let scale = f32_like(b, v, (1.0f64 / fmt.scale()) as f32);
            // f32_like looked at `v`'s form, which matches `f`'s.
            b.ins().fmul(f, scale)
        }
        (Scalar::Fixed(fmt), Scalar::Int) => {
            if fmt.is_unsigned() {
                // No integer bits: every in-range value floors to 0.
                i32_like(b, v, 0)
            } else {
                b.ins().sshr_imm_u(v, fmt.frac as i64)
            }
        }
        (Scalar::Fixed(a), Scalar::Fixed(c)) => fixed_to_fixed(b, a, c, v),
        // Unreachable combinations (same type handled above) keep the value.
        _ => v,
    }
}

/// [`convert`] of a float vector whose every lane is known to be a non-NaN value in
/// `[lo, hi]` (`source_bound`, from `mid::bounds`; an end may be infinite): when
/// truncating (to int) or rounding and scaling (to a signed fixed format) cannot leave the
/// target's range, the result is one `cvttps2dq` (after the scaling and rounding) instead
/// of the saturating sequence, whose NaN and overflow fix-ups cost seven more instructions
/// on x86_64; to `fixed<32,32>`, a value not below 0 needs five instructions after the
/// rounding instead of eight (see [`rounded_nonneg_to_u32_sat`]), and one below 2^-1
/// (scaled: below 2^31 - 1/2) one `cvttps2dq`. Same values as [`convert`]
/// for every lane in the bound; anything else, or no bound, is [`convert`].
pub fn convert_bounded(
    b: &mut FunctionBuilder,
    from: Scalar,
    to: Scalar,
    v: ir::Value,
    source_bound: Option<(f64, f64)>,
) -> ir::Value {
    let Some((lo, hi)) = source_bound else {
        return convert(b, from, to, v);
    };
    if from != Scalar::Float || !is_vec(b, v) || !cfg!(target_arch = "x86_64") {
        return convert(b, from, to, v);
    }
    match to {
        // Truncation toward zero of a value in (-2^31 - 1, 2^31) is an i32.
        Scalar::Int if lo > -2147483649.0 && hi < 2147483648.0 => b.ins().x86_cvtt2dq(I32X4, v),
        // Scaled by 2^32 (exact, or +inf) and rounded to nearest, a value >= -2^-33 is not
        // below -0.0 (ties go to even: -0.5 rounds to -0.0): the saturating form's
        // `maxps(r, 0)` changes nothing, and the upper end needs no bound at all.
        Scalar::Fixed(fmt) if fmt.is_unsigned() && fmt.bits == 32 && lo * fmt.scale() >= -0.5 => {
            let s = f32_like(b, v, fmt.scale() as f32);
            let scaled = b.ins().fmul(v, s);
            let r = b.ins().nearest(scaled);
            if hi * fmt.scale() < 2147483647.5 {
                // Rounded, in [-0, 2^31 - 1]: `cvttps2dq` alone is exact (-0 gives 0).
                b.ins().x86_cvtt2dq(I32X4, r)
            } else {
                rounded_nonneg_to_u32_sat(b, r)
            }
        }
        Scalar::Fixed(fmt) if !fmt.is_unsigned() => {
            // Rounded to nearest, the scaled value must land in the raw range: then the
            // saturating form's clamps (to i32, then to B bits) change nothing.
            let scale = fmt.scale();
            let (raw_lo, raw_hi) = fmt.raw_range();
            if lo * scale >= raw_lo as f64 && hi * scale <= raw_hi as f64 {
                let s = f32_like(b, v, scale as f32);
                let scaled = b.ins().fmul(v, s);
                let r = b.ins().nearest(scaled);
                b.ins().x86_cvtt2dq(I32X4, r)
            } else {
                convert(b, from, to, v)
            }
        }
        _ => convert(b, from, to, v),
    }
}

fn float_to_fixed(b: &mut FunctionBuilder, fmt: FixedFormat, v: ir::Value) -> ir::Value {
    let scale = f32_like(b, v, fmt.scale() as f32);
    // Scaling by a power of two is exact (or overflows to inf, which saturates below).
    let scaled = b.ins().fmul(v, scale);
    if is_vec(b, v) {
        if fmt.is_unsigned() && fmt.bits == 32 {
            return f32x4_to_u32_sat(b, scaled);
        }
        let r = b.ins().nearest(scaled);
        let i = b.ins().fcvt_to_sint_sat(I32X4, r);
        if fmt.bits == 32 {
            return i;
        }
        let (lo, hi) = fmt.raw_range();
        let lo = i32_like(b, i, lo);
        let hi = i32_like(b, i, hi);
        let i = b.ins().smax(i, lo);
        b.ins().smin(i, hi)
    } else {
        let r = b.ins().nearest(scaled);
        let i = b.ins().fcvt_to_sint_sat(types::I64, r);
        saturate64(b, fmt, i)
    }
}

fn fixed_to_fixed(b: &mut FunctionBuilder, from: FixedFormat, to: FixedFormat, v: ir::Value) -> ir::Value {
    per_lane(b, &[v], I32X4, &mut |b, l| {
        let w = widen(b, from, l[0]);
        let diff = to.frac as i64 - from.frac as i64;
        let w = if diff > 0 {
            // |w| < 2^32 and diff <= 32: fits i64 except for the extreme 2^32 << 32 corner,
            // which saturates correctly via the sign check below.
            let shifted = b.ins().ishl_imm_u(w, diff);
            // Detect overflow: shifting back must give w.
            let back = b.ins().sshr_imm_u(shifted, diff);
            let ok = b.ins().icmp(IntCC::Equal, back, w);
            let neg = b.ins().icmp_imm_s(IntCC::SignedLessThan, w, 0);
            let min = b.ins().iconst(types::I64, i64::MIN);
            let max = b.ins().iconst(types::I64, i64::MAX);
            let sat = b.ins().select(neg, min, max);
            b.ins().select(ok, shifted, sat)
        } else if diff < 0 {
            b.ins().sshr_imm_u(w, -diff)
        } else {
            w
        };
        saturate64(b, to, w)
    })
}
