//! Encoding API values into argument-block words (src/runtime/value.rs): fixed formats round
//! and saturate, ints truncate toward zero and saturate, bools are 0/1, points take w = 1 and
//! the `device_from_object` transform, and interpolation data is not settable.

use glam::Mat4;
use primflow::ir::{Elem, FixedFormat, ParamSpace, Scalar, Type};
use primflow::runtime::value::{encode, encode_scalar, EncodeError};

fn fixed(bits: u8, frac: u8) -> Scalar {
    Scalar::Fixed(FixedFormat { bits, frac })
}

#[test]
fn fixed_rounds_and_saturates() {
    assert_eq!(encode_scalar(1.5, fixed(32, 16)), 0x0001_8000);
    assert_eq!(encode_scalar(-1.0, fixed(32, 16)), 0xFFFF_0000);
    assert_eq!(encode_scalar(1e12, fixed(32, 16)), i32::MAX as u32);
    assert_eq!(encode_scalar(-1e12, fixed(32, 16)), i32::MIN as u32);
    assert_eq!(encode_scalar(f32::NAN, fixed(32, 16)), 0);
    // The depth format: unsigned fraction, 1.0 saturates to all ones.
    assert_eq!(encode_scalar(0.5, fixed(32, 32)), 0x8000_0000);
    assert_eq!(encode_scalar(1.0, fixed(32, 32)), u32::MAX);
    assert_eq!(encode_scalar(-0.25, fixed(32, 32)), 0);
    // A narrow signed format is sign-extended.
    assert_eq!(encode_scalar(-0.5, fixed(8, 4)) as i32, -8);
    assert_eq!(encode_scalar(100.0, fixed(8, 4)) as i32, 127);
}

#[test]
fn ints_and_bools() {
    assert_eq!(encode_scalar(-3.7, Scalar::Int) as i32, -3);
    assert_eq!(encode_scalar(f32::INFINITY, Scalar::Int) as i32, i32::MAX);
    assert_eq!(encode_scalar(f32::NAN, Scalar::Int), 0);
    assert_eq!(encode_scalar(2.0, Scalar::Bool), 1);
    assert_eq!(encode_scalar(0.0, Scalar::Bool), 0);
}

#[test]
fn points_take_w_one_and_are_transformed() {
    let point = Type::array(Elem::Scalar(Scalar::Float), vec![4]);
    let device_from_object = Mat4::from_translation(glam::Vec3::new(10.0, 20.0, 0.0));
    let words = encode(&[1.0, 2.0, 0.5], &point, ParamSpace::Point, &device_from_object).unwrap();
    let floats: Vec<f32> = words.iter().map(|&w| f32::from_bits(w)).collect();
    assert_eq!(floats, vec![11.0, 22.0, 0.5, 1.0]);
    // A plain float[4] is neither extended nor transformed.
    let err = encode(&[1.0, 2.0, 0.5], &point, ParamSpace::None, &device_from_object).unwrap_err();
    assert_eq!(
        err,
        EncodeError::Count {
            given: 3,
            expected: vec![4]
        }
    );
}

#[test]
fn interpolation_data_is_not_settable() {
    let interp = Type::array(Elem::Interp, vec![3]);
    assert_eq!(
        encode(&[1.0], &interp, ParamSpace::None, &Mat4::IDENTITY),
        Err(EncodeError::NotSettable)
    );
}
