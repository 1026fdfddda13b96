//! What the variant key makes of a function's code: the `interpolation` arms it lowers,
//! the interpolation-data view each arm is lowered under ([`arm_view`]), and the locals the
//! code reads or assigns as lowered ([`visit_live_locals`]).
//!
//! Invariant: an arm [`arm_view`] answers `None` for is not lowered, so nothing in it is
//! live; every pass that asks which locals pixel code uses asks through
//! [`visit_live_locals`], so they agree with the lowering (`Lower::interpolation` skips the
//! same arms).

use std::collections::HashSet;

use crate::abi::{BindingKind, VariantKey};
use crate::ir::{ArmKind, Function, InterpArm, LocalId, StmtId, StmtKind};

/// The kinds the named arms of an `interpolation` serve.
pub(crate) fn named_kinds(arms: &[InterpArm]) -> Vec<&str> {
    arms.iter()
        .filter_map(|a| match &a.kind {
            ArmKind::Named(k) => Some(k.as_str()),
            ArmKind::Default => None,
        })
        .collect()
}

/// The interpolation-data view (components of the key's interpolated data) and the
/// bindings (indices into `key.bindings`) of `arm` under `key`, or `None` if the key gives
/// the arm nothing to do (it is not lowered). `named`: the arms' kinds ([`named_kinds`]).
pub(crate) fn arm_view(key: &VariantKey, named: &[&str], arm: &InterpArm) -> Option<(Vec<u32>, Vec<usize>)> {
    let has_other = key
        .bindings
        .iter()
        .any(|b| matches!(b.kind, BindingKind::Shared(_) | BindingKind::Constant));
    let mut view = vec![];
    let mut bindings = vec![];
    let mut ic = 0;
    for (i, b) in key.bindings.iter().enumerate() {
        if let BindingKind::Kind(k) = &b.kind {
            let serves = match &arm.kind {
                ArmKind::Named(n) => n == k,
                ArmKind::Default => !named.contains(&k.as_str()),
            };
            if serves {
                view.extend(ic..ic + b.components);
                bindings.push(i);
            }
            ic += b.components;
        }
    }
    let needed = !view.is_empty() || (arm.kind == ArmKind::Default && has_other);
    needed.then_some((view, bindings))
}

/// Every local read or assigned by `stmts` as `key` lowers them (arms the key gives
/// nothing to do are skipped).
pub(crate) fn live_locals(f: &Function, key: &VariantKey, stmts: &[StmtId], out: &mut HashSet<LocalId>) {
    visit_live_locals(f, key, stmts, &mut |l| {
        out.insert(l);
    });
}

/// [`live_locals`] as a flag per local (tier 0's analyses: a HashSet cost more than the
/// walk itself).
pub(crate) fn live_flags(f: &Function, key: &VariantKey, stmts: &[StmtId], out: &mut [bool]) {
    visit_live_locals(f, key, stmts, &mut |l| {
        if let Some(x) = out.get_mut(l.0 as usize) {
            *x = true;
        }
    });
}

/// Calls `out` with every local `stmts` reads or assigns as `key` lowers them (a local as
/// often as it is mentioned).
pub(crate) fn visit_live_locals(f: &Function, key: &VariantKey, stmts: &[StmtId], out: &mut dyn FnMut(LocalId)) {
    let x = &f.exprs;
    for &s in stmts {
        match &f.stmts[s] {
            StmtKind::Assign { place, value } => {
                out(place.local);
                place.indices.iter().for_each(|(i, _)| x.for_each_local(*i, out));
                x.for_each_local(*value, out);
            }
            StmtKind::If { cond, then, otherwise } => {
                x.for_each_local(*cond, out);
                visit_live_locals(f, key, then, out);
                visit_live_locals(f, key, otherwise, out);
            }
            StmtKind::Loop { cond, body, step, .. } => {
                if let Some(c) = cond {
                    x.for_each_local(*c, out);
                }
                visit_live_locals(f, key, body, out);
                visit_live_locals(f, key, step, out);
            }
            StmtKind::Interpolation { arms } => {
                let named = named_kinds(arms);
                for arm in arms {
                    if arm_view(key, &named, arm).is_some() {
                        visit_live_locals(f, key, &arm.body, out);
                    }
                }
            }
            StmtKind::InterpolatorReturn(Some(e)) => x.for_each_local(*e, out),
            StmtKind::Bound(es) => es.iter().for_each(|e| x.for_each_local(*e, out)),
            StmtKind::CallPrimitive { args, .. } => args.iter().for_each(|e| x.for_each_local(*e, out)),
            StmtKind::Break(_) | StmtKind::Continue(_) | StmtKind::Return | StmtKind::InterpolatorReturn(None) => {}
        }
    }
}
