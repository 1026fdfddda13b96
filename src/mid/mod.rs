//! The middle end: the passes between the checked [`crate::ir`] and the JIT's lowering to
//! CLIF that need no code generator. Each reads IR and answers with a table keyed by
//! [`ExprId`], [`LocalId`] or [`FuncId`]; none imports Cranelift or [`crate::jit`].
//!
//! Two entry points, one per level of sharing:
//! - [`body`]: a primitive's body as lowered, once per function (every variant key, both
//!   tiers and every JIT of the program share it): whole-array copies forwarded
//!   ([`crate::ir::forward`]), then constant-trip loops unrolled ([`unroll`]), each result
//!   validated in test and debug builds. The [`Body`] keeps the analyses that depend on the
//!   function alone, each run by the first plan that needs it.
//! - [`plan`]: everything the lowering of one (function, variant key, [`Tier`]) consults,
//!   as a [`Plan`]. The passes run in this order; after each, this holds:
//!   1. [`homes`]: every local of the primitive has a home (SSA variables, a stack slot and
//!      whether [`init`] says it must be zeroed at entry, the argument block, X, Y or Z).
//!   2. Range analysis ([`crate::ir::range`], asked through [`sites`]): every index site the
//!      lowering may check has its verdict, proven in range or not (bodies without such a
//!      site never run it).
//!   3. [`bounds`]: the primitive and every shared interpolator the key binds have their
//!      float locals' bounds, where their code converts a varying float to an int.
//!   4. Tier 0, [`dead`]: the setup locals live code reads are known (assignments to the
//!      others are not lowered), and ([`sites`]) whether the setup may record an index error.
//!   5. Tier 0, no pixel part, [`split`]: where a large setup is split in two functions.
//!   6. With a pixel part ([`PixelPlan`]), in order:
//!      - [`flat`] (tier 0): whether the pixel code runs flat, which of its `if`s run under
//!        masks, which locals a group starts at zero;
//!      - [`spill`]: the uniform frame's words, so which uniform locals stay put while the
//!        pixel loops run;
//!      - [`hoist`]: the row locals, then the row terms and per-run terms with their
//!        offsets in the frame's row section;
//!      - [`affine`] (tier 1): the terms carried along the row, their steps' offsets, the
//!        locals only they read; then the row locals only row terms read;
//!      - [`unswitch`] (tier 1) with [`block`]: the copies of the pixel loops, each with its
//!        decided conditions' guard prefix and the expressions it lowers;
//!      - [`spill`] again (tier 1): the frame stores one side of the first unswitched
//!        condition waits for, and the frame's size.
//!
//! What stays in the lowering (`jit::lower`), because it depends on the code being
//! generated, not on the IR alone:
//! - which guards of a prefix the block walk can decide (`BlockFacts::decidable`): the
//!   interval evaluator finds out while it emits the evaluation, so the expressions a pass
//!   span lowers ([`block::pass_exprs`]) are asked for with that answer;
//! - the guard facts ([`bounds::GuardFacts`]): they follow the statement being lowered;
//! - the homes of an inlined interpolator's locals: its variables take what the kernel's
//!   budget ([`homes::MAX_VAR_WORDS`]) has left when the lowering inlines it (the plan
//!   gives its [`homes::dynamic_locals`]);
//! - statement-local predicates ([`pred`]: speculable statements, constant indices, key
//!   constants), asked of the statement at hand.
//!
//! Tier-0 compile time is the reason some passes run only where their answer is used: a
//! tier-0 plan computes no carried terms, unswitching, guard prefix or deferred stores; the
//! pixel plan exists only for a function with a pixel part; range analysis, local bounds
//! and entry clears run once per body and only for bodies that need them.

pub mod affine;
pub mod block;
pub mod bounds;
pub mod dead;
pub mod flat;
pub mod hoist;
pub mod homes;
pub mod init;
pub mod pred;
pub mod sites;
pub mod spill;
pub mod split;
pub mod unroll;
pub mod unswitch;
pub mod view;

