//! Loop unswitching of the pixel loops (tier 1): a uniform `if` inside the pixel code whose
//! condition cannot change while the loops run is decided once per draw, before them, and
//! the pixel loops (the block walk, its pass spans and the full code) are lowered once per
//! side with that `if` replaced by the side it takes. This module plans the copies
//! ([`plan_loops`]); the JIT's `unswitched_loops` emits the branches and the copies.
//!
//! Why: screen_triangle's `if (exact) { integer edges } else { float edges }` was tested in
//! every pixel group, and both coverage forms' code sat in the group loop; the block walk
//! also carried both sides' interval facts to a join per block. Specialised, a group runs
//! one straight coverage form, and the block walk's prefix sees only that form's guards.
//!
//! Invariants:
//! - A condition is *unswitchable* when it is uniform, pure (no index that may record an
//!   error: evaluating it before the loops, even when no group runs, has no effect) and
//!   reads no local the pixel code assigns (so every group would compute the same value).
//!   Its value before the loops is then bit-identical to the one each group computed.
//! - A copy's decided conditions are keyed by the condition's [`ExprId`] (one program point
//!   of the primitive each). Everything that lowers or walks the primitive's pixel
//!   statements in a copy consults them: `Lower::lower_if` (not in an inlined
//!   interpolator, whose ids are its own), the copy's guard prefix
//!   ([`super::block::prefix`]) and the row terms the copy evaluates
//!   ([`super::block::pass_exprs`], [`full_code_exprs`]).
//! - At most [`MAX_UNSWITCHED`] conditions are decided on any path (copies of the pixel
//!   loops at most 2^MAX_UNSWITCHED), in pre-order of the conditions still reachable under
//!   the ones already decided: a nested `if` is unswitched only inside the side that
//!   contains it. Tier 0 never unswitches (each copy costs compile time), and plans one
//!   copy without a guard prefix (it has no block culling).

use std::collections::{HashMap, HashSet};

use super::block::{self, Prefix};
use super::pred::key_constant;
use super::view;
use crate::abi::VariantKey;
use crate::ir::{ExprId, Exprs, Function, LocalId, StmtId, StmtKind};

/// Uniform conditions decided on one path through the unswitching tree. Each doubles the
/// pixel loops' code (less the untaken sides); measured for screen_triangle (one
/// condition), see docs/performance.md, "Unswitching (`unswitch.rs`)".
pub(crate) const MAX_UNSWITCHED: usize = 2;

/// The copies of the pixel loops: one, or a condition decided before the loops and the
/// copies for each of its sides.
pub(crate) enum Loops {
    Copy(Box<LoopsCopy>),
    /// `sides[0]` runs when `cond` holds, `sides[1]` when it does not.
    Split {
        cond: ExprId,
        sides: Box<[Loops; 2]>,
    },
}

/// What one copy of the pixel loops lowers, under the conditions decided on its path.
pub(crate) struct LoopsCopy {
    /// Tier 1, pixel code opening with guards: the guard prefix the block walk evaluates
    /// (`None`: the plain rows, no block walk).
    pub prefix: Option<Prefix>,
    /// With a prefix: the locals the pixel statements after it use (as the key lowers them).
    pub rest_live: HashSet<LocalId>,
    /// Under decided conditions: the expressions the full pixel code lowers (the row terms
    /// its rows evaluate); `None`: all of them.
    pub full_exprs: Option<HashSet<ExprId>>,
}

impl Loops {
    /// The condition decided first, before every copy (`None`: one copy).
    pub(crate) fn first_condition(&self) -> Option<ExprId> {
        match self {
            Loops::Copy(_) => None,
            Loops::Split { cond, .. } => Some(*cond),
        }
    }
}

/// The copies of `f`'s pixel loops for `key` (`assigned`: the locals the pixel code
/// assigns); `tier1`: unswitch and plan the block walk's prefix.
pub(crate) fn plan_loops(f: &Function, key: &VariantKey, assigned: &HashSet<LocalId>, tier1: bool) -> Loops {
    let mut decided = HashMap::new();
    plan_copies(f, key, assigned, tier1, &mut decided)
}

fn plan_copies(
    f: &Function,
    key: &VariantKey,
    assigned: &HashSet<LocalId>,
    tier1: bool,
    decided: &mut HashMap<ExprId, bool>,
) -> Loops {
    let cond = if !tier1 || decided.len() >= MAX_UNSWITCHED {
        None
    } else {
        next_condition(f, &f.pixel, decided, assigned, key)
    };
    if let Some(cond) = cond {
        let mut side = |on| {
            decided.insert(cond, on);
            let copies = plan_copies(f, key, assigned, tier1, decided);
            decided.remove(&cond);
            copies
        };
        let sides = [side(true), side(false)];
        return Loops::Split {
            cond,
            sides: Box::new(sides),
        };
    }
    let prefix = if tier1 {
        Some(block::prefix(f, decided)).filter(|p| p.guards > 0)
    } else {
        None
    };
    let mut rest_live = HashSet::new();
    if let Some(p) = &prefix {
        view::live_locals(f, key, &f.pixel[p.len..], &mut rest_live);
    }
    let full_exprs = (!decided.is_empty()).then(|| full_code_exprs(f, decided));
    Loops::Copy(Box::new(LoopsCopy {
        prefix,
        rest_live,
        full_exprs,
    }))
}

/// The first (pre-order) unswitchable condition of `stmts` not decided in `decided`,
/// looking only into the sides that `decided` and the variant key leave reachable.
pub(crate) fn next_condition(
    f: &Function,
    stmts: &[StmtId],
    decided: &HashMap<ExprId, bool>,
    assigned: &HashSet<LocalId>,
    key: &VariantKey,
) -> Option<ExprId> {
    let x = &f.exprs;
    for &s in stmts {
        let found = match &f.stmts[s] {
            StmtKind::If { cond, then, otherwise } => {
                let fixed = decided.get(cond).copied().or_else(|| key_constant(x, *cond, key));
                match fixed {
                    Some(on) => next_condition(f, if on { then } else { otherwise }, decided, assigned, key),
                    None if unswitchable(x, *cond, assigned) => Some(*cond),
                    None => next_condition(f, then, decided, assigned, key)
                        .or_else(|| next_condition(f, otherwise, decided, assigned, key)),
                }
            }
            StmtKind::Loop { body, step, .. } => next_condition(f, body, decided, assigned, key)
                .or_else(|| next_condition(f, step, decided, assigned, key)),
            StmtKind::Interpolation { arms } => arms
                .iter()
                .find_map(|a| next_condition(f, &a.body, decided, assigned, key)),
            _ => None,
        };
        if found.is_some() {
            return found;
        }
    }
    None
}

/// See the module comment.
fn unswitchable(x: &Exprs, cond_id: ExprId, assigned: &HashSet<LocalId>) -> bool {
    let cond = &x[cond_id];
    !cond.var.is_varying()
        && cond.ty.dims.is_empty()
        && !cond.ty.per_seq
        && block::pure(x, cond_id)
        && !x.reads_any(cond_id, &|l| assigned.contains(&l))
}

/// The expressions the full pixel code lowers when the conditions in `decided` are fixed
/// (the untaken sides left out): the row terms a copy evaluates.
pub(crate) fn full_code_exprs(f: &Function, decided: &HashMap<ExprId, bool>) -> HashSet<ExprId> {
    let mut out = HashSet::new();
    block::stmt_keys(f, &f.pixel, decided, &mut out);
    out
}
