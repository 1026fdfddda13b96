//! Expressions and places: [`Machine::eval`] computes an expression's components in every
//! lane, [`Machine::assign`] stores into a place, as `jit::lower`'s `expr`, `storage` and
//! `builtin` do.
//!
//! Invariants: a value holds the components of its type as the JIT's `Val` does, as lane
//! words of the run's precision ([`super::precision`]):
//! interpolation data only the current view's components (a local or parameter of it holds
//! all of them per element, and reading it gathers the view); single components broadcast
//! over the other operand's. Every index is clamped per lane into its array, and the error
//! counted when an executing lane was out of range ([`Machine::exec`] is narrowed to the
//! lanes that take an arm of `?:` or the right side of `&&`/`||` while it is evaluated).

use super::precision::{in_precision, Float, Precision};
use super::scalar::{self, arity, convert_lane, float_builtin, int_builtin};
use super::{any, malformed, Lanes, Machine, Res};
use crate::abi::{ParamSlot, ERR_INDEX};
use crate::ir::{
    BinOp, Builtin, ConstValue, Elem, ExprId, ExprKind, LocalId, Place, Scalar, SiteId, Space, Type, UnaryOp,
};

/// A value: its components, each in every lane, of one scalar type.
#[derive(Clone, Debug)]
pub(crate) struct Val {
    pub comps: Vec<Lanes>,
    pub sc: Scalar,
}

impl Val {
    fn map(&self, sc: Scalar, f: impl Fn(u64) -> u64) -> Val {
        Val {
            comps: self.comps.iter().map(|c| c.map(&f)).collect(),
            sc,
        }
    }

    /// Every component converted to `to` in precision `p`.
    pub(crate) fn converted(&self, to: Scalar, p: Precision) -> Val {
        let from = self.sc;
        self.map(to, |w| convert_lane(p, from, to, w))
    }
}

/// The scalar type of a type's components (interpolation data is float).
pub(crate) fn elem_scalar(ty: &Type) -> Scalar {
    match ty.elem {
        Elem::Scalar(s) => s,
        Elem::Interp => Scalar::Float,
    }
}

/// Where an access reads from.
enum Root {
    Local(usize),
    /// The frame's argument block from this word.
    Args(usize),
    Temp(Val),
}

/// A (possibly indexed) value not yet read: per lane, the offset of its first component.
struct Access {
    root: Root,
    elem: Elem,
    dims: Vec<u32>,
    per_seq: bool,
    sc: Scalar,
    base: [usize; 4],
    /// Interpolation data holds only the view's components (a computed value).
    compact: bool,
}

fn fixed_len(dims: &[u32]) -> usize {
    dims.iter().map(|&d| d as usize).product()
}

fn bools(v: &Val, p: Precision) -> Res<Lanes> {
    match v.comps.first() {
        Some(c) => Ok(c.map(|w| convert_lane(p, v.sc, Scalar::Bool, w))),
        None => malformed("a condition without components"),
    }
}

impl Machine<'_, '_> {
    /// Components of one value of `fixed_len` elements of `elem` (`compact`: interpolation
    /// data holds only the view).
    fn value_comps(&self, elem: Elem, fixed_len: usize, compact: bool) -> usize {
        match elem {
            Elem::Scalar(_) => fixed_len,
            Elem::Interp => {
                fixed_len
                    * if compact {
                        self.view.len()
                    } else {
                        self.n_interp as usize
                    }
            }
        }
    }

    /// Offsets of the components such a value shows (interpolation data: the view's).
    fn comp_offsets(&self, elem: Elem, fixed_len: usize, compact: bool) -> Vec<usize> {
        match elem {
            Elem::Scalar(_) => (0..fixed_len).collect(),
            Elem::Interp => {
                let per = if compact {
                    self.view.len()
                } else {
                    self.n_interp as usize
                };
                let mut out = Vec::with_capacity(fixed_len * self.view.len());
                for e in 0..fixed_len {
                    for (j, &v) in self.view.iter().enumerate() {
                        out.push(e * per + if compact { j } else { v as usize });
                    }
                }
                out
            }
        }
    }

