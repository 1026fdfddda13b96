//! Tier 0: which setup assignments no code of the variant reads (they are not lowered).
//!
//! A primitive's setup computes values for every variant: screen_triangle's `linear`
//! planes, say, which a variant binding only `perspective_linear` parameters never reads,
//! or the counters of unrolled loops. Cranelift drops such dead code, but only after our
//! lowering built it and its own passes walked it (~17% of screen_triangle's tier-0 CLIF).
//! [`live_setup_locals`] finds, per variant, the locals something live reads: the pixel
//! code as this key lowers it, conditions, `bound`, primitive calls, and transitively the
//! assignments to live locals and every assignment that is kept for its side effect (one
//! that may record a run-time error, i.e. not speculable). The lowering then skips a setup
//! assignment whose local is not live and that could have no effect but its value.

use crate::ir::{ExprId, Exprs, Function, LocalId, StmtId, StmtKind};

/// The locals read by live code (indexed by local), given `live`, the locals the pixel
/// code reads or assigns as lowered, and `removable` (whether an assignment statement may
/// be skipped when its local is dead).
pub(crate) fn live_setup_locals(
    f: &Function,
    setup: &[StmtId],
    mut live: Vec<bool>,
    removable: &dyn Fn(StmtId) -> bool,
) -> Vec<bool> {
    // Statements are walked last to first, so in straight-line code an assignment is met
    // after the reads that make its local live, and one round finds everything unless an
    // assignment skipped as dead has its local read above it (a reused local, a loop whose
    // later statements feed earlier ones): only then is another round needed. A confirming
    // round when nothing was skipped that way was half of this walk's cost.
    let mut skipped = Vec::new();
    loop {
        skipped.clear();
        walk(f, setup, &mut live, &mut skipped, removable);
        if !skipped
            .iter()
            .any(|l: &LocalId| live.get(l.0 as usize).copied().unwrap_or(true))
        {
            return live;
        }
    }
}

fn mark(l: LocalId, live: &mut [bool]) {
    if let Some(x) = live.get_mut(l.0 as usize) {
        *x = true;
    }
}

fn reads(x: &Exprs, e: ExprId, live: &mut [bool]) {
    x.for_each_local(e, &mut |l| mark(l, live));
}

/// One round: marks what live statements read; `skipped` gets the locals of the assignments
/// left out as dead.
fn walk(
    f: &Function,
    stmts: &[StmtId],
    live: &mut [bool],
    skipped: &mut Vec<LocalId>,
    removable: &dyn Fn(StmtId) -> bool,
) {
    let x = &f.exprs;
    for &s in stmts.iter().rev() {
        match &f.stmts[s] {
            StmtKind::Assign { place, value } => {
                let is_live = live.get(place.local.0 as usize).copied().unwrap_or(true);
                if is_live || !removable(s) {
                    mark(place.local, live);
                    place.indices.iter().for_each(|(i, _)| reads(x, *i, live));
                    reads(x, *value, live);
                } else {
                    skipped.push(place.local);
                }
            }
            StmtKind::If { cond, then, otherwise } => {
                reads(x, *cond, live);
                walk(f, then, live, skipped, removable);
                walk(f, otherwise, live, skipped, removable);
            }
            StmtKind::Loop { cond, body, step, .. } => {
                if let Some(c) = cond {
                    reads(x, *c, live);
                }
                walk(f, step, live, skipped, removable);
                walk(f, body, live, skipped, removable);
            }
            StmtKind::Interpolation { arms } => {
                for a in arms {
                    walk(f, &a.body, live, skipped, removable);
                }
            }
            StmtKind::InterpolatorReturn(Some(e)) => reads(x, *e, live),
            StmtKind::Bound(es) => es.iter().for_each(|e| reads(x, *e, live)),
            StmtKind::CallPrimitive { args, .. } => args.iter().for_each(|e| reads(x, *e, live)),
            StmtKind::Break(_) | StmtKind::Continue(_) | StmtKind::Return | StmtKind::InterpolatorReturn(None) => {}
        }
    }
}

/// Calls `visit` for each assignment in `stmts` of `f` (nested ones too) with the local it
/// assigns (whole or in part); a local assigned twice is passed twice. Tier 0's per-kernel
/// walks collect into flags or a sorted list with it: a HashSet per walk cost more than the
/// walk.
pub(crate) fn visit_assigned(f: &Function, stmts: &[StmtId], visit: &mut dyn FnMut(LocalId)) {
    crate::ir::for_each_assign(&f.stmts, stmts, &mut |place, _| visit(place.local));
}

/// The locals `stmts` of `f` assigns, as a flag per local.
pub(crate) fn assigned_flags(f: &Function, stmts: &[StmtId]) -> Vec<bool> {
    let mut out = vec![false; f.locals.len()];
    visit_assigned(f, stmts, &mut |l| {
        if let Some(x) = out.get_mut(l.0 as usize) {
            *x = true;
        }
    });
    out
}

/// The locals `stmts` of `f` reads or assigns anywhere, as a flag per local.
pub(crate) fn mentioned_flags(f: &Function, stmts: &[StmtId]) -> Vec<bool> {
    // Nothing removable: one round marks every read and every assigned local.
    live_setup_locals(f, stmts, vec![false; f.locals.len()], &|_| false)
}
