//! Expressions: names, literals, operators with the conversions [`super::super::types`]
//! asks for, indexing, lists, built-in calls, `transform` and constructors.
//!
//! Invariants: an expression that lowers returns `Some` with its final type; one that
//! reports an error returns `None` and the enclosing statement is dropped, so one mistake
//! gives one diagnostic.

use crate::diag::Span;
use crate::ir::tree::{Tree, TreeKind};
use crate::ir::{self, BinOp, Builtin, ConstValue, Elem, Scalar, Space, Stmt, Type};
use crate::syntax::ast;

use super::super::types::{self, convert, scalar_of, type_name};
use super::*;

impl<'g, 'a> FnLower<'g, 'a> {
    // ---- expressions ------------------------------------------------------------------

    /// Lower `e` and convert it to `ty` (a `{...}` list is lowered against `ty` directly).
    pub fn expr_to(&mut self, e: &ast::Expr, ty: &Type, pre: &mut Vec<Stmt<Tree>>) -> Option<Tree> {
        if let ast::ExprKind::List(items) = &e.kind {
            if !ty.dims.is_empty() && !ty.per_seq {
                if items.len() != ty.dims[0] as usize {
                    self.sink.push(err(
                        "E0213",
                        format!("list of {} elements for {}", items.len(), type_name(ty)),
                        e.span,
                        format!("expected {} elements", ty.dims[0]),
                    ));
                    return None;
                }
                let et = ty.element();
                let mut out = vec![];
                for it in items {
                    out.push(self.expr_to(it, &et, pre));
                }
                let out: Option<Vec<_>> = out.into_iter().collect();
                return Some(mk(TreeKind::List(out?), ty.clone(), e.span));
            }
        }
        let v = self.expr(e, pre)?;
        self.coerce(v, ty, e.span)
    }

    /// Convert a value to `ty` for assignment: numbers convert, bool only from bool, a
    /// scalar broadcasts over an aggregate, shapes must otherwise match.
    pub(super) fn coerce(&mut self, v: Tree, ty: &Type, span: Span) -> Option<Tree> {
        if v.ty == *ty {
            return Some(v);
        }
        let mismatch = |this: &mut Self, v: &Tree| {
            this.sink.push(err(
                "E0205",
                format!("expected {}, found {}", type_name(ty), type_name(&v.ty)),
                span,
                format!("this is {}", type_name(&v.ty)),
            ));
            None
        };
        if ty.per_seq || v.ty.per_seq {
            return mismatch(self, &v);
        }
        match (ty.elem, v.ty.elem) {
            (Elem::Interp, Elem::Interp) if v.ty.dims.is_empty() => Some(broadcast(v, &ty.dims)),
            (Elem::Interp, Elem::Scalar(s)) if types::is_number(s) && v.ty.dims.is_empty() => {
                Some(broadcast(to_interp(convert(v, Scalar::Float)), &ty.dims))
            }
            // Inside a named interpolation arm the data is narrowed to that kind's
            // parameters, so a list of numbers can stand for them (a primitive that computes
            // a value itself, like a surface normal, hands it on to a sub-primitive this way).
            // The kernel compiler checks the length against the bound components.
            (Elem::Interp, Elem::Scalar(s))
                if types::is_number(s) && v.ty.dims.len() == 1 && ty.dims.is_empty() && self.arm == Some(false) =>
            {
                Some(to_interp(convert(v, Scalar::Float)))
            }
            (Elem::Scalar(t), Elem::Scalar(s)) if types::implicitly_converts(s, t) => {
                if v.ty.dims == ty.dims {
                    Some(self.convert_to(v, t))
                } else if v.ty.dims.is_empty() {
                    Some(broadcast(self.convert_to(v, t), &ty.dims))
                } else {
                    mismatch(self, &v)
                }
            }
            _ => mismatch(self, &v),
        }
    }

