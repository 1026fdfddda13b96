//! Expressions: [`Lower::eval`] lowers one to a [`Val`] (scalar SSA values for uniform
//! expressions, f32x4/i32x4 vectors for varying ones, one per component).
//!
//! Operators go through [`Lower::binary`] / [`Lower::binop`] (operands brought to one form
//! and length first, [`Lower::unify`]), conversions through [`Lower::convert_here`]
//! (bounded float -> int conversions skip their saturation fix-ups, see [`crate::mid::bounds`]),
//! built-ins through `super::super::builtin`. A pixel term hoisted per row or carried along
//! it is read back instead of evaluated ([`Lower::hoisted`], [`super::carry`]).
//!
//! Tier 0 numbers constants, pure operations and address arithmetic per block while
//! lowering ([`Lower::numbered`]); tier 1 leaves that to Cranelift's e-graph. Both tiers
//! compute the same bits. In `c ? a : b` both arms are evaluated and selected; a run-time
//! error in the untaken arm is not recorded ([`Lower::eval_guarded`]).

use cranelift_codegen::ir::{self, condcodes::FloatCC, condcodes::IntCC, types, InstBuilder};

use super::{elem_scalar, err, exact_reciprocal, float_const, speculable_expr, Lower, Res};
use crate::ir::{BinOp, ConstValue, Elem, ExprId, ExprKind, LocalId, Scalar, UnaryOp};
use crate::jit::fixed;
use crate::jit::libm::LibmFn;
use crate::jit::value::{args_flags, blend, splat, zero, Val, VnKey, F32X4, VN_NEG, VN_NOT};

impl<'a, 'b> Lower<'a, 'b> {
    /// Evaluate `e` as the language would only when the bool `cb` is `taken`: the arm of
    /// `c ? a : b`, the right side of `&&` / `||`. The JIT evaluates it regardless, so its
    /// run-time errors are guarded: by `cb` itself when uniform; for a varying `cb` (lane
    /// masks) the executing lanes narrow to those where `cb == taken`, and uniform errors
    /// inside count if some such lane exists.
    pub(super) fn eval_guarded(&mut self, e: ExprId, varying: bool, cb: ir::Value, taken: bool) -> Res<Val> {
        // Tier 0: a uniform guard is only read by an error record, so an expression that
        // cannot record one needs none (Cranelift would drop it, after we built it).
        if !varying && self.tier0() && speculable_expr(self.exprs(), e) {
            return self.eval(e);
        }
        let outer_guard = self.error_guard;
        let outer_exec = self.exec();
        let guard = if varying {
            let lanes = if taken { cb } else { self.b.ins().bnot(cb) };
            let lanes = match outer_exec {
                Some(x) => self.b.ins().band(x, lanes),
                None => lanes,
            };
            self.set_exec(lanes);
            self.b.ins().vany_true(lanes)
        } else {
            let cc = if taken { IntCC::NotEqual } else { IntCC::Equal };
            self.b.ins().icmp_imm_s(cc, cb, 0)
        };
        self.error_guard = Some(match outer_guard {
            Some(g) => self.b.ins().band(g, guard),
            None => guard,
        });
        let v = self.eval(e);
        self.error_guard = outer_guard;
        if let Some(x) = outer_exec {
            self.set_exec(x);
        }
        v
    }

    /// `iconst` of `ty`; tier 0 makes each once per block (it has no pass that would
    /// merge the copies: the NURB setup's CLIF had ~250 duplicate shift amounts).
    pub(super) fn iconst_here(&mut self, ty: ir::Type, v: i64) -> ir::Value {
        self.once_per_block(VnKey::IntConst(ty, v), |l| l.b.ins().iconst(ty, v))
    }

    /// `f32const` `x`, made once per block at tier 0 like [`Self::iconst_here`] (and shared
    /// with the source's float constants of the same bits).
    pub(in crate::jit) fn f32const_here(&mut self, x: f32) -> ir::Value {
        self.once_per_block(VnKey::Const(0, x.to_bits(), Scalar::Float), |l| l.b.ins().f32const(x))
    }

