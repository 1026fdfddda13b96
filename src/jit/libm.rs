//! Math functions Cranelift has no instruction for, as `extern "C"` Rust functions that the
//! JIT module links kernels against by symbol name: the transcendental functions and the
//! noises of 1 to 4 coordinates ([`crate::ir::noise`]).
//!
//! Every function takes and returns `f32` (one to four arguments) and never panics or traps:
//! out-of-domain inputs give NaN exactly as Rust's `f32` methods do (the noises give no NaN).
//! Vector operands are handled by the lowering, which calls these once per lane. New
//! functions go at the end of [`LibmFn::ALL`]: printed CLIF names an import by its position.

use crate::ir::noise;

/// A libm function a kernel may call.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum LibmFn {
    Sin,
    Cos,
    Tan,
    Asin,
    Acos,
    Atan,
    Atan2,
    Pow,
    Exp,
    Log,
    /// `noise` of 1, 2, 3, 4 coordinates.
    Noise1,
    Noise2,
    Noise3,
    Noise4,
    /// `cellnoise` of 1, 2, 3, 4 coordinates.
    CellNoise1,
    CellNoise2,
    CellNoise3,
    CellNoise4,
}

impl LibmFn {
    pub const ALL: [LibmFn; 18] = [
        LibmFn::Sin,
        LibmFn::Cos,
        LibmFn::Tan,
        LibmFn::Asin,
        LibmFn::Acos,
        LibmFn::Atan,
        LibmFn::Atan2,
        LibmFn::Pow,
        LibmFn::Exp,
        LibmFn::Log,
        LibmFn::Noise1,
        LibmFn::Noise2,
        LibmFn::Noise3,
        LibmFn::Noise4,
        LibmFn::CellNoise1,
        LibmFn::CellNoise2,
        LibmFn::CellNoise3,
        LibmFn::CellNoise4,
    ];

    /// `noise` (or `cellnoise` when `cell`) of `dims` coordinates, 1 to 4.
    pub fn noise(cell: bool, dims: usize) -> Option<LibmFn> {
        use LibmFn::*;
        let all = if cell {
            [CellNoise1, CellNoise2, CellNoise3, CellNoise4]
        } else {
            [Noise1, Noise2, Noise3, Noise4]
        };
        all.get(dims.checked_sub(1)?).copied()
    }

    /// The symbol name kernels import it under.
    pub fn symbol(self) -> &'static str {
        match self {
            LibmFn::Sin => "primflow_sinf",
            LibmFn::Cos => "primflow_cosf",
            LibmFn::Tan => "primflow_tanf",
            LibmFn::Asin => "primflow_asinf",
            LibmFn::Acos => "primflow_acosf",
            LibmFn::Atan => "primflow_atanf",
            LibmFn::Atan2 => "primflow_atan2f",
            LibmFn::Pow => "primflow_powf",
            LibmFn::Exp => "primflow_expf",
            LibmFn::Log => "primflow_logf",
            LibmFn::Noise1 => "primflow_noise1",
            LibmFn::Noise2 => "primflow_noise2",
            LibmFn::Noise3 => "primflow_noise3",
            LibmFn::Noise4 => "primflow_noise4",
            LibmFn::CellNoise1 => "primflow_cellnoise1",
            LibmFn::CellNoise2 => "primflow_cellnoise2",
            LibmFn::CellNoise3 => "primflow_cellnoise3",
            LibmFn::CellNoise4 => "primflow_cellnoise4",
        }
    }

    /// Number of f32 arguments.
    pub fn arity(self) -> usize {
        match self {
            LibmFn::Atan2 | LibmFn::Pow | LibmFn::Noise2 | LibmFn::CellNoise2 => 2,
            LibmFn::Noise3 | LibmFn::CellNoise3 => 3,
            LibmFn::Noise4 | LibmFn::CellNoise4 => 4,
            _ => 1,
        }
    }

    /// The function applied to `args` (its first [`Self::arity`] ones; missing ones are 0):
    /// the very functions kernels call, for the IR evaluator (`ir::eval`), which must give
    /// the same bits.
    pub fn apply(self, args: &[f32]) -> f32 {
        let arg = |i: usize| args.get(i).copied().unwrap_or(0.0);
        let (x, y, z, w) = (arg(0), arg(1), arg(2), arg(3));
        match self {
            LibmFn::Sin => primflow_sinf(x),
            LibmFn::Cos => primflow_cosf(x),
            LibmFn::Tan => primflow_tanf(x),
            LibmFn::Asin => primflow_asinf(x),
            LibmFn::Acos => primflow_acosf(x),
            LibmFn::Atan => primflow_atanf(x),
            LibmFn::Atan2 => primflow_atan2f(x, y),
            LibmFn::Pow => primflow_powf(x, y),
            LibmFn::Exp => primflow_expf(x),
            LibmFn::Log => primflow_logf(x),
            LibmFn::Noise1 => primflow_noise1(x),
            LibmFn::Noise2 => primflow_noise2(x, y),
            LibmFn::Noise3 => primflow_noise3(x, y, z),
            LibmFn::Noise4 => primflow_noise4(x, y, z, w),
            LibmFn::CellNoise1 => primflow_cellnoise1(x),
            LibmFn::CellNoise2 => primflow_cellnoise2(x, y),
            LibmFn::CellNoise3 => primflow_cellnoise3(x, y, z),
            LibmFn::CellNoise4 => primflow_cellnoise4(x, y, z, w),
        }
    }

    /// The function's address, for registering the symbol with the JIT.
    pub fn address(self) -> *const u8 {
        match self {
            LibmFn::Sin => primflow_sinf as *const u8,
            LibmFn::Cos => primflow_cosf as *const u8,
            LibmFn::Tan => primflow_tanf as *const u8,
            LibmFn::Asin => primflow_asinf as *const u8,
            LibmFn::Acos => primflow_acosf as *const u8,
            LibmFn::Atan => primflow_atanf as *const u8,
            LibmFn::Atan2 => primflow_atan2f as *const u8,
            LibmFn::Pow => primflow_powf as *const u8,
            LibmFn::Exp => primflow_expf as *const u8,
            LibmFn::Log => primflow_logf as *const u8,
            LibmFn::Noise1 => primflow_noise1 as *const u8,
            LibmFn::Noise2 => primflow_noise2 as *const u8,
            LibmFn::Noise3 => primflow_noise3 as *const u8,
            LibmFn::Noise4 => primflow_noise4 as *const u8,
            LibmFn::CellNoise1 => primflow_cellnoise1 as *const u8,
            LibmFn::CellNoise2 => primflow_cellnoise2 as *const u8,
            LibmFn::CellNoise3 => primflow_cellnoise3 as *const u8,
            LibmFn::CellNoise4 => primflow_cellnoise4 as *const u8,
        }
    }
}