    /// The number of sequence points as indices see it (at least 1).
    fn seq_len(&self) -> Res<u32> {
        Ok(self.frame()?.args.n_seq().max(1))
    }

    fn local_access(&self, local: LocalId) -> Res<Access> {
        let fr = self.frame()?;
        let i = local.0 as usize;
        let Some(l) = fr.func.locals.get(i) else {
            return malformed(format!("unknown local {i}"));
        };
        let slot = fr
            .func
            .params
            .iter()
            .position(|p| p.local == local)
            .map(|p| &fr.slots[p]);
        let root = match slot {
            Some(ParamSlot::Fixed { offset, .. }) => Root::Args(*offset as usize),
            Some(ParamSlot::Seq { seq_offset, .. }) => {
                let n = self.seq_len()? as usize;
                Root::Args(fr.fixed_words as usize + n * *seq_offset as usize)
            }
            Some(ParamSlot::Pixel) | None => Root::Local(i),
        };
        Ok(Access {
            root,
            elem: l.ty.elem,
            dims: l.ty.dims.clone(),
            per_seq: l.ty.per_seq,
            sc: elem_scalar(&l.ty),
            base: [0; 4],
            compact: false,
        })
    }

    fn resolve(&mut self, e_id: ExprId) -> Res<Access> {
        let e = &self.exprs()[e_id];
        match &e.kind {
            ExprKind::Local(l) => self.local_access(*l),
            ExprKind::Index { base, index, site } => {
                self.enter()?;
                let acc = self.resolve(*base);
                let acc = acc.and_then(|acc| self.index_access(acc, *index, *site));
                self.leave();
                acc
            }
            _ => {
                let v = self.eval(e_id)?;
                Ok(Access {
                    sc: v.sc,
                    root: Root::Temp(v),
                    elem: e.ty.elem,
                    dims: e.ty.dims.clone(),
                    per_seq: e.ty.per_seq,
                    base: [0; 4],
                    compact: true,
                })
            }
        }
    }

    /// Apply one index: clamped per lane, `ERR_INDEX` counted at `site` when an executing
    /// lane was out of range.
    fn index_access(&mut self, mut acc: Access, index_id: ExprId, site: SiteId) -> Res<Access> {
        let index = &self.exprs()[index_id];
        if acc.dims.is_empty() && !acc.per_seq {
            return malformed("indexing a scalar");
        }
        let (len, elem_dims) = if acc.per_seq {
            (self.seq_len()?, acc.dims.clone())
        } else {
            (acc.dims[0], acc.dims[1..].to_vec())
        };
        let stride = self.value_comps(acc.elem, fixed_len(&elem_dims), acc.compact);
        let idx = self.eval(index_id)?;
        let Some(&lanes) = idx.comps.first() else {
            return malformed("an index without components");
        };
        let p = self.precision;
        let idx: [u32; 4] = lanes.map(|w| convert_lane(p, idx.sc, Scalar::Int, w) as u32);
        // A uniform index of pixel code fails for the group as the JIT checks it: once,
        // when some lane executes it, under the guards of the arms around it; a varying one
        // where an executing lane is out of range.
        let failed = if self.pix.is_some() && !index.var.is_varying() {
            self.guard && idx[0] >= len && any(self.exec)
        } else {
            self.guard && (0..4).any(|l| idx[l] >= len && self.exec[l])
        };
        if failed {
            self.record(ERR_INDEX, site.0, true)?;
        }
        for (base, &i) in acc.base.iter_mut().zip(&idx) {
            *base += (i as i32).clamp(0, len as i32 - 1) as usize * stride;
        }
        acc.dims = elem_dims;
        acc.per_seq = false;
        Ok(acc)
    }

