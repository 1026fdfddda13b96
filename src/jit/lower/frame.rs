//! The kernel's frame: its exits, `ctx` access, bound mode and the recording of run-time
//! errors.
//!
//! Every kernel has the signature `fn(ctx, args)`. Its entry (built by
//! [`super::lower_kernel`]) checks the stack and, in a tiered JIT, jumps to the tier-1 entry
//! once there is one; [`Lower::finish_function`] fills its exits: `return` goes to
//! `Lower::exit`, which stores the fuel left into `ctx.fuel` and returns.
//!
//! Bound mode: `bound` unions its rectangle into `ctx.bound` and sets the pass rectangle
//! ([`Lower::lower_bound`]); a kernel whose setup ran no `bound` records the viewport.
//!
//! Errors: a run-time error (an index out of range, out of fuel) is recorded in `ctx.error`
//! and `ctx.error_site` only if no error came first ([`Lower::record_error`]), so `ctx` holds
//! the invocation's first error. In tier 1 the record sits in a cold block. In tier 0 an
//! error of the setup code is kept in a variable instead (`pending_error`,
//! [`Lower::defer_error`]) and reaches `ctx.error` at the setup's exits and before
//! primitive calls ([`Lower::flush_errors`]), so `ctx` holds the invocation's first error
//! wherever anyone can read it. Every error but a setup loop out of fuel (which ends the
//! run and leaves its site in `ctx.fuel`, see [`Lower::spend_fuel`]) is also counted where
//! it happens ([`Lower::count_error`]): one added to its slot (`abi::ErrorSlot`) of `ctx.setup_counts`
//! (setup code) or `ctx.pixel_counts` (pixel code) per execution that fails, under the same
//! conditions as the record (the error guard; in flat pixel code, some lane executing). At
//! tier 0 the add is inline (a load, an add of the condition, a store), adding 0 where
//! nothing failed; at tier 1 it sits with the record.

use cranelift_codegen::cursor::{Cursor, FuncCursor};
use cranelift_codegen::ir::{self, condcodes::FloatCC, condcodes::IntCC, types, InstBuilder};

use super::{Lower, Res, PENDING_CODE_SHIFT};
use crate::abi::{ErrorSlot, MODE_BOUND};
use crate::ir::{ExprId, Scalar, SiteId};
use crate::jit::fixed;
use crate::jit::value::{args_flags, ctx_off, mem_flags, VnKey};

impl<'a, 'b> Lower<'a, 'b> {
    /// End the function being lowered where its code ends: jump to the exit, fill the
    /// setup's error exit (the kernel's only) and the exit. The kernel of an outlined pixel
    /// function ends at the call (see [`super::outline`]), the pixel function here.
    pub(super) fn finish_function(&mut self) {
        self.b.ins().jump(self.exit, &[]);
        if let Some(setup_exit) = self.setup_exit.take() {
            // Every jump here was lowered by now: sealed, it knows whether any exists.
            self.b.switch_to_block(setup_exit);
            self.seal_now(setup_exit);
            if self.b.is_unreachable() {
                // No early exit: a jump from here would make this block a predecessor of
                // the exit whose variables read as undefined (see `jump_live`).
                self.b.ins().trap(ir::TrapCode::unwrap_user(1));
            } else {
                self.flush_errors();
                self.b.ins().jump(self.exit, &[]);
            }
        }
        self.return_at_exit();
    }

    /// Count `ERR_STACK` in `ctx.setup_counts` (`abi::ErrorSlot::Stack` of the kernel's
    /// function) on the stack check's failing path, before its `return`. Added once the
    /// function being lowered is otherwise complete, so its values are numbered after all
    /// others and the rest of the printed CLIF reads as without it.
    pub(super) fn count_stack_error(&mut self) {
        let Some(ret) = self.stack_count.take() else { return };
        let slot = ErrorSlot::Stack(self.func_id).index(self.program.sites.len());
        let Ok(offset) = i32::try_from(8 * slot) else { return };
        let ctx = self.ctx;
        let mut pos = FuncCursor::new(self.b.func).at_inst(ret);
        let counts = pos.ins().load(types::I64, mem_flags(), ctx, ctx_off::SETUP_COUNTS);
        let n = pos.ins().load(types::I64, mem_flags(), counts, offset);
        let n = pos.ins().iadd_imm_s(n, 1);
        pos.ins().store(mem_flags(), n, counts, offset);
    }

