//! Tier 0, a kernel without pixel loops: where its setup is split into two functions
//! compiled side by side (`jit::lower::outline` carries the split out).
//!
//! A tier-0 compile is what a scene's first frame waits for, and a large setup in one
//! function (NURB's tessellation, ~4 400 CLIF instructions) is compiled by one thread. So
//! a setup of at least [`SPLIT_SETUP_SIZE`] (in [`stmt_size`] units, a rough measure of
//! the CLIF a statement lowers to) is split before the top-level statement that halves it
//! most evenly, when neither half is under a quarter of it ([`setup_split`]).
//!
//! Invariant: the split falls between top-level setup statements, so both halves are
//! statement lists of the setup as written; [`SetupSplit::shared`] flags every local both
//! halves mention, the ones whose SSA variables must go from the first function to the
//! second.

use super::dead;
use crate::ir::{ExprId, ExprKind, Exprs, Function, StmtId};

/// A setup this large (in [`stmt_size`] units) is split when the kernel has no pixel
/// loops: NURB's is ~4 900, polygon's ~500.
const SPLIT_SETUP_SIZE: usize = 2000;

/// Where a setup is split.
pub(crate) struct SetupSplit {
    /// The top-level setup statement the second function starts with.
    pub at: usize,
    /// Per local: both halves read or assign it.
    pub shared: Vec<bool>,
}

/// The split of `f`'s setup, if it is large enough and splits evenly enough (see the
/// module doc).
pub(crate) fn setup_split(f: &Function) -> Option<SetupSplit> {
    let at = setup_split_point(f)?;
    let before = dead::mentioned_flags(f, &f.setup[..at]);
    let after = dead::mentioned_flags(f, &f.setup[at..]);
    let shared = before.iter().zip(&after).map(|(b, a)| *b && *a).collect();
    Some(SetupSplit { at, shared })
}

/// The top-level setup statement that halves the setup most evenly by size, if the setup
/// is large enough and neither half is under a quarter of it.
fn setup_split_point(f: &Function) -> Option<usize> {
    let sizes: Vec<usize> = f.setup.iter().map(|&s| stmt_size(f, s)).collect();
    let total: usize = sizes.iter().sum();
    if total < SPLIT_SETUP_SIZE {
        return None;
    }
    let mut before: usize = 0;
    let mut best: Option<(usize, usize)> = None;
    for (i, &s) in sizes.iter().enumerate() {
        let imbalance = before.abs_diff(total - before);
        if i > 0 && best.is_none_or(|(_, b)| imbalance < b) {
            best = Some((i, imbalance));
        }
        before += s;
    }
    let (i, imbalance) = best?;
    (imbalance <= total / 2).then_some(i)
}

/// A statement's size with the statements inside it: the components their expressions
/// compute (an operation on a point counts four), a rough measure of the CLIF it lowers to.
fn stmt_size(f: &Function, s: StmtId) -> usize {
    let mut size = 0;
    crate::ir::for_each_stmt(&f.stmts, &[s], &mut |_, s| {
        size += 1;
        s.for_each_expr(|e| size += expr_size(&f.exprs, *e));
    });
    size
}

fn expr_size(x: &Exprs, e: ExprId) -> usize {
    // A local's value is its variables or its address (an index computes the element);
    // whole arrays beyond 16 components are cleared and copied by loops.
    let node = &x[e];
    let mut n = match node.kind {
        ExprKind::Local(_) => 1,
        _ => node.ty.fixed_len().clamp(1, 16) as usize,
    };
    node.for_each_child(|c| n += expr_size(x, c));
    n
}
