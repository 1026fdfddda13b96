//! Splitting a function into its uniform setup and its pixel part.
//!
//! Input: a checked function whose whole body is in `f.setup` (variabilities filled in),
//! `f.pixel` empty. A top-level statement is a *pixel statement* if it contains a varying
//! expression (the X/Y/Z arguments a primitive call passes through do not count: they are
//! bound per pixel by the callee itself), assigns a varying local, contains an
//! `interpolator_return`, or contains a `return` under varying control (a varying `if` or
//! a varying loop). An `interpolation` construct whose arms are uniform and store nothing
//! (figure 8 of the paper: the polygon computing clipped interpolation data) is uniform
//! setup code like any other.
//!
//! With k the index of the first pixel statement, `setup = body[..k]` and the rest goes to
//! `pixel`, except that a later top-level statement that is purely uniform — no pixel
//! content, no `return`, no primitive call, no `break`/`continue` leaving it — is hoisted
//! to the end of setup when that preserves meaning: no statement staying in pixel before it
//! reads or writes a local it writes, or writes a local it reads. A statement containing a
//! uniform `return` stops hoisting past it (what follows might not run at all); varying
//! returns do not (they retire lanes, uniform code is unaffected). After the split:
//! - `setup` holds only uniform statements; `pixel` everything from the first pixel
//!   statement on that could not be hoisted;
//! - every primitive call and every `bound` is in `setup`; one left in `pixel` is an error
//!   (E0411, E0412) reported by [`split_checked`];
//! - statements keep their ids while they move between the two blocks, so a hoisted one
//!   is out of pre-order until the caller renumbers ([`super::number::renumber`]; the
//!   checker does, after this pass).

use std::collections::HashSet;

use super::{ExprId, ExprKind, Exprs, Function, LocalId, LoopId, ParamRole, StmtId, StmtKind, Stmts};
use crate::diag::{Diagnostic, Diagnostics};

/// Move the statements that must run per pixel group from `f.setup` into `f.pixel`.
/// Errors (a primitive call or `bound` that cannot be in setup) are dropped; the checker
/// calls [`split_checked`] to report them.
pub fn split(f: &mut Function) {
    let mut ignored = Diagnostics::new();
    split_checked(f, &mut ignored);
}

/// [`split`], reporting primitive calls and `bound`s that end up in the pixel part.
pub fn split_checked(f: &mut Function, diags: &mut Diagnostics) {
    let pixel_params: HashSet<LocalId> = f
        .params
        .iter()
        .filter(|p| matches!(p.role, ParamRole::X | ParamRole::Y | ParamRole::Z))
        .map(|p| p.local)
        .collect();
    let body = std::mem::take(&mut f.setup);
    let is_pixel = |s: &StmtId| pixel_content(f, *s, &pixel_params, false);
    let Some(k) = body.iter().position(is_pixel) else {
        f.setup = body;
        return;
    };
    let st = &f.stmts;
    let first_pixel_span = st.span(body[k]);
    let mut setup = vec![];
    let mut pixel: Vec<StmtId> = vec![];
    let mut barrier = false;
    for (i, s) in body.into_iter().enumerate() {
        if i < k {
            setup.push(s);
            continue;
        }
        let hoistable = i > k
            && !barrier
            && !pixel_content(f, s, &pixel_params, false)
            && !contains(st, s, &|k| {
                matches!(k, StmtKind::Return | StmtKind::CallPrimitive { .. })
            })
            && no_escaping_jumps(st, s);
        if hoistable && safe_to_hoist(f, s, &pixel) {
            setup.push(s);
            continue;
        }
        if contains(st, s, &|k| matches!(k, StmtKind::CallPrimitive { .. })) {
            diags.push(
                Diagnostic::error(
                    "E0411",
                    "a primitive call must come before the primitive's per-pixel code",
                )
                .primary(st.span(s), "this call is after per-pixel code")
                .secondary(first_pixel_span, "per-pixel code starts here")
                .help("sub-primitives are rendered from the uniform setup part"),
            );
        }
        if contains(st, s, &|k| matches!(k, StmtKind::Bound(_))) {
            diags.push(
                Diagnostic::error("E0412", "`bound` cannot be moved before the per-pixel code")
                    .primary(
                        st.span(s),
                        "this bound depends on per-pixel code or is in a statement that does",
                    )
                    .secondary(first_pixel_span, "per-pixel code starts here")
                    .help("compute the bound from uniform values before the first per-pixel statement"),
            );
        }
        if uniform_return(f, s, false) {
            barrier = true;
        }
        pixel.push(s);
    }
    f.setup = setup;
    f.pixel = pixel;
}

