//! Run-time errors of a frame's kernels: where kernel runs count them, and the W0801
//! warnings they become.
//!
//! A kernel counts every error it meets at the error's slot (`abi::ErrorSlot`: a site, the
//! call-depth limit, a function's stack frame) in one of two arrays the context names:
//! `setup_counts` for its setup code, `pixel_counts` for its pixel code (`abi::ctx`); a
//! setup loop out of fuel it leaves in `TileCtx::fuel` instead, where the bound and expand
//! runs read it (`super::expand`). The renderer makes the sums independent of the thread
//! count and the tile size:
//! - Setup code does not depend on the tile, and a draw's bound run (`MODE_BOUND`) meets the
//!   same setup errors as its render run in any tile (the bound run skips only statements
//!   that cannot fail). So setup errors are counted in the bound runs (and in the expand
//!   runs, `MODE_EXPAND`, which run an expanded instance's setup once) and the render runs
//!   hand their setup counts to a scratch array nobody reads.
//! - Pixel code runs once per pixel group, and each group is rendered in exactly one tile,
//!   so the render runs' pixel counts summed over the tiles are the frame's.
//!
//! Each kernel run uses this thread's arrays ([`CountArrays::with`]), kept at zero between
//! uses: a run that recorded no error (`TileCtx::error` is 0) added nothing, so only the
//! arrays of runs that did are read back ([`CountArrays::take`], which zeroes them again).
//! The frame's counts are summed per slot in 64 bits and reported once per slot, in slot
//! order (by site, i.e. in source order), whatever order the tiles ran in ([`report`]).

use std::cell::RefCell;
use std::collections::BTreeMap;

use crate::abi::{count_slots, ErrorSlot, ERR_CALL_DEPTH, ERR_FUEL, ERR_INDEX, ERR_STACK, MAX_CALL_DEPTH};
use crate::diag::{Diagnostic, Diagnostics};
use crate::ir::{for_each_stmt, ExprId, ExprKind, Exprs, FuncId, Program, SiteId, StmtKind};

/// Error counts of kernel runs, as (slot index, count) pairs (a slot may repeat: sum them).
pub(crate) type Counts = Vec<(u32, u64)>;

/// This thread's count arrays: `counts` all zero between uses, `scratch` written by kernels
/// and never read.
#[derive(Default)]
pub(crate) struct CountArrays {
    counts: Vec<u64>,
    scratch: Vec<u64>,
    /// Slots of the program being rendered.
    slots: usize,
}

impl CountArrays {
    /// Run `f` with this thread's arrays, each at least `program`'s slots long.
    pub fn with<R>(program: &Program, f: impl FnOnce(&mut CountArrays) -> R) -> R {
        thread_local! {
            static ARRAYS: RefCell<CountArrays> = RefCell::new(CountArrays::default());
        }
        let slots = count_slots(program);
        ARRAYS.with(|arrays| match arrays.try_borrow_mut() {
            Ok(mut a) => {
                a.fit(slots);
                f(&mut a)
            }
            // In use further up this thread's stack: arrays of its own.
            Err(_) => {
                let mut a = CountArrays::default();
                a.fit(slots);
                f(&mut a)
            }
        })
    }

    fn fit(&mut self, slots: usize) {
        if self.counts.len() < slots {
            self.counts.resize(slots, 0);
            self.scratch.resize(slots, 0);
        }
        self.slots = slots;
    }

    /// The array counts are read back from.
    pub fn counts(&mut self) -> *mut u64 {
        self.counts.as_mut_ptr()
    }

    /// An array of the same length whose counts are thrown away.
    pub fn scratch(&mut self) -> *mut u64 {
        self.scratch.as_mut_ptr()
    }

    /// Append the non-zero counts to `out` and zero them.
    pub fn take(&mut self, out: &mut Counts) {
        for (i, n) in self.counts[..self.slots].iter_mut().enumerate() {
            if *n != 0 {
                out.push((i as u32, std::mem::take(n)));
            }
        }
    }
}

