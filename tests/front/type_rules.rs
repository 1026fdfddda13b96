//! The checker's type rules (src/check/types.rs): joining fixed-point formats keeps the
//! finer fraction and the wider integer part within 32 bits, arithmetic result scalars, and
//! constant conversions that round and saturate.

use primflow::check::types::{arith_scalar, convert_const, join_fixed};
use primflow::ir::{ConstValue, FixedFormat, Scalar};

fn fx(bits: u8, frac: u8) -> FixedFormat {
    FixedFormat { bits, frac }
}

#[test]
fn join_keeps_finer_fraction_and_wider_integer() {
    // 16 integer bits from the first, 8 fraction bits from the second: fits in 24.
    assert_eq!(join_fixed(fx(20, 4), fx(12, 8)), fx(24, 8));
    // Same format joins to itself.
    assert_eq!(join_fixed(fx(32, 16), fx(32, 16)), fx(32, 16));
}

#[test]
fn join_gives_up_fraction_beyond_32_bits() {
    // X (fixed<32,16>) with Z (fixed<32,32>): I = 16, F = 32 -> F = 16.
    assert_eq!(join_fixed(fx(32, 16), fx(32, 32)), fx(32, 16));
    // An integer part of 32 bits leaves no fraction.
    assert_eq!(join_fixed(fx(32, 0), fx(32, 16)), fx(32, 0));
}

#[test]
fn join_of_unsigned_fractions_stays_unsigned() {
    let j = join_fixed(fx(32, 32), fx(16, 16));
    assert_eq!(j, fx(32, 32));
    assert!(j.is_unsigned());
    // A signed operand brings integer bits: the result is signed.
    let j = join_fixed(fx(32, 32), fx(8, 4));
    assert_eq!(j, fx(32, 28));
    assert!(!j.is_unsigned());
}

#[test]
fn arithmetic_result_scalars() {
    use Scalar::*;
    assert_eq!(arith_scalar(Int, Int), Some(Int));
    assert_eq!(arith_scalar(Int, Float), Some(Float));
    assert_eq!(arith_scalar(Fixed(fx(32, 16)), Float), Some(Float));
    assert_eq!(arith_scalar(Int, Fixed(fx(16, 8))), Some(Fixed(fx(16, 8))));
    assert_eq!(arith_scalar(Bool, Int), None);
}

#[test]
fn constant_conversions_round_and_saturate() {
    let f = Scalar::Fixed(fx(8, 4));
    assert_eq!(
        convert_const(ConstValue::Float(1.53), Scalar::Float, f),
        Some(ConstValue::Fixed(24))
    );
    assert_eq!(
        convert_const(ConstValue::Float(100.0), Scalar::Float, f),
        Some(ConstValue::Fixed(127))
    );
    assert_eq!(
        convert_const(ConstValue::Float(-2.7), Scalar::Float, Scalar::Int),
        Some(ConstValue::Int(-2))
    );
    assert_eq!(convert_const(ConstValue::Bool(true), Scalar::Bool, Scalar::Int), None);
}
