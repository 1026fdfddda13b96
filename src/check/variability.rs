//! Uniform/varying inference over a lowered function, and the variability errors.
//!
//! X, Y and Z are varying; every other parameter is uniform; a local declared `uniform` or
//! `varying` keeps that. A local without a qualifier becomes varying when a varying value
//! (or a value at a varying index) is assigned to it, or when it is assigned under varying
//! control flow: inside an `if` with a varying condition or a loop that is varying. A loop
//! is varying when its condition is, or when a `break`/`continue`/`return` leaving it sits
//! under a varying condition introduced inside it; its body is varying control flow in the
//! first two cases only. Code after a varying `return` is not varying control flow: the
//! lanes that returned simply retired, and the others still agree on uniform values.
//!
//! Because a loop's back edge can carry a varying value to an earlier use, the analysis
//! walks the function until a walk changes no loop and no local that the walk had already
//! read as uniform (locals and loops only ever go from uniform to varying, so this
//! terminates). A local that turns varying before any read of it in the walk was seen
//! varying at every read, so that walk saw what another one would see and is final.
//! Every walk writes every expression's variability and every loop's `varying` flag and
//! collects the errors; those of the final walk are reported, and every local gets its
//! final variability. For each inferred-varying local it remembers why (the span of the
//! first varying operand or condition), so diagnostics can point at the cause.

use crate::diag::{Diagnostic, Span};
use crate::ir::{
    ExprId, ExprKind, Exprs, Function, Local, LocalId, LoopId, ParamRole, StmtId, StmtKind, Stmts, Variability,
};

use super::{LocalInfo, Sink};

/// Why an expression is varying: the varying operand's span, and the local it reads (if
/// the operand is a local whose variability was inferred).
type Cause = Option<(Span, Option<LocalId>)>;

struct State<'i> {
    infos: &'i [LocalInfo<'i>],
    /// The function's locals (for their names in messages).
    locals: &'i [Local],
    /// The function's expressions, whose variabilities the walk sets.
    stmts: Stmts,
    exprs: Exprs,
    var: Vec<Variability>,
    cause: Vec<Option<Span>>,
    /// The loop's IR `varying` flag: it must run until no lane is active.
    loop_var: Vec<bool>,
    /// Its body is varying control flow (varying condition, or a varying break/continue;
    /// a varying `return` only retires lanes, the others still agree).
    loop_ctl: Vec<bool>,
    loop_cause: Vec<Option<Span>>,
    /// Another walk is needed: a loop changed, or a local this walk read as uniform.
    changed: bool,
    /// Locals read as uniform in this walk.
    read_uniform: Vec<bool>,
    /// Varying conditions in effect, each with the loop depth it was introduced at.
    conds: Vec<(Span, usize)>,
    loops: Vec<LoopId>,
}

/// Infer variabilities in `f.setup` (the whole checked body), set them in the IR and report
/// the variability errors. `callee_roles[f]` gives each primitive's parameter roles.
pub fn analyze(f: &mut Function, infos: &[LocalInfo], callee_roles: &[Vec<ParamRole>], sink: &mut Sink) {
    let body = std::mem::take(&mut f.setup);
    let mut st = State {
        infos,
        locals: &f.locals,
        stmts: std::mem::take(&mut f.stmts),
        exprs: std::mem::take(&mut f.exprs),
        var: infos
            .iter()
            .map(|i| i.declared.map_or(Variability::Uniform, |d| d.0))
            .collect(),
        cause: infos.iter().map(|i| i.declared.map(|d| d.1)).collect(),
        loop_var: vec![false; f.loops as usize],
        loop_ctl: vec![false; f.loops as usize],
        loop_cause: vec![None; f.loops as usize],
        changed: false,
        read_uniform: vec![false; infos.len()],
        conds: vec![],
        loops: vec![],
    };
    let errors = loop {
        st.changed = false;
        st.read_uniform.fill(false);
        let mut errors = Sink::default();
        st.block(&body, callee_roles, &mut errors);
        if !st.changed {
            break errors;
        }
    };
    for d in errors.items {
        sink.push(d);
    }
    let var = st.var;
    f.stmts = st.stmts;
    f.exprs = st.exprs;
    f.setup = body;
    for (l, v) in f.locals.iter_mut().zip(&var) {
        l.var = *v;
    }
}