    /// Component `at` of `root` in `lane`, a lane word of scalar type `sc`.
    fn word(&self, root: &Root, at: usize, lane: usize, sc: Scalar) -> Res<u64> {
        let got = match root {
            Root::Local(i) => self.frame()?.locals.get(*i).and_then(|v| v.get(at)).map(|c| c[lane]),
            Root::Args(start) => self
                .frame()?
                .args
                .lane_word(start + at, sc == Scalar::Float, self.precision),
            Root::Temp(v) => v.comps.get(at).map(|c| c[lane]),
        };
        match got {
            Some(w) => Ok(w),
            None => malformed("a read past its storage (argument block too short?)"),
        }
    }

    fn read(&self, acc: &Access) -> Res<Val> {
        let offs = self.comp_offsets(acc.elem, fixed_len(&acc.dims), acc.compact);
        let mut comps = Vec::with_capacity(offs.len());
        for o in offs {
            let mut c = [0; 4];
            for (l, w) in c.iter_mut().enumerate() {
                *w = self.word(&acc.root, acc.base[l] + o, l, acc.sc)?;
            }
            comps.push(c);
        }
        Ok(Val { comps, sc: acc.sc })
    }

    /// `place = value`, converted to the place's type (`Lower::assign`): indices first,
    /// then the value; a varying local takes the executing lanes only, a uniform one every
    /// lane; the primitive's Z also marks the lanes that wrote it.
    pub(crate) fn assign(&mut self, place: &Place, value: ExprId) -> Res<()> {
        let mut acc = self.local_access(place.local)?;
        for (idx, site) in &place.indices {
            acc = self.index_access(acc, *idx, *site)?;
        }
        let Root::Local(li) = acc.root else {
            return malformed("assignment to a parameter");
        };
        let v = self.eval(value)?.converted(acc.sc, self.precision);
        let offs = self.comp_offsets(acc.elem, fixed_len(&acc.dims), false);
        let comps = if v.comps.len() == 1 && offs.len() != 1 {
            vec![v.comps[0]; offs.len()]
        } else {
            v.comps
        };
        if comps.len() != offs.len() {
            return malformed(format!(
                "assignment of {} components to a place of {}",
                comps.len(),
                offs.len()
            ));
        }
        let fr = self.frame()?;
        let varying = fr.func.locals[li].var.is_varying() && self.pix.is_some();
        let is_z = fr.interp_binding.is_none()
            && fr
                .func
                .params
                .iter()
                .any(|p| p.local.0 as usize == li && p.role == crate::ir::ParamRole::Z);
        let exec = self.exec;
        let Some(frame) = self.frames.last_mut() else {
            return malformed("no frame");
        };
        let store = &mut frame.locals[li];
        for (o, c) in offs.iter().zip(comps) {
            for l in 0..4 {
                if varying && !exec[l] {
                    continue;
                }
                match store.get_mut(acc.base[l] + o) {
                    Some(slot) => slot[l] = c[l],
                    None => return malformed("a store past its local"),
                }
            }
        }
        if is_z {
            if let Some(p) = &mut self.pix {
                p.z_written = std::array::from_fn(|l| p.z_written[l] || exec[l]);
            }
        }
        if let Some(l) = self.watched_lane() {
            let fr = self.frame()?;
            let func = fr.func;
            // At most 16 components: the observer gets the local's type for the rest.
            let words: Vec<u64> = fr.locals[li].iter().take(16).map(|c| c[l]).collect();
            let total = fr.locals[li].len();
            self.notify(super::Event::Assign {
                func,
                local: crate::ir::LocalId(li as u32),
                sc: acc.sc,
                words: &words,
                total,
                varying,
            });
        }
        Ok(())
    }

    /// `e` evaluated for the lanes where the bool `cond` is `taken` (an arm of `?:`, the
    /// right side of `&&`/`||`): their errors only are counted.
    fn eval_guarded(&mut self, e: ExprId, cond: Lanes, varying: bool, taken: bool) -> Res<Val> {
        let (outer, outer_guard) = (self.exec, self.guard);
        self.exec = std::array::from_fn(|l| outer[l] && (cond[l] != 0) == taken);
        self.guard &= if varying {
            any(self.exec)
        } else {
            (cond[0] != 0) == taken
        };
        let v = self.eval(e);
        self.exec = outer;
        self.guard = outer_guard;
        v
    }

