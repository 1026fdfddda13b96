//! Which uniform stack arrays of a primitive must be zeroed at kernel entry.
//!
//! No run may read stale stack memory, so a local kept in a stack slot (indexed with a
//! non-constant index) must be zero when read before anything assigned it. Most such arrays
//! are cleared where they are declared (a declaration without initialiser is an all-zero
//! assignment in the IR) before anything reads them, and clearing them at entry too would
//! be dead work: half of the NURB kernel's 2240 vector stores (its tessellation arrays,
//! ~21 KB). [`read_before_assigned`] finds the arrays some read may reach before a whole
//! assignment on some path; only those are cleared at entry.
//!
//! The walk is a forward "definitely assigned" analysis over the IR in lowering order
//! (setup, then the pixel part): a *whole* assignment (no indices) of a tracked local
//! assigns it; `if` sides meet by intersection; a loop body (and step) is walked from the
//! state at the loop's entry (its step too: a `continue` reaches it part-way through the
//! body) and the loop leaves that state unchanged (it may run no trip; later trips only
//! start with more assigned); interpolation arms likewise. `break`,
//! `continue` and `return` only end paths, which never makes the answer unsound. Reads in
//! the pixel part are judged against the state at the end of setup, and assignments there
//! assign nothing (the pixel part runs once per group, under masks).
//!
//! Tracked: uniform locals whose element is a scalar, so that a whole assignment stores
//! every word of the slot (`Lower::assign_at` writes one component per word or fails).
//! Everything else answers `true` (keep the clear).

use crate::ir::{Elem, ExprId, Exprs, Function, LocalId, StmtId, StmtKind, Stmts};

/// Per local of `f`: may a read of it run before a whole assignment has stored every word
/// of it (so its stack slot must start zeroed)? `true` for every local not tracked.
pub(crate) fn read_before_assigned(f: &Function) -> Vec<bool> {
    let tracked: Vec<bool> = f
        .locals
        .iter()
        .map(|l| !l.var.is_varying() && matches!(l.ty.elem, Elem::Scalar(_)) && !l.ty.per_seq)
        .collect();
    let mut walk = Walk {
        st: &f.stmts,
        x: &f.exprs,
        tracked: &tracked,
        needs: tracked.iter().map(|t| !t).collect(),
        credit: true,
    };
    let mut assigned = vec![false; f.locals.len()];
    walk.stmts(&f.setup, &mut assigned);
    walk.credit = false;
    walk.stmts(&f.pixel, &mut assigned);
    walk.needs
}

struct Walk<'t> {
    st: &'t Stmts,
    x: &'t Exprs,
    tracked: &'t [bool],
    /// The answer so far.
    needs: Vec<bool>,
    /// Whether whole assignments count (setup) or not (the pixel part).
    credit: bool,
}

impl Walk<'_> {
    fn reads(&mut self, e: ExprId, assigned: &[bool]) {
        let needs = &mut self.needs;
        self.x.for_each_local(e, &mut |l: LocalId| {
            let i = l.0 as usize;
            if !assigned.get(i).copied().unwrap_or(false) {
                if let Some(n) = needs.get_mut(i) {
                    *n = true;
                }
            }
        });
    }

    fn stmts(&mut self, list: &[StmtId], assigned: &mut Vec<bool>) {
        for &s in list {
            self.stmt(s, assigned);
        }
    }

    fn stmt(&mut self, s: StmtId, assigned: &mut Vec<bool>) {
        let st = self.st;
        match &st[s] {
            StmtKind::Assign { place, value } => {
                // The value and the indices are read before the store.
                for (i, _) in &place.indices {
                    self.reads(*i, assigned);
                }
                self.reads(*value, assigned);
                let i = place.local.0 as usize;
                if self.credit && place.indices.is_empty() && self.tracked.get(i).copied().unwrap_or(false) {
                    assigned[i] = true;
                }
            }
            StmtKind::If { cond, then, otherwise } => {
                self.reads(*cond, assigned);
                let mut then_state = assigned.clone();
                self.stmts(then, &mut then_state);
                self.stmts(otherwise, assigned);
                for (a, t) in assigned.iter_mut().zip(then_state) {
                    *a &= t;
                }
            }
            StmtKind::Loop { cond, body, step, .. } => {
                if let Some(c) = cond {
                    self.reads(*c, assigned);
                }
                // The step also runs after a `continue` part-way through the body, so it is
                // judged from the state at the loop's entry, not from the body's end.
                let mut trip = assigned.clone();
                self.stmts(body, &mut trip);
                let mut step_state = assigned.clone();
                self.stmts(step, &mut step_state);
            }
            StmtKind::Interpolation { arms } => {
                for a in arms {
                    let mut arm = assigned.clone();
                    self.stmts(&a.body, &mut arm);
                }
            }
            StmtKind::InterpolatorReturn(Some(e)) => self.reads(*e, assigned),
            StmtKind::Bound(es) => es.iter().for_each(|e| self.reads(*e, assigned)),
            StmtKind::CallPrimitive { args, .. } => args.iter().for_each(|e| self.reads(*e, assigned)),
            StmtKind::InterpolatorReturn(None) | StmtKind::Break(_) | StmtKind::Continue(_) | StmtKind::Return => {}
        }
    }
}