    /// `make`'s value, or at tier 0 the one it made earlier in the current block for `key`
    /// (see [`Self::numbered`]).
    pub(super) fn once_per_block(&mut self, key: VnKey, make: impl FnOnce(&mut Self) -> ir::Value) -> ir::Value {
        if let Some(v) = self.numbered(key) {
            return v;
        }
        let v = make(self);
        self.number(key, v);
        v
    }

    /// The bound of float expression `e` of the function being lowered (see
    /// [`crate::mid::bounds`]; the plan has the bounds of every function the kernel lowers),
    /// as (lo, hi), at the statement being lowered: every executing lane's value is a
    /// non-NaN f32 within it (an end may be infinite). The flag is true when the guards
    /// before this statement narrowed it: such a bound holds here only, not wherever the
    /// same value is computed (see [`Self::convert_here`]).
    pub(super) fn float_bound_here(&mut self, e: ExprId) -> (Option<(f64, f64)>, bool) {
        let Some(frame) = self.frames.last() else {
            return (None, false);
        };
        let id = frame.id;
        let depth = self.frames.len() - 1;
        let Some(table) = self.plan.bounds(id) else {
            debug_assert!(
                false,
                "the plan has no bounds for the function of a float -> int conversion"
            );
            return (None, false);
        };
        let whole = table.expr(self.exprs(), e).map(|b| (b.lo, b.hi));
        let here = table.expr_here(self.exprs(), e, &self.guard_facts, depth);
        (here, here != whole)
    }

    /// Convert `c`, one component of a value of `e` (a `from` value), to `to`; with the
    /// bound `e` has here when it is a varying float going to int or fixed. Value numbered
    /// (tier 0) by `c` and the types; a conversion made with a bound the guards narrowed
    /// is not recorded (it is right only where the guards' facts hold: a varying `if`'s
    /// other side, in the same block in flat code, must not reuse it), but may reuse one
    /// that was (right for every lane, so for these).
    pub(super) fn convert_here(
        &mut self,
        e: ExprId,
        from: Scalar,
        to: Scalar,
        c: ir::Value,
        varying: bool,
    ) -> ir::Value {
        let (bound, narrowed) = if varying && from == Scalar::Float && matches!(to, Scalar::Int | Scalar::Fixed(_)) {
            self.float_bound_here(e)
        } else {
            (None, false)
        };
        let key = VnKey::Convert(from, to, c);
        if let Some(r) = self.numbered(key) {
            return r;
        }
        let r = fixed::convert_bounded(&mut self.b, from, to, c, bound);
        if !narrowed {
            self.number(key, r);
        }
        r
    }

    /// While a row prologue substitutes row locals: the value of row local `l` (`None`: not
    /// a row local), evaluated from its defining expression once per prologue (the same
    /// operations every time, so reusing them changes no bit).
    pub(super) fn row_local_value(&mut self, l: LocalId) -> Option<Res<Val>> {
        let &value = self.plan.pixel.as_ref()?.row_locals.get(&l)?;
        let block = self.b.current_block();
        if let Some((at, v)) = self.row_local_values.get(&l) {
            if Some(*at) == block {
                return Some(Ok(v.clone()));
            }
        }
        let v = self.eval(value);
        if let (Ok(v), Some(at)) = (&v, block) {
            if self.b.current_block() == Some(at) {
                self.row_local_values.insert(l, (at, v.clone()));
            }
        }
        Some(v)
    }

    /// While a row prologue substitutes row locals: element `k` of a one-dimensional row
    /// local (`along[1]`), from the local's value (see [`crate::mid::hoist`]). `None` for
    /// anything else.
    pub(super) fn row_local_element(&mut self, e_id: ExprId) -> Option<Res<Val>> {
        let e = &self.exprs()[e_id];
        let ExprKind::Index { base, index, .. } = &e.kind else {
            return None;
        };
        let (ExprKind::Local(l), ExprKind::Const(ConstValue::Int(k))) =
            (&self.exprs()[*base].kind, &self.exprs()[*index].kind)
        else {
            return None;
        };
        if self.exprs()[*base].ty.dims.len() != 1 {
            return None;
        }
        let k = usize::try_from(*k).ok()?;
        Some(self.row_local_value(*l)?.and_then(|v| match v.comps.get(k) {
            Some(&c) => Ok(Val { comps: vec![c], ..v }),
            None => err("row local element out of range"),
        }))
    }

