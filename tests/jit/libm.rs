//! The libm functions kernels call (src/jit/libm.rs), through the very addresses the JIT
//! registers for their symbols: `atan2` takes y first, as the language's `atan(y, x)`.

use std::f32::consts::FRAC_PI_2;

use primflow::jit::libm::LibmFn;

#[test]
fn atan2_takes_y_first() {
    // SAFETY: `address` is the symbol the JIT calls: an `extern "C"` function of `arity`
    // f32 arguments returning f32.
    let atan2: extern "C" fn(f32, f32) -> f32 = unsafe { std::mem::transmute(LibmFn::Atan2.address()) };
    let log: extern "C" fn(f32) -> f32 = unsafe { std::mem::transmute(LibmFn::Log.address()) };
    assert_eq!(atan2(1.0, 0.0), FRAC_PI_2);
    assert_eq!(LibmFn::Atan2.arity(), 2);
    assert!(log(-1.0).is_nan());
}
