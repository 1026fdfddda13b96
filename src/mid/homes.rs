//! Where the primitive's locals live while its kernel runs: the decision the lowering
//! (`Lower::make_frame`) carries out for the primitive's own frame.
//!
//! A parameter is the pixel's X or Y (one SSA variable each), the primitive's Z, or words
//! of the argument block. Any other local lives in SSA variables, one per flattened
//! component, unless something indexes it with an index that is not a constant
//! ([`dynamic_locals`]: it needs an address) or its components would pass
//! [`MAX_LOCAL_VAR_WORDS`], or the kernel's [`MAX_VAR_WORDS`] counted over its locals in
//! order: then it lives in a stack slot, zeroed at kernel entry unless every read comes
//! after a whole assignment ([`super::init`]).
//!
//! Invariants: the primitive's frame is the first one a kernel makes, so the budget starts
//! at zero here and [`Homes::var_words`] is what the frame took of it; shared interpolators
//! inlined later take their own locals' words from what is left, in the order the lowering
//! inlines them (so their homes are the lowering's to decide, from their [`dynamic_locals`]).
//! A local with a per-sequence-point type has no home ([`Home::PerSeq`]: the lowering
//! refuses it).

use super::pred::const_int;
use crate::abi::type_words;
use crate::ir::{ExprId, ExprKind, Exprs, Function, LocalId, ParamRole, StmtKind};

/// Most components a local kept in SSA variables may have, and most such components a
/// kernel may have in all its frames; the rest live on the stack. Cranelift allows at most
/// 65535 parameters per block, and a loop header can carry every variable (a
/// `float a[65535]` read at constant indices panicked the SSA builder); SSA over that many
/// values compiles slowly anyway. The built-in primitives' largest register local has 64.
pub(crate) const MAX_LOCAL_VAR_WORDS: u32 = 1024;
pub(crate) const MAX_VAR_WORDS: u32 = 16384;

/// Where one local of the primitive lives.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Home {
    /// The primitive's Z (assignments also mark it written).
    Z,
    /// The pixel's X or Y: one SSA variable.
    Pixel,
    /// A parameter read from the argument block.
    Args,
    /// This many SSA variables (counted against [`MAX_VAR_WORDS`]).
    Vars(u32),
    /// A stack slot; `clear`: zeroed at kernel entry.
    Stack { clear: bool },
    /// A per-sequence-point type: no home.
    PerSeq,
}

/// The homes of the primitive's locals.
pub(crate) struct Homes {
    /// Per local, by index.
    pub locals: Vec<Home>,
    /// The SSA variable words the primitive's frame takes of [`MAX_VAR_WORDS`].
    pub var_words: u32,
}

impl Homes {
    /// Whether local `l` lives in SSA variables (its own, or the pixel's X or Y).
    pub(crate) fn in_vars(&self, l: LocalId) -> bool {
        matches!(self.locals.get(l.0 as usize), Some(Home::Vars(_) | Home::Pixel))
    }
}

/// The homes of `f`'s locals as the primitive's frame (`n_interp`: the key's interpolated
/// components, the words of an interpolation-data local); `read_before_assigned` gives the
/// locals a stack slot must be zeroed for ([`super::init`]), asked only if some local lives
/// on the stack.
pub(crate) fn primitive_homes<'b>(
    f: &Function,
    n_interp: u32,
    read_before_assigned: impl FnOnce() -> &'b [bool],
) -> Homes {
    let dynamic = dynamic_locals(f);
    let mut var_words = 0;
    let mut locals = Vec::with_capacity(f.locals.len());
    for (i, local) in f.locals.iter().enumerate() {
        let role = f.params.iter().find(|p| p.local.0 as usize == i).map(|p| p.role);
        let home = match role {
            Some(ParamRole::Z) => Home::Z,
            Some(ParamRole::X | ParamRole::Y) => Home::Pixel,
            Some(_) => Home::Args,
            None if local.ty.per_seq => Home::PerSeq,
            None => {
                let n = type_words(&local.ty, n_interp);
                let fits = n <= MAX_LOCAL_VAR_WORDS && var_words + n <= MAX_VAR_WORDS;
                if dynamic[i] || !fits {
                    Home::Stack { clear: true }
                } else {
                    var_words += n;
                    Home::Vars(n)
                }
            }
        };
        locals.push(home);
    }
    if locals.iter().any(|h| matches!(h, Home::Stack { .. })) {
        let needs = read_before_assigned();
        for (i, h) in locals.iter_mut().enumerate() {
            if let Home::Stack { clear } = h {
                *clear = needs.get(i).copied().unwrap_or(true);
            }
        }
    }
    Homes { locals, var_words }
}

/// Per local of `f`: indexed somewhere with an index that is not a constant (it needs an
/// address, so a stack slot).
pub(crate) fn dynamic_locals(f: &Function) -> Vec<bool> {
    let mut dynamic = vec![false; f.locals.len()];
    for part in [&f.setup, &f.pixel] {
        crate::ir::for_each_stmt(&f.stmts, part, &mut |_, s| mark_dynamic_stmt(&f.exprs, s, &mut dynamic));
    }
    dynamic
}

/// Marks from the expressions and place of `s` itself (not those inside it).
fn mark_dynamic_stmt(x: &Exprs, s: &StmtKind, dynamic: &mut [bool]) {
    if let StmtKind::Assign { place, .. } = s {
        for (i, _) in &place.indices {
            if const_int(x, *i).is_none() {
                if let Some(d) = dynamic.get_mut(place.local.0 as usize) {
                    *d = true;
                }
            }
        }
    }
    s.for_each_expr(|e| mark_dynamic_expr(x, *e, dynamic));
}

fn mark_dynamic_expr(x: &Exprs, e: ExprId, dynamic: &mut [bool]) {
    if let ExprKind::Index { base, index, .. } = &x[e].kind {
        if const_int(x, *index).is_none() {
            if let Some(d) = root_local(x, *base).and_then(|l| dynamic.get_mut(l.0 as usize)) {
                *d = true;
            }
        }
    }
    x[e].for_each_child(|c| mark_dynamic_expr(x, c, dynamic));
}

fn root_local(x: &Exprs, e: ExprId) -> Option<LocalId> {
    match &x[e].kind {
        ExprKind::Local(l) => Some(*l),
        ExprKind::Index { base, .. } => root_local(x, *base),
        _ => None,
    }
}