    pub(crate) fn eval_uniform(&mut self, e: ExprId) -> Res<Val> {
        let v = self.eval(e)?;
        if v.varying {
            return err("varying value where a uniform one is required");
        }
        Ok(v)
    }

    pub(crate) fn eval(&mut self, e_id: ExprId) -> Res<Val> {
        let e = &self.exprs()[e_id];
        if let Some(v) = self.hoisted(e_id) {
            return Ok(v);
        }
        if self.substitute_row_locals {
            if let ExprKind::Local(l) = &e.kind {
                if let Some(v) = self.row_local_value(*l) {
                    return v;
                }
            }
            if let Some(v) = self.row_local_element(e_id) {
                return v;
            }
        }
        if let Some(v) = self.carried_value(e_id) {
            return Ok(v);
        }
        let sc = elem_scalar(&e.ty);
        match &e.kind {
            ExprKind::Const(c) => self.eval_const(c, sc),
            ExprKind::Local(_) | ExprKind::Index { .. } => {
                let acc = self.resolve(e_id)?;
                self.read(acc)
            }
            ExprKind::Unary { op, expr } => self.eval_unary(op, *expr),
            ExprKind::Binary { op, lhs, rhs } => {
                let a = self.eval(*lhs)?;
                let c = match op {
                    // `a && b` reads b only where a holds, `a || b` only where it does not.
                    BinOp::And | BinOp::Or if a.scalar == Scalar::Bool => {
                        self.eval_guarded(*rhs, a.varying, a.comps[0], *op == BinOp::And)?
                    }
                    _ => self.eval(*rhs)?,
                };
                self.binary(*op, a, c)
            }
            ExprKind::Convert(inner) => self.eval_convert(e_id, *inner, sc),
            ExprKind::Select { cond, then, otherwise } => self.eval_select(*cond, *then, *otherwise),
            ExprKind::Builtin { func, args } => self.builtin(*func, args, e_id),
            ExprKind::List(items) => self.eval_list(items, sc),
            ExprKind::Splat(item) => self.eval_splat(e_id, *item, sc),
            ExprKind::MatMul { lhs, rhs } => self.eval_matmul(*lhs, *rhs),
            ExprKind::SeqCount => {
                let n = self.b.ins().load(types::I32, args_flags(), self.args, 0);
                Ok(Val::one(n, Scalar::Int, false))
            }
            ExprKind::ClipFlag => {
                let on = self.iconst_here(types::I8, i64::from(!self.key.trivial_accept));
                Ok(Val::one(on, Scalar::Bool, false))
            }
        }
    }

    /// A constant, numbered per block at tier 0.
    fn eval_const(&mut self, c: &ConstValue, sc: Scalar) -> Res<Val> {
        let key = match *c {
            ConstValue::Float(x) => VnKey::Const(0, x.to_bits(), sc),
            ConstValue::Int(i) => VnKey::Const(1, i as u32, sc),
            ConstValue::Bool(x) => VnKey::Const(2, x as u32, sc),
            ConstValue::Fixed(i) => VnKey::Const(3, i as u32, sc),
        };
        if let Some(v) = self.numbered(key) {
            return Ok(Val::one(v, sc, false));
        }
        let v = match *c {
            ConstValue::Float(x) => self.f32const_here(x),
            ConstValue::Int(i) | ConstValue::Fixed(i) => self.iconst_here(types::I32, i as i64),
            ConstValue::Bool(x) => self.iconst_here(types::I8, x as i64),
        };
        // A constant of one scalar type used as another (defensive): convert.
        let from = match c {
            ConstValue::Float(_) => Scalar::Float,
            ConstValue::Int(_) => Scalar::Int,
            ConstValue::Bool(_) => Scalar::Bool,
            ConstValue::Fixed(_) => sc,
        };
        let v = fixed::convert(&mut self.b, from, sc, v);
        self.number(key, v);
        Ok(Val::one(v, sc, false))
    }

