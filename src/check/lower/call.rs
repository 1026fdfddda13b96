//! Calls: primitive calls (`CallPrimitive`, arguments checked against the callee's
//! signature, defaults filled in) and helper calls, inlined at the call site as a one-trip
//! loop (see the parent module).
//!
//! Invariants: an inlined helper's parameters are fresh `Temp` locals assigned before its
//! loop, except an `inout` argument naming a whole variable that no other argument reads
//! (the parameter is that variable); inlining depth is bounded by
//! [`crate::limits::MAX_CALL_DEPTH`] (E0110).

use crate::diag::Span;
use crate::ir::tree::Tree;
use crate::ir::{ConstValue, FuncKind, LocalId, LocalKind, ParamRole, Place, Scalar, Stmt, StmtKind};
use crate::syntax::ast;

use super::super::types::{self, type_name};
use super::super::{consts, LocalInfo, LocalWhat, SigParam, Signature};
use super::*;

impl<'g, 'a> FnLower<'g, 'a> {
    // ---- calls ------------------------------------------------------------------------

    pub(super) fn call_primitive(
        &mut self,
        idx: usize,
        callee: &ast::Ident,
        args: &[ast::Expr],
        span: Span,
        pre: &mut Vec<Stmt<Tree>>,
    ) -> Option<Stmt<Tree>> {
        let sig: &Signature = &self.g.sigs[idx];
        if self.kind != FuncKind::Primitive || self.in_helper() {
            let where_ = if self.in_helper() {
                "a helper function"
            } else {
                "an interpolator"
            };
            self.sink.push(err(
                "E0410",
                format!("call to primitive `{}` in {where_}", callee.name),
                span,
                "only a primitive can render another primitive",
            ));
            return None;
        }
        if args.len() > sig.params.len() {
            self.sink.push(arity_error(
                "primitive",
                callee,
                sig,
                args.len(),
                span,
                "too many arguments",
            ));
            return None;
        }
        // Too few arguments are reported alone, as too many are: with some left out, which
        // parameter each given argument was meant for is unknown, and checking them against
        // the first parameters would add a mismatch per argument.
        let missing: Vec<String> = sig.params[args.len()..]
            .iter()
            .filter(|p| p.default.is_none())
            .map(|p| format!("`{}`", p.name))
            .collect();
        if !missing.is_empty() {
            self.sink.push(
                err(
                    "E0215",
                    format!("missing arguments for {} of `{}`", missing.join(", "), callee.name),
                    span,
                    "arguments missing",
                )
                .secondary(
                    sig.item.name.span,
                    "declared here; only trailing parameters with defaults may be left out",
                ),
            );
            return None;
        }
        let mut out = vec![];
        let mut ok = true;
        for (i, p) in sig.params.iter().enumerate() {
            let Some(a) = args.get(i) else {
                if let Some(vals) = &p.default {
                    out.push(consts::const_to_expr(vals, &p.ty, span));
                }
                continue;
            };
            match p.role {
                ParamRole::X | ParamRole::Y | ParamRole::Z => match self.passed_through(p, a, &callee.name) {
                    Some(e) => out.push(e),
                    None => ok = false,
                },
                // A per-sequence-point parameter takes a fixed-size array of its elements: the
                // callee's sequence points are that array's elements (the kernel builds the
                // callee's argument block with a size known at compile time).
                _ if p.ty.per_seq => match self.expr(a, pre) {
                    Some(v)
                        if !v.ty.per_seq && v.ty.elem == p.ty.elem && v.ty.dims.get(1..) == Some(&p.ty.dims[..]) =>
                    {
                        out.push(v)
                    }
                    Some(v) => {
                        let help = if v.ty.per_seq {
                            "copy the sequence points into a fixed-size array first, e.g. `float v[3][4] = {vertex[0], vertex[1], vertex[2]};`"
                        } else {
                            "pass an array whose elements have the parameter's element type"
                        };
                        self.sink.push(
                            err(
                                "E0413",
                                format!(
                                    "argument for per-sequence-point parameter `{}` of `{}` must be a fixed-size array of {}, found {}",
                                    p.name,
                                    callee.name,
                                    types::type_name(&p.ty.element()),
                                    types::type_name(&v.ty)
                                ),
                                a.span,
                                format!("this is {}", types::type_name(&v.ty)),
                            )
                            .help(help),
                        );
                        ok = false;
                    }
                    None => ok = false,
                },
                _ => match self.expr_to(a, &p.ty, pre) {
                    Some(v) => out.push(v),
                    None => ok = false,
                },
            }
        }
        if !ok {
            return None;
        }
        let site = self.new_site(span);
        Some(stmt(
            StmtKind::CallPrimitive {
                callee: sig.func.expect("primitives have a FuncId"),
                args: out,
                site,
            },
            span,
        ))
    }

