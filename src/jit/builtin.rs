//! Built-in functions: native Cranelift instructions where they exist (sqrt, abs, min, max,
//! floor, ceil, nearest — on vectors too), short sequences for the rest (clamp, mix, step,
//! smoothstep, sign, dot, cross, length, normalize, distance), libm calls for the
//! transcendental ones (lane by lane on vectors), the shading ones (faceforward, reflect,
//! refract, noise, cellnoise) in [`super::shading`], and `transform`/`vtransform`/
//! `ntransform` with matrices read from the argument block's `spaces` part.
//!
//! Component-wise built-ins broadcast a single-component argument over the others (the
//! checker allows `mix(a, b, t)` with a scalar `t` over colours).

use cranelift_codegen::ir::{self, condcodes::FloatCC, types, InstBuilder};

use super::libm::LibmFn;
use super::lower::{err, Lower, Res};
use super::value::{blend, Val, F32X4};
use crate::ir::{Builtin, ExprId, Scalar, Space};

/// A 4x4 row-major matrix of uniform f32 values; `None` is the identity.
type Mat = Option<[ir::Value; 16]>;

impl<'a, 'b> Lower<'a, 'b> {
    /// Float constant `x` shaped like `like`: splatted when `like` is a vector.
    pub(super) fn fconst_like(&mut self, like: ir::Value, x: f32) -> ir::Value {
        let c = self.f32const_here(x);
        if self.b.func.dfg.value_type(like).is_vector() {
            self.b.ins().splat(F32X4, c)
        } else {
            c
        }
    }

    /// `mask ? a : b` for a scalar i8 condition or a vector lane mask.
    pub(super) fn fsel(&mut self, mask: ir::Value, a: ir::Value, b: ir::Value) -> ir::Value {
        if self.b.func.dfg.value_type(a).is_vector() {
            blend(&mut self.b, mask, a, b)
        } else {
            self.b.ins().select(mask, a, b)
        }
    }

    /// Bring all operands to one form and length (single components broadcast).
    pub(super) fn unify_all(&mut self, vals: Vec<Val>) -> Res<Vec<Val>> {
        let varying = vals.iter().any(|v| v.varying);
        let len = vals.iter().map(|v| v.comps.len()).max().unwrap_or(0);
        let mut out = vec![];
        for v in vals {
            // A frame word's splat is loaded from the vector section (see `splat_of`).
            let mut v = if varying { self.make_varying(v) } else { v };
            if v.comps.len() != len {
                if v.comps.len() != 1 {
                    return err(format!("built-in operands of {} and {} components", v.comps.len(), len));
                }
                v.comps = vec![v.comps[0]; len];
            }
            out.push(v);
        }
        Ok(out)
    }

    pub(super) fn fl(&self, comps: Vec<ir::Value>, varying: bool) -> Val {
        Val {
            comps,
            scalar: Scalar::Float,
            varying,
        }
    }

    pub(super) fn dot_comps(&mut self, a: &Val, c: &Val) -> ir::Value {
        let mut acc = None;
        for (&x, &y) in a.comps.iter().zip(&c.comps) {
            let p = self.b.ins().fmul(x, y);
            acc = Some(match acc {
                None => p,
                Some(s) => self.b.ins().fadd(s, p),
            });
        }
        match acc {
            Some(v) => v,
            None => {
                let z = self.f32const_here(0.0);
                if a.varying {
                    self.b.ins().splat(F32X4, z)
                } else {
                    z
                }
            }
        }
    }

