//! Statements, and the lane masks pixel statements run under.
//!
//! Setup statements are scalar code. Per pixel group the pixel statements run on vectors
//! under masks: `alive` (lanes not yet retired) and `exec` (the lanes the current statement
//! runs for, always a subset of `alive`). A varying `if` runs both sides under their masks,
//! skipping a side with no lane ([`Lower::lower_if`]); varying loops keep a loop mask and
//! run until it is empty ([`Lower::varying_loop`]); break/continue/return remove lanes.
//! Tier 0 lowers flat pixel code without those early exits ([`crate::mid::flat`]), and may
//! if-convert short setup `if`s ([`Lower::if_converted`]).
//!
//! Invariants: every loop trip spends fuel ([`Lower::spend_fuel`]): setup loops the setup
//! fuel (kept in a variable, `ctx.fuel` at the exit and around primitive calls), loops of
//! pixel code the fuel of their pixel group (a variable set at the start of every group,
//! see [`super::loops`]); code after an unconditional `break`, `continue` or `return` goes
//! to blocks no path reaches ([`Lower::jump_live`]), and jumps from there are not emitted.

use cranelift_codegen::ir::{self, condcodes::IntCC, types, Block, InstBuilder};
use cranelift_frontend::Variable;

use super::{err, key_constant, quiet_stmt, speculable_expr, LoopCtx, Lower, Res, Storage};
use crate::abi::ERR_FUEL;
use crate::ir::{for_each_assign, ExprId, Function, LocalId, LoopId, Scalar, SiteId, StmtId, StmtKind};
use crate::jit::fixed;
use crate::jit::value::{mask_const, splat, I32X4};

impl<'a, 'b> Lower<'a, 'b> {
    /// After a terminator in the middle of a statement list: keep emitting into a fresh
    /// block no edge reaches (Cranelift drops it).
    pub(super) fn continue_unreachable(&mut self) {
        let dead = self.b.create_block();
        // Nothing jumps here: sealed, its reads need no block parameters.
        self.seal_now(dead);
        self.dead_blocks.insert(dead);
        self.b.switch_to_block(dead);
    }

    /// Is the block being filled one no path from the entry reaches?
    pub(super) fn in_dead_block(&self) -> bool {
        self.b.current_block().is_some_and(|b| self.dead_blocks.contains(&b))
    }

    /// End the current block with a jump to `dest`, or, in a dead block, with a trap that
    /// never runs: a jump from dead code would make it a predecessor of `dest` whose
    /// variables all read as undefined (zero), so every variable live at `dest` needed a
    /// block parameter merging that zero with its real value (the NURB setup's loops and
    /// `if`s carried ~40 such parameters each). False if it did not jump.
    pub(super) fn jump_live(&mut self, dest: Block) -> bool {
        if self.in_dead_block() {
            self.b.ins().trap(ir::TrapCode::unwrap_user(1));
            false
        } else {
            self.b.ins().jump(dest, &[]);
            self.live_targets.insert(dest);
            true
        }
    }

    pub(crate) fn exec(&mut self) -> Option<ir::Value> {
        let e = self.pix.as_ref()?.exec;
        Some(self.b.use_var(e))
    }

    pub(super) fn set_exec(&mut self, v: ir::Value) {
        if let Some(p) = &self.pix {
            let e = p.exec;
            self.b.def_var(e, v);
        }
    }

    /// Assignments must blend with the old value (some live lane is not executing).
    pub(super) fn masked(&self) -> bool {
        self.pix.as_ref().is_some_and(|p| p.varying_depth > 0)
    }

    pub(super) fn in_pixel(&self) -> bool {
        self.pix.is_some()
    }

    pub(super) fn depth_add(&mut self, d: i32) {
        if let Some(p) = &mut self.pix {
            p.varying_depth = (p.varying_depth as i32 + d) as u32;
        }
    }

    /// `exec` after leaving a construct entered with `entry`: the entry lanes that are still
    /// alive and have not left an enclosing varying loop.
    pub(super) fn restore_exec(&mut self, entry: ir::Value) {
        let Some(p) = &self.pix else { return };
        let alive = p.alive;
        let a = self.b.use_var(alive);
        let mut m = self.b.ins().band(entry, a);
        for (mask, cont) in self.vloops.clone() {
            let lm = self.b.use_var(mask);
            let c = self.b.use_var(cont);
            let stay = self.b.ins().band_not(lm, c);
            m = self.b.ins().band(m, stay);
        }
        self.set_exec(m);
    }

