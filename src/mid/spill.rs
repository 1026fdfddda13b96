//! The uniform frame's layout: which uniform locals of the primitive the pixel loops read
//! from it, at which words, and where its sections start (the JIT's `spill_uniforms` stores
//! it before the pixel loops).
//!
//! A uniform local that lives in SSA variables ([`super::homes`]) and that the pixel code
//! uses as the key lowers it moves out of its variables before the pixel loops: to the
//! frame at consecutive words, in local order, when the pixel code never assigns it (it is
//! read-only from then on), or to a stack slot of its own otherwise. Then come the
//! frame's *vector section* (a 16-byte splat per word), its *row section* (the hoisted
//! terms, [`super::hoist`]), the carried terms' steps ([`super::affine`]) and the pass's
//! X range as two splats ([`FrameLayout::finish`]).
//!
//! Invariants: a local in the frame never changes while the pixel loops run, so it is a
//! row-invariant leaf for hoisting ([`FrameLayout::resident`], with the parameters read
//! from the argument block); the sections do not overlap, each 16-byte aligned; at tier 1
//! a frame word only one side of the first unswitched condition reads is stored by that
//! side's dispatch block instead ([`deferred_stores`]).

use std::collections::HashMap;

use super::homes::{Home, Homes};
use super::view;
use crate::abi::VariantKey;
use crate::ir::{ExprId, Function, LocalId, StmtKind};

/// Where the uniform frame keeps what (byte offsets from its start).
pub(crate) struct FrameLayout {
    /// The uniform locals moved out of SSA variables before the pixel loops, in local
    /// order: the local's index and its first word in the frame (`None`: the pixel code
    /// assigns it; it gets a stack slot of its own).
    pub placed: Vec<(usize, Option<u32>)>,
    /// Word `w`'s splat is at `vec_section + 16 * w`.
    pub vec_section: u32,
    /// The hoisted terms start here.
    pub row_section: u32,
    /// The pass's lo_x and hi_x, as f32x4 splats (set by [`Self::finish`]).
    pub x_range_at: u32,
    /// The frame's size in bytes (set by [`Self::finish`]).
    pub bytes: u32,
    /// Per local: a uniform value that stays put while the pixel loops run (a frame word,
    /// or a parameter in the argument block).
    pub resident: Vec<bool>,
    /// Tier 1: the first unswitched condition and, by local index, the frame locals only one
    /// of its sides reads (`true`: then), whose stores wait for that side.
    pub deferred: Option<(ExprId, HashMap<usize, bool>)>,
}

impl FrameLayout {
    /// Place the X range after the carried terms' steps (which end at `carried_end`).
    pub(crate) fn finish(&mut self, carried_end: u32) {
        self.x_range_at = carried_end.div_ceil(16) * 16;
        self.bytes = self.x_range_at + 32;
    }
}

/// The frame words of `f`'s uniform locals (see the module doc): `homes` says which live in
/// SSA variables, `assigned` flags the locals the pixel code assigns.
pub(crate) fn place(f: &Function, key: &VariantKey, homes: &Homes, assigned: &[bool]) -> FrameLayout {
    // Uniform locals the variant's pixel code never touches (e.g. the `linear` planes
    // when only perspective_linear parameters are bound) are not stored: their setup
    // computations are then dead and Cranelift drops them.
    let mut pixel_used = vec![false; f.locals.len()];
    view::live_flags(f, key, &f.pixel, &mut pixel_used);
    let mut placed = vec![];
    let mut next_word = 0;
    let mut resident = vec![false; f.locals.len()];
    for (i, home) in homes.locals.iter().enumerate() {
        match *home {
            Home::Args => resident[i] = true,
            Home::Vars(words) => {
                let local = &f.locals[i];
                if local.var.is_varying() || words == 0 || !pixel_used[i] {
                    continue;
                }
                let at = (!assigned[i]).then(|| {
                    let at = next_word;
                    next_word += words;
                    resident[i] = true;
                    at
                });
                placed.push((i, at));
            }
            Home::Z | Home::Pixel | Home::Stack { .. } | Home::PerSeq => {}
        }
    }
    let vec_section = (4 * next_word).div_ceil(16) * 16;
    FrameLayout {
        placed,
        vec_section,
        row_section: vec_section + 16 * next_word,
        x_range_at: 0,
        bytes: 0,
        resident,
        deferred: None,
    }
}

/// Tier 1: the frame locals of `layout` that only one side of `cond`, the pixel code's
/// first unswitched condition, reads, with that side (`true`: then), when `cond` is a
/// top-level statement of the pixel code. Their stores are left to the side's dispatch
/// block, so Cranelift computes them only on the path that reads them: screen_triangle's
/// float edges, read only when the triangle is not `exact`, were computed and stored in
/// every render call.
///
/// A local some other reader needs before the dispatch stays in setup: `early` holds those
/// readers (per-run row terms, carried terms, whose steps are evaluated once per run, and
/// the definitions of the locals either reads); so does one read outside the condition's
/// sides (its row terms and block facts are pixel code too) or in the condition itself.
pub(crate) fn deferred_stores(
    f: &Function,
    key: &VariantKey,
    layout: &FrameLayout,
    cond: ExprId,
    early: &[ExprId],
) -> Option<(ExprId, HashMap<usize, bool>)> {
    let at = f
        .pixel
        .iter()
        .position(|&s| matches!(&f.stmts[s], StmtKind::If { cond: c, .. } if *c == cond))?;
    let StmtKind::If { then, otherwise, .. } = &f.stmts[f.pixel[at]] else {
        return None;
    };
    let n = f.locals.len();
    let mut outside = vec![false; n];
    view::visit_live_locals(f, key, &f.pixel[..at], &mut mark(&mut outside));
    view::visit_live_locals(f, key, &f.pixel[at + 1..], &mut mark(&mut outside));
    f.exprs.for_each_local(cond, &mut mark(&mut outside));
    for &e in early {
        f.exprs.for_each_local(e, &mut mark(&mut outside));
    }
    let mut in_then = vec![false; n];
    let mut in_else = vec![false; n];
    view::visit_live_locals(f, key, then, &mut mark(&mut in_then));
    view::visit_live_locals(f, key, otherwise, &mut mark(&mut in_else));
    let mut deferred = HashMap::new();
    for &(i, word) in &layout.placed {
        if word.is_none() || outside[i] || in_then[i] == in_else[i] {
            continue;
        }
        deferred.insert(i, in_then[i]);
    }
    (!deferred.is_empty()).then_some((cond, deferred))
}

/// A visitor that flags each local it is called with in `flags`.
fn mark(flags: &mut [bool]) -> impl FnMut(LocalId) + '_ {
    move |l| {
        if let Some(x) = flags.get_mut(l.0 as usize) {
            *x = true;
        }
    }
}
