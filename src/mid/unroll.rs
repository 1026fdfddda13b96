//! IR -> IR before lowering: unrolls uniform loops whose trip count is a compile-time
//! constant and propagates integer constants, so arrays indexed by the loop variable become
//! SSA values.
//!
//! Why: a loop like screen_triangle's `for (int i = 0; i < 3; i++) vx[i] = ...` makes `vx`
//! a stack slot addressed with a clamped dynamic index, an error record per access and a
//! fuel check per trip; that was about half of the kernel's CLIF and most of the register
//! allocator's time (docs/performance.md). After this pass every such index is a constant,
//! [`super::homes::dynamic_locals`] leaves the array in SSA variables and the clamping, error
//! records and fuel checks are gone.
//!
//! The pass walks each statement list forward with an environment of *known* locals: uniform
//! scalar `int` locals whose current value is a compile-time constant. Reads of known locals
//! become constants, and integer arithmetic, comparisons, `!`, `&&`, `||` and `?:` on constants
//! are folded with exactly the JIT's semantics (wrapping `+ - *`, `x / 0 == x % 0 == 0`,
//! division in i64 narrowed back). A uniform (`varying == false`) loop is unrolled when,
//! starting from the environment at its entry, its condition folds to a constant on every
//! trip and becomes false within [`MAX_TRIPS`] trips, the copies stay under
//! [`MAX_UNROLLED_STMTS`] statements and contain no loop that stays a loop, and no
//! `break`/`continue` targets the loop itself.
//! Otherwise the loop is kept and every local it assigns is forgotten at its entry (its body
//! runs with what holds on every trip) and after it.
//!
//! A loop without a condition whose body runs exactly once (an inlined helper call whose
//! only `return` is its last statement, see [`one_trip`]) is replaced by its body.
//!
//! What changes at run time: nothing in any pixel or error result, with one documented
//! exception: an unrolled (or one-trip) loop spends no fuel, so once a kept loop has run
//! out (W0801 reported) the code it stands for still runs where the loop would have been
//! left at once: seen in what a pixel group draws (a draw whose setup runs out is drawn
//! nowhere, `abi::ctx`), and in the kernel's own state (`tests/jit/inlined_helpers.rs`). Fuel exists so no source can hang the
//! renderer; a loop with a constant trip count at most `MAX_TRIPS` cannot. Loops whose trip
//! count is not a compile-time constant keep their fuel checks, index clamping and error
//! records unchanged (`tests/jit/unroll.rs`).
//!
//! Invariants kept: the output is a checked program in the sense of [`crate::ir`] (same
//! locals, sites, loop ids, parameter layout, its statements and expressions numbered
//! afresh by [`crate::ir::number::renumber`]); a folded expression is a uniform constant of the
//! expression's own type.

use std::collections::HashMap;

use crate::ir::{
    BinOp, ConstValue, Elem, Expr, ExprId, ExprKind, Exprs, Function, Local, LocalId, LoopId, Scalar, StmtId, StmtKind,
    Stmts, UnaryOp, Variability,
};

/// Longest loop unrolled (trips).
pub(crate) const MAX_TRIPS: u32 = 16;
/// Largest unrolled result of one loop, in statements (nested ones counted).
pub(crate) const MAX_UNROLLED_STMTS: usize = 512;

/// Known values of uniform scalar int locals at the current point.
pub type Env = HashMap<LocalId, i32>;

/// `f` with its constant-trip uniform loops unrolled and integer constants propagated.
///
/// Rewritten in place: statements keep their nodes, blocks are rebuilt, and only unrolled
/// loop bodies are copied (once per trip; copying the whole function first was a quarter of
/// preparing nurb_surface's body).
pub(crate) fn unroll_function(mut f: Function) -> Function {
    let setup = std::mem::take(&mut f.setup);
    let pixel = std::mem::take(&mut f.pixel);
    let mut u = Unroller {
        locals: &f.locals,
        st: &mut f.stmts,
        x: &mut f.exprs,
    };
    let mut env = Env::new();
    let setup = u.stmts(setup, &mut env);
    // The pixel part runs once per pixel group after setup: what it assigns itself may hold
    // a previous group's value when it starts, so it is not known there.
    let mut assigned = vec![];
    assigned_locals(u.st, &pixel, &mut assigned);
    for l in assigned {
        env.remove(&l);
    }
    let pixel = u.stmts(pixel, &mut env);
    f.setup = setup;
    f.pixel = pixel;
    // Unrolled bodies are copies, and folding and unrolling drop nodes.
    crate::ir::number::renumber(&mut f);
    f
}

struct Unroller<'a> {
    locals: &'a [Local],
    /// The function's arenas: folding rewrites expression nodes in place, and each trip of
    /// an unrolled loop gets copies of the body's statements and expressions.
    st: &'a mut Stmts,
    x: &'a mut Exprs,
}