    /// [`convert`] to `to`, warning (W0006) where it turns a constant into a fixed value
    /// that has lost its meaning ([`types::fixed_loss`]): the constant is still as written
    /// here, and folded after.
    pub(super) fn convert_to(&mut self, v: Tree, to: Scalar) -> Tree {
        if let (TreeKind::Const(c), Some(from), Scalar::Fixed(f)) = (&v.kind, scalar_of(&v.ty), to) {
            let fmt = type_name(&Type::scalar(to));
            // A float constant as written (the f32 it is, not its f64 widening).
            let shown = |value: f64| match from {
                Scalar::Float => format!("{}", value as f32),
                _ => format!("{value}"),
            };
            let d = match types::fixed_loss(*c, from, f) {
                Some(types::FixedLoss::Saturates { value, result }) => Some(
                    Diagnostic::warning(
                        "W0006",
                        format!("the constant {} saturates to {result} as {fmt}", shown(value)),
                    )
                    .primary(v.span, format!("this becomes {result}"))
                    .help(format!(
                        "{fmt} holds {} to {}; convert the other operand to a wider type, or use a float",
                        f.raw_range().0 as f64 / f.scale(),
                        f.raw_range().1 as f64 / f.scale()
                    )),
                ),
                Some(types::FixedLoss::Vanishes { value }) => Some(
                    Diagnostic::warning("W0006", format!("the constant {} becomes 0 as {fmt}", shown(value)))
                        .primary(v.span, "this becomes 0")
                        .help(format!(
                            "{fmt} has steps of {}; a constant nearer to 0 than half a step rounds to 0",
                            1.0 / f.scale()
                        )),
                ),
                None => None,
            };
            if let Some(d) = d {
                self.sink.push(d);
            }
        }
        convert(v, to)
    }

    pub fn expr(&mut self, e: &ast::Expr, pre: &mut Vec<Stmt<Tree>>) -> Option<Tree> {
        if !self.enter(1, e.span) {
            return None;
        }
        let v = self.expr_nested(e, pre);
        self.leave(1);
        v
    }

    pub(super) fn expr_nested(&mut self, e: &ast::Expr, pre: &mut Vec<Stmt<Tree>>) -> Option<Tree> {
        use ast::ExprKind as K;
        let span = e.span;
        match &e.kind {
            K::Error => None,
            K::Int(v) => {
                let Ok(v) = i32::try_from(*v) else {
                    self.sink.push(err(
                        "E0203",
                        "integer literal out of range",
                        span,
                        "does not fit in 32 bits",
                    ));
                    return None;
                };
                Some(types::const_expr(ConstValue::Int(v), Scalar::Int, span))
            }
            K::Float(v) => Some(types::const_expr(ConstValue::Float(*v as f32), Scalar::Float, span)),
            K::Bool(b) => Some(types::const_expr(ConstValue::Bool(*b), Scalar::Bool, span)),
            K::Str(_) => {
                self.sink.push(
                    err(
                        "E0211",
                        "string literal outside transform()",
                        span,
                        "strings are space names only",
                    )
                    .help("strings may only name a space in transform/vtransform/ntransform"),
                );
                None
            }
            K::Name(id) => self.name(id, span),
            K::Unary { op, expr } => self.unary(*op, expr, span, pre),
            K::Binary { op, lhs, rhs } => {
                let l = self.expr(lhs, pre);
                let r = self.expr(rhs, pre);
                self.binary(*op, l?, r?, span)
            }
            K::Ternary { cond, then, otherwise } => {
                let c = self.cond(cond, pre);
                let t = self.expr(then, pre);
                let o = self.expr(otherwise, pre);
                let (c, t, o) = (c?, t?, o?);
                let (t, o) = self.unify(t, o, span)?;
                let ty = t.ty.clone();
                Some(mk(
                    TreeKind::Select {
                        cond: Box::new(c),
                        then: Box::new(t),
                        otherwise: Box::new(o),
                    },
                    ty,
                    span,
                ))
            }
            K::Call { callee, args } => self.call_expr(callee, args, span, pre),
            K::Construct { ty, args } => self.construct(ty, args, span, pre),
            K::Index { base, index } => {
                let b = self.expr(base, pre)?;
                let i = self.index_value(&b.ty, index, pre)?;
                let site = self.new_site(index.span);
                let ty = b.ty.element();
                Some(mk(
                    TreeKind::Index {
                        base: Box::new(b),
                        index: Box::new(i),
                        site,
                    },
                    ty,
                    span,
                ))
            }
            K::Field { base, field } => self.field(base, field, span, pre),
            K::List(items) => {
                let mut vals = vec![];
                for it in items {
                    vals.push(self.expr(it, pre));
                }
                let vals: Vec<Tree> = vals.into_iter().collect::<Option<_>>()?;
                self.list(vals, span)
            }
        }
    }