    pub(crate) fn builtin(&mut self, func: Builtin, args: &'a [ExprId], e: ExprId) -> Res<Val> {
        let _ = e;
        let mut vals = vec![];
        for a in args {
            vals.push(self.eval(*a)?);
        }
        let (fewest, most) = func.arities();
        if !(fewest..=most).contains(&vals.len()) {
            return err(format!("{func:?} with {} arguments", vals.len()));
        }
        // Integer and fixed abs/min/max/clamp stay in their type.
        let sc = vals[0].scalar;
        if matches!(sc, Scalar::Int | Scalar::Fixed(_))
            && matches!(func, Builtin::Abs | Builtin::Min | Builtin::Max | Builtin::Clamp)
            && vals.iter().all(|v| v.scalar == sc)
        {
            return self.int_builtin(func, vals, sc);
        }
        let vals: Vec<Val> = vals.into_iter().map(|v| self.float_val(v)).collect();
        match func {
            Builtin::Faceforward | Builtin::Reflect | Builtin::Refract | Builtin::Noise | Builtin::CellNoise => {
                self.shading_builtin(func, vals)
            }
            Builtin::GBuffer => self.gbuffer_read(&vals[0]),
            Builtin::Texture { slot, wrap } => self.texture(slot, wrap, vals),
            Builtin::Dx | Builtin::Dy | Builtin::FilterWidth => {
                let varying = self.exprs()[args[0]].var.is_varying();
                self.derivative(func, &vals[0], varying)
            }
            Builtin::Sqrt
            | Builtin::Abs
            | Builtin::Floor
            | Builtin::Ceil
            | Builtin::Round
            | Builtin::Sign
            | Builtin::Sin
            | Builtin::Cos
            | Builtin::Tan
            | Builtin::Asin
            | Builtin::Acos
            | Builtin::Atan
            | Builtin::Exp
            | Builtin::Log => {
                let v = &vals[0];
                let mut comps = vec![];
                for &x in &v.comps {
                    comps.push(self.unary_float(func, x)?);
                }
                Ok(self.fl(comps, v.varying))
            }
            Builtin::Pow if vals[0].varying && !vals[1].varying && vals[1].comps.len() == 1 => {
                let y = vals[1].comps[0];
                let mut comps = vec![];
                for &x in &vals[0].comps {
                    comps.push(self.pow_uniform_exponent(x, y)?);
                }
                Ok(self.fl(comps, true))
            }
            Builtin::Min | Builtin::Max | Builtin::Atan2 | Builtin::Pow | Builtin::Step => {
                let vs = self.unify_all(vals)?;
                let mut comps = vec![];
                for i in 0..vs[0].comps.len() {
                    let (x, y) = (vs[0].comps[i], vs[1].comps[i]);
                    comps.push(self.binary_float(func, x, y)?);
                }
                Ok(self.fl(comps, vs[0].varying))
            }
            Builtin::Clamp | Builtin::Mix | Builtin::Smoothstep => {
                let vs = self.unify_all(vals)?;
                let mut comps = vec![];
                for i in 0..vs[0].comps.len() {
                    let (x, y, z) = (vs[0].comps[i], vs[1].comps[i], vs[2].comps[i]);
                    comps.push(self.ternary_float(func, x, y, z));
                }
                Ok(self.fl(comps, vs[0].varying))
            }
            Builtin::Dot => {
                let vs = self.unify_all(vals)?;
                let d = self.dot_comps(&vs[0], &vs[1]);
                Ok(self.fl(vec![d], vs[0].varying))
            }
            Builtin::Length => {
                let v = &vals[0];
                let d = self.dot_comps(v, v);
                let l = self.b.ins().sqrt(d);
                Ok(self.fl(vec![l], v.varying))
            }
            Builtin::Distance => {
                let vs = self.unify_all(vals)?;
                let diff: Vec<ir::Value> = vs[0]
                    .comps
                    .iter()
                    .zip(&vs[1].comps)
                    .map(|(&x, &y)| self.b.ins().fsub(x, y))
                    .collect();
                let d = self.fl(diff, vs[0].varying);
                let dd = self.dot_comps(&d, &d);
                let l = self.b.ins().sqrt(dd);
                Ok(self.fl(vec![l], d.varying))
            }
            Builtin::Normalize => {
                let v = &vals[0];
                let d = self.dot_comps(v, v);
                let l = self.b.ins().sqrt(d);
                let comps = v.comps.iter().map(|&x| self.b.ins().fdiv(x, l)).collect();
                Ok(self.fl(comps, v.varying))
            }
            Builtin::Cross => {
                let vs = self.unify_all(vals)?;
                if vs[0].comps.len() != 3 {
                    return err("cross of non-3-component values");
                }
                let (a, c) = (&vs[0].comps, &vs[1].comps);
                let mut comps = vec![];
                for (i, j) in [(1, 2), (2, 0), (0, 1)] {
                    let p = self.b.ins().fmul(a[i], c[j]);
                    let q = self.b.ins().fmul(a[j], c[i]);
                    comps.push(self.b.ins().fsub(p, q));
                }
                Ok(self.fl(comps, vs[0].varying))
            }
            Builtin::TransformPoint { from, to } => {
                let m = self.space_matrix(to, from);
                self.apply_point(m, &vals[0])
            }
            Builtin::TransformVector { from, to } => {
                let m = self.space_matrix(to, from);
                self.apply_3x3(m, &vals[0], false)
            }
            Builtin::TransformNormal { from, to } => {
                // Inverse transpose of to_from_from = transpose of from_from_to.
                let m = self.space_matrix(from, to);
                self.apply_3x3(m, &vals[0], true)
            }
        }
    }