    /// The argument `a` for the callee's X, Y or Z parameter `p`: it must be this
    /// primitive's own, of the callee's type, since the callee works on it in place (E0410
    /// otherwise, and `None`).
    fn passed_through(&mut self, p: &SigParam, a: &ast::Expr, callee: &str) -> Option<Tree> {
        let want = match p.role {
            ParamRole::X => self.xyz[0],
            ParamRole::Y => self.xyz[1],
            _ => self.xyz[2],
        };
        let given = match &a.kind {
            ast::ExprKind::Name(id) => self.lookup(&id.name),
            _ => None,
        };
        match want {
            // The callee writes the caller's Z in place: the same type or nothing.
            Some(w) if given == Some(w) && self.locals[w.0 as usize].ty != p.ty => {
                let (mine, theirs) = (type_name(&self.locals[w.0 as usize].ty), type_name(&p.ty));
                self.sink.push(
                    err(
                        "E0410",
                        format!(
                            "`{}` of `{}` is `{theirs}`, but this primitive's own is `{mine}`",
                            p.name, callee
                        ),
                        a.span,
                        format!("this is `{mine}`"),
                    )
                    .help("a sub-primitive works on its caller's X, Y and Z in place: declare them with the callee's types"),
                );
                None
            }
            Some(w) if given == Some(w) => Some(self.local_expr(w, a.span)),
            _ => {
                let rname = match p.role {
                    ParamRole::X => "X",
                    ParamRole::Y => "Y",
                    _ => "Z",
                };
                self.sink.push(
                    err(
                        "E0410",
                        format!(
                            "argument for `{}` of `{}` must be this primitive's own `{rname}`",
                            p.name, callee
                        ),
                        a.span,
                        format!("expected this primitive's `{rname}` parameter"),
                    )
                    .help("a sub-primitive renders at the same pixel: pass X, Y and Z through"),
                );
                None
            }
        }
    }

