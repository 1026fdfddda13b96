//! Tier 0's *flat* pixel code: a pixel group lowered as (nearly) one basic block.
//!
//! Tier 1 leaves a group as soon as its last lane retires (a branch after every coverage
//! or depth guard) and skips the side of an `if` no lane takes. Each of those branches
//! ends a basic block, and regalloc2's single-pass allocator, which tier 0 uses, spills
//! every value live across a block boundary and reloads it at each use in the next block:
//! measured, the group code's ~20 blocks made the register allocator and the emitted
//! spill/reload code a large part of a tier-0 compile. Tier 0 serves one frame (the tier-1
//! kernel replaces it in ~10 ms), so its pixel code can spend run time to save compile
//! time: when the primitive's pixel code allows it ([`pixel_code_is_flattenable`]), tier 0
//! runs every statement of a group under its lane masks without those early exits, and
//! lowers a uniform `if` of pixel code whose sides allow it ([`maskable_stmts`]) like a
//! varying one whose condition is the same for every lane.
//!
//! Why the results stay bit-identical to tier 1: every effect of pixel code is already
//! masked by the executing lanes (G-buffer stores blend, Z is written back for the lanes
//! that assigned it, varying assignments blend once control flow is varying, varying loops
//! test their mask before spending fuel), so a statement run for no lane changes nothing,
//! with three exceptions the predicates exclude or the lowering guards:
//! - a uniform loop spends fuel whether or not a lane executes it: no uniform loop may be
//!   in the pixel code (nor in a shared interpolator it inlines);
//! - an assignment to a uniform local is not masked: none may be in the pixel code;
//! - a failed array index records a run-time error: in pixel code, at either tier, the
//!   record is further conditioned on some lane executing the access
//!   (`Lower::and_some_lane`).
//!
//! Flat code also starts every group with the varying locals the pixel code assigns (and
//! the setup does not) at zero ([`zeroed_locals`]): assigned under masks, they would
//! otherwise carry the previous group's value through the loops, and no lane reads it (a
//! local is declared, so assigned, before any read of it in the same group).

use std::collections::HashSet;

use super::dead;
use super::homes::{Home, Homes};
use crate::abi::{BindingKind, VariantKey};
use crate::ir::{ExprId, Function, Program, StmtId, StmtKind};

/// Elements of the largest varying local flat pixel code may have. Clearing a bigger one
/// is a loop (`Lower::zero_stack_bytes`), which needs blocks: a varying `float a[65536]`
/// cleared in straight stores was 65536 of them, 11 s of compile.
pub const MAX_FLAT_ARRAY: u32 = 256;

/// Whether tier 0 may lower `f`'s pixel code for `key` flat (see the module doc): no
/// uniform loop, no assignment to a uniform local and no varying local of more than
/// [`MAX_FLAT_ARRAY`] elements in it, nor in any shared interpolator the key binds (those
/// are inlined into the pixel code).
pub(crate) fn pixel_code_is_flattenable(program: &Program, f: &Function, key: &VariantKey) -> bool {
    let small = |g: &Function| {
        g.locals
            .iter()
            .all(|l| !l.var.is_varying() || l.ty.fixed_len() <= MAX_FLAT_ARRAY)
    };
    if !small(f) || !stmts_are_flattenable(f, &f.pixel) {
        return false;
    }
    key.bindings.iter().all(|b| match &b.kind {
        BindingKind::Shared(name) => program.find(name).is_some_and(|id| {
            let g = program.func(id);
            small(g) && stmts_are_flattenable(g, &g.setup) && stmts_are_flattenable(g, &g.pixel)
        }),
        BindingKind::Kind(_) | BindingKind::Constant => true,
    })
}

fn stmts_are_flattenable(f: &Function, stmts: &[StmtId]) -> bool {
    stmts.iter().all(|&s| match &f.stmts[s] {
        StmtKind::Assign { place, .. } => f.locals.get(place.local.0 as usize).is_some_and(|l| l.var.is_varying()),
        StmtKind::If { then, otherwise, .. } => stmts_are_flattenable(f, then) && stmts_are_flattenable(f, otherwise),
        StmtKind::Loop {
            varying, body, step, ..
        } => *varying && stmts_are_flattenable(f, body) && stmts_are_flattenable(f, step),
        StmtKind::Interpolation { arms } => arms.iter().all(|a| stmts_are_flattenable(f, &a.body)),
        StmtKind::Break(_) | StmtKind::Continue(_) | StmtKind::Return | StmtKind::InterpolatorReturn(_) => true,
        // Refused in pixel code by the lowering anyway.
        StmtKind::Bound(_) | StmtKind::CallPrimitive { .. } => false,
    })
}

/// Whether a side of a uniform `if` in flat pixel code can run under a lane mask instead
/// of a branch: varying assignments, nested `if`s of the same kind and `return`s only.
/// (No loops: a `break` or `continue` under the `if` would leave a uniform loop; no
/// `interpolation`: its stores are masked, but the construct is rare under a uniform `if`
/// and is kept on the branching path.)
pub(crate) fn maskable_stmts(f: &Function, stmts: &[StmtId]) -> bool {
    stmts.iter().all(|&s| match &f.stmts[s] {
        StmtKind::Assign { place, .. } => f.locals.get(place.local.0 as usize).is_some_and(|l| l.var.is_varying()),
        StmtKind::If { then, otherwise, .. } => maskable_stmts(f, then) && maskable_stmts(f, otherwise),
        StmtKind::Return => true,
        _ => false,
    })
}

/// The conditions (by id) of the `if`s of `stmts` (flat pixel code of `f`), nested ones
/// too, whose both sides are [`maskable_stmts`].
pub(crate) fn maskable_ifs(f: &Function, stmts: &[StmtId], out: &mut HashSet<ExprId>) {
    crate::ir::for_each_stmt(&f.stmts, stmts, &mut |_, s| {
        if let StmtKind::If { cond, then, otherwise } = s {
            if maskable_stmts(f, then) && maskable_stmts(f, otherwise) {
                out.insert(*cond);
            }
        }
    });
}

/// The varying locals (by index, in order) a group of flat pixel code starts at zero: the
/// ones the pixel code assigns and the setup does not (a local the setup assigns keeps the
/// setup's value until the pixel code assigns it), parameters aside, that live in SSA
/// variables (`homes`).
pub(crate) fn zeroed_locals(f: &Function, homes: &Homes) -> Vec<usize> {
    let assigned = dead::assigned_flags(f, &f.pixel);
    let in_setup = dead::assigned_flags(f, &f.setup);
    (0..f.locals.len())
        .filter(|&i| {
            f.locals[i].var.is_varying()
                && assigned[i]
                && !in_setup[i]
                && !f.params.iter().any(|p| p.local.0 as usize == i)
                && matches!(homes.locals.get(i), Some(Home::Vars(_)))
        })
        .collect()
}
