//! Lowering one primitive or interpolator body from the AST to IR statements.
//!
//! [`FnLower`] resolves names through a stack of block scopes, types every expression
//! (inserting `Convert` where the type rules of [`super::types`] ask for it) and inlines helper
//! functions at their call sites. Lowering of an expression returns `None` after reporting an
//! error, and the enclosing statement is dropped, so one mistake gives one diagnostic.
//!
//! After this pass every IR expression has its final type; variabilities are placeholders
//! (uniform) that [`super::variability`] fills in. The whole body is in `Function::setup`.
//!
//! Helper inlining: a call becomes pre-statements — the arguments assigned to fresh `Temp`
//! locals, then `Loop { cond: None, body: [helper body..., Break(L)] }` in which `return e`
//! is `result = e; break L` — and the call expression becomes `Local(result)`. The argument
//! assignments sit before the loop (not inside it, as a first draft of the design had
//! it) so that a varying `return` inside the helper, which makes the loop varying, does not
//! make the parameter copies "assigned under varying control flow".

use rustc_hash::FxHashMap;

use crate::diag::{Diagnostic, Span};
use crate::ir::{
    self, ArmKind, BinOp, Builtin, ConstValue, Elem, Expr, ExprKind, FuncKind, InterpArm, Local, LocalId, LocalKind,
    LoopId, ParamRole, Place, Scalar, SiteId, Space, Stmt, StmtKind, Type, Variability,
};
use crate::limits::{MAX_CALL_DEPTH, MAX_NESTING};
use crate::syntax::ast;

use super::types::{self, convert, scalar_of, type_name};
use super::{consts, Globals, LocalInfo, LocalWhat, SigParam, Signature, Sink};

/// What an enclosing construct lets `break`/`continue` reach.
#[derive(Clone, Copy)]
enum LoopCtx {
    Loop(LoopId),
    /// An inlined helper's body: loops outside it are not reachable.
    Barrier,
}

struct InlineFrame {
    helper: usize,
    exit: LoopId,
    result: Option<LocalId>,
}

/// Lowers the bodies of one IR function (and of the helpers inlined into it).
pub struct FnLower<'g, 'a> {
    g: &'g Globals<'a>,
    pub sink: &'g mut Sink,
    sites: &'g mut Vec<Span>,
    pub kind: FuncKind,
    pub locals: Vec<Local>,
    pub infos: Vec<LocalInfo<'a>>,
    scopes: Vec<FxHashMap<String, LocalId>>,
    loops: Vec<LoopCtx>,
    inline: Vec<InlineFrame>,
    pub n_loops: u32,
    pub uses_spaces: bool,
    /// Inside an `interpolation` arm: `Some(is_default)`.
    arm: Option<bool>,
    in_interpolation: bool,
    /// Result types of an interpolator's `interpolator_return(e)`s.
    pub interp_returns: Vec<(Type, Span)>,
    /// This function's X, Y and Z parameters.
    xyz: [Option<LocalId>; 3],
    /// Helper calls inlined so far into this function.
    inlined: u32,
    /// The call written in the function itself that the current inlining started from.
    outermost_call: Span,
    /// Report running out of the inlining budget (off when a helper is checked on its own:
    /// only a call from a primitive or interpolator really inlines it).
    pub report_budget: bool,
    /// Helpers whose body was lowered here without a diagnostic the sink did not already
    /// hold and within the inlining budget (see [`super::check_helper`]).
    pub lowered_cleanly: Vec<usize>,
    /// Expression and statement levels (and two per inlined call) open now, counted
    /// through inlined helpers: the depth of this pass's own recursion, kept within
    /// [`MAX_NESTING`].
    nesting: u32,
    /// E0111 was reported for this function.
    nesting_reported: bool,
}

/// Most helper calls inlined into one function.
pub const INLINE_BUDGET: u32 = 20_000;

fn err(code: &'static str, msg: impl Into<String>, span: Span, label: impl Into<String>) -> Diagnostic {
    Diagnostic::error(code, msg).primary(span, label)
}