impl Unroller<'_> {
    /// A local whose constant value is tracked: a uniform scalar int.
    fn tracked(&self, l: LocalId) -> bool {
        self.locals.get(l.0 as usize).is_some_and(|local| {
            local.var == Variability::Uniform && local.ty.is_scalar() && local.ty.elem == Elem::Scalar(Scalar::Int)
        })
    }

    fn stmts(&mut self, list: Vec<StmtId>, env: &mut Env) -> Vec<StmtId> {
        let mut out = Vec::with_capacity(list.len());
        for s in list {
            self.stmt(s, env, &mut out);
        }
        out
    }

    /// Append `s`, folded under `env` (and unrolled where it is such a loop), to `out`;
    /// `env` then holds what is known after it. A statement replaced by others (a decided
    /// `if`, a one-trip or unrolled loop) is left out of the arena's blocks.
    fn stmt(&mut self, s: StmtId, env: &mut Env, out: &mut Vec<StmtId>) {
        // Out of the arena while its blocks are rebuilt (they hold other nodes).
        let mut node = self.st.take(s);
        match &mut node {
            StmtKind::Assign { place, value } => {
                fold_in(self.x, *value, env);
                for (i, _) in &mut place.indices {
                    fold_in(self.x, *i, env);
                }
                match (
                    &self.x[*value].kind,
                    place.indices.is_empty() && self.tracked(place.local),
                ) {
                    (ExprKind::Const(ConstValue::Int(v)), true) => env.insert(place.local, *v),
                    _ => env.remove(&place.local),
                };
            }
            StmtKind::If { cond, then, otherwise } => {
                fold_in(self.x, *cond, env);
                if let ExprKind::Const(ConstValue::Bool(c)) = self.x[*cond].kind {
                    // A constant condition: only the taken side exists.
                    for t in std::mem::take(if c { then } else { otherwise }) {
                        self.stmt(t, env, out);
                    }
                    return;
                }
                let mut then_env = env.clone();
                *then = self.stmts(std::mem::take(then), &mut then_env);
                *otherwise = self.stmts(std::mem::take(otherwise), env);
                env.retain(|l, v| then_env.get(l) == Some(v));
            }
            StmtKind::Loop {
                id,
                cond,
                body,
                step,
                varying,
                ..
            } => {
                if one_trip(self.st, *id, *cond, body) {
                    // An inlined helper: its body runs once, in place (see `one_trip`).
                    let mut body = std::mem::take(body);
                    body.pop();
                    for t in body {
                        self.stmt(t, env, out);
                    }
                    return;
                }
                if !*varying {
                    if let Some(unrolled) = self.unroll(*id, *cond, body, step, env) {
                        out.extend(unrolled);
                        return;
                    }
                }
                // Kept: its body and step see only what holds on every trip.
                let mut assigned = vec![];
                assigned_locals(self.st, body, &mut assigned);
                assigned_locals(self.st, step, &mut assigned);
                for l in assigned {
                    env.remove(&l);
                }
                if let Some(c) = cond {
                    fold_in(self.x, *c, env);
                }
                *body = self.stmts(std::mem::take(body), &mut env.clone());
                *step = self.stmts(std::mem::take(step), &mut env.clone());
            }
            StmtKind::Interpolation { arms } => {
                // Any subset of the arms runs (one per bound kind).
                let entry = env.clone();
                for a in arms.iter_mut() {
                    let mut arm_env = entry.clone();
                    a.body = self.stmts(std::mem::take(&mut a.body), &mut arm_env);
                    env.retain(|l, v| arm_env.get(l) == Some(v));
                }
            }
            StmtKind::InterpolatorReturn(e) => {
                if let Some(e) = e {
                    fold_in(self.x, *e, env);
                }
            }
            StmtKind::Bound(es) => es.iter().for_each(|e| fold_in(self.x, *e, env)),
            StmtKind::CallPrimitive { args, .. } => args.iter().for_each(|a| fold_in(self.x, *a, env)),
            StmtKind::Break(_) | StmtKind::Continue(_) | StmtKind::Return => {}
        }
        self.st[s] = node;
        out.push(s);
    }

    /// The statements of `loop id` run trip by trip, if its trip count is a compile-time
    /// constant within the limits; `env` then holds the state after the loop.
    fn unroll(
        &mut self,
        id: LoopId,
        cond: Option<ExprId>,
        body: &[StmtId],
        step: &[StmtId],
        env: &mut Env,
    ) -> Option<Vec<StmtId>> {
        let cond = cond?;
        if jumps_to(self.st, body, id) || jumps_to(self.st, step, id) {
            return None;
        }
        let mut trip_env = env.clone();
        let mut out = vec![];
        for _ in 0..=MAX_TRIPS {
            let folded = fold(self.x, cond, &trip_env);
            match self.x[folded].kind {
                ExprKind::Const(ConstValue::Bool(false)) => {
                    *env = trip_env;
                    return Some(out);
                }
                ExprKind::Const(ConstValue::Bool(true)) => {}
                _ => return None,
            }
            for &s in body.iter().chain(step) {
                // Each trip folds its own copy of the statement.
                let copy = self.st.copy_tree(self.x, s);
                self.stmt(copy, &mut trip_env, &mut out);
            }
            // A body that still holds a loop after unrolling gains nothing (its arrays stay
            // dynamically indexed) and only grows the code (measured: the NURB kernel's
            // `for (side < 4)` around run-time loops, +3% CLIF).
            if count_stmts(self.st, &out) > MAX_UNROLLED_STMTS || contains_loop(self.st, &out) {
                return None;
            }
        }
        // Still running after MAX_TRIPS: too long to unroll.
        None
    }
}

