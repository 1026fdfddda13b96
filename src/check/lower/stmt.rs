//! Statements: blocks and scopes, declarations, assignments and places, conditions, loops,
//! `return`, `interpolation` blocks, `interpolator_return` and `bound`.
//!
//! Invariants: a statement whose lowering reports an error emits nothing (its
//! pre-statements included); every loop gets a fresh `LoopId` and a fuel site; a `return`
//! inside an inlined helper assigns the helper's result and breaks its one-trip loop.

use crate::diag::{Diagnostic, Span};
use crate::ir::tree::{Tree, TreeKind};
use crate::ir::{self, ArmKind, ConstValue, Elem, FuncKind, InterpArm, LocalKind, Place, Scalar, Stmt, StmtKind, Type};
use crate::syntax::ast;

use super::super::types::{self, convert, type_name};
use super::super::{LocalInfo, LocalWhat};
use super::*;

impl<'g, 'a> FnLower<'g, 'a> {
    // ---- blocks and statements ---------------------------------------------------------

    pub fn block(&mut self, stmts: &[ast::Stmt], out: &mut Vec<Stmt<Tree>>) {
        self.scopes.push(FxHashMap::default());
        self.stmts_in_scope(stmts, out);
        self.scopes.pop();
    }

    /// Lower statements in the current scope (a function body shares its parameters'
    /// scope, so redeclaring a parameter there is an error).
    pub fn stmts_in_scope(&mut self, stmts: &[ast::Stmt], out: &mut Vec<Stmt<Tree>>) {
        for s in stmts {
            self.stmt(s, out);
        }
    }

    pub(super) fn stmt(&mut self, s: &ast::Stmt, out: &mut Vec<Stmt<Tree>>) {
        if self.enter(1, s.span) {
            self.stmt_nested(s, out);
            self.leave(1);
        }
    }

    pub(super) fn stmt_nested(&mut self, s: &ast::Stmt, out: &mut Vec<Stmt<Tree>>) {
        use ast::StmtKind as K;
        match &s.kind {
            K::Error => {}
            K::Decl { quals, ty, vars } => self.decl(quals, ty, vars, out),
            K::Assign { target, op, value } => {
                let mut pre = vec![];
                if let Some(st) = self.assign(target, *op, value, s.span, &mut pre) {
                    out.extend(pre);
                    out.push(st);
                }
            }
            K::Expr(e) => self.expr_stmt(e, s.span, out),
            K::If { cond, then, otherwise } => {
                let mut pre = vec![];
                let Some(c) = self.cond(cond, &mut pre) else { return };
                let mut t = vec![];
                self.block(&then.stmts, &mut t);
                let mut o = vec![];
                if let Some(b) = otherwise {
                    self.block(&b.stmts, &mut o);
                }
                out.extend(pre);
                out.push(stmt(
                    StmtKind::If {
                        cond: c,
                        then: t,
                        otherwise: o,
                    },
                    s.span,
                ));
            }
            K::While { cond, body } => {
                self.scopes.push(FxHashMap::default());
                self.lower_loop(Some(cond), None, &body.stmts, s.span, out);
                self.scopes.pop();
            }
            K::For { init, cond, step, body } => {
                self.scopes.push(FxHashMap::default());
                if let Some(i) = init {
                    self.stmt(i, out);
                }
                self.lower_loop(cond.as_deref(), step.as_deref(), &body.stmts, s.span, out);
                self.scopes.pop();
            }
            K::Break | K::Continue => match self.loops.last() {
                Some(LoopCtx::Loop(id)) => out.push(stmt(
                    if matches!(s.kind, K::Break) {
                        StmtKind::Break(*id)
                    } else {
                        StmtKind::Continue(*id)
                    },
                    s.span,
                )),
                _ => {
                    let what = if matches!(s.kind, K::Break) {
                        "break"
                    } else {
                        "continue"
                    };
                    self.sink.push(err(
                        "E0401",
                        format!("`{what}` outside of a loop"),
                        s.span,
                        "not inside a loop",
                    ));
                }
            },
            K::Return(value) => self.ret(value.as_ref(), s.span, out),
            K::Interpolation { arms } => self.interpolation(arms, s.span, out),
            K::InterpolatorReturn(value) => self.interpolator_return(value.as_ref(), s.span, out),
            K::Bound(args) => self.bound(args, s.span, out),
            // A surface's `illuminance` is unrolled by `crate::link` before checking.
            K::Illuminance { .. } => self.sink.push(
                Diagnostic::error("E1001", "`illuminance` outside a surface shader")
                    .primary(s.span, "only the body of a `surface` may loop over lights"),
            ),
            K::Block(b) => self.block(&b.stmts, out),
        }
    }