/// E0215: a call to `what` (primitive or helper) `callee` with `given` arguments.
fn arity_error(what: &str, callee: &ast::Ident, sig: &Signature, given: usize, span: Span, label: &str) -> Diagnostic {
    err(
        "E0215",
        format!(
            "{what} `{}` takes {} arguments, found {given}",
            callee.name,
            sig.params.len()
        ),
        span,
        label,
    )
    .secondary(sig.item.name.span, "declared here")
}

fn mk(kind: ExprKind, ty: Type, span: Span) -> Expr {
    Expr::new(kind, ty, Variability::Uniform, span)
}

fn stmt(kind: StmtKind, span: Span) -> Stmt {
    Stmt { kind, span }
}

/// Built-in function names (they may not be redefined by items).
pub const BUILTIN_NAMES: &[&str] = &[
    "sqrt",
    "abs",
    "min",
    "max",
    "clamp",
    "floor",
    "ceil",
    "round",
    "sin",
    "cos",
    "tan",
    "asin",
    "acos",
    "atan",
    "pow",
    "exp",
    "log",
    "sign",
    "mix",
    "step",
    "smoothstep",
    "dot",
    "cross",
    "length",
    "normalize",
    "distance",
    "transform",
    "vtransform",
    "ntransform",
    "len",
    "clipping",
    "bound",
    "PI",
];

/// Resolve a written type (without declarator dimensions).
pub fn resolve_type(t: &ast::TypeExpr, sink: &mut Sink) -> Option<Type> {
    use ast::TypeKind as K;
    let f3 = || Type::array(Elem::Scalar(Scalar::Float), vec![3]);
    Some(match &t.kind {
        K::Float => Type::float(),
        K::Int => Type::int(),
        K::Bool => Type::bool(),
        K::Fixed { bits, frac } => {
            if !(1..=32).contains(bits) || *frac < 0 || frac > bits {
                sink.push(
                    err(
                        "E0201",
                        format!("invalid fixed-point format fixed<{bits},{frac}>"),
                        t.span,
                        "not a valid format",
                    )
                    .help("fixed<B,F> needs 1 <= B <= 32 total bits and 0 <= F <= B fraction bits"),
                );
                return None;
            }
            Type::scalar(Scalar::Fixed(ir::FixedFormat {
                bits: *bits as u8,
                frac: *frac as u8,
            }))
        }
        K::Point => Type::array(Elem::Scalar(Scalar::Float), vec![4]),
        K::Vector | K::Normal | K::Color => f3(),
        K::Matrix => Type::array(Elem::Scalar(Scalar::Float), vec![4, 4]),
        K::InterpolationData => Type::scalar_interp(),
        K::String => {
            sink.push(
                err("E0214", "`string` values are not supported", t.span, "string type")
                    .help("a string may only appear as a space name literal in transform()"),
            );
            return None;
        }
        K::Void => {
            sink.push(err(
                "E0214",
                "`void` is only a helper function's return type",
                t.span,
                "void type",
            ));
            return None;
        }
    })
}

trait InterpType {
    fn scalar_interp() -> Type;
}
impl InterpType for Type {
    fn scalar_interp() -> Type {
        Type::array(Elem::Interp, vec![])
    }
}

/// Evaluate declarator dimensions (`[4][4]`): constant positive ints, at most 65536
/// components in all (including the base type's own).
pub fn resolve_dims(dims: &[ast::ArrayDim], base: &Type, sink: &mut Sink) -> Option<Vec<u32>> {
    let mut out = vec![];
    let mut total: u64 = base.fixed_len() as u64;
    for d in dims {
        match d {
            ast::ArrayDim::Sized(e) => match consts::eval(e) {
                Ok(consts::ConstTree::Int(n)) if n > 0 => {
                    total = total.saturating_mul(n as u64);
                    if total > 65536 {
                        sink.push(
                            err("E0208", "array too large", e.span, "more than 65536 components in all")
                                .help("an array may hold at most 65536 components"),
                        );
                        return None;
                    }
                    out.push(n as u32);
                }
                Ok(_) => {
                    sink.push(err(
                        "E0208",
                        "array dimension must be a positive integer constant",
                        e.span,
                        "not a positive int",
                    ));
                    return None;
                }
                Err((span, why)) => {
                    sink.push(err("E0208", "array dimension must be a constant", span, why));
                    return None;
                }
            },
            ast::ArrayDim::Unsized(span) => {
                sink.push(
                    err(
                        "E0505",
                        "unsized array `[]` here",
                        *span,
                        "only a primitive's parameter may be unsized",
                    )
                    .help("unsized arrays are per-sequence-point parameters of primitives"),
                );
                return None;
            }
        }
    }
    out.extend(base.dims.iter().copied());
    Some(out)
}