/// Whether loop `id` runs its body exactly once, straight through: it has no condition, its
/// body ends with `break` to itself and nothing else in the body jumps to it (its step never
/// runs). The checker inlines every helper call as such a loop (a `return` in the helper is
/// a `break`); one whose only `return` is at its end is the body itself, without the loop's
/// block structure, fuel check and the SSA block parameters for every variable live across
/// it (an inlined helper in a setup was 5 loops and ~40 % of the sphere's tier-0 CLIF).
fn one_trip(st: &Stmts, id: LoopId, cond: Option<ExprId>, body: &[StmtId]) -> bool {
    match body.split_last() {
        Some((&last, rest)) => {
            matches!(st[last], StmtKind::Break(l) if l == id) && cond.is_none() && !jumps_to(st, rest, id)
        }
        None => false,
    }
}

/// Whether a `break`/`continue` in `list` targets loop `id`.
fn jumps_to(st: &Stmts, list: &[StmtId], id: LoopId) -> bool {
    let mut found = false;
    crate::ir::for_each_stmt(st, list, &mut |_, s| {
        found |= matches!(s, StmtKind::Break(l) | StmtKind::Continue(l) if *l == id)
    });
    found
}

/// Whether `list` holds a loop (nested ones too).
fn contains_loop(st: &Stmts, list: &[StmtId]) -> bool {
    let mut found = false;
    crate::ir::for_each_stmt(st, list, &mut |_, s| found |= matches!(s, StmtKind::Loop { .. }));
    found
}

/// The statements of `list`, nested ones counted.
fn count_stmts(st: &Stmts, list: &[StmtId]) -> usize {
    let mut n = 0;
    crate::ir::for_each_stmt(st, list, &mut |_, _| n += 1);
    n
}

/// Every local assigned (whole or in part) anywhere in `list`.
fn assigned_locals(st: &Stmts, list: &[StmtId], out: &mut Vec<LocalId>) {
    crate::ir::for_each_assign(st, list, &mut |place, _| out.push(place.local));
}

fn is_scalar_of(e: &Expr, s: Scalar) -> bool {
    e.ty.is_scalar() && e.ty.elem == Elem::Scalar(s)
}

/// A folded copy of `e` (known locals replaced by their values, constant int/bool
/// operations folded); `e` itself is unchanged.
pub fn fold(x: &mut Exprs, e: ExprId, env: &Env) -> ExprId {
    let copy = x.copy_tree(e);
    fold_in(x, copy, env);
    copy
}