    /// Fill the exit block: store the fuel left to `ctx` and return.
    pub(super) fn return_at_exit(&mut self) {
        self.b.switch_to_block(self.exit);
        let fuel = self.b.use_var(self.fuel);
        self.store_ctx(fuel, ctx_off::FUEL);
        self.b.ins().return_(&[]);
    }

    pub(super) fn load_ctx(&mut self, ty: ir::Type, off: i32) -> ir::Value {
        self.b.ins().load(ty, mem_flags(), self.ctx, off)
    }

    pub(super) fn store_ctx(&mut self, v: ir::Value, off: i32) {
        self.b.ins().store(mem_flags(), v, self.ctx, off);
    }

    /// Record `code` at `site` if no error was recorded yet and `cond` (i8) holds; count it
    /// when `cond` holds.
    pub(super) fn record_error(&mut self, code: u32, site: u32, cond: Option<ir::Value>) {
        self.record_error_counted(code, site, cond, true);
    }

    /// [`Self::record_error`], counting the error only when `count` (a loop of setup code
    /// out of fuel is not counted: see [`Self::spend_fuel`]).
    fn record_error_counted(&mut self, code: u32, site: u32, cond: Option<ir::Value>, count: bool) {
        let happened = self.error_condition(cond);
        if count {
            self.count_error(code, site, happened);
        }
        let old = self.load_ctx(types::I32, ctx_off::ERROR);
        let mut first = self.b.ins().icmp_imm_s(IntCC::Equal, old, 0);
        if let Some(h) = happened {
            first = self.b.ins().band(first, h);
        }
        let code_v = self.iconst_here(types::I32, code as i64);
        let new = self.b.ins().select(first, code_v, old);
        self.store_ctx(new, ctx_off::ERROR);
        let old_site = self.load_ctx(types::I32, ctx_off::ERROR_SITE);
        let site_v = self.iconst_here(types::I32, site as i32 as i64);
        let new_site = self.b.ins().select(first, site_v, old_site);
        self.store_ctx(new_site, ctx_off::ERROR_SITE);
    }

    /// When an error whose own condition is `cond` (i8; `None`: always) happens: `cond`
    /// and the error guard. `None`: always.
    pub(super) fn error_condition(&mut self, cond: Option<ir::Value>) -> Option<ir::Value> {
        match (cond, self.error_guard) {
            (Some(c), Some(g)) => Some(self.b.ins().band(c, g)),
            (c, g) => c.or(g),
        }
    }

    /// `cond` (i8; `None`: always) and, in pixel code, some lane executing: when a uniform
    /// index of pixel code fails. Pixel code can run a statement no lane executes (flat
    /// code always does, see [`crate::mid::flat`]; at either tier, the statements after a
    /// varying `break`, `continue` or `return` left no lane running), and an access no pixel
    /// makes fails for none: a group counts an access that fails in any of its pixels. (A
    /// varying index's condition already has the lanes.)
    pub(super) fn and_some_lane(&mut self, cond: Option<ir::Value>) -> Option<ir::Value> {
        let Some(e) = self.exec() else { return cond };
        let any = self.b.ins().vany_true(e);
        Some(match cond {
            Some(c) => self.b.ins().band(c, any),
            None => any,
        })
    }