    /// `-x` and `!x`, component by component.
    fn eval_unary(&mut self, op: &UnaryOp, expr: ExprId) -> Res<Val> {
        let v = self.eval(expr)?;
        let code = if *op == UnaryOp::Neg { VN_NEG } else { VN_NOT };
        let comps = v
            .comps
            .iter()
            .map(|&c| {
                let key = VnKey::Op(code, v.scalar, c, c);
                if let Some(r) = self.numbered(key) {
                    return r;
                }
                let r = match (op, v.scalar) {
                    (UnaryOp::Neg, Scalar::Float) => self.b.ins().fneg(c),
                    (UnaryOp::Neg, Scalar::Fixed(f)) => fixed::neg(&mut self.b, f, c),
                    (UnaryOp::Neg, _) => self.b.ins().ineg(c),
                    (UnaryOp::Not, _) => {
                        let c = fixed::convert(&mut self.b, v.scalar, Scalar::Bool, c);
                        if v.varying {
                            self.b.ins().bnot(c)
                        } else {
                            self.b.ins().bxor_imm_s(c, 1)
                        }
                    }
                };
                self.number(key, r);
                r
            })
            .collect();
        let scalar = if *op == UnaryOp::Not { Scalar::Bool } else { v.scalar };
        Ok(Val {
            comps,
            scalar,
            varying: v.varying,
        })
    }

    /// A conversion of `inner` to `e`'s type (scalar `sc`).
    fn eval_convert(&mut self, e_id: ExprId, inner: ExprId, sc: Scalar) -> Res<Val> {
        let e = &self.exprs()[e_id];
        let v = self.eval(inner)?;
        let mut comps: Vec<ir::Value> = v
            .comps
            .iter()
            .map(|&c| match (v.scalar, sc, crate::jit::value::iconst_i32(&self.b, c)) {
                // An int constant as a float (`float({1, 0, 0, 0})`): the constant
                // itself (`as` rounds to nearest like `fcvt_from_sint`), shared like
                // any other constant at tier 0, instead of a conversion at run time.
                (Scalar::Int, Scalar::Float, Some(i)) => {
                    let x = i as f32;
                    let key = VnKey::Const(0, x.to_bits(), Scalar::Float);
                    self.numbered(key).unwrap_or_else(|| {
                        let f = self.f32const_here(x);
                        self.number(key, f);
                        f
                    })
                }
                _ if v.scalar == sc => c,
                // A varying float whose lanes are proven finite and in the target's
                // range converts without the saturation fix-ups
                // (`fixed::convert_bounded`). Shared with an unbounded conversion
                // of the same value: the value is in the bound, where both agree.
                _ => self.convert_here(inner, v.scalar, sc, c, v.varying),
            })
            .collect();
        // A number converted to interpolation data stands for that number in every
        // component of the current view (the checker's zero-initialisation and
        // broadcasts).
        if e.ty.elem == Elem::Interp && self.exprs()[inner].ty.elem != Elem::Interp && comps.len() == 1 {
            let offs = self.comp_offsets(e.ty.elem, e.ty.fixed_len(), true);
            let n = offs.len();
            self.give_back_offsets(offs);
            comps = vec![comps[0]; n];
        }
        Ok(Val {
            comps,
            scalar: sc,
            varying: v.varying,
        })
    }

    /// `cond ? then : otherwise`: both arms evaluated (errors only where taken), then selected.
    fn eval_select(&mut self, cond: ExprId, then: ExprId, otherwise: ExprId) -> Res<Val> {
        let c = self.eval(cond)?;
        let cb = fixed::convert(&mut self.b, c.scalar, Scalar::Bool, c.comps[0]);
        let t = self.eval_guarded(then, c.varying, cb, true)?;
        let o = self.eval_guarded(otherwise, c.varying, cb, false)?;
        let (t, o) = self.unify(t, o)?;
        if !c.varying {
            // A uniform condition picks whole values, vectors too: a scalar `select`
            // (a test and a move) instead of splatting the condition to a lane mask
            // and blending (eight instructions per group for `a != 0 ? x : y`).
            // `unify` left both arms equally varying.
            let comps = t
                .comps
                .iter()
                .zip(&o.comps)
                .map(|(&x, &y)| self.b.ins().select(cb, x, y))
                .collect();
            return Ok(Val {
                comps,
                scalar: t.scalar,
                varying: t.varying,
            });
        }
        let t = self.make_varying(t);
        let o = self.make_varying(o);
        let m = splat(&mut self.b, Scalar::Bool, cb);
        let comps = t
            .comps
            .iter()
            .zip(&o.comps)
            .map(|(&x, &y)| blend(&mut self.b, m, x, y))
            .collect();
        Ok(Val {
            comps,
            scalar: t.scalar,
            varying: true,
        })
    }