    pub(crate) fn eval(&mut self, e: ExprId) -> Res<Val> {
        self.enter()?;
        let v = self.eval_inner(e);
        self.leave();
        v
    }

    fn eval_inner(&mut self, e_id: ExprId) -> Res<Val> {
        let e = &self.exprs()[e_id];
        let sc = elem_scalar(&e.ty);
        let p = self.precision;
        match &e.kind {
            ExprKind::Const(c) => {
                let (from, w) = match *c {
                    ConstValue::Float(x) => (Scalar::Float, p.from_f32(x)),
                    ConstValue::Int(i) => (Scalar::Int, u64::from(i as u32)),
                    ConstValue::Bool(b) => (Scalar::Bool, u64::from(b)),
                    ConstValue::Fixed(i) => (sc, u64::from(i as u32)),
                };
                Ok(Val {
                    comps: vec![[convert_lane(p, from, sc, w); 4]],
                    sc,
                })
            }
            ExprKind::Local(_) | ExprKind::Index { .. } => {
                let acc = self.resolve(e_id)?;
                self.read(&acc)
            }
            ExprKind::Unary { op, expr } => {
                let v = self.eval(*expr)?;
                Ok(match op {
                    UnaryOp::Neg => v.map(v.sc, |w| scalar::neg_lane(p, v.sc, w)),
                    UnaryOp::Not => v.map(Scalar::Bool, |w| convert_lane(p, v.sc, Scalar::Bool, w) ^ 1),
                })
            }
            ExprKind::Binary { op, lhs, rhs } => {
                let a = self.eval(*lhs)?;
                let c = match op {
                    BinOp::And | BinOp::Or if a.sc == Scalar::Bool => {
                        let cond = bools(&a, p)?;
                        self.eval_guarded(*rhs, cond, self.exprs()[*lhs].var.is_varying(), *op == BinOp::And)?
                    }
                    _ => self.eval(*rhs)?,
                };
                binary(p, *op, a, c)
            }
            ExprKind::Convert(inner) => {
                let v = self.eval(*inner)?.converted(sc, p);
                if e.ty.elem == Elem::Interp && self.exprs()[*inner].ty.elem != Elem::Interp && v.comps.len() == 1 {
                    let n = self.comp_offsets(e.ty.elem, fixed_len(&e.ty.dims), true).len();
                    return Ok(Val {
                        comps: vec![v.comps[0]; n],
                        sc,
                    });
                }
                Ok(v)
            }
            ExprKind::Select { cond, then, otherwise } => {
                let c = bools(&self.eval(*cond)?, p)?;
                let varying = self.exprs()[*cond].var.is_varying();
                let t = self.eval_guarded(*then, c, varying, true)?;
                let o = self.eval_guarded(*otherwise, c, varying, false)?;
                let (t, o) = unify(t, o)?;
                let comps = t
                    .comps
                    .iter()
                    .zip(&o.comps)
                    .map(|(x, y)| std::array::from_fn(|l| if c[l] != 0 { x[l] } else { y[l] }))
                    .collect();
                Ok(Val { comps, sc: t.sc })
            }
            ExprKind::Builtin { func, args } => self.builtin(*func, args),
            ExprKind::List(items) => {
                let mut comps = vec![];
                for it in items {
                    comps.extend(self.eval(*it)?.converted(sc, p).comps);
                }
                Ok(Val { comps, sc })
            }
            ExprKind::Splat(item) => {
                let one = self.eval(*item)?.converted(sc, p).comps;
                let n = fixed_len(&e.ty.dims);
                if one.len().saturating_mul(n) > 1 << 26 {
                    return Err(super::EvalError::Unsupported("a splat of over 2^26 components".into()));
                }
                Ok(Val {
                    comps: one.repeat(n),
                    sc,
                })
            }
            ExprKind::MatMul { lhs, rhs } => {
                let a = self.eval(*lhs)?.converted(Scalar::Float, p);
                let c = self.eval(*rhs)?.converted(Scalar::Float, p);
                let (ldims, rdims) = (&self.exprs()[*lhs].ty.dims, &self.exprs()[*rhs].ty.dims);
                in_precision!(p, F => matmul::<F>(&a, &c, ldims, rdims))
            }
            ExprKind::SeqCount => {
                let n = u64::from(self.frame()?.args.n_seq());
                Ok(Val {
                    comps: vec![[n; 4]],
                    sc: Scalar::Int,
                })
            }
            ExprKind::ClipFlag => Ok(Val {
                comps: vec![[u64::from(!self.key.trivial_accept); 4]],
                sc: Scalar::Bool,
            }),
        }
    }