    /// Add one to the count of error `code` at `site` (`abi::ErrorSlot::of`) when
    /// `happened` (i8, 0 or 1; `None`: always) holds: in `ctx.setup_counts` from setup code,
    /// in `ctx.pixel_counts` from pixel code. The caller has applied the error guard and
    /// the lanes ([`Self::error_condition`]).
    pub(super) fn count_error(&mut self, code: u32, site: u32, happened: Option<ir::Value>) {
        let sites = self.program.sites.len();
        let Some(offset) = ErrorSlot::of(code, site).and_then(|slot| i32::try_from(8 * slot.index(sites)).ok()) else {
            // Not a countable error, or a slot beyond any program's (2^28 sites).
            return;
        };
        let field = if self.pix.is_some() {
            ctx_off::PIXEL_COUNTS
        } else {
            ctx_off::SETUP_COUNTS
        };
        // The arrays never change while the kernel runs: one load per block at tier 0.
        let base = self.once_per_block(VnKey::CtxPtr(field), |l| {
            l.b.ins().load(types::I64, args_flags(), l.ctx, field)
        });
        let old = self.b.ins().load(types::I64, mem_flags(), base, offset);
        let new = match happened {
            Some(h) => {
                let one = self.b.ins().uextend(types::I64, h);
                self.b.ins().iadd(old, one)
            }
            None => self.b.ins().iadd_imm_s(old, 1),
        };
        self.b.ins().store(mem_flags(), new, base, offset);
    }

    /// Record `code` (ERR_INDEX or ERR_FUEL) at `site` if no error was recorded yet and
    /// `cond` (i8) holds, and count it when `cond` holds. In the tier-0 setup code of a
    /// kernel that defers them, the count is added and otherwise only `pending_error`
    /// changes: a select keeps the first error (~4 instructions instead of two loads, two
    /// stores and ~10 more; ~60 index sites and ~80 loops of the NURB setup record one).
    pub(super) fn defer_error(&mut self, code: u32, site: SiteId, cond: Option<ir::Value>) {
        self.defer_error_counted(code, site, cond, true);
    }

    /// [`Self::defer_error`], counting the error only when `count`.
    pub(super) fn defer_error_counted(&mut self, code: u32, site: SiteId, cond: Option<ir::Value>, count: bool) {
        let site_plus_one = i64::from(site.0) + 1;
        if !self.deferring_errors || site_plus_one >= 1 << PENDING_CODE_SHIFT {
            // Not deferred: after the deferred ones, which came first.
            if self.deferring_errors {
                self.flush_errors();
            }
            return self.record_error_counted(code, site.0, cond, count);
        }
        let bad = self.error_condition(cond);
        if count {
            self.count_error(code, site.0, bad);
        }
        let pending = self.b.use_var(self.pending_error);
        let error = self
            .b
            .ins()
            .iconst(types::I32, i64::from(code) << PENDING_CODE_SHIFT | site_plus_one);
        let candidate = match bad {
            Some(c) => self.b.ins().select(c, error, pending),
            None => error,
        };
        // An earlier error (pending != 0) stays.
        let new = self.b.ins().select(pending, pending, candidate);
        self.b.def_var(self.pending_error, new);
    }

    /// Put the setup's deferred error into `ctx.error` / `ctx.error_site` unless an error
    /// is already there (one recorded earlier: by a callee, a call too deep, or before the
    /// kernel ran). Called wherever the error state can be observed or an error that is
    /// not deferred be recorded: the setup's exits and its end, and before primitive calls
    /// (the callee, or the expand recorder, runs with `ctx`), so the first error of the run
    /// wins across kinds.
    pub(super) fn flush_errors(&mut self) {
        if !self.defer_errors {
            return;
        }
        let pending = self.b.use_var(self.pending_error);
        let old = self.load_ctx(types::I32, ctx_off::ERROR);
        let zero = self.iconst_here(types::I32, 0);
        // The pending error if it is to be recorded now, else 0.
        let first = self.b.ins().select(old, zero, pending);
        // `first` is 0 where `old` is not: the OR keeps `old` then.
        let code = self.b.ins().ushr_imm_u(first, i64::from(PENDING_CODE_SHIFT));
        let new = self.b.ins().bor(old, code);
        self.store_ctx(new, ctx_off::ERROR);
        let old_site = self.load_ctx(types::I32, ctx_off::ERROR_SITE);
        let site = self.b.ins().band_imm_u(first, (1i64 << PENDING_CODE_SHIFT) - 1);
        let site = self.b.ins().iadd_imm_s(site, -1);
        let new_site = self.b.ins().select(first, site, old_site);
        self.store_ctx(new_site, ctx_off::ERROR_SITE);
    }