    /// A name as a value: a local, `PI`, or an error naming what it is instead.
    fn name(&mut self, id: &ast::Ident, span: Span) -> Option<Tree> {
        if let Some(l) = self.lookup(&id.name) {
            return Some(self.local_expr(l, span));
        }
        if id.name == "PI" {
            return Some(types::const_expr(
                ConstValue::Float(std::f32::consts::PI),
                Scalar::Float,
                span,
            ));
        }
        if self.g.by_name.contains_key(&id.name) {
            self.sink.push(err(
                "E0108",
                format!("`{}` is a function, not a value", id.name),
                span,
                "used as a value",
            ));
        } else {
            let d = err("E0101", format!("unknown variable `{}`", id.name), span, "not declared")
                .suggest(&id.name, self.visible_values());
            self.sink.push(d);
        }
        None
    }

    /// `-v` (a constant folded) or `!v`.
    fn unary(&mut self, op: ast::UnaryOp, expr: &ast::Expr, span: Span, pre: &mut Vec<Stmt<Tree>>) -> Option<Tree> {
        let v = self.expr(expr, pre)?;
        match op {
            ast::UnaryOp::Neg => {
                if scalar_of(&v.ty) == Some(Scalar::Bool) {
                    self.sink
                        .push(err("E0203", "cannot negate a bool", span, "use `!` for bools"));
                    return None;
                }
                if let (TreeKind::Const(c), Some(s)) = (&v.kind, scalar_of(&v.ty)) {
                    if let Some(n) = negate_const(*c, s) {
                        return Some(types::const_expr(n, s, span));
                    }
                }
                let ty = v.ty.clone();
                Some(mk(
                    TreeKind::Unary {
                        op: ir::UnaryOp::Neg,
                        expr: Box::new(v),
                    },
                    ty,
                    span,
                ))
            }
            ast::UnaryOp::Not => {
                if v.ty != Type::bool() {
                    self.sink.push(err(
                        "E0203",
                        format!("`!` needs a bool, found {}", type_name(&v.ty)),
                        span,
                        "not a bool",
                    ));
                    return None;
                }
                Some(mk(
                    TreeKind::Unary {
                        op: ir::UnaryOp::Not,
                        expr: Box::new(v),
                    },
                    Type::bool(),
                    span,
                ))
            }
        }
    }

    /// The index of `base[index]`: an int, and in range when both are constant.
    pub(super) fn index_value(&mut self, base: &Type, index: &ast::Expr, pre: &mut Vec<Stmt<Tree>>) -> Option<Tree> {
        if base.dims.is_empty() && !base.per_seq {
            self.sink.push(err(
                "E0206",
                format!("cannot index a {}", type_name(base)),
                index.span,
                "indexing a value that is not an array",
            ));
            return None;
        }
        let i = self.expr(index, pre)?;
        if i.ty != Type::int() {
            self.sink.push(
                err(
                    "E0206",
                    format!("array index must be an int, found {}", type_name(&i.ty)),
                    index.span,
                    "not an int",
                )
                .help("convert with int(...)"),
            );
            return None;
        }
        if let (TreeKind::Const(ConstValue::Int(k)), false) = (&i.kind, base.per_seq) {
            let n = base.dims[0];
            if *k < 0 || *k as u32 >= n {
                self.sink.push(err(
                    "E0207",
                    format!("index {k} is out of range for {}", type_name(base)),
                    index.span,
                    format!("valid indices are 0..{}", n - 1),
                ));
                return None;
            }
        }
        Some(i)
    }

    /// Infer the type of a `{...}` list from its elements.
    pub(super) fn list(&mut self, vals: Vec<Tree>, span: Span) -> Option<Tree> {
        let Some(first) = vals.first() else {
            self.sink
                .push(err("E0213", "empty list", span, "a list needs at least one element"));
            return None;
        };
        let dims = first.ty.dims.clone();
        let mut elem = first.ty.elem;
        for v in &vals {
            if v.ty.dims != dims || v.ty.per_seq {
                self.sink.push(err(
                    "E0213",
                    "list elements have different shapes",
                    v.span,
                    format!("this is {}, the first is {}", type_name(&v.ty), type_name(&first.ty)),
                ));
                return None;
            }
            elem = match (elem, v.ty.elem) {
                (Elem::Interp, Elem::Interp) => Elem::Interp,
                (Elem::Scalar(a), Elem::Scalar(b)) if a == b => Elem::Scalar(a),
                (Elem::Scalar(a), Elem::Scalar(b)) => match types::arith_scalar(a, b) {
                    Some(s) => Elem::Scalar(s),
                    None => {
                        self.sink.push(err(
                            "E0213",
                            "list mixes bools and numbers",
                            v.span,
                            format!("this is {}", type_name(&v.ty)),
                        ));
                        return None;
                    }
                },
                _ => {
                    self.sink.push(err(
                        "E0213",
                        "list mixes interpolation data and numbers",
                        v.span,
                        format!("this is {}", type_name(&v.ty)),
                    ));
                    return None;
                }
            };
        }
        let et = Type::array(elem, dims.clone());
        let mut out = vec![];
        for v in vals {
            out.push(self.coerce(v, &et, span)?);
        }
        let mut all = vec![out.len() as u32];
        all.extend(dims);
        Some(mk(TreeKind::List(out), Type::array(elem, all), span))
    }