    pub(super) fn stmts(&mut self, stmts: &'a [StmtId]) -> Res<()> {
        // A guard's facts hold to the end of the statement list it is in.
        let mark = self.guard_facts.mark();
        for &s in stmts {
            self.stmt(s)?;
        }
        self.guard_facts.truncate(mark);
        Ok(())
    }

    pub(super) fn stmt(&mut self, s: StmtId) -> Res<()> {
        let st = self.stmt_nodes();
        match &st[s] {
            StmtKind::Assign { place, value } => {
                if self.dead_setup_assign(s, place.local) {
                    return Ok(());
                }
                // Only carried or row terms read it: nothing in the group does.
                if self.pix.is_some()
                    && self.frames.len() == 1
                    && place.indices.is_empty()
                    && self
                        .pixel_plan()
                        .is_ok_and(|p| p.unread_in_groups.contains(&place.local))
                {
                    return Ok(());
                }
                self.assign(place, *value)
            }
            StmtKind::If { cond, then, otherwise } => {
                self.lower_if(*cond, then, otherwise)?;
                // `if (c) return;`: every lane still executing has `c` false.
                if self.in_pixel()
                    && otherwise.is_empty()
                    && matches!(then.as_slice(), [t] if matches!(st[*t], StmtKind::Return))
                {
                    self.assume_guard(*cond);
                }
                Ok(())
            }
            StmtKind::Loop {
                id,
                cond,
                body,
                step,
                varying,
                site,
            } => {
                // The body runs again after its assignments: no fact about what it assigns
                // holds in it (or after it).
                // (Setup code has none: no walk there.)
                if !self.guard_facts.is_empty() {
                    let frame = self.frames.len() - 1;
                    for_each_assign(st, body, &mut |p, _| self.guard_facts.kill(frame, p.local));
                    for_each_assign(st, step, &mut |p, _| self.guard_facts.kill(frame, p.local));
                }
                if *varying && self.in_pixel() {
                    self.varying_loop(*id, *cond, body, step, *site)
                } else {
                    self.uniform_loop(*id, *cond, body, step, *site)
                }
            }
            StmtKind::Break(id) => self.break_continue(*id, true),
            StmtKind::Continue(id) => self.break_continue(*id, false),
            StmtKind::Return => self.lower_return(),
            StmtKind::Interpolation { arms } => self.interpolation(arms),
            StmtKind::InterpolatorReturn(e) => self.interpolator_return(*e),
            StmtKind::Bound(es) => {
                if self.in_pixel() || self.frames.len() > 1 {
                    return err("`bound` in per-pixel code");
                }
                self.lower_bound(es, false)
            }
            StmtKind::CallPrimitive { callee, args, site } => {
                if self.in_pixel() || self.frames.len() > 1 {
                    return err("primitive call in per-pixel code");
                }
                // The callee (compiled for the same key) answers for the bindings itself.
                self.written.iter_mut().for_each(|w| *w = true);
                self.call_primitive(*callee, args, *site)
            }
        }
    }

    /// Tier 0: `s`, an assignment to `local` in the primitive's setup, computes a value no
    /// live code reads and has no other effect (see [`crate::mid::dead`]).
    pub(super) fn dead_setup_assign(&self, s: StmtId, local: LocalId) -> bool {
        let Some(live) = &self.plan.setup_live else {
            return false;
        };
        let mut budget = usize::MAX;
        self.pix.is_none()
            && self.frames.len() == 1
            && !live.get(local.0 as usize).copied().unwrap_or(true)
            && self.speculable_stmts(&[s], &mut budget)
    }