/// [`fold`] in place: replaces known locals by their values and folds constant int/bool
/// operations, rewriting the nodes of the tree at `e` (operands a fold drops stay in the
/// arena, unreachable, until the function is renumbered).
fn fold_in(x: &mut Exprs, e: ExprId, env: &Env) {
    let node = &x[e];
    let (ty_int, ty_bool) = (is_scalar_of(node, Scalar::Int), is_scalar_of(node, Scalar::Bool));
    let folded = match node.kind {
        ExprKind::Local(l) => match env.get(&l) {
            Some(&v) if ty_int => Some(ConstValue::Int(v)),
            _ => None,
        },
        ExprKind::Const(_) | ExprKind::SeqCount | ExprKind::ClipFlag => None,
        ExprKind::Unary { op, expr } => {
            fold_in(x, expr, env);
            match (op, &x[expr].kind) {
                (UnaryOp::Neg, ExprKind::Const(ConstValue::Int(v))) if ty_int => {
                    Some(ConstValue::Int(v.wrapping_neg()))
                }
                (UnaryOp::Not, ExprKind::Const(ConstValue::Bool(v))) if ty_bool => Some(ConstValue::Bool(!v)),
                _ => None,
            }
        }
        ExprKind::Binary { op, lhs, rhs } => {
            fold_in(x, lhs, env);
            fold_in(x, rhs, env);
            let ty = &x[e].ty;
            match fold_binary(op, &x[lhs], &x[rhs]) {
                Some(v) if ty.is_scalar() && ty.elem == Elem::Scalar(const_scalar(v)) => Some(v),
                _ => None,
            }
        }
        ExprKind::Select { cond, then, otherwise } => {
            fold_in(x, cond, env);
            let taken = match x[cond].kind {
                ExprKind::Const(ConstValue::Bool(v)) => Some(v),
                _ => None,
            };
            // Expressions are pure: a constant condition selects one side.
            if let Some(v) = taken {
                let (side, other) = if v { (then, otherwise) } else { (otherwise, then) };
                fold_in(x, side, env);
                if x[side].ty == x[e].ty && x[side].var <= x[e].var {
                    // The side takes the select's place (its operands with it).
                    let side_node = x[side].clone();
                    x.replace(e, side_node, x.span(side));
                    return;
                }
                fold_in(x, other, env);
            } else {
                fold_in(x, then, env);
                fold_in(x, otherwise, env);
            }
            None
        }
        ExprKind::Index { .. }
        | ExprKind::Convert(_)
        | ExprKind::Builtin { .. }
        | ExprKind::List(_)
        | ExprKind::Splat(_)
        | ExprKind::MatMul { .. } => {
            let mut k = 0;
            while let Some(c) = x[e].child(k) {
                fold_in(x, c, env);
                k += 1;
            }
            None
        }
    };
    if let Some(c) = folded {
        x[e].kind = ExprKind::Const(c);
        x[e].var = Variability::Uniform;
        return;
    }
    // Folding may have made every operand uniform (a `?:` with a constant condition keeps
    // its uniform side): an expression is varying iff an operand is (`ir::valid`'s
    // `ExprVariability`). Leaves keep theirs: a local's, or uniform.
    let node = &x[e];
    if !matches!(
        node.kind,
        ExprKind::Local(_) | ExprKind::Const(_) | ExprKind::SeqCount | ExprKind::ClipFlag
    ) {
        let mut var = Variability::Uniform;
        node.for_each_child(|c| var = var.join(x[c].var));
        x[e].var = var;
    }
}

fn const_scalar(c: ConstValue) -> Scalar {
    match c {
        ConstValue::Int(_) => Scalar::Int,
        ConstValue::Bool(_) => Scalar::Bool,
        // Never produced by `fold_binary`.
        ConstValue::Float(_) | ConstValue::Fixed(_) => Scalar::Float,
    }
}

/// `a op c` on scalar int or bool constants, with the JIT's semantics (see `lower::binop`
/// and `fixed::int_div_rem`).
fn fold_binary(op: BinOp, a: &Expr, c: &Expr) -> Option<ConstValue> {
    if !a.ty.is_scalar() || !c.ty.is_scalar() {
        return None;
    }
    match (&a.kind, &c.kind) {
        (ExprKind::Const(ConstValue::Int(x)), ExprKind::Const(ConstValue::Int(y)))
            if is_scalar_of(a, Scalar::Int) && is_scalar_of(c, Scalar::Int) =>
        {
            let (x, y) = (*x, *y);
            Some(match op {
                BinOp::Add => ConstValue::Int(x.wrapping_add(y)),
                BinOp::Sub => ConstValue::Int(x.wrapping_sub(y)),
                BinOp::Mul => ConstValue::Int(x.wrapping_mul(y)),
                // In i64, i32::MIN / -1 does not overflow; narrowing wraps it back.
                BinOp::Div if y == 0 => ConstValue::Int(0),
                BinOp::Div => ConstValue::Int((x as i64 / y as i64) as i32),
                BinOp::Rem if y == 0 => ConstValue::Int(0),
                BinOp::Rem => ConstValue::Int((x as i64 % y as i64) as i32),
                BinOp::Lt => ConstValue::Bool(x < y),
                BinOp::Le => ConstValue::Bool(x <= y),
                BinOp::Gt => ConstValue::Bool(x > y),
                BinOp::Ge => ConstValue::Bool(x >= y),
                BinOp::Eq => ConstValue::Bool(x == y),
                BinOp::Ne => ConstValue::Bool(x != y),
                BinOp::And | BinOp::Or => return None,
            })
        }
        (ExprKind::Const(ConstValue::Bool(x)), ExprKind::Const(ConstValue::Bool(y)))
            if is_scalar_of(a, Scalar::Bool) && is_scalar_of(c, Scalar::Bool) =>
        {
            let (x, y) = (*x, *y);
            Some(match op {
                BinOp::And => ConstValue::Bool(x && y),
                BinOp::Or => ConstValue::Bool(x || y),
                BinOp::Eq => ConstValue::Bool(x == y),
                BinOp::Ne => ConstValue::Bool(x != y),
                _ => return None,
            })
        }
        _ => None,
    }
}