    /// Bring two values to one type (for `?:`): numbers to their common scalar, a scalar
    /// broadcast to the other side's shape.
    pub(super) fn unify(&mut self, a: Tree, b: Tree, span: Span) -> Option<(Tree, Tree)> {
        if a.ty == b.ty {
            return Some((a, b));
        }
        let target = match (a.ty.elem, b.ty.elem) {
            (Elem::Scalar(x), Elem::Scalar(y)) => {
                let s = if x == y { Some(x) } else { types::arith_scalar(x, y) };
                let dims = if a.ty.dims.is_empty() {
                    b.ty.dims.clone()
                } else {
                    a.ty.dims.clone()
                };
                s.map(|s| Type::array(Elem::Scalar(s), dims))
            }
            (Elem::Interp, _) => Some(Type::array(Elem::Interp, a.ty.dims.clone())),
            (_, Elem::Interp) => Some(Type::array(Elem::Interp, b.ty.dims.clone())),
        };
        let Some(target) = target else {
            self.sink.push(err(
                "E0202",
                format!("the two sides have types {} and {}", type_name(&a.ty), type_name(&b.ty)),
                span,
                "no common type",
            ));
            return None;
        };
        let a = self.coerce(a, &target, span)?;
        let b = self.coerce(b, &target, span)?;
        Some((a, b))
    }

    /// Type a binary operation (see the module docs of [`super::types`]).
    pub fn binary(&mut self, op: ast::BinOp, l: Tree, r: Tree, span: Span) -> Option<Tree> {
        use ast::BinOp as B;
        let iop = op;
        if l.ty.per_seq || r.ty.per_seq {
            self.sink.push(
                err(
                    "E0203",
                    "a per-sequence-point array cannot be used in arithmetic as a whole",
                    span,
                    shapes(&l, &r),
                )
                .help("index it: `vertex[i]`"),
            );
            return None;
        }
        match op {
            B::And | B::Or => {
                if l.ty != Type::bool() || r.ty != Type::bool() {
                    self.sink.push(err(
                        "E0203",
                        format!("`&&` and `||` need bools, found {}", shapes(&l, &r)),
                        span,
                        "not bools",
                    ));
                    return None;
                }
                Some(bin(iop, l, r, Type::bool(), span))
            }
            B::Eq | B::Ne | B::Lt | B::Le | B::Gt | B::Ge => {
                if !l.ty.dims.is_empty()
                    || !r.ty.dims.is_empty()
                    || l.ty.elem == Elem::Interp
                    || r.ty.elem == Elem::Interp
                {
                    self.sink.push(
                        err(
                            "E0212",
                            format!("comparison of {}", shapes(&l, &r)),
                            span,
                            "only scalars can be compared",
                        )
                        .help("compare the components one by one"),
                    );
                    return None;
                }
                let (a, b) = (
                    scalar_of(&l.ty).unwrap_or(Scalar::Float),
                    scalar_of(&r.ty).unwrap_or(Scalar::Float),
                );
                let common = if a == Scalar::Bool && b == Scalar::Bool && matches!(op, B::Eq | B::Ne) {
                    Some(Scalar::Bool)
                } else {
                    types::arith_scalar(a, b)
                };
                let Some(s) = common else {
                    self.sink.push(err(
                        "E0203",
                        format!("cannot compare {}", shapes(&l, &r)),
                        span,
                        "bools only compare with `==` and `!=` to bools",
                    ));
                    return None;
                };
                let (l, r) = (self.convert_to(l, s), self.convert_to(r, s));
                Some(bin(iop, l, r, Type::bool(), span))
            }
            B::Add | B::Sub | B::Mul | B::Div | B::Rem => self.arith(op, iop, l, r, span),
        }
    }