    /// Whether helper `idx` may be inlined at this call: not recursive, within the inlining
    /// budget (E0109) and the nesting limit (E0110), used as a value only if it returns one
    /// (E0214), with an argument for every parameter without a default. Reports why not.
    fn may_inline(
        &mut self,
        idx: usize,
        callee: &ast::Ident,
        args: &[ast::Expr],
        span: Span,
        as_statement: bool,
    ) -> bool {
        let g = self.g;
        let sig = &g.sigs[idx];
        // The callee as it was declared (the same name as `callee`, which found it).
        let helper_name: &'a str = &sig.item.name.name;
        if g.recursive.contains(&idx) {
            // The cycle was reported once where it is; inlining would not terminate.
            return false;
        }
        // Helpers calling helpers several times each can multiply the inlined code
        // exponentially; past a budget, stop with an error instead of running out of memory.
        if self.inline.is_empty() {
            self.outermost_call = span;
        }
        self.inlined += 1;
        if self.inlined > INLINE_BUDGET {
            if self.inlined == INLINE_BUDGET + 1 && self.report_budget {
                self.sink.push(
                    err(
                        "E0109",
                        format!("too many helper calls to inline (more than {INLINE_BUDGET})"),
                        self.outermost_call,
                        "inlining this call needs too much code",
                    )
                    .secondary(span, "the budget ran out at this nested call")
                    .help(
                        "helpers are inlined at every call; nested helpers that call each other several times multiply",
                    ),
                );
            }
            return false;
        }
        // A chain of helpers inlines one inside another; past the limit, stop before this
        // pass recurses into the callee.
        if self.inline.len() as u32 >= MAX_CALL_DEPTH {
            if self.report_budget {
                let mut chain: Vec<&str> = self
                    .inline
                    .iter()
                    .map(|f| g.sigs[f.helper].item.name.name.as_str())
                    .collect();
                chain.push(helper_name);
                let n = chain.len();
                let shown = if n > 6 {
                    format!("{} -> ... -> {}", chain[..3].join(" -> "), chain[n - 3..].join(" -> "))
                } else {
                    chain.join(" -> ")
                };
                let mut d = err(
                    "E0110",
                    format!("helper calls nested too deeply (more than {MAX_CALL_DEPTH})"),
                    span,
                    format!("this call would inline `{helper_name}` as helper {n} of a chain"),
                )
                .help(format!("the chain of calls: {shown}"));
                if self.outermost_call != span {
                    d = d.secondary(self.outermost_call, "the chain starts with this call");
                }
                self.sink.push(d);
            }
            return false;
        }
        if sig.ret.is_none() && !as_statement {
            self.sink.push(
                err(
                    "E0214",
                    format!("helper `{}` returns void; it has no value", callee.name),
                    span,
                    "used as a value",
                )
                .secondary(sig.item.name.span, "declared void here"),
            );
            return false;
        }
        if args.len() > sig.params.len() || (args.len() < sig.params.len() && sig.params[args.len()].default.is_none())
        {
            self.sink.push(arity_error(
                "helper",
                callee,
                sig,
                args.len(),
                span,
                "wrong number of arguments",
            ));
            return false;
        }
        true
    }

    /// Inline helper `idx` at a call site. Returns the result expression (`Local(result)`
    /// or, for a void helper called as a statement, a placeholder constant).
    pub(super) fn inline_call(
        &mut self,
        idx: usize,
        callee: &ast::Ident,
        args: &[ast::Expr],
        span: Span,
        pre: &mut Vec<Stmt<Tree>>,
        as_statement: bool,
    ) -> Option<Tree> {
        if !self.may_inline(idx, callee, args, span, as_statement) {
            return None;
        }
        let g = self.g;
        let sig = &g.sigs[idx];
        let helper_name: &'a str = &sig.item.name.name;
        // Arguments, by value into fresh temporaries; inout ones remember their place, or
        // are the parameter themselves (see `Self::inout_alias`).
        let mut param_locals = vec![];
        let mut write_back = vec![];
        let mut ok = true;
        for (i, p) in sig.params.iter().enumerate() {
            let value = match args.get(i) {
                Some(a) if p.inout => match self.place(a, pre) {
                    Some((place, pty)) => {
                        if pty != p.ty {
                            self.sink.push(
                                err(
                                    "E0205",
                                    format!(
                                        "inout argument of type {} for parameter `{}` of type {}",
                                        type_name(&pty),
                                        p.name,
                                        type_name(&p.ty)
                                    ),
                                    a.span,
                                    "types must be the same for inout",
                                )
                                .secondary(p.span, "parameter declared here"),
                            );
                            ok = false;
                            continue;
                        }
                        if self.inout_alias(p, &place, args, i) {
                            param_locals.push(place.local);
                            continue;
                        }
                        let cur = self.place_expr(&place, &pty);
                        write_back.push((i, place));
                        Some(cur)
                    }
                    None => None,
                },
                Some(a) => self.expr_to(a, &p.ty, pre),
                None => p.default.as_ref().map(|vals| consts::const_to_expr(vals, &p.ty, span)),
            };
            let Some(value) = value else {
                ok = false;
                continue;
            };
            let t = self.new_local(
                &p.name,
                p.ty.clone(),
                LocalKind::Temp,
                p.span,
                LocalInfo {
                    declared: p.declared,
                    what: LocalWhat::HelperParam(helper_name),
                    read_only: false,
                },
            );
            pre.push(stmt(
                StmtKind::Assign {
                    place: Place {
                        local: t,
                        indices: vec![],
                        span: value.span,
                    },
                    value,
                },
                span,
            ));
            param_locals.push(t);
        }
        if !ok {
            return None;
        }
        let result = self.inline_body(idx, &param_locals, span, pre);
        for (i, place) in write_back {
            let t = param_locals[i];
            let v = self.local_expr(t, span);
            pre.push(stmt(StmtKind::Assign { place, value: v }, span));
        }
        Some(match result {
            Some(r) => self.local_expr(r, span),
            None => types::const_expr(ConstValue::Int(0), Scalar::Int, span),
        })
    }

