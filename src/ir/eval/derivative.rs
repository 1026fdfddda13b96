//! `Dx`, `Dy` and `filterwidth` over a group's 2x2 quad of pixels, as `jit::derivative`
//! emits them: the difference across the lane's own row (column) of the quad when both of
//! its pixels execute, else across the other row (column) when both of those do, else 0;
//! 0 for a uniform operand. Same f32 operations in the same order, so the same bits.

use super::expr::Val;
use super::{Lanes, Mask};
use crate::ir::{Builtin, Scalar};

/// (hi, lo, other) lanes along rows (`Dx`) and columns (`Dy`), as in `jit::derivative`.
const ROWS: ([usize; 4], [usize; 4], [usize; 4]) = ([1, 1, 3, 3], [0, 0, 2, 2], [2, 3, 0, 1]);
const COLUMNS: ([usize; 4], [usize; 4], [usize; 4]) = ([2, 3, 2, 3], [0, 1, 0, 1], [1, 0, 3, 2]);

/// `func` (one of the three) of float value `v` under `exec`; `varying`: the operand is
/// varying pixel code.
pub(super) fn derivative(func: Builtin, v: &Val, varying: bool, exec: Mask) -> Val {
    let comps = v
        .comps
        .iter()
        .map(|x| {
            if !varying {
                return [0f32.to_bits(); 4];
            }
            match func {
                Builtin::Dx => difference(x, exec, ROWS),
                Builtin::Dy => difference(x, exec, COLUMNS),
                _ => {
                    let (dx, dy) = (difference(x, exec, ROWS), difference(x, exec, COLUMNS));
                    std::array::from_fn(|l| {
                        let (a, b) = (f32::from_bits(dx[l]), f32::from_bits(dy[l]));
                        (a * a + b * b).sqrt().to_bits()
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

fn difference(x: &Lanes, exec: Mask, (hi, lo, other): ([usize; 4], [usize; 4], [usize; 4])) -> Lanes {
    let own: [f32; 4] = std::array::from_fn(|l| f32::from_bits(x[hi[l]]) - f32::from_bits(x[lo[l]]));
    let own_ok: Mask = std::array::from_fn(|l| exec[hi[l]] && exec[lo[l]]);
    std::array::from_fn(|l| {
        let d = if own_ok[l] {
            own[l]
        } else if own_ok[other[l]] {
            own[other[l]]
        } else {
            0.0
        };
        d.to_bits()
    })
}