    /// `__gbuffer(plane, X, Y)` at the group's pixels, as `jit::lower::planes` reads it: the
    /// plane number converted saturating, a plane the tile lacks (or a lane outside the
    /// tile's buffers) reads 0; the plane's f32 widened to the run's precision.
    fn gbuffer_read(&self, plane: &Val) -> Res<Val> {
        let Some((gx, y)) = self.pix.as_ref().map(|p| (p.gx, p.y)) else {
            return malformed("`__gbuffer` outside per-pixel code");
        };
        let Some(k) = plane.comps.first() else {
            return malformed("`__gbuffer` without a plane");
        };
        // `fcvt_to_uint_sat`: NaN and negatives to 0, the rest truncated and saturated.
        let p = self.precision;
        let k = in_precision!(p, F => F::from_word(k[0]).to_u32()) as usize;
        let lanes = std::array::from_fn(|l| match self.tile.index(gx + l as i32, y) {
            Some(i) if k < self.tile.num_planes => p.from_f32(self.tile.planes[k * self.tile.plane_stride + i]),
            _ => 0,
        });
        Ok(Val {
            comps: vec![lanes],
            sc: Scalar::Float,
        })
    }

    /// `texture`: `TextureSet::sample` per lane, as the kernels' `primflow_texture` calls
    /// it; black without a loaded set (a uniform result is the same in every lane). The
    /// sampler is f32: it takes the operands rounded to f32, its result is widened.
    fn texture(&self, slot: u32, wrap: u32, vals: &[Val]) -> Val {
        use crate::runtime::texture::Wrap;
        let p = self.precision;
        let arg = |k: usize, l: usize| {
            vals.get(k)
                .and_then(|v| v.comps.first())
                .map_or(0.0, |c| p.to_f32(c[l]))
        };
        let mut comps = vec![[0u64; 4]; 3];
        if let Some((set, id)) = self.program.textures.lookup(slot) {
            for l in 0..4 {
                let a = |k| arg(k, l);
                let rgb = set.sample(id, Wrap::from_u32(wrap), a(0), a(1), a(2), a(3), a(4), a(5));
                for c in 0..3 {
                    comps[c][l] = p.from_f32(rgb[c]);
                }
            }
        }
        Val {
            comps,
            sc: Scalar::Float,
        }
    }

    fn builtin(&mut self, func: Builtin, args: &[ExprId]) -> Res<Val> {
        let mut vals = vec![];
        for a in args {
            vals.push(self.eval(*a)?);
        }
        let (fewest, most) = func.arities();
        if !(fewest..=most).contains(&vals.len()) {
            return malformed(format!("{func:?} with {} arguments", vals.len()));
        }
        let sc = vals[0].sc;
        if matches!(sc, Scalar::Int | Scalar::Fixed(_))
            && matches!(func, Builtin::Abs | Builtin::Min | Builtin::Max | Builtin::Clamp)
            && vals.iter().all(|v| v.sc == sc)
        {
            let vs = unify_all(vals)?;
            return Ok(componentwise(&vs, sc, |a| int_builtin(func, sc, a)));
        }
        let p = self.precision;
        let vals: Vec<Val> = vals.iter().map(|v| v.converted(Scalar::Float, p)).collect();
        if func == Builtin::GBuffer {
            return self.gbuffer_read(&vals[0]);
        }
        if let Builtin::Texture { slot, wrap } = func {
            return Ok(self.texture(slot, wrap, &vals));
        }
        if matches!(func, Builtin::Dx | Builtin::Dy | Builtin::FilterWidth) {
            let varying = self.pix.is_some() && self.exprs()[args[0]].var.is_varying();
            return Ok(super::derivative::derivative(p, func, &vals[0], varying, self.exec));
        }
        if let Some(v) = super::shading::builtin(p, func, &vals) {
            return v;
        }
        in_precision!(p, F => self.float_builtin::<F>(func, vals))
    }