    /// Can the variable `place` names stand for inout parameter `p` (argument `i` of
    /// `args`) in the inlined body, instead of a copy in and a copy out? Only a whole
    /// variable that no other argument names: then nothing reads or writes it between the
    /// copy in and the copy out but the body, through the parameter, so every read sees
    /// what the copy would hold (for an array the copies were a load and a store per
    /// element each way: nurb_surface's de Boor weights and points). Not when the parameter
    /// or the variable declares its variability: the copies are where those rules are
    /// checked, and where their errors point.
    pub(super) fn inout_alias(&self, p: &SigParam, place: &Place<Tree>, args: &[ast::Expr], i: usize) -> bool {
        let ast::ExprKind::Name(id) = &args[i].kind else {
            return false;
        };
        place.indices.is_empty()
            && p.declared.is_none()
            && self.infos[place.local.0 as usize].declared.is_none()
            && !args.iter().enumerate().any(|(j, a)| j != i && mentions(a, &id.name))
    }

    /// Lower helper `idx`'s body as a one-trip loop with its parameters bound to
    /// `param_locals`; returns the result temporary of a non-void helper.
    pub fn inline_body(
        &mut self,
        idx: usize,
        param_locals: &[LocalId],
        span: Span,
        pre: &mut Vec<Stmt<Tree>>,
    ) -> Option<LocalId> {
        let g = self.g;
        let sig = &g.sigs[idx];
        let result = sig.ret.clone().map(|rt| {
            self.new_local(
                &format!("{}_result", sig.item.name.name),
                rt,
                LocalKind::Temp,
                span,
                LocalInfo {
                    declared: None,
                    what: LocalWhat::Result(&sig.item.name.name),
                    read_only: false,
                },
            )
        });
        let exit = self.new_loop();
        let site = self.new_site(span);
        // The helper sees only its own parameters: a fresh scope stack, no enclosing loops.
        let saved_scopes = std::mem::replace(&mut self.scopes, vec![FxHashMap::default()]);
        for (p, &l) in sig.item.params.iter().zip(param_locals) {
            self.declare_param(&p.name.name, l);
        }
        self.loops.push(LoopCtx::Barrier);
        self.inline.push(InlineFrame {
            helper: idx,
            exit,
            result,
        });
        let saved_arm = self.arm.take();
        let saved_interp = std::mem::replace(&mut self.in_interpolation, false);
        let diags_before = self.sink.items.len();
        let mut body = vec![];
        // The body is lowered two levels deeper than the call (the inlining and its loop).
        let entered = self.enter(2, span);
        if entered {
            self.stmts_in_scope(&sig.item.body.stmts, &mut body);
            self.leave(2);
        }
        if entered && self.sink.items.len() == diags_before && self.inlined <= INLINE_BUDGET {
            self.lowered_cleanly.push(idx);
        }
        // Falling off the end leaves the helper too (unless it just returned).
        if !matches!(body.last(), Some(Stmt { kind: StmtKind::Break(l), .. }) if *l == exit) {
            body.push(stmt(StmtKind::Break(exit), sig.item.body.span));
        }
        self.arm = saved_arm;
        self.in_interpolation = saved_interp;
        self.inline.pop();
        self.loops.pop();
        self.scopes = saved_scopes;
        pre.push(stmt(
            StmtKind::Loop {
                id: exit,
                cond: None,
                body,
                step: vec![],
                varying: false,
                site,
            },
            span,
        ));
        result
    }
}