    pub(super) fn decl(
        &mut self,
        quals: &ast::Qualifiers,
        ty: &ast::TypeExpr,
        vars: &[ast::DeclVar],
        out: &mut Vec<Stmt<Tree>>,
    ) {
        if let Some(sp) = quals.inout {
            self.sink.push(err(
                "E0504",
                "`inout` on a local variable",
                sp,
                "only the Z parameter may be inout",
            ));
        }
        let Some(base) = resolve_type(ty, self.sink) else {
            return;
        };
        let declared = quals.variability.map(|(v, sp)| (var_of(v), sp));
        for v in vars {
            let Some(dims) = resolve_dims(&v.dims, &base, self.sink) else {
                continue;
            };
            let t = Type::array(base.elem, dims);
            let mut pre = vec![];
            // The initialiser is lowered before the name is declared, so `float x = x;` in an
            // inner block reads the outer `x`.
            let value = match &v.init {
                Some(e) => self.expr_to(e, &t, &mut pre),
                None => Some(self.zero(&t, v.name.span)),
            };
            let id = self.new_local(
                &v.name.name,
                t,
                LocalKind::Var,
                v.name.span,
                LocalInfo {
                    declared,
                    what: LocalWhat::Variable,
                    read_only: false,
                },
            );
            self.declare(&v.name, id);
            if let Some(value) = value {
                out.extend(pre);
                out.push(stmt(
                    StmtKind::Assign {
                        place: Place {
                            local: id,
                            indices: vec![],
                            span: v.name.span,
                        },
                        value,
                    },
                    v.span,
                ));
            }
        }
    }

    /// The zero value of a type (interpolation data: a float 0 broadcast).
    pub(super) fn zero(&mut self, ty: &Type, span: Span) -> Tree {
        let scalar = match ty.elem {
            Elem::Scalar(s) => types::const_expr(types::zero_const(s), s, span),
            Elem::Interp => to_interp(types::const_expr(ConstValue::Float(0.0), Scalar::Float, span)),
        };
        broadcast(scalar, &ty.dims)
    }

    pub(super) fn assign(
        &mut self,
        target: &ast::Expr,
        op: ast::AssignOp,
        value: &ast::Expr,
        span: Span,
        pre: &mut Vec<Stmt<Tree>>,
    ) -> Option<Stmt<Tree>> {
        let (place, pty) = self.place(target, pre)?;
        let v = match op {
            ast::AssignOp::Set => self.expr_to(value, &pty, pre)?,
            _ => {
                let bop = match op {
                    ast::AssignOp::Add => ast::BinOp::Add,
                    ast::AssignOp::Sub => ast::BinOp::Sub,
                    ast::AssignOp::Mul => ast::BinOp::Mul,
                    _ => ast::BinOp::Div,
                };
                let cur = self.place_expr(&place, &pty);
                let rhs = self.expr(value, pre)?;
                let combined = self.binary(bop, cur, rhs, span)?;
                self.coerce(combined, &pty, value.span)?
            }
        };
        Some(stmt(StmtKind::Assign { place, value: v }, span))
    }

    /// Lower an assignment target. Parameters other than Z are read-only.
    pub(super) fn place(&mut self, e: &ast::Expr, pre: &mut Vec<Stmt<Tree>>) -> Option<(Place<Tree>, Type)> {
        match &e.kind {
            ast::ExprKind::Name(id) => {
                let Some(local) = self.lookup(&id.name) else {
                    let d = err(
                        "E0101",
                        format!("unknown variable `{}`", id.name),
                        id.span,
                        "not declared",
                    )
                    .suggest(&id.name, self.visible_values());
                    self.sink.push(d);
                    return None;
                };
                if self.infos[local.0 as usize].read_only {
                    let decl = self.locals[local.0 as usize].span;
                    self.sink.push(
                        err(
                            "E0402",
                            format!("parameter `{}` is read-only", id.name),
                            e.span,
                            "assigned here",
                        )
                        .secondary(decl, "declared as a parameter here")
                        .help("copy it into a local variable and change that"),
                    );
                    return None;
                }
                let ty = self.locals[local.0 as usize].ty.clone();
                Some((
                    Place {
                        local,
                        indices: vec![],
                        span: e.span,
                    },
                    ty,
                ))
            }
            ast::ExprKind::Index { base, index } => {
                let (mut place, ty) = self.place(base, pre)?;
                let idx = self.index_value(&ty, index, pre)?;
                let site = self.new_site(index.span);
                place.indices.push((idx, site));
                place.span = e.span;
                Some((place, ty.element()))
            }
            ast::ExprKind::Field { base, field } => self.field_place(e, base, field, pre),
            _ => {
                self.sink.push(err(
                    "E0403",
                    "cannot assign to this expression",
                    e.span,
                    "not a variable or an element of one",
                ));
                None
            }
        }
    }