    pub(super) fn arith(&mut self, op: ast::BinOp, iop: BinOp, l: Tree, r: Tree, span: Span) -> Option<Tree> {
        // Interpolation data: with itself, or with a number (taken as float).
        if l.ty.elem == Elem::Interp || r.ty.elem == Elem::Interp {
            let ok_other = |e: &Tree| {
                e.ty.elem == Elem::Interp || (e.ty.dims.is_empty() && scalar_of(&e.ty).is_some_and(types::is_number))
            };
            let same_or_scalar = l.ty.dims == r.ty.dims || l.ty.dims.is_empty() || r.ty.dims.is_empty();
            let interp_scalar_side = |e: &Tree| e.ty.elem == Elem::Interp || e.ty.dims.is_empty();
            if !(ok_other(&l) && ok_other(&r) && same_or_scalar && interp_scalar_side(&l) && interp_scalar_side(&r)) {
                self.sink.push(
                    err(
                        "E0202",
                        format!("interpolation data combined with {}", shapes(&l, &r)),
                        span,
                        "interpolation data only mixes with itself and with numbers",
                    )
                    .help("index arrays of interpolation data first"),
                );
                return None;
            }
            let l = if l.ty.elem == Elem::Interp {
                l
            } else {
                convert(l, Scalar::Float)
            };
            let r = if r.ty.elem == Elem::Interp {
                r
            } else {
                convert(r, Scalar::Float)
            };
            let dims = if l.ty.dims.is_empty() {
                r.ty.dims.clone()
            } else {
                l.ty.dims.clone()
            };
            return Some(bin(iop, l, r, Type::array(Elem::Interp, dims), span));
        }
        let (a, b) = (
            scalar_of(&l.ty).unwrap_or(Scalar::Bool),
            scalar_of(&r.ty).unwrap_or(Scalar::Bool),
        );
        let Some(s) = types::arith_scalar(a, b) else {
            self.sink.push(err(
                "E0203",
                format!("arithmetic on {}", shapes(&l, &r)),
                span,
                "bools are not numbers",
            ));
            return None;
        };
        // matrix * vector and matrix * matrix.
        if op == ast::BinOp::Mul && l.ty.dims.len() == 2 && !r.ty.dims.is_empty() && r.ty.dims.len() <= 2 {
            let (n, m) = (l.ty.dims[0], l.ty.dims[1]);
            if r.ty.dims[0] != m {
                self.sink.push(err(
                    "E0202",
                    format!("matrix product of {}", shapes(&l, &r)),
                    span,
                    format!("the left side has {m} columns, the right side {} rows", r.ty.dims[0]),
                ));
                return None;
            }
            let mut dims = vec![n];
            dims.extend(r.ty.dims.get(1).copied());
            return Some(mk(
                TreeKind::MatMul {
                    lhs: Box::new(convert(l, Scalar::Float)),
                    rhs: Box::new(convert(r, Scalar::Float)),
                },
                Type::array(Elem::Scalar(Scalar::Float), dims),
                span,
            ));
        }
        let dims = if l.ty.dims == r.ty.dims || r.ty.dims.is_empty() {
            l.ty.dims.clone()
        } else if l.ty.dims.is_empty() {
            r.ty.dims.clone()
        } else {
            self.sink.push(err(
                "E0202",
                format!("mismatched shapes: {}", shapes(&l, &r)),
                span,
                "component-wise operations need equal shapes (or a scalar)",
            ));
            return None;
        };
        let (l, r) = (self.convert_to(l, s), self.convert_to(r, s));
        Some(bin(iop, l, r, Type::array(Elem::Scalar(s), dims), span))
    }