extern "C" fn primflow_sinf(x: f32) -> f32 {
    x.sin()
}
extern "C" fn primflow_cosf(x: f32) -> f32 {
    x.cos()
}
extern "C" fn primflow_tanf(x: f32) -> f32 {
    x.tan()
}
extern "C" fn primflow_asinf(x: f32) -> f32 {
    x.asin()
}
extern "C" fn primflow_acosf(x: f32) -> f32 {
    x.acos()
}
extern "C" fn primflow_atanf(x: f32) -> f32 {
    x.atan()
}
/// `atan(y, x)`, the angle of the point (x, y).
extern "C" fn primflow_atan2f(y: f32, x: f32) -> f32 {
    y.atan2(x)
}
/// `pow`: by repeated squaring when `y` is an integer of magnitude at most
/// [`POW_INT_MAX`] ([`pow_int`]), else Rust's `powf`.
extern "C" fn primflow_powf(x: f32, y: f32) -> f32 {
    if is_small_int(y) {
        pow_int(x, y)
    } else {
        x.powf(y)
    }
}

/// The largest integer exponent `pow` raises to by repeated squaring.
pub const POW_INT_MAX: f32 = 64.0;

/// `y` is an integer in `[-POW_INT_MAX, POW_INT_MAX]` (NaN is not).
pub fn is_small_int(y: f32) -> bool {
    y.floor() == y && y.abs() <= POW_INT_MAX
}

/// `x^y` for an integer `y` of magnitude at most [`POW_INT_MAX`]: `r = 1`, `b = x`, for each
/// of the 7 bits of `|y|` from the lowest, `r = r * b` when it is set, then `b = b * b`
/// (not after the last); `1 / r` for a negative `y`. The JIT emits exactly these f32
/// operations on vectors when the exponent is uniform (`jit::builtin`), so both give these
/// bits. Each multiply rounds once: `x^n` is within about `2n` ulps (a few for the small
/// exponents of specular highlights), not correctly rounded as `powf` nearly is.
pub fn pow_int(x: f32, y: f32) -> f32 {
    let n = y.abs() as u32;
    let mut r = 1.0f32;
    let mut b = x;
    for bit in 0..POW_INT_BITS {
        if (n >> bit) & 1 == 1 {
            r *= b;
        }
        if bit + 1 < POW_INT_BITS {
            b *= b;
        }
    }
    if y < 0.0 {
        1.0 / r
    } else {
        r
    }
}

/// Bits of the largest exponent [`pow_int`] handles.
pub const POW_INT_BITS: u32 = 7;
extern "C" fn primflow_expf(x: f32) -> f32 {
    x.exp()
}
extern "C" fn primflow_logf(x: f32) -> f32 {
    x.ln()
}

extern "C" fn primflow_noise1(x: f32) -> f32 {
    noise::noise(&[x])
}
extern "C" fn primflow_noise2(x: f32, y: f32) -> f32 {
    noise::noise(&[x, y])
}
extern "C" fn primflow_noise3(x: f32, y: f32, z: f32) -> f32 {
    noise::noise(&[x, y, z])
}
extern "C" fn primflow_noise4(x: f32, y: f32, z: f32, w: f32) -> f32 {
    noise::noise(&[x, y, z, w])
}
extern "C" fn primflow_cellnoise1(x: f32) -> f32 {
    noise::cellnoise(&[x])
}
extern "C" fn primflow_cellnoise2(x: f32, y: f32) -> f32 {
    noise::cellnoise(&[x, y])
}
extern "C" fn primflow_cellnoise3(x: f32, y: f32, z: f32) -> f32 {
    noise::cellnoise(&[x, y, z])
}
extern "C" fn primflow_cellnoise4(x: f32, y: f32, z: f32, w: f32) -> f32 {
    noise::cellnoise(&[x, y, z, w])
}
