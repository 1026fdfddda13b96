//! Block-level culling, its compile-time half: the *guard prefix* of a primitive's pixel
//! part ([`prefix`]) and the expressions each variant of the pixel code lowers
//! ([`pass_exprs`]). The run-time half, the interval evaluation of the prefix over a block
//! of pixels, is the JIT's (`jit::lower::block`).
//!
//! The guard prefix is the leading statements that are assignments of pure expressions to
//! varying scalar locals, `if (c) return;` guards on varying conditions, and `if` on uniform
//! conditions whose branches are themselves such statements. It stops at the first
//! statement with an effect a skipped block would lose (a Z or G-buffer write, a loop that
//! spends fuel, an index that may record an error, ...).
//!
//! Invariants: nothing in the prefix has an effect ([`pure`] expressions, assignments to
//! varying locals that are not parameters, guards that only retire lanes), so a block where
//! every lane leaves at a guard does nothing at all, and a variant that drops a guard the
//! block facts proved never fires computes what the full code computes. Guards are numbered
//! in pre-order (`PStmt::Guard::id`); a uniform `if` whose condition is decided for the
//! copy of the loops being planned ([`super::unswitch`]) contributes its taken side inline.

use std::collections::{HashMap, HashSet};

use crate::ir::{ConstValue, Elem, ExprId, ExprKind, Exprs, Function, LocalId, StmtId, StmtKind};

/// One statement of the guard prefix.
pub(crate) enum PStmt {
    /// `local = value` for a varying scalar local: kept in both variants.
    Assign {
        stmt: StmtId,
        local: LocalId,
        value: ExprId,
    },
    /// `if (cond) return;` with a varying `cond`; `id` numbers guards in pre-order.
    Guard { stmt: StmtId, cond: ExprId, id: usize },
    /// `if (cond) {..} else {..}` on a uniform `cond`, both sides prefix statements.
    UniformIf {
        cond: ExprId,
        then: Vec<PStmt>,
        otherwise: Vec<PStmt>,
    },
    /// `return` under uniform control: every lane that gets here retires.
    Kill(StmtId),
}

/// The guard prefix of a primitive's pixel part.
pub(crate) struct Prefix {
    pub stmts: Vec<PStmt>,
    /// How many top-level pixel statements the prefix covers.
    pub len: usize,
    /// Number of guards (ids 0..guards).
    pub guards: usize,
}

/// Find the guard prefix of `f`'s pixel statements (see the module comment). A uniform `if`
/// whose condition `decided` fixes (see [`super::unswitch`]) contributes the statements of
/// the side it takes, inline.
pub(crate) fn prefix(f: &Function, decided: &HashMap<ExprId, bool>) -> Prefix {
    let mut stmts = vec![];
    let mut guards = 0;
    let mut len = 0;
    for &s in &f.pixel {
        let mut n = guards;
        let mut out = vec![];
        if !classify_into(f, s, &mut n, decided, &mut out) {
            break;
        }
        guards = n;
        stmts.append(&mut out);
        len += 1;
    }
    Prefix { len, stmts, guards }
}

/// Append `s`'s prefix statements to `out` (several when `s` is a decided `if`); false
/// when `s` is not a prefix statement.
fn classify_into(
    f: &Function,
    s: StmtId,
    guards: &mut usize,
    decided: &HashMap<ExprId, bool>,
    out: &mut Vec<PStmt>,
) -> bool {
    if let StmtKind::If { cond, then, otherwise } = &f.stmts[s] {
        if let Some(&on) = decided.get(cond) {
            let taken = if on { then } else { otherwise };
            return taken.iter().all(|&t| classify_into(f, t, guards, decided, out));
        }
    }
    match classify(f, s, guards, decided) {
        Some(p) => {
            out.push(p);
            true
        }
        None => false,
    }
}