    pub(super) fn call_expr(
        &mut self,
        callee: &ast::Ident,
        args: &[ast::Expr],
        span: Span,
        pre: &mut Vec<Stmt<Tree>>,
    ) -> Option<Tree> {
        if let Some(&idx) = self.g.by_name.get(&callee.name) {
            let sig = &self.g.sigs[idx];
            return match sig.item.kind {
                ast::ItemKind::Function => self.inline_call(idx, callee, args, span, pre, false),
                ast::ItemKind::Primitive => {
                    self.sink.push(
                        err(
                            "E0410",
                            format!("primitive `{}` called inside an expression", callee.name),
                            span,
                            "a primitive call is a statement",
                        )
                        .help("write the call on its own: `name(args);`"),
                    );
                    None
                }
                ast::ItemKind::Surface | ast::ItemKind::Light | ast::ItemKind::Atmosphere => {
                    self.sink.push(err(
                        "E0108",
                        format!("shader `{}` cannot be called", callee.name),
                        span,
                        "called here",
                    ));
                    None
                }
                ast::ItemKind::Interpolator => {
                    self.sink.push(
                        err(
                            "E0108",
                            format!("shared interpolator `{}` cannot be called", callee.name),
                            span,
                            "called here",
                        )
                        .help("the application binds shading parameters to shared interpolators"),
                    );
                    None
                }
            };
        }
        match callee.name.as_str() {
            "transform" | "vtransform" | "ntransform" => return self.transform(callee, args, span, pre),
            "texture" => return self.texture(callee, args, span, pre),
            "clipping" => {
                if !args.is_empty() {
                    self.sink.push(err(
                        "E0210",
                        "`clipping` takes no arguments",
                        span,
                        "wrong number of arguments",
                    ));
                    return None;
                }
                return Some(mk(TreeKind::ClipFlag, Type::bool(), span));
            }
            "len" => {
                if args.len() != 1 {
                    self.sink.push(err(
                        "E0210",
                        "`len` takes one argument",
                        span,
                        "wrong number of arguments",
                    ));
                    return None;
                }
                let a = self.expr(&args[0], pre)?;
                if a.ty.per_seq {
                    return Some(mk(TreeKind::SeqCount, Type::int(), span));
                }
                let Some(&n) = a.ty.dims.first() else {
                    self.sink.push(err(
                        "E0210",
                        format!("`len` of a {}", type_name(&a.ty)),
                        args[0].span,
                        "not an array",
                    ));
                    return None;
                };
                return Some(types::const_expr(ConstValue::Int(n as i32), Scalar::Int, span));
            }
            _ => {}
        }
        let mut vals = vec![];
        for a in args {
            vals.push(self.expr(a, pre));
        }
        let vals: Vec<Tree> = vals.into_iter().collect::<Option<_>>()?;
        let internal = callee.name == "__gbuffer" && !self.g.linked;
        if matches!(callee.name.as_str(), "Dx" | "Dy" | "filterwidth") && !self.in_shader(callee) {
            return None;
        }
        match super::super::builtins::lower(&callee.name, vals, span) {
            Ok(Some(e)) if !internal => Some(e),
            Ok(_) => {
                let d = err(
                    "E0102",
                    format!("unknown function `{}`", callee.name),
                    callee.span,
                    "not defined",
                )
                .suggest(&callee.name, self.visible_functions());
                self.sink.push(d);
                None
            }
            Err((sp, msg, label)) => {
                self.sink.push(err("E0210", msg, sp, label));
                None
            }
        }
    }

    /// Whether the code is a shader's (a linked group's), where built-ins that take
    /// derivatives (`callee`) may be called; E1003 if not.
    fn in_shader(&mut self, callee: &ast::Ident) -> bool {
        if !self.g.linked {
            self.sink.push(err(
                "E1003",
                format!("`{}` outside a shader", callee.name),
                callee.span,
                "derivatives are taken between the pixels a shader runs on: only surface, light and atmosphere shaders take them",
            ));
        }
        self.g.linked
    }