    pub(super) fn lower_if(&mut self, cond: ExprId, then: &'a [StmtId], otherwise: &'a [StmtId]) -> Res<()> {
        // `clipping()` (possibly negated) is a constant of the key: lower only the branch it
        // selects, so a trivially accepted variant contains no clipping code at all.
        if let Some(on) = key_constant(self.exprs(), cond, self.key) {
            let taken = if on { then } else { otherwise };
            for &s in taken {
                self.stmt(s)?;
            }
            return Ok(());
        }
        // A condition of the primitive decided before the pixel loops (tier 1, see
        // [`crate::mid::unswitch`]): this copy of the loops holds the side it takes only.
        if let (1, Some(&on)) = (self.frames.len(), self.unswitched.get(&cond)) {
            return self.stmts(if on { then } else { otherwise });
        }
        let c = self.eval(cond)?;
        if !c.varying {
            let c = fixed::convert(&mut self.b, c.scalar, Scalar::Bool, c.comps[0]);
            // Tier 0, flat pixel code: a uniform `if` whose sides run under masks as well
            // as after a branch is lowered like a varying one, with the condition splatted
            // to every lane: no blocks for its sides (see [`crate::mid::flat`]).
            if self.flat && self.frames.len() == 1 && self.pixel_plan().is_ok_and(|p| p.maskable_ifs.contains(&cond)) {
                if let Some(entry) = self.exec() {
                    let m = splat(&mut self.b, Scalar::Bool, c);
                    return self.masked_if(entry, m, then, otherwise);
                }
            }
            // Small assigning `if`s of setup code: straight-line (see `if_converted`).
            if self.pix.is_none() && self.if_convertible(then, otherwise) {
                return self.if_converted(c, then, otherwise);
            }
            // Tier 0: `if (c) return;` in setup is one branch to the exit, not a `then`
            // block, an unreachable block after its return and a join.
            if self.tier0()
                && otherwise.is_empty()
                && matches!(then, [s] if matches!(self.stmt_nodes()[*s], StmtKind::Return))
                && self.pix.is_none()
                && self.frame().interp_binding.is_none()
            {
                let cont = self.b.create_block();
                self.b.ins().brif(c, self.exit, &[], cont, &[]);
                self.seal_now(cont);
                self.b.switch_to_block(cont);
                return Ok(());
            }
            let then_blk = self.b.create_block();
            let else_blk = self.b.create_block();
            let join = self.b.create_block();
            if self.in_dead_block() {
                self.dead_blocks.extend([then_blk, else_blk]);
            }
            self.b.ins().brif(c, then_blk, &[], else_blk, &[]);
            // Each block sealed once its predecessors are all known (see `seal_now`).
            self.seal_now(then_blk);
            self.seal_now(else_blk);
            self.b.switch_to_block(then_blk);
            self.stmts(then)?;
            let from_then = self.jump_live(join);
            self.b.switch_to_block(else_blk);
            self.stmts(otherwise)?;
            let from_else = self.jump_live(join);
            if !from_then && !from_else {
                self.dead_blocks.insert(join);
            }
            self.seal_now(join);
            self.b.switch_to_block(join);
            return Ok(());
        }
        let Some(entry) = self.exec() else {
            return err("varying condition outside per-pixel code");
        };
        let c = fixed::convert(&mut self.b, c.scalar, Scalar::Bool, c.comps[0]);
        self.masked_if(entry, c, then, otherwise)
    }

    /// `if (c) then else otherwise` for the lanes of `entry`, with `c` a lane mask: each
    /// side runs under its mask and is skipped when no lane takes it (flat pixel code runs
    /// both sides whatever the masks: see [`crate::mid::flat`]).
    pub(super) fn masked_if(
        &mut self,
        entry: ir::Value,
        c: ir::Value,
        then: &'a [StmtId],
        otherwise: &'a [StmtId],
    ) -> Res<()> {
        if otherwise.is_empty()
            && matches!(then, [s] if matches!(self.stmt_nodes()[*s], StmtKind::Return))
            && self.frame().interp_binding.is_none()
        {
            return self.varying_guard_return(entry, c);
        }
        let then_mask = self.b.ins().band(entry, c);
        let else_mask = self.b.ins().band_not(entry, c);
        let then_out = self.declare_var(I32X4);
        self.b.def_var(then_out, then_mask);
        self.depth_add(1);
        self.masked_side(then_mask, then, then_out)?;
        let else_out = self.declare_var(I32X4);
        self.b.def_var(else_out, else_mask);
        if !otherwise.is_empty() {
            self.masked_side(else_mask, otherwise, else_out)?;
        }
        self.depth_add(-1);
        let t = self.b.use_var(then_out);
        let e = self.b.use_var(else_out);
        let m = self.b.ins().bor(t, e);
        self.set_exec(m);
        Ok(())
    }

    /// One side of [`Self::masked_if`]: `stmts` with `exec = mask`, skipped when `mask` is
    /// empty unless the pixel code is flat; `out` gets the lanes still executing after it.
    pub(super) fn masked_side(&mut self, mask: ir::Value, stmts: &'a [StmtId], out: Variable) -> Res<()> {
        if self.flat {
            self.set_exec(mask);
            self.stmts(stmts)?;
            let x = self.exec().expect("pixel context");
            self.b.def_var(out, x);
            return Ok(());
        }
        let side = self.b.create_block();
        let join = self.b.create_block();
        let any = self.b.ins().vany_true(mask);
        let none = self.b.ins().icmp_imm_s(IntCC::Equal, any, 0);
        self.b.ins().brif(none, join, &[], side, &[]);
        self.b.switch_to_block(side);
        self.set_exec(mask);
        self.stmts(stmts)?;
        let x = self.exec().expect("pixel context");
        self.b.def_var(out, x);
        self.b.ins().jump(join, &[]);
        self.b.switch_to_block(join);
        Ok(())
    }