    /// A built-in of float operands `vals` (converted), computed in `F`: the vector ones
    /// and the component-wise ones.
    fn float_builtin<F: Float>(&self, func: Builtin, vals: Vec<Val>) -> Res<Val> {
        let g = F::from_word;
        match func {
            Builtin::Dot => {
                let vs = unify_all(vals)?;
                Ok(one(dot::<F>(&vs[0], &vs[1])))
            }
            Builtin::Length => Ok(one(dot::<F>(&vals[0], &vals[0]).map(|d| g(d).sqrt().word()))),
            Builtin::Distance => {
                let vs = unify_all(vals)?;
                let diff = Val {
                    comps: vs[0]
                        .comps
                        .iter()
                        .zip(&vs[1].comps)
                        .map(|(x, y)| std::array::from_fn(|l| (g(x[l]) - g(y[l])).word()))
                        .collect(),
                    sc: Scalar::Float,
                };
                Ok(one(dot::<F>(&diff, &diff).map(|d| g(d).sqrt().word())))
            }
            Builtin::Normalize => {
                let len = dot::<F>(&vals[0], &vals[0]).map(|d| g(d).sqrt());
                Ok(Val {
                    comps: vals[0]
                        .comps
                        .iter()
                        .map(|x| std::array::from_fn(|l| (g(x[l]) / len[l]).word()))
                        .collect(),
                    sc: Scalar::Float,
                })
            }
            Builtin::Cross => {
                let vs = unify_all(vals)?;
                if vs[0].comps.len() != 3 {
                    return malformed("cross of non-3-component values");
                }
                let (a, c) = (&vs[0].comps, &vs[1].comps);
                let comps = [(1, 2), (2, 0), (0, 1)]
                    .iter()
                    .map(|&(i, j)| std::array::from_fn(|l| (g(a[i][l]) * g(c[j][l]) - g(a[j][l]) * g(c[i][l])).word()))
                    .collect();
                Ok(Val {
                    comps,
                    sc: Scalar::Float,
                })
            }
            Builtin::TransformPoint { from, to } => {
                let m = self.space_matrix::<F>(to, from)?;
                apply_point(m, &vals[0])
            }
            Builtin::TransformVector { from, to } => {
                let m = self.space_matrix::<F>(to, from)?;
                apply_3x3(m, &vals[0], false)
            }
            Builtin::TransformNormal { from, to } => {
                // The inverse transpose of to_from_from is the transpose of from_from_to.
                let m = self.space_matrix::<F>(from, to)?;
                apply_3x3(m, &vals[0], true)
            }
            _ => {
                let unary = arity(func) == 1;
                let vs = if unary { vals } else { unify_all(vals)? };
                let mut bad = false;
                let v = componentwise(&vs, Scalar::Float, |a| {
                    float_builtin::<F>(func, a).unwrap_or_else(|| {
                        bad = true;
                        0
                    })
                });
                if bad {
                    return malformed(format!("{func:?} is not component-wise"));
                }
                Ok(v)
            }
        }
    }