use std::collections::{HashMap, HashSet};
use std::sync::OnceLock;

use crate::abi::{BindingKind, KernelError, VariantKey};
use crate::ir::{Elem, ExprId, ExprKind, FuncId, FuncKind, Function, LocalId, Program, Scalar, SiteId, StmtId};
use affine::Carry;
use bounds::LocalBounds;
use hoist::Hoist;
use homes::Homes;
use spill::FrameLayout;
use split::SetupSplit;
use unswitch::Loops;

/// How much work the code generator spends on a kernel, and so which passes its plan runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Tier {
    /// Tier 0: regalloc2's single-pass register allocator, `opt_level=none`, no block-level
    /// culling, and a lighter lowering. Compiles several times faster; the kernel runs
    /// slower (mostly spills).
    Fast,
    /// Tier 1: the backtracking register allocator and block-level culling.
    Optimised,
}

/// A primitive's body as lowered (see [`body`]), with the analyses that depend on the
/// function alone, each run by the first plan that needs it and kept for every other.
pub(crate) struct Body {
    pub function: Function,
    /// Test and debug builds: the IR rule the passes broke (see [`crate::ir::valid`]), as
    /// the internal compiler error every kernel of this body reports.
    pub invalid: Option<KernelError>,
    /// Index sites proven in range; `None` when no site needs a proof.
    range: OnceLock<Option<HashSet<SiteId>>>,
    /// The float locals' bounds; `None` when no varying float is converted to an int.
    bounds: OnceLock<Option<LocalBounds>>,
    /// Per local: its stack slot must be zeroed at entry ([`init`]).
    clears: OnceLock<Vec<bool>>,
}

impl Body {
    /// Index sites proven in range ([`crate::ir::range`], ~20 % of a NURB tier-0 compile),
    /// or `None` when the body has no site the lowering would ask about ([`sites`]).
    fn proven_sites(&self) -> Option<&HashSet<SiteId>> {
        self.range
            .get_or_init(|| {
                sites::needs_range(&self.function).then(|| crate::ir::range::proven_index_sites(&self.function))
            })
            .as_ref()
    }

    /// The bounds of the body's float locals, if the lowering may ask for them.
    fn local_bounds(&self) -> Option<&LocalBounds> {
        self.bounds
            .get_or_init(|| converts_varying_float(&self.function).then(|| LocalBounds::of_function(&self.function)))
            .as_ref()
    }

    fn read_before_assigned(&self) -> &[bool] {
        self.clears.get_or_init(|| init::read_before_assigned(&self.function))
    }
}

/// `func`'s body as lowered: forwarded, then unrolled when `unroll_loops`; in test and
/// debug builds, [`Body::invalid`] holds the first IR rule a pass broke.
pub(crate) fn body(program: &Program, func: FuncId, unroll_loops: bool) -> Body {
    let check = |pass: &str, f: &Function| {
        let e = crate::ir::valid::validate_function(program, f).err()?;
        Some(KernelError {
            message: format!("internal compiler error: IR invalid after {pass}: {e}"),
        })
    };
    let f = crate::ir::forward::forward_copies(program.func(func));
    let mut invalid = if cfg!(debug_assertions) {
        check("forward", &f)
    } else {
        None
    };
    let function = if unroll_loops { unroll::unroll_function(f) } else { f };
    if cfg!(debug_assertions) && unroll_loops && invalid.is_none() {
        invalid = check("unroll", &function);
    }
    Body {
        function,
        invalid,
        range: OnceLock::new(),
        bounds: OnceLock::new(),
        clears: OnceLock::new(),
    }
}

