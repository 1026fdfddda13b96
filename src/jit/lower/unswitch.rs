//! Loop unswitching of the pixel loops (tier 1): a uniform `if` inside the pixel code whose
//! condition cannot change while the loops run is decided once per draw, before them, and
//! the pixel loops (the block walk, its pass spans and the full code) are lowered once per
//! side with that `if` replaced by the side it takes.
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
//! - Decided conditions live in [`Lower::unswitched`], keyed by the condition's [`ExprId`]
//!   (one program point of the primitive each). Everything that lowers or walks the
//!   primitive's pixel statements in the loops consults it: [`Lower::lower_if`] (not in an
//!   inlined interpolator, whose ids are its own), the guard prefix
//!   ([`super::block::prefix`]) and the row terms a copy evaluates
//!   ([`super::block::pass_exprs`], [`full_code_exprs`]).
//! - At most [`MAX_UNSWITCHED`] conditions are decided on any path (copies of the pixel
//!   loops at most 2^MAX_UNSWITCHED), in pre-order of the conditions still reachable under
//!   the ones already decided: a nested `if` is unswitched only inside the side that
//!   contains it. Tier 0 never unswitches (each copy costs compile time).

use std::collections::{HashMap, HashSet};

use cranelift_codegen::ir::{Block, InstBuilder};

use super::{block, key_constant, Lower, Res};
use crate::abi::VariantKey;
use crate::ir::{Expr, ExprId, Function, LocalId, Scalar, Stmt, StmtKind};
use crate::jit::fixed;

/// Uniform conditions decided on one path through the unswitching tree. Each doubles the
/// pixel loops' code (less the untaken sides); measured for screen_triangle (one
/// condition), see docs/performance.md, "Unswitching (`unswitch.rs`)".
pub(super) const MAX_UNSWITCHED: usize = 2;

/// The first (pre-order) unswitchable condition of `stmts` not decided in `decided`,
/// looking only into the sides that `decided` and the variant key leave reachable.
pub(super) fn next_condition<'a>(
    stmts: &'a [Stmt],
    decided: &HashMap<ExprId, bool>,
    assigned: &HashSet<LocalId>,
    key: &VariantKey,
) -> Option<&'a Expr> {
    for s in stmts {
        let found = match &s.kind {
            StmtKind::If { cond, then, otherwise } => {
                let fixed = decided.get(&cond.id).copied().or_else(|| key_constant(cond, key));
                match fixed {
                    Some(on) => next_condition(if on { then } else { otherwise }, decided, assigned, key),
                    None if unswitchable(cond, assigned) => Some(cond),
                    None => next_condition(then, decided, assigned, key)
                        .or_else(|| next_condition(otherwise, decided, assigned, key)),
                }
            }
            StmtKind::Loop { body, step, .. } => {
                next_condition(body, decided, assigned, key).or_else(|| next_condition(step, decided, assigned, key))
            }
            StmtKind::Interpolation { arms } => arms
                .iter()
                .find_map(|a| next_condition(&a.body, decided, assigned, key)),
            _ => None,
        };
        if found.is_some() {
            return found;
        }
    }
    None
}

/// See the module comment.
fn unswitchable(cond: &Expr, assigned: &HashSet<LocalId>) -> bool {
    !cond.var.is_varying()
        && cond.ty.dims.is_empty()
        && !cond.ty.per_seq
        && block::pure(cond)
        && !cond.reads_any(&|l| assigned.contains(&l))
}

/// The expressions the full pixel code lowers when the conditions in `decided` are fixed
/// (the untaken sides left out): the row terms a copy evaluates.
pub(super) fn full_code_exprs(f: &Function, decided: &HashMap<ExprId, bool>) -> HashSet<ExprId> {
    let mut out = HashSet::new();
    block::stmt_keys(&f.pixel, decided, &mut out);
    out
}

impl<'a, 'b> Lower<'a, 'b> {
    /// Lower the pixel loops (`loops` lowers one copy; every copy ends by jumping to the
    /// block the caller continues in), first deciding up to [`MAX_UNSWITCHED`] uniform
    /// conditions of `f`'s pixel code, one branch each, in the current block.
    pub(super) fn unswitched_loops(
        &mut self,
        f: &'a Function,
        depth: usize,
        loops: &mut dyn FnMut(&mut Self) -> Res<()>,
    ) -> Res<()> {
        let cond = if self.tier0() || depth >= MAX_UNSWITCHED {
            None
        } else {
            let mut assigned = HashSet::new();
            block::assigned_locals(&f.pixel, &mut assigned);
            next_condition(&f.pixel, &self.unswitched, &assigned, self.key)
        };
        let Some(cond) = cond else {
            return loops(self);
        };
        let c = self.eval_uniform(cond)?;
        let c = fixed::convert(&mut self.b, c.scalar, Scalar::Bool, c.comps[0]);
        let sides: [Block; 2] = [self.b.create_block(), self.b.create_block()];
        self.b.ins().brif(c, sides[0], &[], sides[1], &[]);
        for (side, on) in sides.into_iter().zip([true, false]) {
            self.b.switch_to_block(side);
            if depth == 0 {
                self.store_deferred_frame(cond.id, on);
            }
            self.unswitched.insert(cond.id, on);
            let r = self.unswitched_loops(f, depth + 1, loops);
            self.unswitched.remove(&cond.id);
            r?;
        }
        Ok(())
    }
}