    /// A matrix of the argument block's `spaces` (row-major, f32 words widened to `F`);
    /// `None` when the kernel's function has none (the JIT then takes every space as the
    /// identity).
    fn load_matrix<F: Float>(&self, word: u32) -> Res<Option<[F; 16]>> {
        let k = self.kernel()?;
        let Some(base) = k.layout.spaces else { return Ok(None) };
        let args = &self.frames[k.frame].args;
        let mut m = [F::ZERO; 16];
        for (i, x) in m.iter_mut().enumerate() {
            match args.float((base + word) as usize + i, self.precision) {
                Some(w) => *x = F::from_word(w),
                None => return malformed("space matrices past the argument block"),
            }
        }
        Ok(Some(m))
    }

    /// `to_from_from` = to_from_device * device_from_from (`None`: the identity).
    fn space_matrix<F: Float>(&self, to: Space, from: Space) -> Res<Option<[F; 16]>> {
        if to == from {
            return Ok(None);
        }
        let word = |s: Space, base: u32| match s {
            Space::Device => None,
            Space::Object => Some(base),
            Space::World => Some(base + 16),
            Space::Lighting => Some(base + 32),
        };
        let a = match word(to, 48) {
            Some(w) => self.load_matrix::<F>(w)?,
            None => None,
        };
        let c = match word(from, 0) {
            Some(w) => self.load_matrix::<F>(w)?,
            None => None,
        };
        Ok(match (a, c) {
            (None, m) | (m, None) => m,
            (Some(a), Some(c)) => Some(std::array::from_fn(|ij| {
                let (i, j) = (ij / 4, ij % 4);
                let mut acc = a[i * 4] * c[j];
                for k in 1..4 {
                    acc = acc + a[i * 4 + k] * c[k * 4 + j];
                }
                acc
            })),
        })
    }
}

fn one(c: Lanes) -> Val {
    Val {
        comps: vec![c],
        sc: Scalar::Float,
    }
}

/// `Σ a[i] * b[i]` left to right in `F`, per lane (0 without components).
fn dot<F: Float>(a: &Val, c: &Val) -> Lanes {
    let g = F::from_word;
    std::array::from_fn(|l| {
        let mut acc: Option<F> = None;
        for (x, y) in a.comps.iter().zip(&c.comps) {
            let p = g(x[l]) * g(y[l]);
            acc = Some(match acc {
                None => p,
                Some(s) => s + p,
            });
        }
        acc.unwrap_or(F::ZERO).word()
    })
}

fn apply_point<F: Float>(m: Option<[F; 16]>, v: &Val) -> Res<Val> {
    let Some(m) = m else { return Ok(v.clone()) };
    let n = v.comps.len();
    if n != 3 && n != 4 {
        return malformed("transform of a point that has neither 3 nor 4 components");
    }
    let g = F::from_word;
    let comps = (0..n)
        .map(|i| {
            std::array::from_fn(|l| {
                // A 3-component point is taken with w = 1 (no divide afterwards).
                let mut acc = m[i * 4 + 3];
                if n == 4 {
                    acc = acc * g(v.comps[3][l]);
                }
                for j in 0..3 {
                    acc = acc + m[i * 4 + j] * g(v.comps[j][l]);
                }
                acc.word()
            })
        })
        .collect();
    Ok(Val {
        comps,
        sc: Scalar::Float,
    })
}

fn apply_3x3<F: Float>(m: Option<[F; 16]>, v: &Val, transpose: bool) -> Res<Val> {
    let Some(m) = m else { return Ok(v.clone()) };
    if v.comps.len() < 3 {
        return malformed("transform of a direction with fewer than 3 components");
    }
    let g = F::from_word;
    let mut comps: Vec<Lanes> = (0..3)
        .map(|i| {
            std::array::from_fn(|l| {
                let at = |j: usize| if transpose { j * 4 + i } else { i * 4 + j };
                let mut acc = m[at(0)] * g(v.comps[0][l]);
                for j in 1..3 {
                    acc = acc + m[at(j)] * g(v.comps[j][l]);
                }
                acc.word()
            })
        })
        .collect();
    // A homogeneous direction keeps its w.
    comps.extend_from_slice(&v.comps[3..]);
    Ok(Val {
        comps,
        sc: Scalar::Float,
    })
}