/// What the lowering of one (function, variant key, tier) consults (see the module doc).
pub(crate) struct Plan<'a> {
    pub func: FuncId,
    /// The primitive's body as lowered.
    pub function: &'a Function,
    pub tier: Tier,
    /// Where each local of the primitive lives.
    pub homes: Homes,
    /// Index sites of the body proven in range; `None`: no site needs a proof.
    pub proven_sites: Option<&'a HashSet<SiteId>>,
    /// The primitive's float locals' bounds, if its code converts a varying float to an int.
    pub bounds: Option<&'a LocalBounds>,
    /// The shared interpolators the key binds, by id.
    pub interpolators: HashMap<FuncId, Interpolator>,
    /// Tier 0: per local, whether live code reads it ([`dead`]); `None`: every setup
    /// assignment is lowered.
    pub setup_live: Option<Vec<bool>>,
    /// Tier 0: the setup may record an index error, so it defers its errors.
    pub setup_may_fail_index: bool,
    /// Tier 0, no pixel part: where the setup is split in two functions.
    pub setup_split: Option<SetupSplit>,
    /// The pixel part's plan; `None`: the function has none.
    pub pixel: Option<PixelPlan>,
}

/// What the lowering needs of a shared interpolator it inlines.
pub(crate) struct Interpolator {
    /// Per local: indexed with an index that is not a constant (a stack slot).
    pub dynamic: Vec<bool>,
    /// Its float locals' bounds, if its code converts a varying float to an int.
    pub bounds: Option<LocalBounds>,
}

/// The plan of a primitive's pixel part (see the module doc, step 6).
pub(crate) struct PixelPlan {
    /// Tier 0: the pixel code is lowered flat ([`flat`]).
    pub flat: bool,
    /// Flat code: the uniform `if`s (by condition) lowered under masks instead of branches.
    pub maskable_ifs: HashSet<ExprId>,
    /// Flat code: the varying locals (by index) every group starts at zero.
    pub zeroed: Vec<usize>,
    /// The locals the pixel code assigns (their values change between groups).
    pub assigned: HashSet<LocalId>,
    /// The uniform frame's layout.
    pub frame: FrameLayout,
    /// Row locals, by their defining value ([`hoist`]).
    pub row_locals: HashMap<LocalId, ExprId>,
    /// Row terms and per-run terms, with their offsets in the frame.
    pub hoists: Vec<Hoist>,
    /// Tier 1: the terms carried along the row ([`affine`]).
    pub carry: Carry,
    /// Pixel locals no group reads (only carried or row terms do): their assignments are
    /// not lowered in a group.
    pub unread_in_groups: HashSet<LocalId>,
    /// The expressions of those locals' values: their row terms are not stored per row.
    pub unstored_terms: HashSet<ExprId>,
    /// The copies of the pixel loops ([`unswitch`]).
    pub loops: Loops,
}

impl Plan<'_> {
    /// The bounds of `func`'s float locals: the primitive's or a bound interpolator's.
    pub(crate) fn bounds(&self, func: FuncId) -> Option<&LocalBounds> {
        if func == self.func {
            self.bounds
        } else {
            self.interpolators.get(&func)?.bounds.as_ref()
        }
    }
}