/// Whether `s` needs to run per pixel. `ctl`: `s` sits under varying control flow.
fn pixel_content(f: &Function, s: StmtId, pixel_params: &HashSet<LocalId>, ctl: bool) -> bool {
    let any = |b: &[StmtId], ctl: bool| b.iter().any(|s| pixel_content(f, *s, pixel_params, ctl));
    let is_varying = |e: &ExprId| f.exprs[*e].var.is_varying();
    match &f.stmts[s] {
        StmtKind::Assign { place, value } => {
            is_varying(value)
                || place.indices.iter().any(|(i, _)| is_varying(i))
                || f.local(place.local).var.is_varying()
        }
        StmtKind::If { cond, then, otherwise } => {
            let c = ctl || is_varying(cond);
            is_varying(cond) || any(then, c) || any(otherwise, c)
        }
        StmtKind::Loop {
            cond,
            body,
            step,
            varying,
            ..
        } => {
            let c = ctl || *varying;
            *varying || cond.as_ref().is_some_and(|e| is_varying(e)) || any(body, c) || any(step, c)
        }
        StmtKind::Break(_) | StmtKind::Continue(_) => false,
        StmtKind::Return => ctl,
        StmtKind::Interpolation { arms } => arms.iter().any(|a| any(&a.body, ctl)),
        StmtKind::InterpolatorReturn(_) => true,
        StmtKind::Bound(args) => args.iter().any(|a| is_varying(a)),
        StmtKind::CallPrimitive { args, .. } => args.iter().any(|a| {
            let passthrough = matches!(f.exprs[*a].kind, ExprKind::Local(l) if pixel_params.contains(&l));
            is_varying(a) && !passthrough
        }),
    }
}

/// Whether `s` holds a `return` that is not under varying control (it may end the whole
/// primitive, so nothing after it may move before it). `ctl`: under varying control.
fn uniform_return(f: &Function, s: StmtId, ctl: bool) -> bool {
    let any = |b: &[StmtId], ctl: bool| b.iter().any(|s| uniform_return(f, *s, ctl));
    let x = &f.exprs;
    match &f.stmts[s] {
        StmtKind::Return => !ctl,
        StmtKind::If { cond, then, otherwise } => {
            let c = ctl || x[*cond].var.is_varying();
            any(then, c) || any(otherwise, c)
        }
        StmtKind::Loop {
            body, step, varying, ..
        } => any(body, ctl || *varying) || any(step, ctl || *varying),
        StmtKind::Interpolation { arms } => arms.iter().any(|a| any(&a.body, ctl)),
        _ => false,
    }
}

/// Whether `s` or a statement nested in it has a kind matching `pred`.
fn contains(st: &Stmts, s: StmtId, pred: &dyn Fn(&StmtKind) -> bool) -> bool {
    let mut found = false;
    super::for_each_stmt(st, &[s], &mut |_, k| found |= pred(k));
    found
}

/// True when every `break`/`continue` in `s` targets a loop inside `s`.
fn no_escaping_jumps(st: &Stmts, s: StmtId) -> bool {
    fn walk(st: &Stmts, s: StmtId, inside: &mut Vec<LoopId>) -> bool {
        let all = |b: &[StmtId], inside: &mut Vec<LoopId>| b.iter().all(|s| walk(st, *s, inside));
        match &st[s] {
            StmtKind::Break(l) | StmtKind::Continue(l) => inside.contains(l),
            StmtKind::If { then, otherwise, .. } => all(then, inside) && all(otherwise, inside),
            StmtKind::Loop { id, body, step, .. } => {
                inside.push(*id);
                let ok = all(body, inside) && all(step, inside);
                inside.pop();
                ok
            }
            StmtKind::Interpolation { arms } => arms.iter().all(|a| all(&a.body, inside)),
            _ => true,
        }
    }
    walk(st, s, &mut vec![])
}

/// Moving `s` before the statements of `pixel` keeps the program's meaning.
fn safe_to_hoist(f: &Function, s: StmtId, pixel: &[StmtId]) -> bool {
    let (mut r, mut w) = (HashSet::new(), HashSet::new());
    reads_writes(f, s, &mut r, &mut w);
    pixel.iter().all(|t| {
        let (mut tr, mut tw) = (HashSet::new(), HashSet::new());
        reads_writes(f, *t, &mut tr, &mut tw);
        tr.is_disjoint(&w) && tw.is_disjoint(&w) && tw.is_disjoint(&r)
    })
}

/// The locals a statement reads and writes (anywhere inside it).
pub(crate) fn reads_writes(f: &Function, s: StmtId, r: &mut HashSet<LocalId>, w: &mut HashSet<LocalId>) {
    let block = |b: &[StmtId], r: &mut HashSet<LocalId>, w: &mut HashSet<LocalId>| {
        for s in b {
            reads_writes(f, *s, r, w);
        }
    };
    let x = &f.exprs;
    match &f.stmts[s] {
        StmtKind::Assign { place, value } => {
            w.insert(place.local);
            for (i, _) in &place.indices {
                expr_reads(x, *i, r);
            }
            expr_reads(x, *value, r);
        }
        StmtKind::If { cond, then, otherwise } => {
            expr_reads(x, *cond, r);
            block(then, r, w);
            block(otherwise, r, w);
        }
        StmtKind::Loop { cond, body, step, .. } => {
            if let Some(c) = cond {
                expr_reads(x, *c, r);
            }
            block(body, r, w);
            block(step, r, w);
        }
        StmtKind::Interpolation { arms } => {
            for a in arms {
                block(&a.body, r, w);
            }
        }
        StmtKind::InterpolatorReturn(Some(e)) => expr_reads(x, *e, r),
        StmtKind::Bound(args) => args.iter().for_each(|a| expr_reads(x, *a, r)),
        StmtKind::CallPrimitive { args, .. } => args.iter().for_each(|a| expr_reads(x, *a, r)),
        StmtKind::InterpolatorReturn(None) | StmtKind::Break(_) | StmtKind::Continue(_) | StmtKind::Return => {}
    }
}

/// Every local `e` reads.
pub(crate) fn expr_reads(x: &Exprs, e: ExprId, r: &mut HashSet<LocalId>) {
    x.for_each_local(e, &mut |l| {
        r.insert(l);
    });
}