    /// Read the current value of a place (for compound assignment and inout write-back).
    pub(super) fn place_expr(&self, place: &Place<Tree>, _ty: &Type) -> Tree {
        let mut e = self.local_expr(place.local, place.span);
        for (idx, site) in &place.indices {
            let ty = e.ty.element();
            e = mk(
                TreeKind::Index {
                    base: Box::new(e),
                    index: Box::new(idx.clone()),
                    site: *site,
                },
                ty,
                place.span,
            );
        }
        e
    }

    pub(super) fn expr_stmt(&mut self, e: &ast::Expr, span: Span, out: &mut Vec<Stmt<Tree>>) {
        if let ast::ExprKind::Call { callee, args } = &e.kind {
            if let Some(&idx) = self.g.by_name.get(&callee.name) {
                let sig = &self.g.sigs[idx];
                match sig.item.kind {
                    ast::ItemKind::Primitive => {
                        let mut pre = vec![];
                        if let Some(st) = self.call_primitive(idx, callee, args, span, &mut pre) {
                            out.extend(pre);
                            out.push(st);
                        }
                        return;
                    }
                    ast::ItemKind::Function => {
                        let mut pre = vec![];
                        if self.inline_call(idx, callee, args, span, &mut pre, true).is_some() {
                            out.extend(pre);
                        }
                        return;
                    }
                    ast::ItemKind::Interpolator
                    | ast::ItemKind::Surface
                    | ast::ItemKind::Light
                    | ast::ItemKind::Atmosphere => {}
                }
            }
        }
        let mut pre = vec![];
        if self.expr(e, &mut pre).is_some() {
            self.sink.push(
                Diagnostic::warning("W0002", "this statement has no effect")
                    .primary(e.span, "value computed and dropped"),
            );
        }
    }

    /// A bool scalar condition (with a hint for the C habit of testing numbers).
    pub(super) fn cond(&mut self, e: &ast::Expr, pre: &mut Vec<Stmt<Tree>>) -> Option<Tree> {
        let c = self.expr(e, pre)?;
        if c.ty != Type::bool() {
            self.sink.push(
                err(
                    "E0204",
                    "condition must be a bool",
                    e.span,
                    format!("this is {}", type_name(&c.ty)),
                )
                .help("compare with 0, e.g. `x != 0`"),
            );
            return None;
        }
        Some(c)
    }

    pub(super) fn lower_loop(
        &mut self,
        cond: Option<&ast::Expr>,
        step: Option<&ast::Stmt>,
        body: &[ast::Stmt],
        span: Span,
        out: &mut Vec<Stmt<Tree>>,
    ) {
        let id = self.new_loop();
        let site = self.new_site(span);
        let mut cond_pre = vec![];
        let c = match cond {
            Some(e) => match self.cond(e, &mut cond_pre) {
                Some(c) => Some(c),
                None => return,
            },
            None => None,
        };
        self.loops.push(LoopCtx::Loop(id));
        let mut b = vec![];
        // A condition that inlines a helper cannot be a `Loop::cond` (it needs statements
        // first): test it at the top of the body instead.
        let c = if cond_pre.is_empty() {
            c
        } else {
            b.extend(cond_pre);
            let c = c.expect("pre-statements come from a condition");
            let cspan = c.span;
            let not_c = mk(
                TreeKind::Unary {
                    op: ir::UnaryOp::Not,
                    expr: Box::new(c),
                },
                Type::bool(),
                cspan,
            );
            b.push(stmt(
                StmtKind::If {
                    cond: not_c,
                    then: vec![stmt(StmtKind::Break(id), cspan)],
                    otherwise: vec![],
                },
                cspan,
            ));
            None
        };
        self.block(body, &mut b);
        self.loops.pop();
        let mut st = vec![];
        if let Some(s) = step {
            // The step is outside the body's scope but inside the loop: `continue` reaches it.
            self.loops.push(LoopCtx::Barrier);
            self.stmt(s, &mut st);
            self.loops.pop();
        }
        out.push(stmt(
            StmtKind::Loop {
                id,
                cond: c,
                body: b,
                step: st,
                varying: false,
                site,
            },
            span,
        ));
    }

