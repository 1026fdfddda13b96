//! Index sites: which bodies the range analysis ([`crate::ir::range`]) has something to
//! prove in, and whether a setup may record an index error.
//!
//! The lowering checks an index (clamps it and records `ERR_INDEX` when it is out of
//! range) unless it is a constant inside a fixed-size array, or the range analysis proved
//! its site in range. So the analysis is asked only about the other sites: a body without
//! one ([`needs_range`] false: most kernels once their loops are unrolled) never runs it.
//!
//! Invariant: [`index_sites`] lists every site the lowering may check, with the static
//! length it checks against (`Lower::index_access`: places indexed one dimension per site,
//! expressions at their base's type).

use std::collections::HashSet;

use super::pred::const_int;
use crate::ir::{ExprId, ExprKind, Exprs, Function, SiteId, StmtId, StmtKind, Type};

/// An index site: the static length of the array it indexes (`None`: a sequence, or not
/// an array), its index and its site.
pub(crate) type IndexSite = (Option<u32>, ExprId, SiteId);

/// The static length the lowering checks an index of a `ty` value against.
fn static_len_of(ty: &Type) -> Option<u32> {
    if ty.per_seq {
        None
    } else {
        ty.dims.first().copied()
    }
}

/// A site whose index is a constant inside its fixed-size array: never checked.
fn constant_in_fixed(x: &Exprs, site: &IndexSite) -> bool {
    site.0.is_some() && const_int(x, site.1).is_some()
}

/// Every index site of `stmts` (statements of `f`): in places (`a[i] = ...`, the local's
/// type indexed one dimension per site) and in expressions.
pub(crate) fn index_sites(f: &Function, stmts: &[StmtId], out: &mut Vec<IndexSite>) {
    fn expr(x: &Exprs, e: ExprId, out: &mut Vec<IndexSite>) {
        if let ExprKind::Index { base, index, site } = &x[e].kind {
            out.push((static_len_of(&x[*base].ty), *index, *site));
        }
        x[e].for_each_child(|c| expr(x, c, out));
    }
    let x = &f.exprs;
    // Each statement before those inside it; a place's sites before its index expressions.
    crate::ir::for_each_stmt(&f.stmts, stmts, &mut |_, s| match s {
        StmtKind::Assign { place, value } => {
            if let Some(local) = f.locals.get(place.local.0 as usize) {
                let mut ty = local.ty.clone();
                for (index, site) in &place.indices {
                    out.push((static_len_of(&ty), *index, *site));
                    expr(x, *index, out);
                    ty = ty.element();
                }
            }
            expr(x, *value, out);
        }
        _ => s.for_each_expr(|e| expr(x, *e, out)),
    });
}

/// Whether `f` has a site the lowering may ask the range analysis about: one whose index
/// is not a constant inside a fixed-size array.
pub(crate) fn needs_range(f: &Function) -> bool {
    let mut sites = vec![];
    index_sites(f, &f.setup, &mut sites);
    index_sites(f, &f.pixel, &mut sites);
    !sites.iter().all(|s| constant_in_fixed(&f.exprs, s))
}

/// Whether lowering `f`'s setup may record an index error: some index site is neither a
/// constant inside a fixed array nor proven in range (`proven`; `None`: no site needs a
/// proof). Mirrors `Lower::index_access`.
pub(crate) fn setup_may_fail_index(f: &Function, proven: Option<&HashSet<SiteId>>) -> bool {
    let mut sites = vec![];
    index_sites(f, &f.setup, &mut sites);
    sites.into_iter().any(
        |(static_len, index, site)| match (static_len, const_int(&f.exprs, index)) {
            (Some(len), Some(k)) => k < 0 || k >= i64::from(len),
            _ => !proven.is_some_and(|p| p.contains(&site)),
        },
    )
}