    /// One component of a two-operand float built-in (min, max, atan2, pow, step).
    /// `pow` of a varying `x` by a uniform `y`: when `y` is a small integer, the vector form
    /// of `libm::pow_int` (a few multiplies for four lanes), else `powf` lane by lane. The
    /// same bits as `primflow_powf` per lane either way.
    fn pow_uniform_exponent(&mut self, x: ir::Value, y: ir::Value) -> Res<ir::Value> {
        let floor = self.b.ins().floor(y);
        let whole = self.b.ins().fcmp(FloatCC::Equal, floor, y);
        let mag = self.b.ins().fabs(y);
        let limit = self.f32const_here(super::libm::POW_INT_MAX);
        let small = self.b.ins().fcmp(FloatCC::LessThanOrEqual, mag, limit);
        let int = self.b.ins().band(whole, small);
        let int_blk = self.b.create_block();
        let call_blk = self.b.create_block();
        let join = self.b.create_block();
        let result = self.b.append_block_param(join, F32X4);
        self.b.ins().brif(int, int_blk, &[], call_blk, &[]);

        self.b.switch_to_block(int_blk);
        let n = self.b.ins().fcvt_to_uint_sat(types::I32, mag);
        let one = self.f32const_here(1.0);
        let mut r = self.b.ins().splat(F32X4, one);
        let mut base = x;
        let bits = super::libm::POW_INT_BITS;
        for bit in 0..bits {
            let shifted = self.b.ins().ushr_imm_u(n, i64::from(bit));
            let set = self.b.ins().band_imm_u(shifted, 1);
            let product = self.b.ins().fmul(r, base);
            r = self.b.ins().select(set, product, r);
            if bit + 1 < bits {
                base = self.b.ins().fmul(base, base);
            }
        }
        let zero = self.f32const_here(0.0);
        let negative = self.b.ins().fcmp(FloatCC::LessThan, y, zero);
        let ones = self.b.ins().splat(F32X4, one);
        let inverse = self.b.ins().fdiv(ones, r);
        let r = self.b.ins().select(negative, inverse, r);
        self.b.ins().jump(join, &[r.into()]);

        self.b.switch_to_block(call_blk);
        let ys = self.b.ins().splat(F32X4, y);
        let r = self.call_libm(LibmFn::Pow, &[x, ys])?;
        self.b.ins().jump(join, &[r.into()]);

        self.b.switch_to_block(join);
        Ok(result)
    }

    fn binary_float(&mut self, func: Builtin, x: ir::Value, y: ir::Value) -> Res<ir::Value> {
        Ok(match func {
            Builtin::Min => self.b.ins().fmin(x, y),
            Builtin::Max => self.b.ins().fmax(x, y),
            Builtin::Atan2 => self.call_libm(LibmFn::Atan2, &[x, y])?,
            Builtin::Pow => self.call_libm(LibmFn::Pow, &[x, y])?,
            _ => {
                // step(edge, x) = x < edge ? 0 : 1
                let lt = self.b.ins().fcmp(FloatCC::LessThan, y, x);
                let zero = self.fconst_like(x, 0.0);
                let one = self.fconst_like(x, 1.0);
                self.fsel(lt, zero, one)
            }
        })
    }