    // ------------------------------------------------ tier 0: deferred setup returns

    /// The primitive's setup statements. Tier 1 ends a bound run right after a `bound` that
    /// nothing after it can widen (see [`quiet_stmt`]). Tier 0 defers each `if (c) return;` among them to
    /// the end of the run of statements that can run speculatively around it: the
    /// statements after the guard run whether or not it returns (they compute values
    /// only), and one branch at the run's end returns if any of its guards held.
    ///
    /// Why: a guard splits the setup into blocks, and the single-pass allocator spills
    /// every value that lives across the split (screen_triangle's edge and plane
    /// computations around its area test: 20 values) and reloads it after. The statements
    /// run are those tier 1 runs plus ones whose results nothing reads when a guard holds
    /// (no stores, no possible run-time error, no loop), so results are the same.
    ///
    /// Returns the condition of the guards deferred to the end of the setup: the caller
    /// returns on it (after storing the uniform frame, see [`Self::pixel_passes`]).
    pub(super) fn setup_stmts(&mut self, f: &'a Function) -> Res<Option<ir::Value>> {
        let setup = &f.setup;
        if !self.tier0() {
            for (i, &s) in setup.iter().enumerate() {
                if let StmtKind::Bound(es) = &f.stmts[s] {
                    // A bound run wants nothing but the bound: when the rest of the setup can
                    // neither widen it (another `bound`, a call) nor record an error, it ends
                    // here (the rest is the render run's work: edge and plane equations...).
                    let last_effect = setup[i + 1..].iter().all(|&t| quiet_stmt(f, t));
                    self.lower_bound(es, last_effect)?;
                } else {
                    self.stmt(s)?;
                }
            }
            return Ok(None);
        }
        // The OR of the guards deferred so far in this run.
        let mut pending: Option<ir::Value> = None;
        for (i, &s) in setup.iter().enumerate() {
            if self.outline.setup_split == Some(i) {
                if let Some(p) = pending.take() {
                    self.return_if(p);
                }
                self.begin_outlined_setup(i)?;
            }
            if let Some(cond) = self.deferrable_guard(s) {
                let c = self.eval_uniform(cond)?;
                let c = fixed::convert(&mut self.b, c.scalar, Scalar::Bool, c.comps[0]);
                pending = Some(match pending {
                    Some(p) => self.b.ins().bor(p, c),
                    None => c,
                });
                continue;
            }
            let mut budget = usize::MAX;
            if !self.speculable_stmts(&[s], &mut budget) {
                if let Some(p) = pending.take() {
                    self.return_if(p);
                }
            }
            self.stmt(s)?;
        }
        Ok(pending)
    }

    /// `c` of a setup statement `if (c) return;` whose condition cannot fail.
    pub(super) fn deferrable_guard(&self, s: StmtId) -> Option<ExprId> {
        let st = self.stmt_nodes();
        let StmtKind::If { cond, then, otherwise } = &st[s] else {
            return None;
        };
        let is_return = otherwise.is_empty() && matches!(then.as_slice(), [t] if matches!(st[*t], StmtKind::Return));
        (is_return && key_constant(self.exprs(), *cond, self.key).is_none() && speculable_expr(self.exprs(), *cond))
            .then_some(*cond)
    }

    /// End the kernel if `c` (i8) holds; code goes on in a new block.
    pub(super) fn return_if(&mut self, c: ir::Value) {
        let cont = self.b.create_block();
        self.b.ins().brif(c, self.exit, &[], cont, &[]);
        self.b.switch_to_block(cont);
    }

    // ------------------------------------------------ if-conversion in setup

    /// A small uniform `if` of setup code whose sides only assign SSA variables from
    /// expressions that cannot fail is lowered as straight-line code: both sides, then one
    /// `select` per variable either side assigns. The values assigned are the same, so
    /// results are bit-identical to the branching form. At tier 0 each block boundary
    /// costs the register allocator (it spills every live value there and reloads it on
    /// use), so fewer blocks compile faster. At tier 1 the e-graph places a pure value at
    /// its first use: a value used inside one side and again after the join was computed
    /// twice (screen_triangle's snapped vertices, used for `px` in the `exact` side and for
    /// the integer edges after it: 6 of its setup's rounds and conversions repeated).
    pub(super) fn if_convertible(&self, then: &[StmtId], otherwise: &[StmtId]) -> bool {
        const MAX_STMTS: usize = 24;
        let mut budget = MAX_STMTS;
        self.speculable_stmts(then, &mut budget) && self.speculable_stmts(otherwise, &mut budget)
    }