fn matmul<F: Float>(a: &Val, c: &Val, ldims: &[u32], rdims: &[u32]) -> Res<Val> {
    let (n, m) = match ldims {
        [n, m] => (*n as usize, *m as usize),
        _ => return malformed("matrix product with a non-2-D left side"),
    };
    let k = match rdims {
        [r] if *r as usize == m => 1,
        [r, k] if *r as usize == m => *k as usize,
        _ => return malformed("matrix product with mismatched shapes"),
    };
    if a.comps.len() < n * m || c.comps.len() < m * k {
        return malformed("matrix product operands shorter than their shapes");
    }
    let g = F::from_word;
    let mut comps = Vec::with_capacity(n * k);
    for i in 0..n {
        for j in 0..k {
            comps.push(std::array::from_fn(|l| {
                let mut acc: Option<F> = None;
                for t in 0..m {
                    let p = g(a.comps[i * m + t][l]) * g(c.comps[t * k + j][l]);
                    acc = Some(match acc {
                        None => p,
                        Some(s) => s + p,
                    });
                }
                acc.unwrap_or(F::ZERO).word()
            }));
        }
    }
    Ok(Val {
        comps,
        sc: Scalar::Float,
    })
}

/// Bring two operands to one length (a single component broadcasts).
fn unify(a: Val, c: Val) -> Res<(Val, Val)> {
    let (mut a, mut c) = (a, c);
    if a.comps.len() != c.comps.len() {
        if a.comps.len() == 1 {
            a.comps = vec![a.comps[0]; c.comps.len()];
        } else if c.comps.len() == 1 {
            c.comps = vec![c.comps[0]; a.comps.len()];
        } else {
            return malformed(format!(
                "operands of {} and {} components",
                a.comps.len(),
                c.comps.len()
            ));
        }
    }
    Ok((a, c))
}

fn unify_all(vals: Vec<Val>) -> Res<Vec<Val>> {
    let len = vals.iter().map(|v| v.comps.len()).max().unwrap_or(0);
    vals.into_iter()
        .map(|mut v| {
            if v.comps.len() != len {
                if v.comps.len() != 1 {
                    return malformed(format!("built-in operands of {} and {len} components", v.comps.len()));
                }
                v.comps = vec![v.comps[0]; len];
            }
            Ok(v)
        })
        .collect()
}

/// `f` of the operands' i-th components, lane by lane, for every i.
fn componentwise(vs: &[Val], sc: Scalar, mut f: impl FnMut(&[u64]) -> u64) -> Val {
    let n = vs.first().map_or(0, |v| v.comps.len());
    let comps = (0..n)
        .map(|i| {
            let mut c = [0; 4];
            for (l, out) in c.iter_mut().enumerate() {
                let args: Vec<u64> = vs.iter().map(|v| v.comps[i][l]).collect();
                *out = f(&args);
            }
            c
        })
        .collect();
    Val { comps, sc }
}

fn binary(p: Precision, op: BinOp, a: Val, c: Val) -> Res<Val> {
    // Operands share a scalar type (checker); converted as the JIT does if they do not.
    let c = if c.sc != a.sc { c.converted(a.sc, p) } else { c };
    let (a, c) = unify(a, c)?;
    let sc = a.sc;
    let out = if matches!(
        op,
        BinOp::Lt | BinOp::Le | BinOp::Gt | BinOp::Ge | BinOp::Eq | BinOp::Ne | BinOp::And | BinOp::Or
    ) {
        Scalar::Bool
    } else {
        sc
    };
    let mut comps = Vec::with_capacity(a.comps.len());
    for (x, y) in a.comps.iter().zip(&c.comps) {
        let mut r = [0; 4];
        for l in 0..4 {
            match scalar::binop_lane(p, op, sc, x[l], y[l]) {
                Some(w) => r[l] = w,
                None => return malformed(format!("{op:?} on {sc:?}")),
            }
        }
        comps.push(r);
    }
    Ok(Val { comps, sc: out })
}
