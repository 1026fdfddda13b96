//! Math functions Cranelift has no instruction for, as `extern "C"` Rust functions that the
//! JIT module links kernels against by symbol name.
//!
//! Every function takes and returns `f32` (one or two arguments) and never panics or traps:
//! out-of-domain inputs give NaN exactly as Rust's `f32` methods do. Vector operands are
//! handled by the lowering, which calls these once per lane.

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
}

impl LibmFn {
    pub const ALL: [LibmFn; 10] = [
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
    ];

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
        }
    }

    /// Number of f32 arguments.
    pub fn arity(self) -> usize {
        match self {
            LibmFn::Atan2 | LibmFn::Pow => 2,
            _ => 1,
        }
    }

    /// The function applied to `args` (`args[1]` is read only by the two-argument ones):
    /// the very functions kernels call, for the IR evaluator (`ir::eval`), which must give
    /// the same bits.
    pub fn apply(self, args: [f32; 2]) -> f32 {
        let [x, y] = args;
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
extern "C" fn primflow_powf(x: f32, y: f32) -> f32 {
    x.powf(y)
}
extern "C" fn primflow_expf(x: f32) -> f32 {
    x.exp()
}
extern "C" fn primflow_logf(x: f32) -> f32 {
    x.ln()
}