    /// See [`crate::mid::pred::speculable_stmts`], for the frame being lowered.
    pub(super) fn speculable_stmts(&self, stmts: &[StmtId], budget: &mut usize) -> bool {
        let fr = self.frame();
        let in_vars = |l: LocalId| matches!(fr.storage.get(l.0 as usize), Some(Storage::Vars(_)));
        crate::mid::pred::speculable_stmts(fr.func, self.key, &in_vars, stmts, budget)
    }

    /// Lower `if (c) then else otherwise` (checked by [`Self::if_convertible`]) without
    /// branches: `then` from the entry values, `otherwise` from the entry values, then each
    /// assigned variable selects its `then` or `otherwise` value by `c`.
    pub(super) fn if_converted(&mut self, c: ir::Value, then: &'a [StmtId], otherwise: &'a [StmtId]) -> Res<()> {
        let mut locals = vec![];
        let st = self.stmt_nodes();
        for_each_assign(st, then, &mut |p, _| locals.push(p.local));
        for_each_assign(st, otherwise, &mut |p, _| locals.push(p.local));
        locals.sort_unstable_by_key(|l| l.0);
        locals.dedup();
        let mut vars = vec![];
        for l in locals {
            if let Some(Storage::Vars(vs)) = self.frame().storage.get(l.0 as usize) {
                vars.extend(vs.iter().copied());
            }
        }
        let entry: Vec<ir::Value> = vars.iter().map(|&v| self.b.use_var(v)).collect();
        self.stmts(then)?;
        let then_vals: Vec<ir::Value> = vars.iter().map(|&v| self.b.use_var(v)).collect();
        for (&v, &x) in vars.iter().zip(&entry) {
            self.b.def_var(v, x);
        }
        self.stmts(otherwise)?;
        for (k, &v) in vars.iter().enumerate() {
            let else_val = self.b.use_var(v);
            if then_vals[k] != else_val {
                let x = self.b.ins().select(c, then_vals[k], else_val);
                self.b.def_var(v, x);
            }
        }
        Ok(())
    }

    /// `if (c) return;` with a varying `c` in the primitive's own pixel code (a coverage or
    /// depth guard): the lanes executing it with `c` set retire, the others go on.
    ///
    /// Same masks as the general path (`then` with `exec = entry & c`, `lower_return`, the
    /// join's `exec = else_mask`), without its branch on "any lane takes `then`" and the
    /// mask copies around it: `alive &= !(entry & c)`, `exec = entry & !c`, and the group
    /// ends when no lane is left. While pixel code runs `alive` is never empty (the group
    /// ends when it becomes so), so when no lane takes the `then` the test cannot end the
    /// group early: both paths end in the same state.
    pub(super) fn varying_guard_return(&mut self, entry: ir::Value, c: ir::Value) -> Res<()> {
        let Some(p) = &self.pix else {
            return err("varying condition outside per-pixel code");
        };
        let (alive_var, group_end) = (p.alive, p.group_end);
        let alive = self.b.use_var(alive_var);
        let stay = self.not_and(entry, c);
        // Every live lane executing (no varying control flow entered yet, as at a leading
        // guard): `alive & !(entry & c)` is `stay` itself.
        let alive = if alive == entry {
            stay
        } else {
            let leaving = self.b.ins().band(entry, c);
            self.b.ins().band_not(alive, leaving)
        };
        self.b.def_var(alive_var, alive);
        self.set_exec(stay);
        // Flat pixel code goes on with no lane left (see [`crate::mid::flat`]).
        if self.flat {
            return Ok(());
        }
        let any = self.b.ins().vany_true(alive);
        let all_gone = self.b.ins().icmp_imm_s(IntCC::Equal, any, 0);
        let cont = self.b.create_block();
        self.b.ins().brif(all_gone, group_end, &[], cont, &[]);
        self.b.switch_to_block(cont);
        // This branch is `cont`'s only predecessor. Sealed now, the next guard's reads of
        // `alive` and `exec` are this block's values themselves, equal, so it takes the
        // `stay` path above; unsealed, each read got a block parameter of its own (merged
        // only when the function is sealed) and every guard after the first recomputed
        // `alive & !(entry & c)`: five instructions instead of two per integer edge test.
        self.b.seal_block(cont);
        self.sealed_early.insert(cont);
        Ok(())
    }