impl<'g, 'a> FnLower<'g, 'a> {
    pub fn new(g: &'g Globals<'a>, sink: &'g mut Sink, sites: &'g mut Vec<Span>, kind: FuncKind) -> Self {
        FnLower {
            g,
            sink,
            sites,
            kind,
            locals: vec![],
            infos: vec![],
            scopes: vec![FxHashMap::default()],
            loops: vec![],
            inline: vec![],
            n_loops: 0,
            uses_spaces: false,
            arm: None,
            in_interpolation: false,
            interp_returns: vec![],
            xyz: [None; 3],
            inlined: 0,
            outermost_call: Span::default(),
            report_budget: true,
            lowered_cleanly: vec![],
            nesting: 0,
            nesting_reported: false,
        }
    }

    // ---- depth ------------------------------------------------------------------------

    /// Open `levels` levels of nesting for the construct at `span`; false (after E0111,
    /// once per function) when that goes past [`MAX_NESTING`]: the caller then lowers
    /// nothing below it and does not call [`Self::leave`].
    fn enter(&mut self, levels: u32, span: Span) -> bool {
        if self.nesting + levels > MAX_NESTING {
            if !self.nesting_reported && self.report_budget {
                self.nesting_reported = true;
                self.sink.push(
                    err(
                        "E0111",
                        format!("nested too deeply after inlining helpers (more than {MAX_NESTING} levels)"),
                        span,
                        "this is past the limit",
                    )
                    .secondary(self.outermost_call, "in the helpers inlined for this call")
                    .help("expressions, statements and helper calls nest through every helper a call inlines"),
                );
            }
            return false;
        }
        self.nesting += levels;
        true
    }

    fn leave(&mut self, levels: u32) {
        self.nesting -= levels;
    }

    // ---- locals, scopes, ids ----------------------------------------------------------

    pub fn new_local(&mut self, name: &str, ty: Type, kind: LocalKind, span: Span, info: LocalInfo<'a>) -> LocalId {
        let id = LocalId(self.locals.len() as u32);
        self.locals.push(Local {
            name: name.to_string(),
            ty,
            var: Variability::Uniform,
            kind,
            span,
        });
        self.infos.push(info);
        id
    }

    /// Bind `name` in the innermost scope; a second declaration in the same scope is an
    /// error (shadowing in an inner block is fine).
    /// Bind a parameter (duplicates were reported with the signature).
    pub fn declare_param(&mut self, name: &str, id: LocalId) {
        self.scopes
            .last_mut()
            .expect("scope stack never empty")
            .insert(name.to_string(), id);
    }

    pub fn declare(&mut self, name: &ast::Ident, id: LocalId) {
        let scope = self.scopes.last_mut().expect("scope stack never empty");
        if let Some(&prev) = scope.get(&name.name) {
            let prev_span = self.locals[prev.0 as usize].span;
            self.sink.push(
                err(
                    "E0105",
                    format!("`{}` is declared twice in the same block", name.name),
                    name.span,
                    "declared again here",
                )
                .secondary(prev_span, "first declared here"),
            );
        }
        scope.insert(name.name.clone(), id);
    }

    pub fn set_xyz(&mut self, role: ParamRole, id: LocalId) {
        match role {
            ParamRole::X => self.xyz[0] = Some(id),
            ParamRole::Y => self.xyz[1] = Some(id),
            ParamRole::Z => self.xyz[2] = Some(id),
            _ => {}
        }
    }

    fn lookup(&self, name: &str) -> Option<LocalId> {
        self.scopes.iter().rev().find_map(|s| s.get(name).copied())
    }

    fn new_site(&mut self, span: Span) -> SiteId {
        self.sites.push(span);
        SiteId((self.sites.len() - 1) as u32)
    }