impl State<'_> {
    fn ctl(&self) -> Option<Span> {
        self.conds.last().map(|c| c.0)
    }

    fn set_varying(&mut self, l: LocalId, why: Option<Span>) {
        let i = l.0 as usize;
        if self.var[i] == Variability::Uniform && self.infos[i].declared.is_none() {
            self.var[i] = Variability::Varying;
            self.cause[i] = why;
            self.changed |= self.read_uniform[i];
        }
    }

    /// Mark loops left by a jump as varying when a varying condition introduced inside them
    /// controls the jump. `target` is the outermost loop left (its index in `self.loops`).
    /// A `break`/`continue` also makes the loop body varying control flow; a `return` does
    /// not (the lanes still running agree on the iterations).
    fn jump(&mut self, target: usize, is_return: bool) {
        let Some(&(span, depth)) = self.conds.iter().max_by_key(|c| c.1) else {
            return;
        };
        for q in target..depth.min(self.loops.len()) {
            let id = self.loops[q].0 as usize;
            if !self.loop_var[id] || (!is_return && !self.loop_ctl[id]) {
                self.loop_var[id] = true;
                self.loop_ctl[id] |= !is_return;
                self.loop_cause[id].get_or_insert(span);
                self.changed = true;
            }
        }
    }

    fn block(&mut self, stmts: &[StmtId], roles: &[Vec<ParamRole>], sink: &mut Sink) {
        for &s in stmts {
            self.stmt(s, roles, sink);
        }
    }

    fn stmt(&mut self, s: StmtId, roles: &[Vec<ParamRole>], sink: &mut Sink) {
        let span = self.stmts.span(s);
        // Out of the arena while it is analysed (a loop's `varying` is set in it); the
        // statements inside it are other nodes.
        let mut node = self.stmts.take(s);
        self.stmt_kind(&mut node, span, roles, sink);
        self.stmts[s] = node;
    }

    fn stmt_kind(&mut self, node: &mut StmtKind, span: Span, roles: &[Vec<ParamRole>], sink: &mut Sink) {
        match node {
            StmtKind::Assign { place, value } => {
                let (mut v, mut cause) = self.expr(*value);
                for (idx, _) in &mut place.indices {
                    let (iv, ic) = self.expr(*idx);
                    if iv.is_varying() && !v.is_varying() {
                        v = iv;
                        cause = ic;
                    }
                }
                let l = place.local;
                let info = &self.infos[l.0 as usize];
                let what = || info.what.describe(&self.locals[l.0 as usize].name);
                match info.declared {
                    Some((Variability::Uniform, decl)) => {
                        if v.is_varying() {
                            let mut d =
                                Diagnostic::error("E0301", format!("varying value assigned to uniform {}", what()))
                                    .primary(span, "assigned here")
                                    .secondary(decl, "declared uniform here");
                            d = self.explain(d, cause);
                            sink.push(d.help("remove `uniform` or compute the value from uniform values only"));
                        } else if let Some(c) = self.ctl() {
                            sink.push(
                                Diagnostic::error(
                                    "E0302",
                                    format!("uniform {} assigned under varying control flow", what()),
                                )
                                .primary(span, "assigned here")
                                .secondary(c, "this condition is varying")
                                .secondary(decl, "declared uniform here")
                                .help("a uniform has one value for all pixels; declare it varying or move the assignment out"),
                            );
                        }
                    }
                    Some(_) => {}
                    None => {
                        if v.is_varying() {
                            self.set_varying(l, cause.map(|c| c.0));
                        } else if let Some(c) = self.ctl() {
                            self.set_varying(l, Some(c));
                        }
                    }
                }
            }
            StmtKind::If { cond, then, otherwise } => {
                let (cv, _) = self.expr(*cond);
                let pushed = cv.is_varying();
                if pushed {
                    self.conds.push((self.exprs.span(*cond), self.loops.len()));
                }
                self.block(then, roles, sink);
                self.block(otherwise, roles, sink);
                if pushed {
                    self.conds.pop();
                }
            }
            StmtKind::Loop {
                id,
                cond,
                body,
                step,
                varying,
                ..
            } => {
                let i = id.0 as usize;
                self.loops.push(*id);
                if let Some(c) = cond {
                    let (cv, _) = self.expr(*c);
                    if cv.is_varying() && !self.loop_ctl[i] {
                        self.loop_var[i] = true;
                        self.loop_ctl[i] = true;
                        self.loop_cause[i] = Some(self.exprs.span(*c));
                        self.changed = true;
                    }
                }
                let pushed = self.loop_ctl[i];
                if pushed {
                    self.conds.push((self.loop_cause[i].unwrap_or(span), self.loops.len()));
                }
                self.block(body, roles, sink);
                self.block(step, roles, sink);
                if pushed {
                    self.conds.pop();
                }
                self.loops.pop();
                *varying = self.loop_var[i];
            }
            StmtKind::Break(id) | StmtKind::Continue(id) => {
                if let Some(p) = self.loops.iter().position(|l| l == id) {
                    self.jump(p, false);
                }
            }
            StmtKind::Return => self.jump(0, true),
            StmtKind::Interpolation { arms } => {
                for a in arms.iter() {
                    self.block(&a.body, roles, sink);
                }
            }
            StmtKind::InterpolatorReturn(v) => {
                if let Some(e) = v {
                    self.expr(*e);
                }
            }
            StmtKind::Bound(args) => {
                for a in args.iter_mut() {
                    let (v, cause) = self.expr(*a);
                    if v.is_varying() {
                        let d = Diagnostic::error("E0303", "varying argument to `bound`")
                            .primary(self.exprs.span(*a), "varies per pixel")
                            .help("a bound is one rectangle per primitive: compute it from uniform values");
                        sink.push(self.explain(d, cause));
                    }
                }
                if let Some(c) = self.ctl() {
                    sink.push(
                        Diagnostic::error("E0305", "`bound` under varying control flow")
                            .primary(span, "bound here")
                            .secondary(c, "this condition is varying"),
                    );
                }
            }
            StmtKind::CallPrimitive { callee, args, .. } => {
                let callee_roles = roles.get(callee.0 as usize);
                for (k, a) in args.iter_mut().enumerate() {
                    let (v, cause) = self.expr(*a);
                    let pixel = callee_roles
                        .and_then(|r| r.get(k))
                        .is_some_and(|r| matches!(r, ParamRole::X | ParamRole::Y | ParamRole::Z));
                    if v.is_varying() && !pixel {
                        let d = Diagnostic::error("E0304", "varying argument to a primitive call")
                            .primary(self.exprs.span(*a), "varies per pixel")
                            .help("parameters of a primitive are per-primitive (uniform) values");
                        sink.push(self.explain(d, cause));
                    }
                }
                if let Some(c) = self.ctl() {
                    sink.push(
                        Diagnostic::error("E0306", "primitive call under varying control flow")
                            .primary(span, "called here")
                            .secondary(c, "this condition is varying")
                            .help("a sub-primitive is rendered for all pixels or none"),
                    );
                }
            }
        }
    }

    /// Add "varying because of this" labels: the varying operand, and where an inferred
    /// local it reads became varying.
    fn explain(&self, mut d: Diagnostic, cause: Cause) -> Diagnostic {
        if let Some((span, local)) = cause {
            d = d.secondary(span, "varying because of this");
            if let Some(l) = local {
                if let (None, Some(why)) = (self.infos[l.0 as usize].declared, self.cause[l.0 as usize]) {
                    if why != span {
                        d = d.secondary(why, "which is varying because of this");
                    }
                }
            }
        }
        d
    }

    /// Compute (and store) the variability of an expression and of all its parts.
    fn expr(&mut self, e: ExprId) -> (Variability, Cause) {
        let mut acc = (Variability::Uniform, None);
        if let ExprKind::Local(l) = self.exprs[e].kind {
            let v = self.var[l.0 as usize];
            if v.is_varying() {
                acc = (v, Some((self.exprs.span(e), Some(l))));
            } else {
                self.read_uniform[l.0 as usize] = true;
            }
        }
        let mut k = 0;
        while let Some(c) = self.exprs[e].child(k) {
            let (v, cause) = self.expr(c);
            if v.is_varying() && !acc.0.is_varying() {
                acc = (v, cause);
            }
            k += 1;
        }
        self.exprs[e].var = acc.0;
        acc
    }
}
