//! Warnings about primitives that check cleanly but do not do what they look like they do:
//! the last pass of the checker ([`super::check`]), run on a program without errors.
//!
//! Each lint reads the split, numbered IR of one primitive (helpers inlined, so a helper's
//! assignment to an `inout` Z counts) and reports at most once per primitive or arm:
//! - W0003: no statement assigns `Z` and none calls a primitive (a callee writes the
//!   caller's Z), so no pixel is ever drawn by it;
//! - W0004: per-pixel code and no `bound` anywhere, so that code runs over the whole
//!   viewport for every instance (a `bound` on some path only is the library's sphere: it
//!   covers the viewport on the others by design);
//! - W0005: a named `interpolation` arm without `interpolator_return` in a construct that
//!   stores (another arm has one, or it is per-pixel code), so the parameters bound to its
//!   kind are never written by it. A construct in setup code whose arms only compute (the
//!   polygon's) is left alone.
//!
//! W0006 (a constant that saturates converting to fixed point) is found while lowering,
//! where the constant is still as written (`FnLower::convert`).

use rustc_hash::FxHashSet;

use crate::diag::Diagnostic;
use crate::ir::{ArmKind, Block, FuncKind, Function, ParamRole, Program, StmtId, StmtKind};

use super::Sink;

/// Run every lint on the primitives of `program`.
pub fn program(program: &Program, sink: &mut Sink) {
    for f in &program.functions {
        if f.kind == FuncKind::Primitive {
            never_writes_z(f, sink);
            no_bound(f, sink);
            arms_without_return(f, sink);
        }
    }
}

fn never_writes_z(f: &Function, sink: &mut Sink) {
    let z = f.param_by_role(ParamRole::Z).map(|p| p.local);
    let writes = f.stmts.iter().any(|(_, s)| match s {
        StmtKind::Assign { place, .. } => Some(place.local) == z,
        StmtKind::CallPrimitive { .. } => true,
        _ => false,
    });
    if !writes {
        sink.push(
            Diagnostic::warning("W0003", format!("primitive `{}` never writes `Z`, so it draws no pixel", f.name))
                .primary(f.span, "no path assigns `Z` or calls a primitive")
                .help("a pixel is drawn where a primitive assigns its depth `Z` (after the depth test); one it only gives shading values keeps the depth drawn there before"),
        );
    }
}

fn no_bound(f: &Function, sink: &mut Sink) {
    if !f.runs_unbounded() {
        return;
    }
    sink.push(
        Diagnostic::warning(
            "W0004",
            format!(
                "primitive `{}` has no `bound`: its per-pixel code runs over the whole viewport for every instance",
                f.name
            ),
        )
        .primary(f.span, "no path calls `bound`")
        .help("call `bound(xmin, ymin, xmax, ymax)` before the per-pixel code with a rectangle no covered pixel lies outside of; one that holds the viewport says the whole viewport is meant"),
    );
}

fn arms_without_return(f: &Function, sink: &mut Sink) {
    let mut pixel = FxHashSet::default();
    collect(f, &f.pixel, &mut pixel);
    for (id, s) in f.stmts.iter() {
        let StmtKind::Interpolation { arms } = s else {
            continue;
        };
        let returns: Vec<bool> = arms.iter().map(|a| block_returns(f, &a.body)).collect();
        if !pixel.contains(&id) && !returns.contains(&true) {
            continue;
        }
        for (arm, &ret) in arms.iter().zip(&returns) {
            if let (ArmKind::Named(kind), false) = (&arm.kind, ret) {
                sink.push(
                    Diagnostic::warning(
                        "W0005",
                        format!("the `{kind}:` arm has no `interpolator_return`: shading parameters bound to `{kind}` are not written here"),
                    )
                    .primary(arm.span, "no `interpolator_return(value)` in this arm")
                    .help("their pixels keep the value drawn there before; end the arm with `interpolator_return(value)`"),
                );
            }
        }
    }
}

/// Every statement of `block`, nested ones too.
fn collect(f: &Function, block: &Block, out: &mut FxHashSet<StmtId>) {
    for &s in block {
        out.insert(s);
        f.stmts[s].for_each_block(|b| collect(f, b, out));
    }
}

/// Whether `block` holds an `interpolator_return`, nested ones too.
fn block_returns(f: &Function, block: &Block) -> bool {
    block.iter().any(|&s| {
        let node = &f.stmts[s];
        let mut nested = false;
        node.for_each_block(|b| nested |= block_returns(f, b));
        nested || matches!(node, StmtKind::InterpolatorReturn(_))
    })
}
