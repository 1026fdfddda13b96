//! `Dx`, `Dy` and `filterwidth` over a group's 2x2 quad of pixels, as `jit::derivative`
//! emits them: the difference across the lane's own row (column) of the quad when both of
//! its pixels execute, else across the other row (column) when both of those do, else 0;
//! 0 for a uniform operand. Same operations in the same order in the run's precision: the
//! same bits as the JIT in f32, the f64 differences in f64.

use super::expr::Val;
use super::precision::{in_precision, Float, Precision};
use super::{Lanes, Mask};
use crate::ir::{Builtin, Scalar};

/// (hi, lo, other) lanes along rows (`Dx`) and columns (`Dy`), as in `jit::derivative`.
const ROWS: ([usize; 4], [usize; 4], [usize; 4]) = ([1, 1, 3, 3], [0, 0, 2, 2], [2, 3, 0, 1]);
const COLUMNS: ([usize; 4], [usize; 4], [usize; 4]) = ([2, 3, 2, 3], [0, 1, 0, 1], [1, 0, 3, 2]);

/// `func` (one of the three) of float value `v` under `exec` in precision `p`; `varying`:
/// the operand is varying pixel code.
pub(super) fn derivative(p: Precision, func: Builtin, v: &Val, varying: bool, exec: Mask) -> Val {
    in_precision!(p, F => derivative_in::<F>(func, v, varying, exec))
}

fn derivative_in<F: Float>(func: Builtin, v: &Val, varying: bool, exec: Mask) -> Val {
    let comps = v
        .comps
        .iter()
        .map(|x| {
            if !varying {
                return [F::ZERO.word(); 4];
            }
            match func {
                Builtin::Dx => difference::<F>(x, exec, ROWS),
                Builtin::Dy => difference::<F>(x, exec, COLUMNS),
                _ => {
                    let (dx, dy) = (difference::<F>(x, exec, ROWS), difference::<F>(x, exec, COLUMNS));
                    std::array::from_fn(|l| {
                        let (a, b) = (F::from_word(dx[l]), F::from_word(dy[l]));
                        (a * a + b * b).sqrt().word()
                    })
                }
            }
        })
        .collect();
    Val {
        comps,
        sc: Scalar::Float,
    }
}

fn difference<F: Float>(x: &Lanes, exec: Mask, (hi, lo, other): ([usize; 4], [usize; 4], [usize; 4])) -> Lanes {
    let own: [F; 4] = std::array::from_fn(|l| F::from_word(x[hi[l]]) - F::from_word(x[lo[l]]));
    let own_ok: Mask = std::array::from_fn(|l| exec[hi[l]] && exec[lo[l]]);
    std::array::from_fn(|l| {
        let d = if own_ok[l] {
            own[l]
        } else if own_ok[other[l]] {
            own[other[l]]
        } else {
            F::ZERO
        };
        d.word()
    })
}