    fn new_loop(&mut self) -> LoopId {
        self.n_loops += 1;
        LoopId(self.n_loops - 1)
    }

    fn in_helper(&self) -> bool {
        !self.inline.is_empty()
    }

    fn local_expr(&self, id: LocalId, span: Span) -> Expr {
        mk(ExprKind::Local(id), self.locals[id.0 as usize].ty.clone(), span)
    }

    // ---- blocks and statements ---------------------------------------------------------

    pub fn block(&mut self, stmts: &[ast::Stmt], out: &mut Vec<Stmt>) {
        self.scopes.push(FxHashMap::default());
        self.stmts_in_scope(stmts, out);
        self.scopes.pop();
    }

    /// Lower statements in the current scope (a function body shares its parameters'
    /// scope, so redeclaring a parameter there is an error).
    pub fn stmts_in_scope(&mut self, stmts: &[ast::Stmt], out: &mut Vec<Stmt>) {
        for s in stmts {
            self.stmt(s, out);
        }
    }

    fn stmt(&mut self, s: &ast::Stmt, out: &mut Vec<Stmt>) {
        if self.enter(1, s.span) {
            self.stmt_nested(s, out);
            self.leave(1);
        }
    }

    fn stmt_nested(&mut self, s: &ast::Stmt, out: &mut Vec<Stmt>) {
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
            K::Block(b) => self.block(&b.stmts, out),
        }
    }

    fn decl(&mut self, quals: &ast::Qualifiers, ty: &ast::TypeExpr, vars: &[ast::DeclVar], out: &mut Vec<Stmt>) {
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
    fn zero(&mut self, ty: &Type, span: Span) -> Expr {
        let scalar = match ty.elem {
            Elem::Scalar(s) => types::const_expr(types::zero_const(s), s, span),
            Elem::Interp => to_interp(types::const_expr(ConstValue::Float(0.0), Scalar::Float, span)),
        };
        broadcast(scalar, &ty.dims)
    }

    fn assign(
        &mut self,
        target: &ast::Expr,
        op: ast::AssignOp,
        value: &ast::Expr,
        span: Span,
        pre: &mut Vec<Stmt>,
    ) -> Option<Stmt> {
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
    fn place(&mut self, e: &ast::Expr, pre: &mut Vec<Stmt>) -> Option<(Place, Type)> {
        match &e.kind {
            ast::ExprKind::Name(id) => {
                let Some(local) = self.lookup(&id.name) else {
                    self.sink.push(err(
                        "E0101",
                        format!("unknown variable `{}`", id.name),
                        id.span,
                        "not declared",
                    ));
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
    fn place_expr(&self, place: &Place, _ty: &Type) -> Expr {
        let mut e = self.local_expr(place.local, place.span);
        for (idx, site) in &place.indices {
            let ty = e.ty.element();
            e = mk(
                ExprKind::Index {
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

    fn expr_stmt(&mut self, e: &ast::Expr, span: Span, out: &mut Vec<Stmt>) {
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
                    ast::ItemKind::Interpolator => {}
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
    fn cond(&mut self, e: &ast::Expr, pre: &mut Vec<Stmt>) -> Option<Expr> {
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

    fn lower_loop(
        &mut self,
        cond: Option<&ast::Expr>,
        step: Option<&ast::Stmt>,
        body: &[ast::Stmt],
        span: Span,
        out: &mut Vec<Stmt>,
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
                ExprKind::Unary {
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

    fn ret(&mut self, value: Option<&ast::Expr>, span: Span, out: &mut Vec<Stmt>) {
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

    fn interpolation(&mut self, arms: &[ast::InterpArm], span: Span, out: &mut Vec<Stmt>) {
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

    fn interpolator_return(&mut self, value: Option<&ast::Expr>, span: Span, out: &mut Vec<Stmt>) {
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
    fn float_result(&mut self, e: &ast::Expr, interp_ok: bool, pre: &mut Vec<Stmt>) -> Option<Expr> {
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

    fn bound(&mut self, args: &[ast::Expr], span: Span, out: &mut Vec<Stmt>) {
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
        let vals: Option<Vec<Expr>> = vals.into_iter().collect();
        let Some(vals) = vals else { return };
        let Ok(arr): Result<[Expr; 4], _> = vals.try_into() else {
            return;
        };
        out.extend(pre);
        out.push(stmt(StmtKind::Bound(Box::new(arr)), span));
    }

    // ---- calls ------------------------------------------------------------------------

    fn call_primitive(
        &mut self,
        idx: usize,
        callee: &ast::Ident,
        args: &[ast::Expr],
        span: Span,
        pre: &mut Vec<Stmt>,
    ) -> Option<Stmt> {
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
        let mut out = vec![];
        let mut ok = true;
        let mut missing = vec![];
        for (i, p) in sig.params.iter().enumerate() {
            let Some(a) = args.get(i) else {
                match &p.default {
                    Some(vals) => out.push(consts::const_to_expr(vals, &p.ty, span)),
                    None => missing.push(p.name.as_str()),
                }
                continue;
            };
            match p.role {
                ParamRole::X | ParamRole::Y | ParamRole::Z => {
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
                        Some(w) if given == Some(w) => out.push(self.local_expr(w, a.span)),
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
                                        p.name, callee.name
                                    ),
                                    a.span,
                                    format!("expected this primitive's `{rname}` parameter"),
                                )
                                .help("a sub-primitive renders at the same pixel: pass X, Y and Z through"),
                            );
                            ok = false;
                        }
                    }
                }
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
        if !missing.is_empty() {
            let list = missing.iter().map(|m| format!("`{m}`")).collect::<Vec<_>>().join(", ");
            self.sink.push(
                err(
                    "E0215",
                    format!("missing arguments for {list} of `{}`", callee.name),
                    span,
                    "arguments missing",
                )
                .secondary(
                    sig.item.name.span,
                    "declared here; only trailing parameters with defaults may be left out",
                ),
            );
            ok = false;
        }
        if !ok {
            return None;
        }
        Some(stmt(
            StmtKind::CallPrimitive {
                callee: sig.func.expect("primitives have a FuncId"),
                args: out,
            },
            span,
        ))
    }

    /// Inline helper `idx` at a call site. Returns the result expression (`Local(result)`
    /// or, for a void helper called as a statement, a placeholder constant).
    fn inline_call(
        &mut self,
        idx: usize,
        callee: &ast::Ident,
        args: &[ast::Expr],
        span: Span,
        pre: &mut Vec<Stmt>,
        as_statement: bool,
    ) -> Option<Expr> {
        let g = self.g;
        let sig = &g.sigs[idx];
        // The callee as it was declared (the same name as `callee`, which found it).
        let helper_name: &'a str = &sig.item.name.name;
        if g.recursive.contains(&idx) {
            // The cycle was reported once where it is; inlining would not terminate.
            return None;
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
            return None;
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
            return None;
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
            return None;
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
            return None;
        }
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
    fn inout_alias(&self, p: &SigParam, place: &Place, args: &[ast::Expr], i: usize) -> bool {
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
        pre: &mut Vec<Stmt>,
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

    // ---- expressions ------------------------------------------------------------------

    /// Lower `e` and convert it to `ty` (a `{...}` list is lowered against `ty` directly).
    pub fn expr_to(&mut self, e: &ast::Expr, ty: &Type, pre: &mut Vec<Stmt>) -> Option<Expr> {
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
                return Some(mk(ExprKind::List(out?), ty.clone(), e.span));
            }
        }
        let v = self.expr(e, pre)?;
        self.coerce(v, ty, e.span)
    }

    /// Convert a value to `ty` for assignment: numbers convert, bool only from bool, a
    /// scalar broadcasts over an aggregate, shapes must otherwise match.
    fn coerce(&mut self, v: Expr, ty: &Type, span: Span) -> Option<Expr> {
        if v.ty == *ty {
            return Some(v);
        }
        let mismatch = |this: &mut Self, v: &Expr| {
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
                    Some(convert(v, t))
                } else if v.ty.dims.is_empty() {
                    Some(broadcast(convert(v, t), &ty.dims))
                } else {
                    mismatch(self, &v)
                }
            }
            _ => mismatch(self, &v),
        }
    }

    pub fn expr(&mut self, e: &ast::Expr, pre: &mut Vec<Stmt>) -> Option<Expr> {
        if !self.enter(1, e.span) {
            return None;
        }
        let v = self.expr_nested(e, pre);
        self.leave(1);
        v
    }

    fn expr_nested(&mut self, e: &ast::Expr, pre: &mut Vec<Stmt>) -> Option<Expr> {
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
            K::Name(id) => {
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
                    self.sink.push(err(
                        "E0101",
                        format!("unknown variable `{}`", id.name),
                        span,
                        "not declared",
                    ));
                }
                None
            }
            K::Unary { op, expr } => {
                let v = self.expr(expr, pre)?;
                match op {
                    ast::UnaryOp::Neg => {
                        if scalar_of(&v.ty) == Some(Scalar::Bool) {
                            self.sink
                                .push(err("E0203", "cannot negate a bool", span, "use `!` for bools"));
                            return None;
                        }
                        if let (ExprKind::Const(c), Some(s)) = (&v.kind, scalar_of(&v.ty)) {
                            if let Some(n) = negate_const(*c, s) {
                                return Some(types::const_expr(n, s, span));
                            }
                        }
                        let ty = v.ty.clone();
                        Some(mk(
                            ExprKind::Unary {
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
                            ExprKind::Unary {
                                op: ir::UnaryOp::Not,
                                expr: Box::new(v),
                            },
                            Type::bool(),
                            span,
                        ))
                    }
                }
            }
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
                    ExprKind::Select {
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
                    ExprKind::Index {
                        base: Box::new(b),
                        index: Box::new(i),
                        site,
                    },
                    ty,
                    span,
                ))
            }
            K::List(items) => {
                let mut vals = vec![];
                for it in items {
                    vals.push(self.expr(it, pre));
                }
                let vals: Vec<Expr> = vals.into_iter().collect::<Option<_>>()?;
                self.list(vals, span)
            }
        }
    }

    /// The index of `base[index]`: an int, and in range when both are constant.
    fn index_value(&mut self, base: &Type, index: &ast::Expr, pre: &mut Vec<Stmt>) -> Option<Expr> {
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
        if let (ExprKind::Const(ConstValue::Int(k)), false) = (&i.kind, base.per_seq) {
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
    fn list(&mut self, vals: Vec<Expr>, span: Span) -> Option<Expr> {
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
        Some(mk(ExprKind::List(out), Type::array(elem, all), span))
    }

    /// Bring two values to one type (for `?:`): numbers to their common scalar, a scalar
    /// broadcast to the other side's shape.
    fn unify(&mut self, a: Expr, b: Expr, span: Span) -> Option<(Expr, Expr)> {
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
    pub fn binary(&mut self, op: ast::BinOp, l: Expr, r: Expr, span: Span) -> Option<Expr> {
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
                Some(bin(iop, convert(l, s), convert(r, s), Type::bool(), span))
            }
            B::Add | B::Sub | B::Mul | B::Div | B::Rem => self.arith(op, iop, l, r, span),
        }
    }

    fn arith(&mut self, op: ast::BinOp, iop: BinOp, l: Expr, r: Expr, span: Span) -> Option<Expr> {
        // Interpolation data: with itself, or with a number (taken as float).
        if l.ty.elem == Elem::Interp || r.ty.elem == Elem::Interp {
            let ok_other = |e: &Expr| {
                e.ty.elem == Elem::Interp || (e.ty.dims.is_empty() && scalar_of(&e.ty).is_some_and(types::is_number))
            };
            let same_or_scalar = l.ty.dims == r.ty.dims || l.ty.dims.is_empty() || r.ty.dims.is_empty();
            let interp_scalar_side = |e: &Expr| e.ty.elem == Elem::Interp || e.ty.dims.is_empty();
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
                ExprKind::MatMul {
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
        Some(bin(
            iop,
            convert(l, s),
            convert(r, s),
            Type::array(Elem::Scalar(s), dims),
            span,
        ))
    }

    fn call_expr(&mut self, callee: &ast::Ident, args: &[ast::Expr], span: Span, pre: &mut Vec<Stmt>) -> Option<Expr> {
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
                return Some(mk(ExprKind::ClipFlag, Type::bool(), span));
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
                    return Some(mk(ExprKind::SeqCount, Type::int(), span));
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
        let vals: Vec<Expr> = vals.into_iter().collect::<Option<_>>()?;
        match super::builtins::lower(&callee.name, vals, span) {
            Ok(Some(e)) => Some(e),
            Ok(None) => {
                self.sink.push(err(
                    "E0102",
                    format!("unknown function `{}`", callee.name),
                    callee.span,
                    "not defined",
                ));
                None
            }
            Err((sp, msg, label)) => {
                self.sink.push(err("E0210", msg, sp, label));
                None
            }
        }
    }

    fn transform(&mut self, callee: &ast::Ident, args: &[ast::Expr], span: Span, pre: &mut Vec<Stmt>) -> Option<Expr> {
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
        Some(mk(ExprKind::Builtin { func, args: vec![v] }, ty, span))
    }

    fn construct(&mut self, ty: &ast::TypeExpr, args: &[ast::Expr], span: Span, pre: &mut Vec<Stmt>) -> Option<Expr> {
        use ast::TypeKind as K;
        let mut vals = vec![];
        for a in args {
            vals.push(self.expr(a, pre));
        }
        let vals: Vec<Expr> = vals.into_iter().collect::<Option<_>>()?;
        let arity = |this: &mut Self, what: &str, want: &str| {
            this.sink.push(err(
                "E0214",
                format!("`{what}(...)` takes {want}, found {} arguments", args.len()),
                span,
                "wrong number of arguments",
            ));
            None
        };
        let float_scalars = |this: &mut Self, vals: Vec<Expr>| -> Option<Vec<Expr>> {
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
        let list = |items: Vec<Expr>, dims: Vec<u32>| {
            mk(
                ExprKind::List(items),
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
                            ExprKind::Select {
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

pub fn var_of(v: ast::Variability) -> Variability {
    match v {
        ast::Variability::Uniform => Variability::Uniform,
        ast::Variability::Varying => Variability::Varying,
    }
}

/// `float and point`: the operand types of a binary operation, for its error messages
/// (formatted only when there is an error: this is the hot path of lowering).
fn shapes(l: &Expr, r: &Expr) -> String {
    format!("{} and {}", type_name(&l.ty), type_name(&r.ty))
}

fn bin(op: BinOp, l: Expr, r: Expr, ty: Type, span: Span) -> Expr {
    mk(
        ExprKind::Binary {
            op,
            lhs: Box::new(l),
            rhs: Box::new(r),
        },
        ty,
        span,
    )
}

fn negate_const(c: ConstValue, s: Scalar) -> Option<ConstValue> {
    match (c, s) {
        (ConstValue::Float(v), _) => Some(ConstValue::Float(-v)),
        (ConstValue::Int(v), _) => Some(ConstValue::Int(v.wrapping_neg())),
        (ConstValue::Fixed(raw), Scalar::Fixed(f)) if !f.is_unsigned() => Some(ConstValue::Fixed(raw.wrapping_neg())),
        _ => None,
    }
}

/// A float scalar seen as interpolation data: the same value for every component.
fn to_interp(v: Expr) -> Expr {
    let span = v.span;
    mk(ExprKind::Convert(Box::new(v)), Type::array(Elem::Interp, vec![]), span)
}

/// A scalar (or interpolation_data element) repeated over an array of the given
/// dimensions: one [`ExprKind::Splat`] node, not a tree of lists.
fn broadcast(v: Expr, dims: &[u32]) -> Expr {
    if dims.is_empty() {
        return v;
    }
    let span = v.span;
    let ty = Type::array(v.ty.elem, dims.to_vec());
    mk(ExprKind::Splat(Box::new(v)), ty, span)
}

/// Does the name `name` occur anywhere in `e` (in nested calls' arguments too)?
fn mentions(e: &ast::Expr, name: &str) -> bool {
    if let ast::ExprKind::Name(id) = &e.kind {
        return id.name == name;
    }
    let mut found = false;
    e.for_each_child(|c| found = found || mentions(c, name));
    found
}