    pub(super) fn ret(&mut self, value: Option<&ast::Expr>, span: Span, out: &mut Vec<Stmt<Tree>>) {
        if let Some(frame) = self.inline.last() {
            let (exit, result, helper) = (frame.exit, frame.result, frame.helper);
            let g = self.g;
            let (hname, ret) = (&g.sigs[helper].item.name.name, g.sigs[helper].ret.as_ref());
            match (value, result, ret) {
                (Some(e), Some(r), Some(rt)) => {
                    let mut pre = vec![];
                    if let Some(v) = self.expr_to(e, rt, &mut pre) {
                        out.extend(pre);
                        out.push(stmt(
                            StmtKind::Assign {
                                place: Place {
                                    local: r,
                                    indices: vec![],
                                    span: e.span,
                                },
                                value: v,
                            },
                            span,
                        ));
                        out.push(stmt(StmtKind::Break(exit), span));
                    }
                }
                (None, None, _) => out.push(stmt(StmtKind::Break(exit), span)),
                (Some(e), None, _) => self.sink.push(err(
                    "E0404",
                    format!("`{hname}` returns void but this `return` has a value"),
                    e.span,
                    "unexpected value",
                )),
                (None, Some(_), _) | (Some(_), Some(_), None) => self.sink.push(err(
                    "E0404",
                    format!("`return;` without a value in helper `{hname}`, which returns a value"),
                    span,
                    "value missing",
                )),
            }
            return;
        }
        if let Some(e) = value {
            let what = match self.kind {
                FuncKind::Primitive => "a primitive",
                FuncKind::Interpolator => "an interpolator",
            };
            self.sink.push(
                err(
                    "E0404",
                    format!("`return` with a value in {what}"),
                    e.span,
                    "unexpected value",
                )
                .help(if self.kind == FuncKind::Interpolator {
                    "an interpolator gives its value with `interpolator_return(e);`"
                } else {
                    "a primitive's `return;` ends it for this pixel; results go through `interpolator_return`"
                }),
            );
            return;
        }
        out.push(stmt(StmtKind::Return, span));
    }

    pub(super) fn interpolation(&mut self, arms: &[ast::InterpArm], span: Span, out: &mut Vec<Stmt<Tree>>) {
        if self.kind != FuncKind::Primitive || self.in_helper() {
            let where_ = if self.in_helper() {
                "a helper function"
            } else {
                "an interpolator"
            };
            self.sink.push(err(
                "E0406",
                format!("`interpolation` construct in {where_}"),
                span,
                "only allowed in a primitive's body",
            ));
            return;
        }
        if self.in_interpolation {
            self.sink.push(err(
                "E0406",
                "nested `interpolation` construct",
                span,
                "inside another interpolation arm",
            ));
            return;
        }
        let mut seen: FxHashMap<String, Span> = FxHashMap::default();
        let mut default_seen: Option<Span> = None;
        let mut ir_arms = vec![];
        self.in_interpolation = true;
        for (i, arm) in arms.iter().enumerate() {
            let (kind, is_default) = match &arm.kind {
                ast::InterpArmKind::Named(id) => {
                    if let Some(prev) = seen.get(&id.name) {
                        self.sink.push(
                            err(
                                "E0407",
                                format!("interpolation kind `{}` has two arms", id.name),
                                id.span,
                                "again here",
                            )
                            .secondary(*prev, "first arm here"),
                        );
                        continue;
                    }
                    seen.insert(id.name.clone(), id.span);
                    (ArmKind::Named(id.name.clone()), false)
                }
                ast::InterpArmKind::Default(sp) => {
                    if let Some(prev) = default_seen {
                        self.sink.push(
                            err("E0407", "two `default:` arms", *sp, "again here")
                                .secondary(prev, "first default here"),
                        );
                        continue;
                    }
                    default_seen = Some(*sp);
                    (ArmKind::Default, true)
                }
            };
            // Stacked labels (`perspective_linear: linear: ...`) share the next arm's body,
            // as in a C switch.
            let body = if arm.body.is_empty() {
                arms[i + 1..]
                    .iter()
                    .find(|a| !a.body.is_empty())
                    .map_or(&arm.body[..], |a| &a.body[..])
            } else {
                &arm.body[..]
            };
            let saved = self.arm.replace(is_default);
            let mut b = vec![];
            self.block(body, &mut b);
            self.arm = saved;
            ir_arms.push(InterpArm {
                kind,
                body: b,
                span: arm.span,
            });
        }
        self.in_interpolation = false;
        out.push(stmt(StmtKind::Interpolation { arms: ir_arms }, span));
    }