    /// After `if (cond) return;` in pixel code (lowered, or dropped by a block variant that
    /// proved it fires for no lane): record what `cond` being false says about float
    /// locals for the rest of the statement list (see [`super::bounds::GuardFacts`]).
    pub(in crate::jit) fn assume_guard(&mut self, cond: ExprId) {
        let frame = self.frames.len() - 1;
        self.guard_facts.assume(self.exprs(), frame, cond, false);
    }

    /// `m & !c` for a lane mask `m` and a varying condition `c`. When `c` is a vector
    /// integer compare, the complementary compare instead (`a <u b` -> `a >=u b`): same
    /// lanes, and x86 has no unsigned less-than, so `!(a <u b)` was min + compare + not.
    pub(super) fn not_and(&mut self, m: ir::Value, c: ir::Value) -> ir::Value {
        let dfg = &self.b.func.dfg;
        if let ir::ValueDef::Result(inst, 0) = dfg.value_def(c) {
            if let ir::InstructionData::IntCompare {
                opcode: ir::Opcode::Icmp,
                cond,
                args,
            } = dfg.insts[inst]
            {
                use cranelift_codegen::ir::condcodes::CondCode;
                let inv = self.b.ins().icmp(cond.complement(), args[0], args[1]);
                return self.b.ins().band(m, inv);
            }
        }
        self.b.ins().band_not(m, c)
    }

    /// Spend one unit of fuel (the setup's, or in pixel code the group's) and go on; with
    /// none left:
    /// - in pixel code, record ERR_FUEL at `site` if the group's fuel is empty (0), count it
    ///   and mark the fuel spent (-1), and jump to `exit` (the loop's): a loop head that
    ///   finds the fuel spent only leaves, so a group counts one out-of-fuel error, at the
    ///   loop that ran out;
    /// - in setup code, record ERR_FUEL at `site`, put `-(2 + site)` in the fuel and end
    ///   the run (its callers end theirs after the call, see [`Self::call_primitive`]). No
    ///   count: the runner reads the site from `ctx.fuel` (`abi::setup_fuel_ran_out`), which
    ///   spares the setup's out-of-fuel paths (~80 in the NURB kernel) the counting code.
    pub(super) fn spend_fuel(&mut self, site: SiteId, exit: Block) {
        let in_pixels = self.pix.is_some();
        let var = if in_pixels { self.group_fuel } else { self.fuel };
        let fuel = self.b.use_var(var);
        let empty = self.b.ins().icmp_imm_s(IntCC::SignedLessThanOrEqual, fuel, 0);
        let out_blk = self.b.create_block();
        let ok_blk = self.b.create_block();
        if self.in_dead_block() {
            // A loop no path reaches: so are its fuel paths (no jump from them is live).
            self.dead_blocks.extend([out_blk, ok_blk]);
        }
        self.b.ins().brif(empty, out_blk, &[], ok_blk, &[]);
        self.seal_now(out_blk);
        self.seal_now(ok_blk);
        self.b.set_cold_block(out_blk);
        self.b.switch_to_block(out_blk);
        if in_pixels {
            let first = self.b.ins().icmp_imm_s(IntCC::Equal, fuel, 0);
            self.defer_error(ERR_FUEL, site, Some(first));
            let spent = self.iconst_here(types::I64, -1);
            self.b.def_var(var, spent);
            self.b.ins().jump(exit, &[]);
        } else {
            self.defer_error_counted(ERR_FUEL, site, None, false);
            let spent = self.iconst_here(types::I64, -2 - i64::from(site.0));
            self.b.def_var(var, spent);
            let end = self.exit;
            self.jump_live(end);
        }
        self.b.switch_to_block(ok_blk);
        let less = self.b.ins().iadd_imm_s(fuel, -1);
        self.b.def_var(var, less);
    }

