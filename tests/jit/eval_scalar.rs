//! The IR evaluator's scalar semantics (src/ir/eval/scalar.rs), which the JIT tests use as
//! their oracle: Cranelift's `fmin`/`fmax` (NaN propagates, -0 below +0), fixed-point
//! arithmetic that wraps and conversions that saturate, guarded division.

use primflow::ir::eval::scalar::{binop, convert, fmax, fmin, DEPTH};
use primflow::ir::{BinOp, FixedFormat, Scalar};

#[test]
fn cranelift_min_and_max_propagate_nan_and_order_zeros() {
    assert!(fmin(1.0, f32::NAN).is_nan() && fmax(f32::NAN, 1.0).is_nan());
    assert!(fmin(0.0, -0.0).is_sign_negative() && fmin(-0.0, 0.0).is_sign_negative());
    assert!(fmax(-0.0, 0.0).is_sign_positive() && fmax(0.0, -0.0).is_sign_positive());
}

#[test]
fn fixed_arithmetic_wraps_and_conversions_saturate() {
    let f8_4 = FixedFormat { bits: 8, frac: 4 };
    // 7.9375 + 0.0625 wraps to -8.
    assert_eq!(binop(BinOp::Add, Scalar::Fixed(f8_4), 127, 1), Some((-128i32) as u32));
    // 100.0 saturates to 7.9375; 0.03125 rounds to even (0).
    assert_eq!(convert(Scalar::Float, Scalar::Fixed(f8_4), 100f32.to_bits()), 127);
    assert_eq!(convert(Scalar::Float, Scalar::Fixed(f8_4), 0.03125f32.to_bits()), 0);
    assert_eq!(convert(Scalar::Float, Scalar::Fixed(DEPTH), f32::NAN.to_bits()), 0);
    assert_eq!(convert(Scalar::Float, Scalar::Fixed(DEPTH), 2f32.to_bits()), u32::MAX);
    // Division by zero: the format's ends, or 0.
    assert_eq!(
        binop(BinOp::Div, Scalar::Fixed(f8_4), (-16i32) as u32, 0),
        Some((-128i32) as u32)
    );
    assert_eq!(binop(BinOp::Div, Scalar::Int, 7, 0), Some(0));
    assert_eq!(
        binop(BinOp::Div, Scalar::Int, i32::MIN as u32, u32::MAX),
        Some(i32::MIN as u32)
    );
    // Unsigned formats compare unsigned.
    assert_eq!(binop(BinOp::Lt, Scalar::Fixed(DEPTH), 1, 0x8000_0000), Some(1));
}