    pub(super) fn interpolator_return(&mut self, value: Option<&ast::Expr>, span: Span, out: &mut Vec<Stmt<Tree>>) {
        if self.in_helper() {
            self.sink.push(err(
                "E0408",
                "`interpolator_return` in a helper function",
                span,
                "only allowed in primitives and interpolators",
            ));
            return;
        }
        let mut pre = vec![];
        match (self.kind, value) {
            (FuncKind::Interpolator, None) => {
                self.sink.push(
                    err(
                        "E0408",
                        "`interpolator_return;` without a value in an interpolator",
                        span,
                        "value missing",
                    )
                    .help("an interpolator gives its value with `interpolator_return(e);`"),
                );
            }
            (FuncKind::Interpolator, Some(e)) => {
                let Some(v) = self.float_result(e, false, &mut pre) else {
                    return;
                };
                self.interp_returns.push((v.ty.clone(), e.span));
                out.extend(pre);
                out.push(stmt(StmtKind::InterpolatorReturn(Some(v)), span));
            }
            (FuncKind::Primitive, None) => {
                if self.arm == Some(false) {
                    self.sink.push(
                        err(
                            "E0408",
                            "`interpolator_return;` without a value in a named interpolation arm",
                            span,
                            "value missing",
                        )
                        .help("only a `default:` arm (or code outside `interpolation`) runs the shared interpolators"),
                    );
                    return;
                }
                out.push(stmt(StmtKind::InterpolatorReturn(None), span));
            }
            (FuncKind::Primitive, Some(e)) => {
                if self.arm.is_none() {
                    self.sink.push(
                        err(
                            "E0408",
                            "`interpolator_return(e)` outside an interpolation arm",
                            span,
                            "no interpolation kind to store into",
                        )
                        .help("put it in an arm of `interpolation { KIND: ... }`"),
                    );
                    return;
                }
                let Some(v) = self.float_result(e, true, &mut pre) else {
                    return;
                };
                out.extend(pre);
                out.push(stmt(StmtKind::InterpolatorReturn(Some(v)), span));
            }
        }
    }

    /// A value `interpolator_return` may store: interpolation data (if allowed), a float
    /// scalar or a float aggregate; other numbers are converted to float.
    pub(super) fn float_result(&mut self, e: &ast::Expr, interp_ok: bool, pre: &mut Vec<Stmt<Tree>>) -> Option<Tree> {
        let v = self.expr(e, pre)?;
        match v.ty.elem {
            Elem::Interp if interp_ok && v.ty.dims.is_empty() => Some(v),
            Elem::Scalar(s) if types::is_number(s) && !v.ty.per_seq => Some(convert(v, Scalar::Float)),
            _ => {
                let expected = if interp_ok {
                    "interpolation data, a float or a float aggregate"
                } else {
                    "a float or a float aggregate"
                };
                self.sink.push(err(
                    "E0408",
                    format!("`interpolator_return` takes {expected}"),
                    e.span,
                    format!("this is {}", type_name(&v.ty)),
                ));
                None
            }
        }
    }

    pub(super) fn bound(&mut self, args: &[ast::Expr], span: Span, out: &mut Vec<Stmt<Tree>>) {
        if self.kind != FuncKind::Primitive || self.in_helper() {
            self.sink.push(err(
                "E0409",
                "`bound` outside a primitive's own body",
                span,
                "only a primitive can bound its pixels",
            ));
            return;
        }
        if args.len() != 4 {
            self.sink.push(err(
                "E0409",
                format!(
                    "`bound` takes 4 arguments (xmin, ymin, xmax, ymax), found {}",
                    args.len()
                ),
                span,
                "wrong number of arguments",
            ));
            return;
        }
        let mut pre = vec![];
        let mut vals = vec![];
        for a in args {
            vals.push(self.expr_to(a, &Type::float(), &mut pre));
        }
        let vals: Option<Vec<Tree>> = vals.into_iter().collect();
        let Some(vals) = vals else { return };
        let Ok(arr): Result<[Tree; 4], _> = vals.try_into() else {
            return;
        };
        out.extend(pre);
        out.push(stmt(StmtKind::Bound(arr), span));
    }
}