    /// Union a rectangle into `ctx.bound` (bound mode only; the caller checks for NaN).
    /// `go`: only if this holds; the fields are then rewritten with their own values
    /// otherwise (branch-free, for tier 0's setup: one block fewer).
    pub(super) fn union_bound(&mut self, r: [ir::Value; 4], go: Option<ir::Value>) {
        let set = self.load_ctx(types::I32, ctx_off::BOUND_SET);
        let has = self.b.ins().icmp_imm_s(IntCC::NotEqual, set, 0);
        for (i, &v) in r.iter().enumerate() {
            let off = ctx_off::BOUND + 4 * i as i32;
            let cur = self.load_ctx(types::F32, off);
            let merged = if i < 2 {
                self.b.ins().fmin(cur, v)
            } else {
                self.b.ins().fmax(cur, v)
            };
            let new = self.b.ins().select(has, merged, v);
            let new = match go {
                Some(go) => self.b.ins().select(go, new, cur),
                None => new,
            };
            self.store_ctx(new, off);
        }
        let one = self.iconst_here(types::I32, 1);
        let one = match go {
            Some(go) => self.b.ins().select(go, one, set),
            None => one,
        };
        self.store_ctx(one, ctx_off::BOUND_SET);
    }

    /// `bound(...)`. `then_done`: nothing after it in the setup matters to a bound run
    /// (see `body`), so in bound mode the kernel returns right after recording it.
    pub(super) fn lower_bound(&mut self, es: &'a [ExprId; 4], then_done: bool) -> Res<()> {
        let mut r = [self.f32const_here(0.0); 4];
        for (i, &e) in es.iter().enumerate() {
            let v = self.eval_uniform(e)?;
            r[i] = fixed::convert(&mut self.b, v.scalar, Scalar::Float, v.comps[0]);
        }
        let mut nan = self.b.ins().fcmp(FloatCC::Unordered, r[0], r[1]);
        let n2 = self.b.ins().fcmp(FloatCC::Unordered, r[2], r[3]);
        nan = self.b.ins().bor(nan, n2);
        let mode = self.load_ctx(types::I32, ctx_off::MODE);
        let is_bound = self.b.ins().icmp_imm_s(IntCC::Equal, mode, MODE_BOUND as i64);
        let skip = self.b.ins().bnot(nan);
        let go = self.b.ins().band(is_bound, skip);
        if self.tier0() {
            // Tier 0: no block for the union (see `union_bound`) and no early end of a
            // bound run (blocks cost tier 0 more compile time than the bound run saves).
            self.union_bound(r, Some(go));
        } else {
            let union_blk = self.b.create_block();
            let after = self.b.create_block();
            self.b.ins().brif(go, union_blk, &[], after, &[]);
            self.b.switch_to_block(union_blk);
            self.union_bound(r, None);
            if then_done {
                self.b.ins().jump(self.exit, &[]);
                // The NaN bound of a bound run is not recorded, and nothing else is either.
                let render = self.b.create_block();
                self.b.switch_to_block(after);
                self.b.ins().brif(is_bound, self.exit, &[], render, &[]);
                self.b.switch_to_block(render);
            } else {
                self.b.ins().jump(after, &[]);
                self.b.switch_to_block(after);
            }
        }
        for (i, &v) in r.iter().enumerate() {
            self.b.def_var(self.bound_vars[i], v);
        }
        let yes = self.iconst_here(types::I8, 1);
        self.b.def_var(self.has_bound, yes);
        Ok(())
    }
}
