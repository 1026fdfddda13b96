//! Values handed to the API and their encoding into argument-block words.
//!
//! The API takes every value as a list of f32 components ([`Value`]); ints and bools are given
//! as numbers. [`encode`] turns such a list into the 32-bit words a kernel reads for a
//! parameter of a given [`ir::Type`](crate::ir::Type) (see `abi::ArgLayout`): floats as their
//! bits, ints saturated toward zero, bools as 0/1, `fixed<B,F>` as `round(x * 2^F)` saturated to
//! the format's raw range. Points (`ParamSpace::Point`) are multiplied by the current
//! `device_from_object` matrix first (homogeneous, no divide: the primitive divides).
//! Encoding never panics: NaN and infinities are passed through for floats and map to the
//! saturated (or zero, for NaN) raw value for ints and fixed formats.

use glam::{Mat4, Vec4};

use crate::ir::{ConstValue, Elem, ParamSpace, Scalar, Type};

/// A value given to the API: its float components in order (a point is x y z [w]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Value(pub Vec<f32>);

impl Value {
    pub fn components(&self) -> &[f32] {
        &self.0
    }
    pub fn len(&self) -> usize {
        self.0.len()
    }
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }
}

impl From<f32> for Value {
    fn from(x: f32) -> Value {
        Value(vec![x])
    }
}

impl From<&[f32]> for Value {
    fn from(xs: &[f32]) -> Value {
        Value(xs.to_vec())
    }
}

impl From<Vec<f32>> for Value {
    fn from(xs: Vec<f32>) -> Value {
        Value(xs)
    }
}

impl<const N: usize> From<[f32; N]> for Value {
    fn from(xs: [f32; N]) -> Value {
        Value(xs.to_vec())
    }
}

/// Why a value could not be encoded for a parameter.
#[derive(Clone, Debug, PartialEq)]
pub enum EncodeError {
    /// The parameter is interpolation data: it is filled from material values, not set.
    NotSettable,
    /// Wrong number of components; `expected` lists the accepted counts.
    Count { given: usize, expected: Vec<usize> },
}

/// The scalar kind of a type's elements (`None` for interpolation data).
fn scalar_of(ty: &Type) -> Option<Scalar> {
    match ty.elem {
        Elem::Scalar(s) => Some(s),
        Elem::Interp => None,
    }
}

/// Encode `value` for one value of type `ty` (for a per-sequence-point parameter, pass the
/// element type). A point (space `Point`, last dimension 4) may be given with 3 components
/// per point, w = 1.
pub fn encode(value: &[f32], ty: &Type, space: ParamSpace, device_from_object: &Mat4) -> Result<Vec<u32>, EncodeError> {
    let scalar = scalar_of(ty).ok_or(EncodeError::NotSettable)?;
    let expected = ty.fixed_len() as usize;
    let is_point = space == ParamSpace::Point && ty.dims.last() == Some(&4) && scalar == Scalar::Float;
    let mut comps: Vec<f32> = if value.len() == expected {
        value.to_vec()
    } else if is_point && value.len() == expected / 4 * 3 {
        // x y z per point: append w = 1 to each.
        value.chunks(3).flat_map(|p| [p[0], p[1], p[2], 1.0]).collect()
    } else {
        let mut accepted = vec![expected];
        if is_point {
            accepted.push(expected / 4 * 3);
        }
        return Err(EncodeError::Count {
            given: value.len(),
            expected: accepted,
        });
    };
    // The identity leaves points exactly as given (a NaN in x must not leak into y, z, w
    // through 0 * NaN).
    if is_point && *device_from_object != Mat4::IDENTITY {
        for p in comps.chunks_mut(4) {
            let device = *device_from_object * Vec4::new(p[0], p[1], p[2], p[3]);
            p.copy_from_slice(&device.to_array());
        }
    }
    Ok(comps.iter().map(|&x| encode_scalar(x, scalar)).collect())
}

/// One component as the word a kernel reads for scalar kind `s`.
pub fn encode_scalar(x: f32, s: Scalar) -> u32 {
    match s {
        Scalar::Float => x.to_bits(),
        // `as` saturates and maps NaN to 0: exactly the documented conversion.
        Scalar::Int => (x as i32) as u32,
        Scalar::Bool => u32::from(x != 0.0),
        Scalar::Fixed(format) => {
            if x.is_nan() {
                return 0;
            }
            let (lo, hi) = format.raw_range();
            let raw = (f64::from(x) * format.scale()).round().clamp(lo as f64, hi as f64) as i64;
            // Signed formats are stored sign-extended in the i32 lane; the unsigned
            // fixed<32,32> uses all 32 bits. Truncating the i64 gives both.
            raw as u32
        }
    }
}

/// A parameter default (flattened constants) as words. Points are transformed like given
/// values; a default of the wrong length is padded with zeros or cut (the checker makes it
/// right, this only keeps a malformed program from panicking).
pub fn encode_default(default: &[ConstValue], ty: &Type, space: ParamSpace, device_from_object: &Mat4) -> Vec<u32> {
    let want = ty.fixed_len() as usize;
    if space == ParamSpace::Point {
        let floats: Vec<f32> = default.iter().map(const_as_f32).collect();
        if let Ok(words) = encode(&floats, ty, space, device_from_object) {
            return words;
        }
    }
    let mut words: Vec<u32> = default
        .iter()
        .map(|c| match *c {
            ConstValue::Float(f) => f.to_bits(),
            ConstValue::Int(i) => i as u32,
            ConstValue::Bool(b) => u32::from(b),
            ConstValue::Fixed(raw) => raw as u32,
        })
        .collect();
    words.resize(want, 0);
    words
}

fn const_as_f32(c: &ConstValue) -> f32 {
    match *c {
        ConstValue::Float(f) => f,
        ConstValue::Int(i) => i as f32,
        ConstValue::Bool(b) => f32::from(u8::from(b)),
        ConstValue::Fixed(raw) => raw as f32,
    }
}
