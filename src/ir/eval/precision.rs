//! The precision the evaluator computes floats in ([`Precision`]), and the float
//! arithmetic of each ([`Float`]), so that one generic routine serves both: instantiated at
//! `f32` it is the JIT's sequence of f32 operations, at `f64` the same sequence in f64.
//!
//! A lane word ([`super::Lanes`]) is 64 bits. A float is its f32 bits zero-extended in
//! [`Precision::F32`] and its f64 bits in [`Precision::F64`]; an int, a bool or a fixed
//! value's raw bits is a 32-bit word zero-extended in both.

use crate::jit::libm::LibmFn;
use crate::pipeline::real::Real;

/// What a float lane holds and what float arithmetic computes in.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Precision {
    /// f32, bit for bit as the JIT's kernels compute (the differential oracle).
    #[default]
    F32,
    /// f64: the reference the f32 kernels' shading is measured against (see the module
    /// doc of `ir::eval` for where it still meets f32).
    F64,
}

/// `$body` with the type name `$F` standing for precision `$p`'s [`Float`] type.
macro_rules! in_precision {
    ($p:expr, $F:ident => $body:expr) => {
        match $p {
            $crate::ir::eval::Precision::F32 => {
                type $F = f32;
                $body
            }
            $crate::ir::eval::Precision::F64 => {
                type $F = f64;
                $body
            }
        }
    };
}
pub(crate) use in_precision;

impl Precision {
    /// The lane word of f32 `x` (widened exactly in F64).
    pub(crate) fn from_f32(self, x: f32) -> u64 {
        in_precision!(self, F => F::from_f32(x).word())
    }

    /// The float of lane word `w` rounded to f32 (exact in F32).
    pub(crate) fn to_f32(self, w: u64) -> f32 {
        in_precision!(self, F => F::from_word(w).to_f32())
    }

    pub(crate) fn is_nan(self, w: u64) -> bool {
        in_precision!(self, F => F::from_word(w).is_nan())
    }
}

/// A float type the evaluator computes in: the pipeline's [`Real`] (arithmetic, `ZERO`,
/// `ONE`, `from_f64`, `sqrt`, `abs`) plus its lane words, conversions (Rust's `as`: rounding
/// to nearest, float to int truncated and saturated with NaN to 0, as Cranelift's
/// `fcvt_*_sat`), and the operations the built-ins need.
pub(crate) trait Float: Real {
    fn from_word(w: u64) -> Self;
    fn word(self) -> u64;
    fn from_f32(x: f32) -> Self;
    fn to_f32(self) -> f32;
    fn from_i32(x: i32) -> Self;
    fn from_u32(x: u32) -> Self;
    fn to_i32(self) -> i32;
    fn to_u32(self) -> u32;
    fn to_i64(self) -> i64;
    fn is_nan(self) -> bool;
    fn is_sign_negative(self) -> bool;
    fn floor(self) -> Self;
    fn ceil(self) -> Self;
    fn trunc(self) -> Self;
    fn round_ties_even(self) -> Self;
    /// The transcendental function `func` of `x` (and `y`, its second operand).
    fn libm(func: LibmFn, x: Self, y: Self) -> Self;
}

/// The methods both float types share, by the same names as the types' own.
macro_rules! shared_float_methods {
    ($F:ident) => {
        fn to_i32(self) -> i32 {
            self as i32
        }
        fn to_u32(self) -> u32 {
            self as u32
        }
        fn to_i64(self) -> i64 {
            self as i64
        }
        fn is_nan(self) -> bool {
            $F::is_nan(self)
        }
        fn is_sign_negative(self) -> bool {
            $F::is_sign_negative(self)
        }
        fn floor(self) -> $F {
            $F::floor(self)
        }
        fn ceil(self) -> $F {
            $F::ceil(self)
        }
        fn trunc(self) -> $F {
            $F::trunc(self)
        }
        fn round_ties_even(self) -> $F {
            $F::round_ties_even(self)
        }
    };
}

impl Float for f32 {
    shared_float_methods!(f32);
    fn from_word(w: u64) -> f32 {
        f32::from_bits(w as u32)
    }
    fn word(self) -> u64 {
        u64::from(self.to_bits())
    }
    fn from_f32(x: f32) -> f32 {
        x
    }
    fn to_f32(self) -> f32 {
        self
    }
    fn from_i32(x: i32) -> f32 {
        x as f32
    }
    fn from_u32(x: u32) -> f32 {
        x as f32
    }
    /// The very function kernels call (`jit::libm`): `pow` by repeated squaring for small
    /// integer exponents.
    fn libm(func: LibmFn, x: f32, y: f32) -> f32 {
        func.apply(&[x, y])
    }
}

impl Float for f64 {
    shared_float_methods!(f64);
    fn from_word(w: u64) -> f64 {
        f64::from_bits(w)
    }
    fn word(self) -> u64 {
        self.to_bits()
    }
    fn from_f32(x: f32) -> f64 {
        f64::from(x)
    }
    fn to_f32(self) -> f32 {
        self as f32
    }
    fn from_i32(x: i32) -> f64 {
        f64::from(x)
    }
    fn from_u32(x: u32) -> f64 {
        f64::from(x)
    }
    /// Rust's f64 functions (`pow` is `powf` for every exponent). The noises have no f64
    /// definition: they are the f32 ones on the operands rounded to f32, widened.
    fn libm(func: LibmFn, x: f64, y: f64) -> f64 {
        match func {
            LibmFn::Sin => x.sin(),
            LibmFn::Cos => x.cos(),
            LibmFn::Tan => x.tan(),
            LibmFn::Asin => x.asin(),
            LibmFn::Acos => x.acos(),
            LibmFn::Atan => x.atan(),
            // `atan(y, x)`: the first operand is y, as in `jit::libm`.
            LibmFn::Atan2 => x.atan2(y),
            LibmFn::Pow => x.powf(y),
            LibmFn::Exp => x.exp(),
            LibmFn::Log => x.ln(),
            noise => f64::from(noise.apply(&[x as f32, y as f32])),
        }
    }
}