    pub(super) fn uniform_loop(
        &mut self,
        id: LoopId,
        cond: Option<ExprId>,
        body: &'a [StmtId],
        step: &'a [StmtId],
        site: SiteId,
    ) -> Res<()> {
        let header = self.b.create_block();
        let body_blk = self.b.create_block();
        let step_blk = self.b.create_block();
        let exit = self.b.create_block();
        if self.in_dead_block() {
            // Dead code: so is the whole loop (its jumps stay among dead blocks).
            self.dead_blocks.extend([header, body_blk, step_blk, exit]);
        }
        self.b.ins().jump(header, &[]);
        self.b.switch_to_block(header);
        if crate::ir::loop_repeats(self.stmt_nodes(), id, body) {
            self.spend_fuel(site, exit);
        }
        if let Some(c) = cond {
            let v = self.eval_uniform(c)?;
            let v = fixed::convert(&mut self.b, v.scalar, Scalar::Bool, v.comps[0]);
            let done = self.b.ins().icmp_imm_s(IntCC::Equal, v, 0);
            self.b.ins().brif(done, exit, &[], body_blk, &[]);
        } else {
            self.b.ins().jump(body_blk, &[]);
        }
        self.seal_now(body_blk);
        self.b.switch_to_block(body_blk);
        self.frame_mut().loops.push(LoopCtx {
            id: Some(id),
            varying: false,
            step: step_blk,
            exit,
            mask: None,
            cont: None,
        });
        let r = self.stmts(body);
        self.frame_mut().loops.pop();
        r?;
        // A body that always leaves by `break` or `return` (and never `continue`s) leaves
        // the step dead.
        if !self.jump_live(step_blk) && !self.live_targets.contains(&step_blk) {
            self.dead_blocks.insert(step_blk);
        }
        // The body's `continue`s are lowered: the step's predecessors are all known; after
        // the back edge, the header's; after the step (its `break`s, if any), the exit's.
        self.seal_now(step_blk);
        self.b.switch_to_block(step_blk);
        self.stmts(step)?;
        self.jump_live(header);
        self.seal_now(header);
        self.seal_now(exit);
        self.b.switch_to_block(exit);
        Ok(())
    }

    /// Seal `block` now: every jump to it has been emitted. Uniform code seals its blocks
    /// as soon as their predecessors are known (an `if`'s sides and join, a uniform loop's
    /// blocks, the fuel check's): a variable read in a sealed block is looked up through
    /// its predecessors at once, where an unsealed block got a speculative block parameter
    /// per variable read in it, each resolved (mostly into an alias) only when the function
    /// was sealed whole. In the NURB kernel's setup those were ~2700 block parameters,
    /// ~5800 jump arguments and ~6400 aliases, and a quarter of the frontend's time.
    pub(super) fn seal_now(&mut self, block: Block) {
        if self.sealed_early.insert(block) {
            self.b.seal_block(block);
        }
    }

    pub(super) fn varying_loop(
        &mut self,
        id: LoopId,
        cond: Option<ExprId>,
        body: &'a [StmtId],
        step: &'a [StmtId],
        site: SiteId,
    ) -> Res<()> {
        let entry = self.exec().expect("pixel context");
        let alive_var = self.pix.as_ref().expect("pixel context").alive;
        let mask = self.declare_var(I32X4);
        let cont = self.declare_var(I32X4);
        self.b.def_var(mask, entry);
        let none_mask = mask_const(&mut self.b, false);
        self.b.def_var(cont, none_mask);
        let header = self.b.create_block();
        let fuel_blk = self.b.create_block();
        let body_blk = self.b.create_block();
        let step_blk = self.b.create_block();
        let exit = self.b.create_block();
        self.b.ins().jump(header, &[]);

        self.b.switch_to_block(header);
        let lm = self.b.use_var(mask);
        let alive = self.b.use_var(alive_var);
        let lm = self.b.ins().band(lm, alive);
        self.b.def_var(mask, lm);
        let any = self.b.ins().vany_true(lm);
        let none = self.b.ins().icmp_imm_s(IntCC::Equal, any, 0);
        self.b.ins().brif(none, exit, &[], fuel_blk, &[]);

        self.b.switch_to_block(fuel_blk);
        if crate::ir::loop_repeats(self.stmt_nodes(), id, body) {
            self.spend_fuel(site, exit);
        }
        let none_mask = mask_const(&mut self.b, false);
        self.b.def_var(cont, none_mask);
        self.set_exec(lm);
        self.depth_add(1);
        if let Some(c) = cond {
            let v = self.eval(c)?;
            let v = fixed::convert(&mut self.b, v.scalar, Scalar::Bool, v.comps[0]);
            let cm = splat(&mut self.b, Scalar::Bool, v);
            let lm2 = self.b.ins().band(lm, cm);
            self.b.def_var(mask, lm2);
            self.set_exec(lm2);
            let any = self.b.ins().vany_true(lm2);
            let none = self.b.ins().icmp_imm_s(IntCC::Equal, any, 0);
            self.b.ins().brif(none, exit, &[], body_blk, &[]);
        } else {
            self.b.ins().jump(body_blk, &[]);
        }
        self.b.switch_to_block(body_blk);
        self.frame_mut().loops.push(LoopCtx {
            id: Some(id),
            varying: true,
            step: step_blk,
            exit,
            mask: Some(mask),
            cont: Some(cont),
        });
        self.vloops.push((mask, cont));
        let r = self.stmts(body);
        self.b.ins().jump(step_blk, &[]);
        self.b.switch_to_block(step_blk);
        // Continued lanes come back for the step; broken and retired ones do not.
        let lm = self.b.use_var(mask);
        let alive = self.b.use_var(alive_var);
        let ex = self.b.ins().band(lm, alive);
        self.set_exec(ex);
        let none_mask = mask_const(&mut self.b, false);
        self.b.def_var(cont, none_mask);
        let r2 = r.and_then(|_| self.stmts(step));
        self.vloops.pop();
        self.frame_mut().loops.pop();
        self.depth_add(-1);
        r2?;
        self.b.ins().jump(header, &[]);
        self.b.switch_to_block(exit);
        self.restore_exec(entry);
        Ok(())
    }