fn classify(f: &Function, s: StmtId, guards: &mut usize, decided: &HashMap<ExprId, bool>) -> Option<PStmt> {
    match &f.stmts[s] {
        StmtKind::Assign { place, value } => {
            let local = f.locals.get(place.local.0 as usize)?;
            let is_param = f.params.iter().any(|p| p.local == place.local);
            let scalar_ok = matches!(local.ty.elem, Elem::Scalar(_)) && local.ty.dims.is_empty() && !local.ty.per_seq;
            (place.indices.is_empty() && !is_param && scalar_ok && local.var.is_varying() && pure(&f.exprs, *value))
                .then_some(PStmt::Assign {
                    stmt: s,
                    local: place.local,
                    value: *value,
                })
        }
        StmtKind::If { cond, then, otherwise } => {
            if !pure(&f.exprs, *cond) {
                return None;
            }
            if f.exprs[*cond].var.is_varying() {
                let is_guard = otherwise.is_empty() && then.len() == 1 && matches!(f.stmts[then[0]], StmtKind::Return);
                if !is_guard {
                    return None;
                }
                let id = *guards;
                *guards += 1;
                return Some(PStmt::Guard {
                    stmt: s,
                    cond: *cond,
                    id,
                });
            }
            let mut then_p = vec![];
            let mut otherwise_p = vec![];
            let ok = then.iter().all(|&t| classify_into(f, t, guards, decided, &mut then_p))
                && otherwise
                    .iter()
                    .all(|&t| classify_into(f, t, guards, decided, &mut otherwise_p));
            ok.then_some(PStmt::UniformIf {
                cond: *cond,
                then: then_p,
                otherwise: otherwise_p,
            })
        }
        StmtKind::Return => Some(PStmt::Kill(s)),
        _ => None,
    }
}

/// No effect when evaluated: no index that may be out of range (which records an error).
pub(crate) fn pure(x: &Exprs, e: ExprId) -> bool {
    let pure = |c: &ExprId| pure(x, *c);
    match &x[e].kind {
        ExprKind::Index { base, index, .. } => {
            let base_ty = &x[*base].ty;
            let in_range = match (&x[*index].kind, base_ty.per_seq, base_ty.dims.first()) {
                (ExprKind::Const(ConstValue::Int(k)), false, Some(&len)) => *k >= 0 && (*k as i64) < len as i64,
                _ => false,
            };
            in_range && pure(base)
        }
        ExprKind::Unary { expr, .. } | ExprKind::Convert(expr) | ExprKind::Splat(expr) => pure(expr),
        ExprKind::Binary { lhs, rhs, .. } | ExprKind::MatMul { lhs, rhs } => pure(lhs) && pure(rhs),
        ExprKind::Select { cond, then, otherwise } => pure(cond) && pure(then) && pure(otherwise),
        ExprKind::Builtin { args, .. } | ExprKind::List(args) => args.iter().all(pure),
        ExprKind::Const(_) | ExprKind::Local(_) | ExprKind::SeqCount | ExprKind::ClipFlag => true,
    }
}

/// Locals assigned anywhere in `block` of `f` (their values change between pixel groups).
pub(crate) fn assigned_locals(f: &Function, block: &[StmtId], out: &mut HashSet<LocalId>) {
    crate::ir::for_each_assign(&f.stmts, block, &mut |place, _| {
        out.insert(place.local);
    });
}

/// The expressions the pass variant lowers: what `Lower::prefix_without_guards`
/// emits, then `rest` (the pixel statements after the prefix). The row prologue of a pass
/// span evaluates only the hoisted row terms among them: the Y terms of dropped guards
/// (screen_triangle's `int(Y * 16) - int(oy * 16)` and float edge terms) cost every pixel
/// row of a span for nothing.
pub(crate) fn pass_exprs(
    f: &Function,
    all: &[PStmt],
    rest: &[StmtId],
    decidable: &[bool],
    live: &HashSet<LocalId>,
    decided: &HashMap<ExprId, bool>,
) -> HashSet<ExprId> {
    fn prefix(
        x: &Exprs,
        all: &[PStmt],
        stmts: &[PStmt],
        decidable: &[bool],
        live: &HashSet<LocalId>,
        out: &mut HashSet<ExprId>,
    ) {
        for s in stmts {
            match s {
                PStmt::Assign { value, .. } => expr_keys(x, *value, out),
                PStmt::Guard { cond, id, .. } => {
                    if !decidable[*id] {
                        expr_keys(x, *cond, out);
                    }
                }
                PStmt::UniformIf { cond, then, otherwise } => {
                    if !no_effect_in_pass(x, all, s, decidable, live) {
                        expr_keys(x, *cond, out);
                        prefix(x, all, then, decidable, live, out);
                        prefix(x, all, otherwise, decidable, live, out);
                    }
                }
                PStmt::Kill(_) => {}
            }
        }
    }
    let mut out = HashSet::new();
    prefix(&f.exprs, all, all, decidable, live, &mut out);
    stmt_keys(f, rest, decided, &mut out);
    out
}