    /// One component of a three-operand float built-in (clamp, mix, smoothstep).
    fn ternary_float(&mut self, func: Builtin, x: ir::Value, y: ir::Value, z: ir::Value) -> ir::Value {
        match func {
            Builtin::Clamp => {
                let m = self.b.ins().fmax(x, y);
                self.b.ins().fmin(m, z)
            }
            Builtin::Mix => {
                let d = self.b.ins().fsub(y, x);
                let p = self.b.ins().fmul(d, z);
                self.b.ins().fadd(x, p)
            }
            _ => {
                // smoothstep(e0, e1, x): t = clamp((x-e0)/(e1-e0), 0, 1); t*t*(3-2t)
                let num = self.b.ins().fsub(z, x);
                let den = self.b.ins().fsub(y, x);
                let t = self.b.ins().fdiv(num, den);
                let zero = self.fconst_like(x, 0.0);
                let one = self.fconst_like(x, 1.0);
                let t = self.b.ins().fmax(t, zero);
                let t = self.b.ins().fmin(t, one);
                let two = self.fconst_like(x, 2.0);
                let three = self.fconst_like(x, 3.0);
                let tt = self.b.ins().fmul(t, t);
                let t2 = self.b.ins().fmul(two, t);
                let k = self.b.ins().fsub(three, t2);
                self.b.ins().fmul(tt, k)
            }
        }
    }

    fn unary_float(&mut self, func: Builtin, x: ir::Value) -> Res<ir::Value> {
        Ok(match func {
            Builtin::Sqrt => self.b.ins().sqrt(x),
            Builtin::Abs => self.b.ins().fabs(x),
            Builtin::Floor => self.b.ins().floor(x),
            Builtin::Ceil => self.b.ins().ceil(x),
            Builtin::Round => self.b.ins().nearest(x),
            Builtin::Sign => {
                let zero = self.fconst_like(x, 0.0);
                let one = self.fconst_like(x, 1.0);
                let minus = self.fconst_like(x, -1.0);
                let gt = self.b.ins().fcmp(FloatCC::GreaterThan, x, zero);
                let lt = self.b.ins().fcmp(FloatCC::LessThan, x, zero);
                let s = self.fsel(lt, minus, zero);
                self.fsel(gt, one, s)
            }
            Builtin::Sin => self.call_libm(LibmFn::Sin, &[x])?,
            Builtin::Cos => self.call_libm(LibmFn::Cos, &[x])?,
            Builtin::Tan => self.call_libm(LibmFn::Tan, &[x])?,
            Builtin::Asin => self.call_libm(LibmFn::Asin, &[x])?,
            Builtin::Acos => self.call_libm(LibmFn::Acos, &[x])?,
            Builtin::Atan => self.call_libm(LibmFn::Atan, &[x])?,
            Builtin::Exp => self.call_libm(LibmFn::Exp, &[x])?,
            Builtin::Log => self.call_libm(LibmFn::Log, &[x])?,
            other => return err(format!("{other:?} is not a unary built-in")),
        })
    }

    fn int_builtin(&mut self, func: Builtin, vals: Vec<Val>, sc: Scalar) -> Res<Val> {
        let unsigned = matches!(sc, Scalar::Fixed(f) if f.is_unsigned());
        let vs = self.unify_all(vals)?;
        let mut comps = vec![];
        for i in 0..vs[0].comps.len() {
            let x = vs[0].comps[i];
            let min = |l: &mut Self, a, c| {
                if unsigned {
                    l.b.ins().umin(a, c)
                } else {
                    l.b.ins().smin(a, c)
                }
            };
            let max = |l: &mut Self, a, c| {
                if unsigned {
                    l.b.ins().umax(a, c)
                } else {
                    l.b.ins().smax(a, c)
                }
            };
            comps.push(match func {
                Builtin::Abs if unsigned => x,
                Builtin::Abs => self.b.ins().iabs(x),
                Builtin::Min => min(self, x, vs[1].comps[i]),
                Builtin::Max => max(self, x, vs[1].comps[i]),
                _ => {
                    let m = max(self, x, vs[1].comps[i]);
                    min(self, m, vs[2].comps[i])
                }
            });
        }
        Ok(Val {
            comps,
            scalar: sc,
            varying: vs[0].varying,
        })
    }