    /// A list literal: its items' components converted to `sc`, one after the other.
    fn eval_list(&mut self, items: &'a [ExprId], sc: Scalar) -> Res<Val> {
        let mut vals = vec![];
        for it in items {
            vals.push(self.eval(*it)?);
        }
        let varying = vals.iter().any(|v| v.varying);
        let mut comps = vec![];
        for v in vals {
            let v = Val {
                comps: v
                    .comps
                    .iter()
                    .map(|&c| fixed::convert(&mut self.b, v.scalar, sc, c))
                    .collect(),
                scalar: sc,
                varying: v.varying,
            };
            let v = if varying { self.make_varying(v) } else { v };
            comps.extend(v.comps);
        }
        Ok(Val {
            comps,
            scalar: sc,
            varying,
        })
    }

    /// `item` repeated over every element of `e`'s type.
    fn eval_splat(&mut self, e_id: ExprId, item: ExprId, sc: Scalar) -> Res<Val> {
        let e = &self.exprs()[e_id];
        let v = self.eval(item)?;
        let one: Vec<ir::Value> = v
            .comps
            .iter()
            .map(|&c| fixed::convert(&mut self.b, v.scalar, sc, c))
            .collect();
        Ok(Val {
            comps: one.repeat(e.ty.fixed_len() as usize),
            scalar: sc,
            varying: v.varying,
        })
    }

    /// A matrix product (`n x m` by `m` or `m x k`), as sums of products in index order.
    fn eval_matmul(&mut self, lhs_id: ExprId, rhs: ExprId) -> Res<Val> {
        let lhs = &self.exprs()[lhs_id];
        let a = self.eval(lhs_id)?;
        let c = self.eval(rhs)?;
        let (n, m) = match lhs.ty.dims.as_slice() {
            [n, m] => (*n as usize, *m as usize),
            _ => return err("matrix product with a non-2-D left side"),
        };
        let k = match self.exprs()[rhs].ty.dims.as_slice() {
            [r] if *r as usize == m => None,
            [r, k] if *r as usize == m => Some(*k as usize),
            _ => return err("matrix product with mismatched shapes"),
        };
        // Only the variability is unified: the operands' lengths differ by design
        // (n*m and m*k components), which `unify` would reject.
        let (a, c) = if a.varying != c.varying {
            (self.make_varying(a), self.make_varying(c))
        } else {
            (a, c)
        };
        let a = self.float_val(a);
        let c = self.float_val(c);
        let kk = k.unwrap_or(1);
        let mut comps = vec![];
        for i in 0..n {
            for j in 0..kk {
                let mut acc = None;
                for t in 0..m {
                    let x = a.comps[i * m + t];
                    let y = c.comps[t * kk + j];
                    let p = self.b.ins().fmul(x, y);
                    acc = Some(match acc {
                        None => p,
                        Some(s) => self.b.ins().fadd(s, p),
                    });
                }
                comps.push(acc.unwrap_or_else(|| zero(&mut self.b, Scalar::Float, a.varying)));
            }
        }
        Ok(Val {
            comps,
            scalar: Scalar::Float,
            varying: a.varying,
        })
    }

    pub(crate) fn float_val(&mut self, v: Val) -> Val {
        if v.scalar == Scalar::Float {
            return v;
        }
        let comps = v
            .comps
            .iter()
            .map(|&c| fixed::convert(&mut self.b, v.scalar, Scalar::Float, c))
            .collect();
        Val {
            comps,
            scalar: Scalar::Float,
            varying: v.varying,
        }
    }