/// Where each site of `program` is: the function whose code holds it and whether in its
/// pixel part.
fn site_owners(program: &Program) -> Vec<Option<(FuncId, bool)>> {
    fn expr(x: &Exprs, e: ExprId, mark: &mut dyn FnMut(SiteId)) {
        if let ExprKind::Index { site, .. } = &x[e].kind {
            mark(*site);
        }
        x[e].for_each_child(|c| expr(x, c, mark));
    }
    let mut owners = vec![None; program.sites.len()];
    for (i, f) in program.functions.iter().enumerate() {
        for (stmts, pixel) in [(&f.setup, false), (&f.pixel, true)] {
            let x = &f.exprs;
            let mut mark = |site: SiteId| {
                if let Some(o) = owners.get_mut(site.0 as usize) {
                    *o = Some((FuncId(i as u32), pixel));
                }
            };
            for_each_stmt(&f.stmts, stmts, &mut |_, s| match s {
                StmtKind::Assign { place, value } => {
                    for (index, site) in &place.indices {
                        mark(*site);
                        expr(x, *index, &mut mark);
                    }
                    expr(x, *value, &mut mark);
                }
                StmtKind::If { cond, .. } => expr(x, *cond, &mut mark),
                StmtKind::Loop { cond, site, .. } => {
                    mark(*site);
                    if let Some(c) = cond {
                        expr(x, *c, &mut mark);
                    }
                }
                StmtKind::InterpolatorReturn(Some(e)) => expr(x, *e, &mut mark),
                StmtKind::Bound(es) => es.iter().for_each(|e| expr(x, *e, &mut mark)),
                StmtKind::CallPrimitive { args, site, .. } => {
                    mark(*site);
                    args.iter().for_each(|e| expr(x, *e, &mut mark))
                }
                _ => {}
            });
        }
    }
    owners
}

/// "once" or "N times".
fn times(n: u64) -> String {
    if n == 1 {
        "once".to_string()
    } else {
        format!("{n} times")
    }
}

/// One W0801 per slot of `counts` (summed per slot), in slot order: the site's function,
/// what failed and how often, located at the site (a stack error at its function; a call a
/// hand-written kernel skipped for depth has no place).
pub(crate) fn report(program: &Program, counts: &[(u32, u64)], diags: &mut Diagnostics) {
    let mut total: BTreeMap<u32, u64> = BTreeMap::new();
    for &(slot, n) in counts {
        let t = total.entry(slot).or_default();
        *t = t.wrapping_add(n);
    }
    if total.is_empty() {
        return;
    }
    let sites = program.sites.len();
    let owners = site_owners(program);
    let name = |f: FuncId| program.functions.get(f.0 as usize).map_or("?", |f| f.name.as_str());
    for (slot, n) in total {
        let slot = ErrorSlot::at(slot as usize, sites);
        let (owner, span) = match slot {
            ErrorSlot::Index(s) | ErrorSlot::Fuel(s) | ErrorSlot::CallDepth(Some(s)) => (
                owners.get(s.0 as usize).copied().flatten(),
                program.sites.get(s.0 as usize).copied(),
            ),
            ErrorSlot::Stack(f) => (Some((f, false)), program.functions.get(f.0 as usize).map(|f| f.span)),
            ErrorSlot::CallDepth(None) => (None, None),
        };
        let in_pixels = owner.is_some_and(|(_, pixel)| pixel);
        let what = match slot.code() {
            ERR_INDEX if in_pixels => format!(
                "an index was out of range (clamped) {} (a 4-pixel group counts once an access)",
                times(n)
            ),
            ERR_INDEX => format!("an index was out of range (clamped) {}", times(n)),
            ERR_FUEL if in_pixels => format!("a loop ran out of fuel (left early) in {}", plural(n, "pixel group")),
            ERR_FUEL => format!("a setup loop ran out of fuel in {} (not drawn)", plural(n, "draw")),
            ERR_CALL_DEPTH => format!(
                "primitive calls nested too deep (more than {MAX_CALL_DEPTH}; call skipped) {}",
                times(n)
            ),
            ERR_STACK => format!(
                "its stack frame (local arrays) did not fit in the thread's stack (not run) {}",
                times(n)
            ),
            _ => format!("an unknown run-time error {}", times(n)),
        };
        let message = match owner {
            Some((f, _)) => format!("in `{}` at run time: {what}", name(f)),
            None => format!("at run time: {what}"),
        };
        let mut d = Diagnostic::warning("W0801", message);
        if let Some(span) = span {
            d = d.primary(span, what);
        }
        diags.push(d);
    }
}

fn plural(n: u64, what: &str) -> String {
    if n == 1 {
        format!("1 {what}")
    } else {
        format!("{n} {what}s")
    }
}