/// The ids of `e` and all its subexpressions.
pub(crate) fn expr_keys(x: &Exprs, e: ExprId, out: &mut HashSet<ExprId>) {
    out.insert(e);
    x[e].for_each_child(|c| expr_keys(x, c, out));
}

/// The ids of every expression in `stmts`, but for the untaken side (and the condition) of
/// each `if` that `decided` fixes (see [`super::unswitch`]).
pub(crate) fn stmt_keys(f: &Function, stmts: &[StmtId], decided: &HashMap<ExprId, bool>, out: &mut HashSet<ExprId>) {
    let x = &f.exprs;
    for &s in stmts {
        let node = &f.stmts[s];
        if let StmtKind::If { cond, then, otherwise } = node {
            if let Some(&on) = decided.get(cond) {
                stmt_keys(f, if on { then } else { otherwise }, decided, out);
                continue;
            }
        }
        node.for_each_expr(|e| expr_keys(x, *e, out));
        node.for_each_block(|b| stmt_keys(f, b, decided, out));
    }
}

/// Locals assigned by prefix statements (recursively).
fn prefix_assigned(stmts: &[PStmt], out: &mut HashSet<LocalId>) {
    for s in stmts {
        match s {
            PStmt::Assign { local, .. } => {
                out.insert(*local);
            }
            PStmt::UniformIf { then, otherwise, .. } => {
                prefix_assigned(then, out);
                prefix_assigned(otherwise, out);
            }
            PStmt::Guard { .. } | PStmt::Kill(_) => {}
        }
    }
}

/// Locals the pass variant's prefix reads outside `skip` (an `if` of the prefix): the values
/// of assignments, the conditions of the guards it keeps and of uniform `if`s.
fn prefix_reads(x: &Exprs, stmts: &[PStmt], skip: &PStmt, decidable: &[bool], out: &mut HashSet<LocalId>) {
    for s in stmts {
        if std::ptr::eq(s, skip) {
            continue;
        }
        match s {
            PStmt::Assign { value, .. } => crate::ir::split::expr_reads(x, *value, out),
            PStmt::Guard { cond, id, .. } => {
                if !decidable[*id] {
                    crate::ir::split::expr_reads(x, *cond, out);
                }
            }
            PStmt::UniformIf { cond, then, otherwise } => {
                crate::ir::split::expr_reads(x, *cond, out);
                prefix_reads(x, then, skip, decidable, out);
                prefix_reads(x, otherwise, skip, decidable, out);
            }
            PStmt::Kill(_) => {}
        }
    }
}

/// `s` (a uniform `if` of the prefix) does nothing in the pass variant: every guard in it
/// is dropped, it kills no lane, and no local it assigns is read outside it (`live`: the
/// locals the pixel code after the prefix uses).
pub(crate) fn no_effect_in_pass(
    x: &Exprs,
    all: &[PStmt],
    s: &PStmt,
    decidable: &[bool],
    live: &HashSet<LocalId>,
) -> bool {
    fn only_dropped(stmts: &[PStmt], decidable: &[bool]) -> bool {
        stmts.iter().all(|s| match s {
            PStmt::Assign { .. } => true,
            PStmt::Guard { id, .. } => decidable[*id],
            PStmt::Kill(_) => false,
            PStmt::UniformIf { then, otherwise, .. } => {
                only_dropped(then, decidable) && only_dropped(otherwise, decidable)
            }
        })
    }
    let PStmt::UniformIf { then, otherwise, .. } = s else {
        return false;
    };
    if !only_dropped(then, decidable) || !only_dropped(otherwise, decidable) {
        return false;
    }
    let mut assigned = HashSet::new();
    prefix_assigned(std::slice::from_ref(s), &mut assigned);
    let mut reads = live.clone();
    prefix_reads(x, all, s, decidable, &mut reads);
    assigned.is_disjoint(&reads)
}