    /// Bring two operands to the same form and length (a single component broadcasts).
    pub(crate) fn unify(&mut self, a: Val, c: Val) -> Res<(Val, Val)> {
        let (mut a, mut c) = (a, c);
        if a.varying != c.varying {
            a = self.make_varying(a);
            c = self.make_varying(c);
        }
        if a.comps.len() != c.comps.len() {
            if a.comps.len() == 1 {
                a.comps = vec![a.comps[0]; c.comps.len()];
            } else if c.comps.len() == 1 {
                c.comps = vec![c.comps[0]; a.comps.len()];
            } else {
                return err(format!(
                    "operands of {} and {} components",
                    a.comps.len(),
                    c.comps.len()
                ));
            }
        }
        Ok((a, c))
    }

    pub(super) fn binary(&mut self, op: BinOp, a: Val, c: Val) -> Res<Val> {
        // Operands share a scalar type (checker); convert defensively if they do not.
        let c = if c.scalar != a.scalar {
            Val {
                comps: c
                    .comps
                    .iter()
                    .map(|&x| fixed::convert(&mut self.b, c.scalar, a.scalar, x))
                    .collect(),
                scalar: a.scalar,
                varying: c.varying,
            }
        } else {
            c
        };
        let (a, c) = self.unify(a, c)?;
        let sc = a.scalar;
        let is_cmp = matches!(
            op,
            BinOp::Lt | BinOp::Le | BinOp::Gt | BinOp::Ge | BinOp::Eq | BinOp::Ne
        );
        let mut comps = Vec::with_capacity(a.comps.len());
        for (&x, &y) in a.comps.iter().zip(&c.comps) {
            let key = VnKey::Op(op as u8, sc, x, y);
            let v = match self.numbered(key) {
                Some(v) => v,
                None => {
                    let v = self.binop(op, sc, x, y)?;
                    self.number(key, v);
                    v
                }
            };
            comps.push(v);
        }
        let scalar = if is_cmp || matches!(op, BinOp::And | BinOp::Or) {
            Scalar::Bool
        } else {
            sc
        };
        Ok(Val {
            comps,
            scalar,
            varying: a.varying,
        })
    }

    /// Tier 0: the value `key` already has in the current block, if it was lowered there.
    /// Every key is a pure function of SSA values (or a constant), so an earlier result in
    /// the same block is the same value and dominates the use: an assignment to a local
    /// gives the local a new SSA value, and so a new key. Sharing shortens the CLIF (a
    /// triangle repeats `-orient`, `interp_data[0] * q0`, many constants) without a pass over
    /// the finished function.
    pub(super) fn numbered(&self, key: VnKey) -> Option<ir::Value> {
        if !self.tier0() {
            return None;
        }
        let block = self.b.current_block()?;
        self.vn.get(block, key)
    }

    /// Record `v` as the value of `key` in the current block (tier 0; see [`Self::numbered`]).
    pub(super) fn number(&mut self, key: VnKey, v: ir::Value) {
        if let (true, Some(block)) = (self.tier0(), self.b.current_block()) {
            self.vn.insert(block, key, v);
        }
    }

    /// `x * y`, or the other factor where one is the constant 1: `x * 1` is `x` for every
    /// float (NaN, infinities and signed zeros included). Transforms of unit vectors
    /// (`transform("device", "object", {1, 0, 0, 0})`, the sphere's matrix columns) have
    /// a quarter of their products by 1; `x / 1.0` is one too (`exact_reciprocal`).
    /// `tests/jit/multiply_by_one.rs`.
    pub(crate) fn fmul(&mut self, x: ir::Value, y: ir::Value) -> ir::Value {
        if float_const(self.b.func, y) == Some(1.0) {
            x
        } else if float_const(self.b.func, x) == Some(1.0) {
            y
        } else {
            self.b.ins().fmul(x, y)
        }
    }