/// The plan for lowering `func` (whose body is `body`) for `key` at `tier`: the passes of
/// the module doc, in that order. Errors are the kernel's: no such function, a body the
/// passes broke, a function that is not a primitive.
pub(crate) fn plan<'a>(
    program: &'a Program,
    func: FuncId,
    body: &'a Body,
    key: &VariantKey,
    tier: Tier,
) -> Result<Plan<'a>, KernelError> {
    let err = |message: String| Err(KernelError { message });
    if program.functions.get(func.0 as usize).is_none() {
        return err(format!("no function {}", func.0));
    }
    if let Some(e) = &body.invalid {
        return Err(e.clone());
    }
    let f = &body.function;
    if f.kind != FuncKind::Primitive {
        return err(format!(
            "`{}` is an interpolator, not a primitive: it has no kernel",
            f.name
        ));
    }
    let fast = tier == Tier::Fast;
    // Every local of the primitive has a home; a stack array knows whether it is zeroed at
    // entry.
    let homes = homes::primitive_homes(f, key.interp_components(), || body.read_before_assigned());
    // Every index site the lowering may check has its range verdict.
    let proven_sites = body.proven_sites();
    // The primitive has its float locals' bounds where it converts a varying float to int.
    let bounds = body.local_bounds();
    // Every shared interpolator the key binds has its dynamic locals, and bounds likewise.
    let interpolators = interpolators(program, key);
    // Tier 0: the setup locals live code reads are known.
    let setup_live = fast.then(|| dead_setup(f, key, &homes));
    // Tier 0: whether the setup may record an index error (it then defers its errors).
    let setup_may_fail_index = fast && sites::setup_may_fail_index(f, proven_sites);
    // Tier 0, no pixel part: the statement a large setup is split before, if any.
    let setup_split = if fast && f.pixel.is_empty() {
        split::setup_split(f)
    } else {
        None
    };
    // With a pixel part: its plan (see `pixel_plan`).
    let pixel = (!f.pixel.is_empty()).then(|| pixel_plan(program, f, key, tier, &homes));
    Ok(Plan {
        func,
        function: f,
        tier,
        homes,
        proven_sites,
        bounds,
        interpolators,
        setup_live,
        setup_may_fail_index,
        setup_split,
        pixel,
    })
}

/// Step 6 of the module doc.
fn pixel_plan(program: &Program, f: &Function, key: &VariantKey, tier: Tier, homes: &Homes) -> PixelPlan {
    let fast = tier == Tier::Fast;
    // Tier 0: whether the pixel code runs flat, and if so which `if`s run under masks and
    // which locals a group starts at zero.
    let flat = fast && flat::pixel_code_is_flattenable(program, f, key);
    let mut maskable_ifs = HashSet::new();
    let mut zeroed = vec![];
    if flat {
        flat::maskable_ifs(f, &f.pixel, &mut maskable_ifs);
        zeroed = flat::zeroed_locals(f, homes);
    }
    // The locals the pixel code assigns are known.
    let mut assigned = HashSet::new();
    block::assigned_locals(f, &f.pixel, &mut assigned);
    // The uniform frame's words are placed: every uniform local a row term may read is
    // known to stay put.
    let assigned_flags = dead::assigned_flags(f, &f.pixel);
    let mut frame = spill::place(f, key, homes, &assigned_flags);
    let mut scope = hoist::Scope {
        key,
        n_interp: key.interp_components(),
        resident: &frame.resident,
        row_locals: HashMap::new(),
    };
    // The row locals are known, with their defining values.
    scope.row_locals = scope.collect_row_locals(f, &assigned);
    // The row and per-run terms are known, at their offsets in the row section.
    let hoists = scope.collect_hoists(f, &assigned, frame.row_section);
    let carry_section = frame.row_section + hoists.iter().map(|h| 16 * h.comps).sum::<u32>();
    let mut unread_in_groups = HashSet::new();
    let mut unstored_terms = HashSet::new();
    // Tier 1: the carried terms are known, their steps after the row section, and the
    // substitutable locals only they read.
    let carry = if fast {
        Carry::default()
    } else {
        affine::collect_carried(
            &scope,
            f,
            &assigned,
            carry_section,
            &mut unread_in_groups,
            &mut unstored_terms,
        )
    };
    let row_locals = scope.row_locals;
    // The row locals only row terms read are known too.
    hoist::row_locals_unread(f, &hoists, &row_locals, &mut unread_in_groups, &mut unstored_terms);
    // The copies of the pixel loops are planned: tier 1's unswitched conditions, each
    // copy's guard prefix and the expressions it lowers.
    let loops = unswitch::plan_loops(f, key, &assigned, !fast);
    // Tier 1: the frame words only one side of the first unswitched condition reads wait
    // for that side.
    if let Some(cond) = loops.first_condition() {
        let early: Vec<ExprId> = hoists
            .iter()
            .filter(|h| h.per_run)
            .map(|h| h.expr)
            .chain(carry.carried.iter().map(|c| c.expr))
            .chain(carry.defs.values().copied())
            .chain(row_locals.values().copied())
            .collect();
        frame.deferred = spill::deferred_stores(f, key, &frame, cond, &early);
    }
    // The frame's size is known: the X range after the carried terms' steps.
    let carried_end = carry
        .carried
        .iter()
        .map(|c| c.row_step_offset.unwrap_or(c.step_offset) + 16)
        .fold(carry_section, u32::max);
    frame.finish(carried_end);
    PixelPlan {
        flat,
        maskable_ifs,
        zeroed,
        assigned,
        frame,
        row_locals,
        hoists,
        carry,
        unread_in_groups,
        unstored_terms,
        loops,
    }
}

