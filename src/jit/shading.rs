//! The shading built-ins: `faceforward`, `reflect` and `refract` as short sequences of f32
//! instructions (on vectors too), and `noise`/`cellnoise` as calls of the Rust functions of
//! [`crate::ir::noise`] through [`LibmFn`], lane by lane on vectors.
//!
//! The noises call out rather than emit their arithmetic: one Rust function then defines
//! them for both tiers and for the IR evaluator, bit for bit, with the same guard against
//! NaN, infinite and huge coordinates, at the price of four calls per varying group.
//! `ir::eval::shading` performs the same f32 operations as the sequences here, in the
//! same order, so the evaluator's values are the kernels' bits.
//!
//! Invariant: the checker gives these built-ins float operands of the shapes
//! `ir::valid` states; anything else is a `JitError`, never a panic.

use cranelift_codegen::ir::{self, condcodes::FloatCC, InstBuilder};

use super::libm::LibmFn;
use super::lower::{err, Lower, Res};
use super::value::Val;
use crate::ir::Builtin;

impl<'a, 'b> Lower<'a, 'b> {
    /// A shading built-in of float operands.
    pub(super) fn shading_builtin(&mut self, func: Builtin, vals: Vec<Val>) -> Res<Val> {
        if matches!(func, Builtin::Noise | Builtin::CellNoise) {
            return self.noise(func == Builtin::CellNoise, vals);
        }
        // `refract`'s eta is broadcast over three components (only the first is read).
        let vs = self.unify_all(vals)?;
        if vs.iter().any(|v| v.comps.len() != 3) {
            return err(format!("{func:?} of operands that are not float[3]"));
        }
        let varying = vs[0].varying;
        let comps = match func {
            Builtin::Faceforward => self.faceforward(&vs),
            Builtin::Reflect => self.reflect(&vs),
            Builtin::Refract => self.refract(&vs),
            other => return err(format!("{other:?} is not a shading built-in")),
        };
        Ok(self.fl(comps, varying))
    }

    /// `N` where `dot(Nref, I) < 0`, else `-N` (`Nref` = `N` without a third operand).
    fn faceforward(&mut self, vs: &[Val]) -> Vec<ir::Value> {
        let (n, i) = (&vs[0], &vs[1]);
        let nref = vs.get(2).unwrap_or(n);
        let d = self.dot_comps(nref, i);
        let zero = self.fconst_like(d, 0.0);
        let facing = self.b.ins().fcmp(FloatCC::LessThan, d, zero);
        n.comps
            .iter()
            .map(|&x| {
                let flipped = self.b.ins().fneg(x);
                self.fsel(facing, x, flipped)
            })
            .collect()
    }

    /// `I - (d + d) N` with `d = dot(N, I)`.
    fn reflect(&mut self, vs: &[Val]) -> Vec<ir::Value> {
        let (i, n) = (&vs[0], &vs[1]);
        let d = self.dot_comps(n, i);
        let s = self.b.ins().fadd(d, d);
        (0..3)
            .map(|k| {
                let p = self.b.ins().fmul(s, n.comps[k]);
                self.b.ins().fsub(i.comps[k], p)
            })
            .collect()
    }

    /// With `d = dot(N, I)`, `k = 1 - eta² (1 - d²)`: zero where `k < 0`, else
    /// `eta I - (eta d + √k) N`.
    fn refract(&mut self, vs: &[Val]) -> Vec<ir::Value> {
        let (i, n, e) = (&vs[0], &vs[1], vs[2].comps[0]);
        let d = self.dot_comps(n, i);
        let one = self.fconst_like(d, 1.0);
        let zero = self.fconst_like(d, 0.0);
        let ee = self.b.ins().fmul(e, e);
        let dd = self.b.ins().fmul(d, d);
        let om = self.b.ins().fsub(one, dd);
        let t = self.b.ins().fmul(ee, om);
        let k = self.b.ins().fsub(one, t);
        let total = self.b.ins().fcmp(FloatCC::LessThan, k, zero);
        let root = self.b.ins().sqrt(k);
        let ed = self.b.ins().fmul(e, d);
        let c = self.b.ins().fadd(ed, root);
        (0..3)
            .map(|j| {
                let a = self.b.ins().fmul(e, i.comps[j]);
                let b = self.b.ins().fmul(c, n.comps[j]);
                let r = self.b.ins().fsub(a, b);
                self.fsel(total, zero, r)
            })
            .collect()
    }

    /// `noise`/`cellnoise` of the operands' components (at most 3 of an aggregate: a
    /// point's w is not a coordinate), all varying when one is.
    fn noise(&mut self, cell: bool, vals: Vec<Val>) -> Res<Val> {
        let varying = vals.iter().any(|v| v.varying);
        let mut coords = vec![];
        for v in vals {
            let v = if varying { self.make_varying(v) } else { v };
            coords.extend(v.comps.iter().take(3).copied());
        }
        let Some(f) = LibmFn::noise(cell, coords.len()) else {
            return err(format!("noise of {} coordinates", coords.len()));
        };
        let r = self.call_libm(f, &coords)?;
        Ok(self.fl(vec![r], varying))
    }
}