    pub(super) fn binop(&mut self, op: BinOp, sc: Scalar, x: ir::Value, y: ir::Value) -> Res<ir::Value> {
        let b = &mut self.b;
        Ok(match sc {
            Scalar::Float => match op {
                BinOp::Add => b.ins().fadd(x, y),
                BinOp::Sub => b.ins().fsub(x, y),
                BinOp::Mul => self.fmul(x, y),
                BinOp::Div => match exact_reciprocal(b.func, y) {
                    // x / 2^k and x * 2^-k round the same real number, so they are the same
                    // value for every x (NaN, infinities, zeros and subnormals included);
                    // the multiply is ~4 cycles to the division's ~11 (`vx[i] / 16.0` of
                    // the triangle's snapping, six per setup).
                    Some(r) => {
                        let r = self.fconst_like(x, r);
                        self.fmul(x, r)
                    }
                    None => b.ins().fdiv(x, y),
                },
                BinOp::Rem => {
                    // C fmodf: x - trunc(x / y) * y.
                    let q = b.ins().fdiv(x, y);
                    let t = b.ins().trunc(q);
                    let p = b.ins().fmul(t, y);
                    b.ins().fsub(x, p)
                }
                BinOp::Lt => b.ins().fcmp(FloatCC::LessThan, x, y),
                BinOp::Le => b.ins().fcmp(FloatCC::LessThanOrEqual, x, y),
                BinOp::Gt => b.ins().fcmp(FloatCC::GreaterThan, x, y),
                BinOp::Ge => b.ins().fcmp(FloatCC::GreaterThanOrEqual, x, y),
                BinOp::Eq => b.ins().fcmp(FloatCC::Equal, x, y),
                BinOp::Ne => b.ins().fcmp(FloatCC::NotEqual, x, y),
                BinOp::And | BinOp::Or => return err("logical operator on floats"),
            },
            Scalar::Int | Scalar::Fixed(_) => {
                let fmt = match sc {
                    Scalar::Fixed(f) => Some(f),
                    _ => None,
                };
                match op {
                    BinOp::Add => match fmt {
                        Some(f) => fixed::add(b, f, x, y),
                        None => b.ins().iadd(x, y),
                    },
                    BinOp::Sub => match fmt {
                        Some(f) => fixed::sub(b, f, x, y),
                        None => b.ins().isub(x, y),
                    },
                    BinOp::Mul => match fmt {
                        Some(f) => fixed::mul(b, f, x, y),
                        None => b.ins().imul(x, y),
                    },
                    BinOp::Div => match fmt {
                        Some(f) => fixed::div(b, f, x, y),
                        None => fixed::int_div_rem(b, x, y, false),
                    },
                    BinOp::Rem => match fmt {
                        Some(f) => fixed::rem(b, f, x, y),
                        None => fixed::int_div_rem(b, x, y, true),
                    },
                    BinOp::Lt => b.ins().icmp(fixed::int_cc(sc, IntCC::SignedLessThan), x, y),
                    BinOp::Le => b.ins().icmp(fixed::int_cc(sc, IntCC::SignedLessThanOrEqual), x, y),
                    BinOp::Gt => b.ins().icmp(fixed::int_cc(sc, IntCC::SignedGreaterThan), x, y),
                    BinOp::Ge => b.ins().icmp(fixed::int_cc(sc, IntCC::SignedGreaterThanOrEqual), x, y),
                    BinOp::Eq => b.ins().icmp(IntCC::Equal, x, y),
                    BinOp::Ne => b.ins().icmp(IntCC::NotEqual, x, y),
                    BinOp::And | BinOp::Or => return err("logical operator on numbers"),
                }
            }
            Scalar::Bool => match op {
                BinOp::And => b.ins().band(x, y),
                BinOp::Or => b.ins().bor(x, y),
                BinOp::Eq => b.ins().icmp(IntCC::Equal, x, y),
                BinOp::Ne => b.ins().icmp(IntCC::NotEqual, x, y),
                _ => return err("arithmetic on bools"),
            },
        })
    }

    /// Call a libm helper on a scalar or each lane of a vector.
    pub(crate) fn call_libm(&mut self, f: LibmFn, operands: &[ir::Value]) -> Res<ir::Value> {
        let fref = self.linker.libm_ref(self.b.func, f)?;
        let vec = self.b.func.dfg.value_type(operands[0]).is_vector();
        if !vec {
            let call = self.b.ins().call(fref, operands);
            return Ok(self.b.inst_results(call)[0]);
        }
        Ok(crate::jit::value::map_lanes(
            &mut self.b,
            F32X4,
            operands,
            &mut |b, lanes| {
                let call = b.ins().call(fref, lanes);
                b.inst_results(call)[0]
            },
        ))
    }

    pub(crate) fn spaces_base(&self) -> Option<u32> {
        self.layout.spaces
    }

    pub(crate) fn args_ptr(&self) -> ir::Value {
        self.args
    }
}