    pub(super) fn break_continue(&mut self, id: LoopId, is_break: bool) -> Res<()> {
        let frame = self.frame();
        let Some(pos) = frame.loops.iter().rposition(|l| l.id == Some(id)) else {
            return err(format!("break/continue of loop {} outside it", id.0));
        };
        let target = &frame.loops[pos];
        let inner: Vec<(Option<Variable>, Option<Variable>)> =
            frame.loops[pos..].iter().map(|l| (l.mask, l.cont)).collect();
        if !target.varying {
            let dest = if is_break { target.exit } else { target.step };
            self.jump_live(dest);
            self.continue_unreachable();
            return Ok(());
        }
        let exec = self.exec().expect("varying loop in pixel context");
        for (k, (mask, cont)) in inner.into_iter().enumerate() {
            let outermost = k == 0;
            if outermost && !is_break {
                if let Some(c) = cont {
                    let old = self.b.use_var(c);
                    let new = self.b.ins().bor(old, exec);
                    self.b.def_var(c, new);
                }
            } else if let Some(m) = mask {
                let old = self.b.use_var(m);
                let new = self.b.ins().band_not(old, exec);
                self.b.def_var(m, new);
            }
        }
        let none = mask_const(&mut self.b, false);
        self.set_exec(none);
        Ok(())
    }

    /// Ends the inlined interpolator for the executing lanes (its `return`).
    pub(super) fn leave_interpolator(&mut self) -> Res<()> {
        let exec = self.exec().expect("interpolators run in pixel context");
        let masks: Vec<Option<Variable>> = self.frame().loops.iter().map(|l| l.mask).collect();
        for m in masks.into_iter().flatten() {
            let old = self.b.use_var(m);
            let new = self.b.ins().band_not(old, exec);
            self.b.def_var(m, new);
        }
        let none = mask_const(&mut self.b, false);
        self.set_exec(none);
        Ok(())
    }

    pub(super) fn lower_return(&mut self) -> Res<()> {
        if self.frame().interp_binding.is_some() {
            return self.leave_interpolator();
        }
        let Some(p) = &self.pix else {
            // Setup: the primitive ends.
            self.jump_live(self.exit);
            self.continue_unreachable();
            return Ok(());
        };
        let (alive_var, group_end, depth) = (p.alive, p.group_end, p.varying_depth);
        if depth == 0 {
            // Uniform control flow: every lane of the group retires.
            self.b.ins().jump(group_end, &[]);
            self.continue_unreachable();
            return Ok(());
        }
        let exec = self.exec().expect("pixel context");
        let alive = self.b.use_var(alive_var);
        let alive = self.b.ins().band_not(alive, exec);
        self.b.def_var(alive_var, alive);
        let none = mask_const(&mut self.b, false);
        self.set_exec(none);
        // Flat pixel code goes on with no lane left (see [`crate::mid::flat`]).
        if self.flat {
            return Ok(());
        }
        let any = self.b.ins().vany_true(alive);
        let all_gone = self.b.ins().icmp_imm_s(IntCC::Equal, any, 0);
        let cont = self.b.create_block();
        self.b.ins().brif(all_gone, group_end, &[], cont, &[]);
        self.b.switch_to_block(cont);
        Ok(())
    }
}
