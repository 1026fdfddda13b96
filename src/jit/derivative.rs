//! Screen-space derivatives, `Dx`, `Dy` and `filterwidth`, as lane shuffles of a shading
//! group's 2x2 quad of pixels (lanes 0, 1: the upper row, left to right; 2, 3: the lower
//! row). Only shaders take derivatives, and `crate::link` runs every group of a frame whose
//! shaders take one on quads (`runtime::shading::quads`).
//!
//! `Dx` at a lane is the difference across the lane's own row of the quad when both of its
//! pixels execute, else across the other row when both of those do, else 0; `Dy` the same
//! with columns. So a value computed only where a pixel executes never leaks into another
//! pixel's derivative, and a pixel alone in its quad (an edge of the shaded region) gets 0.
//! `ir::eval::derivative` computes the same differences, so the evaluator's bits are the
//! kernels'.
//!
//! Invariant: a uniform operand gives 0 without any instruction on lanes.

use cranelift_codegen::ir::{self, types, InstBuilder};

use super::lower::{Lower, Res};
use super::value::{blend, to_f32x4, to_i32x4, Val, F32X4};
use crate::ir::Builtin;

/// For each lane, the lane whose value it subtracts from (`from`) and the lane it subtracts
/// (`to`), along the quad's rows (`Dx`) or columns (`Dy`); `other` swaps rows (columns).
struct Pairs {
    hi: [u8; 4],
    lo: [u8; 4],
    other: [u8; 4],
}

const ROWS: Pairs = Pairs {
    hi: [1, 1, 3, 3],
    lo: [0, 0, 2, 2],
    other: [2, 3, 0, 1],
};
const COLUMNS: Pairs = Pairs {
    hi: [2, 3, 2, 3],
    lo: [0, 1, 0, 1],
    other: [1, 0, 3, 2],
};

impl<'a, 'b> Lower<'a, 'b> {
    /// `Dx(v)`, `Dy(v)` or `filterwidth(v)` of a float value, per component; `varying`:
    /// the operand's variability in the IR (what the evaluator goes by too).
    pub(super) fn derivative(&mut self, func: Builtin, v: &Val, varying: bool) -> Res<Val> {
        let exec = match (varying, self.exec()) {
            (true, Some(exec)) => exec,
            _ => {
                let zero = self.f32const_here(0.0);
                return Ok(self.fl(vec![zero; v.comps.len()], false));
            }
        };
        let v = self.to_varying(v);
        let mut comps = vec![];
        for &x in &v.comps {
            comps.push(match func {
                Builtin::Dx => self.difference(x, exec, &ROWS),
                Builtin::Dy => self.difference(x, exec, &COLUMNS),
                _ => {
                    let dx = self.difference(x, exec, &ROWS);
                    let dy = self.difference(x, exec, &COLUMNS);
                    let xx = self.b.ins().fmul(dx, dx);
                    let yy = self.b.ins().fmul(dy, dy);
                    let sum = self.b.ins().fadd(xx, yy);
                    self.b.ins().sqrt(sum)
                }
            });
        }
        Ok(self.fl(comps, true))
    }

    fn to_varying(&mut self, v: &Val) -> Val {
        let comps = v
            .comps
            .iter()
            .map(|&c| super::value::splat(&mut self.b, crate::ir::Scalar::Float, c))
            .collect();
        self.fl(comps, true)
    }

    fn difference(&mut self, x: ir::Value, exec: ir::Value, pairs: &Pairs) -> ir::Value {
        let hi = self.lanes(x, pairs.hi);
        let lo = self.lanes(x, pairs.lo);
        let own = self.b.ins().fsub(hi, lo);
        let exec_hi = self.lanes(exec, pairs.hi);
        let exec_lo = self.lanes(exec, pairs.lo);
        let own_ok = self.b.ins().band(exec_hi, exec_lo);
        let other = self.lanes(own, pairs.other);
        let other_ok = self.lanes(own_ok, pairs.other);
        let zero = self.fconst_like(own, 0.0);
        let fallback = blend(&mut self.b, other_ok, other, zero);
        blend(&mut self.b, own_ok, own, fallback)
    }

    /// `v` (f32x4 or i32x4) with lane `i` taken from lane `from[i]`.
    fn lanes(&mut self, v: ir::Value, from: [u8; 4]) -> ir::Value {
        let ty = self.b.func.dfg.value_type(v);
        let bytes: Vec<u8> = from.iter().flat_map(|&l| (0..4).map(move |k| 4 * l + k)).collect();
        let mask = self.b.func.dfg.immediates.push(bytes.into());
        let as_int = to_i32x4(&mut self.b, v);
        let wide = self
            .b
            .ins()
            .bitcast(types::I8X16, super::value::bitcast_flags(), as_int);
        let moved = self.b.ins().shuffle(wide, wide, mask);
        let back = self.b.ins().bitcast(types::I32X4, super::value::bitcast_flags(), moved);
        if ty == F32X4 {
            to_f32x4(&mut self.b, back)
        } else {
            back
        }
    }
}