    /// `texture("file", s, t)` or `texture("file", s, t, "wrap", "MODE")`: the file's slot,
    /// and `s`, `t` with their derivatives as operands (only shaders take derivatives).
    pub(super) fn texture(
        &mut self,
        callee: &ast::Ident,
        args: &[ast::Expr],
        span: Span,
        pre: &mut Vec<Stmt<Tree>>,
    ) -> Option<Tree> {
        use crate::runtime::texture::Wrap;
        if !self.in_shader(callee) {
            return None;
        }
        if args.len() != 3 && args.len() != 5 {
            self.sink.push(err(
                "E0210",
                format!("`texture` takes 3 or 5 arguments, found {}", args.len()),
                span,
                "texture(\"file.png\", s, t) or texture(\"file.png\", s, t, \"wrap\", \"clamp\")",
            ));
            return None;
        }
        let literal = |e: &ast::Expr| match &e.kind {
            ast::ExprKind::Str(s) => Some(s.clone()),
            _ => None,
        };
        let Some(name) = literal(&args[0]) else {
            self.sink.push(err(
                "E0210",
                "`texture` takes the file name as a string literal",
                args[0].span,
                "not a string literal",
            ));
            return None;
        };
        if name.is_empty() {
            // No texture (a `string` parameter left empty): white.
            let one = || types::const_expr(ConstValue::Float(1.0), Scalar::Float, span);
            let ty = Type::array(Elem::Scalar(Scalar::Float), vec![3]);
            return Some(mk(TreeKind::List(vec![one(), one(), one()]), ty, span));
        }
        let mut wrap = Wrap::Periodic;
        if args.len() == 5 {
            let mode = literal(&args[4]).and_then(|m| Wrap::from_name(&m));
            match (literal(&args[3]).as_deref(), mode) {
                (Some("wrap"), Some(m)) => wrap = m,
                _ => {
                    self.sink.push(
                        err(
                            "E0210",
                            "unknown `texture` option",
                            args[3].span.to(args[4].span),
                            "not a wrap mode",
                        )
                        .help(format!("the option is \"wrap\", one of {:?}", Wrap::NAMES)),
                    );
                    return None;
                }
            }
        }
        let mut coords = vec![];
        for a in &args[1..3] {
            let v = self.expr(a, pre)?;
            if !(matches!(v.ty.elem, Elem::Scalar(s) if types::is_number(s)) && v.ty.dims.is_empty() && !v.ty.per_seq) {
                self.sink.push(err(
                    "E0210",
                    format!("`texture` takes float coordinates, found {}", type_name(&v.ty)),
                    a.span,
                    "not a float",
                ));
                return None;
            }
            coords.push(convert(v, Scalar::Float));
        }
        let slot = {
            let mut names = self.g.textures.borrow_mut();
            match names.iter().position(|(n, _)| *n == name) {
                Some(i) => i,
                None => {
                    names.push((name, args[0].span));
                    names.len() - 1
                }
            }
        } as u32;
        let d = |func: Builtin, v: &Tree| {
            mk(
                TreeKind::Builtin {
                    func,
                    args: vec![v.clone()],
                },
                Type::float(),
                span,
            )
        };
        let (s, t) = (&coords[0], &coords[1]);
        let operands = vec![
            s.clone(),
            t.clone(),
            d(Builtin::Dx, s),
            d(Builtin::Dx, t),
            d(Builtin::Dy, s),
            d(Builtin::Dy, t),
        ];
        let func = Builtin::Texture {
            slot,
            wrap: wrap as u32,
        };
        let ty = Type::array(Elem::Scalar(Scalar::Float), vec![3]);
        Some(mk(TreeKind::Builtin { func, args: operands }, ty, span))
    }

    pub(super) fn transform(
        &mut self,
        callee: &ast::Ident,
        args: &[ast::Expr],
        span: Span,
        pre: &mut Vec<Stmt<Tree>>,
    ) -> Option<Tree> {
        if args.len() != 3 {
            self.sink.push(err(
                "E0210",
                format!("`{}` takes 3 arguments (from, to, value)", callee.name),
                span,
                "wrong number of arguments",
            ));
            return None;
        }
        let mut spaces = vec![];
        for a in &args[..2] {
            let sp = match &a.kind {
                ast::ExprKind::Str(s) => match s.as_str() {
                    "object" => Some(Space::Object),
                    "world" => Some(Space::World),
                    "lighting" => Some(Space::Lighting),
                    "device" => Some(Space::Device),
                    _ => None,
                },
                _ => None,
            };
            match sp {
                Some(s) => spaces.push(s),
                None => {
                    self.sink.push(
                        err("E0211", "unknown space name", a.span, "not a space name literal")
                            .help("spaces are \"object\", \"world\", \"lighting\" and \"device\""),
                    );
                    return None;
                }
            }
        }
        let v = self.expr(&args[2], pre)?;
        let (from, to) = (spaces[0], spaces[1]);
        let func = match callee.name.as_str() {
            "transform" => Builtin::TransformPoint { from, to },
            "vtransform" => Builtin::TransformVector { from, to },
            _ => Builtin::TransformNormal { from, to },
        };
        let okshape = matches!(v.ty.elem, Elem::Scalar(s) if types::is_number(s))
            && !v.ty.per_seq
            && (v.ty.dims == [3] || (v.ty.dims == [4] && callee.name == "transform"));
        if !okshape {
            self.sink.push(err(
                "E0210",
                format!("`{}` of a {}", callee.name, type_name(&v.ty)),
                args[2].span,
                "expected a point (float[4] or float[3]) or a vector/normal (float[3])",
            ));
            return None;
        }
        self.uses_spaces = true;
        let v = convert(v, Scalar::Float);
        let ty = v.ty.clone();
        Some(mk(TreeKind::Builtin { func, args: vec![v] }, ty, span))
    }