/// Tier 0: per local of `f`, whether live code reads it (see [`dead`]): the pixel code as
/// `key` lowers it, and what setup statements that are not removable read.
fn dead_setup(f: &Function, key: &VariantKey, homes: &Homes) -> Vec<bool> {
    let mut live = vec![false; f.locals.len()];
    view::live_flags(f, key, &f.pixel, &mut live);
    let in_vars = |l: LocalId| homes.in_vars(l);
    let removable = |s: StmtId| {
        let mut budget = usize::MAX;
        pred::speculable_stmts(f, key, &in_vars, &[s], &mut budget)
    };
    dead::live_setup_locals(f, &f.setup, live, &removable)
}

/// The shared interpolators `key` binds (the ones the lowering may inline), by id.
fn interpolators(program: &Program, key: &VariantKey) -> HashMap<FuncId, Interpolator> {
    let mut out = HashMap::new();
    for b in &key.bindings {
        let BindingKind::Shared(name) = &b.kind else { continue };
        let Some(id) = program.find(name) else { continue };
        let g = program.func(id);
        if g.kind != FuncKind::Interpolator || out.contains_key(&id) {
            continue;
        }
        let bounds = converts_varying_float(g).then(|| LocalBounds::of_function(g));
        out.insert(
            id,
            Interpolator {
                dynamic: homes::dynamic_locals(g),
                bounds,
            },
        );
    }
    out
}

/// Whether `f` converts a varying float to an int or fixed-point value somewhere: only then
/// does the lowering ask for its locals' bounds (`Lower::convert_here`).
fn converts_varying_float(f: &Function) -> bool {
    // Every node of the arena is an expression of the function (see `ir::number`).
    f.exprs.iter().any(|(_, e)| match e.kind {
        ExprKind::Convert(inner) => {
            let inner = &f.exprs[inner];
            let to_int = matches!(e.ty.elem, Elem::Scalar(Scalar::Int | Scalar::Fixed(_)));
            let from_float = matches!(inner.ty.elem, Elem::Scalar(Scalar::Float) | Elem::Interp);
            to_int && from_float && (e.var.is_varying() || inner.var.is_varying())
        }
        _ => false,
    })
}

/// Whether `f`'s pixel code for `key` may spend fuel: it has a loop, or a shared
/// interpolator the key binds (inlined into the pixel code) has one.
pub(crate) fn pixel_code_has_loops(program: &Program, f: &Function, key: &VariantKey) -> bool {
    fn loops(f: &Function, stmts: &[StmtId]) -> bool {
        let mut found = false;
        crate::ir::for_each_stmt(&f.stmts, stmts, &mut |_, s| {
            found |= matches!(s, crate::ir::StmtKind::Loop { .. })
        });
        found
    }
    loops(f, &f.pixel)
        || key.bindings.iter().any(|b| match &b.kind {
            BindingKind::Shared(name) => program.find(name).is_some_and(|id| {
                let g = program.func(id);
                loops(g, &g.setup) || loops(g, &g.pixel)
            }),
            BindingKind::Kind(_) | BindingKind::Constant => false,
        })
}