    // ---------------------------------------------------------------- spaces

    /// A matrix of the argument block (through `load_uniform`: at tier 0 a matrix several
    /// transforms use is loaded once per block).
    fn load_matrix(&mut self, word: u32) -> [ir::Value; 16] {
        let args = self.args_ptr();
        std::array::from_fn(|k| self.load_uniform(Scalar::Float, args, ((word + k as u32) * 4) as i32, false, true))
    }

    fn device_from_space(&mut self, s: Space) -> Mat {
        let base = self.spaces_base()?;
        match s {
            Space::Device => None,
            Space::Object => Some(self.load_matrix(base)),
            Space::World => Some(self.load_matrix(base + 16)),
            Space::Lighting => Some(self.load_matrix(base + 32)),
        }
    }

    fn space_from_device(&mut self, s: Space) -> Mat {
        let base = self.spaces_base()?;
        match s {
            Space::Device => None,
            Space::Object => Some(self.load_matrix(base + 48)),
            Space::World => Some(self.load_matrix(base + 64)),
            Space::Lighting => Some(self.load_matrix(base + 80)),
        }
    }

    /// `to_from_from` = to_from_device * device_from_from.
    fn space_matrix(&mut self, to: Space, from: Space) -> Mat {
        if to == from {
            return None;
        }
        let a = self.space_from_device(to);
        let c = self.device_from_space(from);
        match (a, c) {
            (None, m) | (m, None) => m,
            (Some(a), Some(c)) => {
                let mut out = [a[0]; 16];
                for i in 0..4 {
                    for j in 0..4 {
                        let mut acc = self.b.ins().fmul(a[i * 4], c[j]);
                        for k in 1..4 {
                            let p = self.b.ins().fmul(a[i * 4 + k], c[k * 4 + j]);
                            acc = self.b.ins().fadd(acc, p);
                        }
                        out[i * 4 + j] = acc;
                    }
                }
                Some(out)
            }
        }
    }

    fn mat_entry(&mut self, m: &[ir::Value; 16], k: usize, varying: bool) -> ir::Value {
        if varying {
            self.b.ins().splat(F32X4, m[k])
        } else {
            m[k]
        }
    }

    fn apply_point(&mut self, m: Mat, v: &Val) -> Res<Val> {
        let Some(m) = m else { return Ok(v.clone()) };
        let n = v.comps.len();
        if n != 3 && n != 4 {
            return err("transform of a point that has neither 3 nor 4 components");
        }
        let mut comps = vec![];
        for i in 0..n {
            // A 3-component point is taken with w = 1 (no divide afterwards).
            let mut acc = self.mat_entry(&m, i * 4 + 3, v.varying);
            if n == 4 {
                acc = self.fmul(acc, v.comps[3]);
            }
            for j in 0..3 {
                let e = self.mat_entry(&m, i * 4 + j, v.varying);
                let p = self.fmul(e, v.comps[j]);
                acc = self.b.ins().fadd(acc, p);
            }
            comps.push(acc);
        }
        Ok(self.fl(comps, v.varying))
    }

    fn apply_3x3(&mut self, m: Mat, v: &Val, transpose: bool) -> Res<Val> {
        let Some(m) = m else { return Ok(v.clone()) };
        if v.comps.len() < 3 {
            return err("transform of a direction with fewer than 3 components");
        }
        let mut comps = vec![];
        for i in 0..3 {
            let mut acc = None;
            for j in 0..3 {
                let k = if transpose { j * 4 + i } else { i * 4 + j };
                let e = self.mat_entry(&m, k, v.varying);
                let p = self.fmul(e, v.comps[j]);
                acc = Some(match acc {
                    None => p,
                    Some(s) => self.b.ins().fadd(s, p),
                });
            }
            comps.push(acc.expect("three terms"));
        }
        // A homogeneous direction keeps its w.
        comps.extend_from_slice(&v.comps[3..]);
        Ok(self.fl(comps, v.varying))
    }
}