    pub(super) fn construct(
        &mut self,
        ty: &ast::TypeExpr,
        args: &[ast::Expr],
        span: Span,
        pre: &mut Vec<Stmt<Tree>>,
    ) -> Option<Tree> {
        use ast::TypeKind as K;
        let mut vals = vec![];
        for a in args {
            vals.push(self.expr(a, pre));
        }
        let vals: Vec<Tree> = vals.into_iter().collect::<Option<_>>()?;
        let arity = |this: &mut Self, what: &str, want: &str| {
            this.sink.push(err(
                "E0214",
                format!("`{what}(...)` takes {want}, found {} arguments", args.len()),
                span,
                "wrong number of arguments",
            ));
            None
        };
        let float_scalars = |this: &mut Self, vals: Vec<Tree>| -> Option<Vec<Tree>> {
            let mut out = vec![];
            for v in vals {
                if !v.ty.dims.is_empty() || v.ty.per_seq || !scalar_of(&v.ty).is_some_and(types::is_number) {
                    this.sink.push(err(
                        "E0214",
                        format!("constructor argument must be a number, found {}", type_name(&v.ty)),
                        v.span,
                        "not a number",
                    ));
                    return None;
                }
                out.push(convert(v, Scalar::Float));
            }
            Some(out)
        };
        let list = |items: Vec<Tree>, dims: Vec<u32>| {
            mk(
                TreeKind::List(items),
                Type::array(Elem::Scalar(Scalar::Float), dims),
                span,
            )
        };
        match &ty.kind {
            K::Point => {
                if !(3..=4).contains(&vals.len()) {
                    return arity(self, "point", "3 or 4");
                }
                let mut items = float_scalars(self, vals)?;
                if items.len() == 3 {
                    items.push(types::const_expr(ConstValue::Float(1.0), Scalar::Float, span));
                }
                Some(list(items, vec![4]))
            }
            K::Vector | K::Normal | K::Color => {
                let name = match ty.kind {
                    K::Vector => "vector",
                    K::Normal => "normal",
                    _ => "color",
                };
                if vals.len() != 3 && vals.len() != 1 {
                    return arity(self, name, "1 or 3");
                }
                let items = float_scalars(self, vals)?;
                if items.len() == 1 {
                    return Some(broadcast(items[0].clone(), &[3]));
                }
                Some(list(items, vec![3]))
            }
            K::Matrix => {
                if vals.len() != 16 {
                    return arity(self, "matrix", "16");
                }
                let items = float_scalars(self, vals)?;
                let rows = items.chunks(4).map(|r| list(r.to_vec(), vec![4])).collect();
                Some(list(rows, vec![4, 4]))
            }
            K::Float | K::Int | K::Fixed { .. } | K::Bool => {
                let t = resolve_type(ty, self.sink)?;
                let s = scalar_of(&t).expect("scalar types");
                if vals.len() != 1 {
                    return arity(self, &types::scalar_name(s), "1");
                }
                let v = vals.into_iter().next().expect("one argument");
                let from = scalar_of(&v.ty);
                match (from, s) {
                    (None, _) => {
                        self.sink.push(err(
                            "E0214",
                            "interpolation data cannot be converted",
                            v.span,
                            "interpolation data",
                        ));
                        None
                    }
                    (Some(f), t) if types::implicitly_converts(f, t) => Some(convert(v, t)),
                    // bool -> number: 1 or 0; number -> bool: != 0 (scalars only).
                    (Some(Scalar::Bool), t) if v.ty.is_scalar() => {
                        let one = convert(types::const_expr(ConstValue::Int(1), Scalar::Int, span), t);
                        let zero = convert(types::const_expr(ConstValue::Int(0), Scalar::Int, span), t);
                        Some(mk(
                            TreeKind::Select {
                                cond: Box::new(v),
                                then: Box::new(one),
                                otherwise: Box::new(zero),
                            },
                            Type::scalar(t),
                            span,
                        ))
                    }
                    (Some(f), Scalar::Bool) if v.ty.is_scalar() => {
                        let zero = types::const_expr(types::zero_const(f), f, span);
                        Some(bin(BinOp::Ne, v, zero, Type::bool(), span))
                    }
                    _ => {
                        self.sink.push(err(
                            "E0214",
                            format!("cannot convert {} to {}", type_name(&v.ty), types::scalar_name(s)),
                            v.span,
                            "only scalars convert between bool and numbers",
                        ));
                        None
                    }
                }
            }
            _ => {
                self.sink.push(err(
                    "E0214",
                    "this type cannot be constructed",
                    ty.span,
                    "no constructor",
                ));
                None
            }
        }
    }
}
