//! The uniform frame: a stack slot holding what the pixel loops read of the setup.
//!
//! Before the pixel loops, uniform locals move to the frame ([`Lower::spill_uniforms`]):
//! a uniform local the pixel code reads but never assigns is stored once and read-only
//! from then on (`Storage::Frame`); one the pixel code assigns gets a slot of its own that
//! every group starts by resetting from the setup's final value (`group_resets`). The frame
//! also holds, per word, a splatted f32x4/i32x4 copy (its *vector section*), the render
//! pass's X range as splats, the results of uniform terms evaluated once per run
//! ([`Lower::run_hoists`]) and the *row section* the row prologue fills with the pixel
//! terms that depend on Y alone ([`crate::mid::hoist`]; read back by [`Lower::hoisted`]).
//! Which local goes where, and every offset, is the plan's ([`crate::mid::spill`]); this
//! module stores and reads.
//!
//! Invariants: the pixel loops read setup values only through the frame, other stack slots
//! and the pass rectangle (which is what lets tier 0 put them in a function of their own,
//! [`super::outline`]); a splat no group reads is removed once the pixel code is lowered
//! ([`Lower::drop_unread_splats`]); in tier 1 a frame word only one side of the first
//! unswitched condition reads is stored by that side's dispatch block
//! ([`Lower::store_deferred_frame`]).

use cranelift_codegen::ir::{self, InstBuilder, StackSlot, StackSlotData, StackSlotKind};
use cranelift_frontend::Variable;

use super::{elem_scalar, err, DeferredStore, Lower, Res, Storage};
use crate::ir::{Elem, ExprId, Function, LocalId, ParamRole, Scalar};
use crate::jit::fixed;
use crate::jit::value::{args_flags, cl_type, mem_flags, splat, Val};

impl<'a, 'b> Lower<'a, 'b> {
    /// Move the primitive's uniform register locals into stack memory before the pixel
    /// loops; the pixel code then loads each where it uses it.
    ///
    /// Why: kept in SSA registers, every setup result (edge and plane coefficients: ~50 for
    /// four perspective parameters) is live across every block of the pixel loops. That is
    /// more than the 16 xmm registers, so they spill anyway, and regalloc2's live-range
    /// splitting over ~150 blocks was 75% of the compile time (10 of 14 ms per variant).
    ///
    /// Locals the pixel part never assigns go to one *uniform frame*, read in pixel code
    /// through a base pointer loaded once per group (`PixelState::frame_base`): those reads
    /// are pure (readonly, can_move), so Cranelift places each load next to its use, folds it
    /// into `vbroadcastss mem` and merges repeats, but cannot hoist them out of the group
    /// loop (their address is defined in it). Locals the pixel part assigns get a stack
    /// slot of their own with ordinary loads and stores.
    pub(super) fn spill_uniforms(&mut self, f: &'a Function) -> Res<()> {
        let pix = self.pixel_plan()?;
        let layout = &pix.frame;
        // The locals that move, with their variables (the plan's words in the frame, or
        // `None` for a slot of their own).
        let mut placed = vec![];
        for &(i, at) in &layout.placed {
            let Some(Storage::Vars(vars)) = self.frames[0].storage.get(i) else {
                return err("a spilled local is not in SSA variables");
            };
            let vars = vars.clone();
            if let Some(at) = at {
                self.frames[0].storage[i] = Storage::Frame(at);
            }
            placed.push((i, vars, at));
        }
        let pixel_assigned = |i: usize| pix.assigned.contains(&LocalId(i as u32));
        let deferred = layout.deferred.as_ref().map(|(_, sides)| sides);
        if let Some((cond, _)) = &layout.deferred {
            self.deferred_frame = Some((*cond, vec![]));
        }
        self.vec_section = layout.vec_section;
        // Last in the frame, the render pass's x range as two splats (see `pixel_group`).
        self.x_range_at = layout.x_range_at;
        let frame_bytes = layout.bytes;
        let frame_slot =
            self.b
                .create_sized_stack_slot(StackSlotData::new(StackSlotKind::ExplicitSlot, frame_bytes, 4));
        // One frame address for all the stores below (they are consecutive, so it is live
        // only across them): a `stack_addr` per local was 36 of K=4's CLIF instructions.
        let frame_addr = placed
            .iter()
            .any(|(_, _, at)| at.is_some())
            .then(|| self.slot_addr(frame_slot));
        let mut deferred_stores = vec![];
        for (i, vars, at) in placed {
            let sc = elem_scalar(&f.locals[i].ty);
            if let (Some(&on), Some(first_word)) = (deferred.and_then(|d| d.get(&i)), at) {
                deferred_stores.push(DeferredStore {
                    on,
                    vars,
                    first_word,
                    scalar: sc,
                });
                continue;
            }
            match (at, frame_addr) {
                (Some(first), Some(addr)) => {
                    self.store_frame_words(addr, &vars, first, sc);
                }
                _ => {
                    let slot = self.b.create_sized_stack_slot(StackSlotData::new(
                        StackSlotKind::ExplicitSlot,
                        4 * vars.len() as u32,
                        2,
                    ));
                    let addr = self.slot_addr(slot);
                    for (c, v) in vars.iter().enumerate() {
                        let x = self.b.use_var(*v);
                        self.b.ins().store(mem_flags(), x, addr, (4 * c) as i32);
                    }
                    self.frames[0].storage[i] = Storage::Stack(slot);
                }
            }
        }
        // Per-pixel semantics: every pixel runs the pixel part from the setup's final state.
        // A uniform local the pixel part assigns (a loop counter, say) would otherwise
        // carry one group's last value into the next group, so its setup value is kept
        // aside here and every group starts from it (`reset_group_locals`).
        for (i, st) in self.frames[0].storage.iter().enumerate() {
            let Storage::Stack(slot) = *st else { continue };
            if f.locals[i].var.is_varying() || !pixel_assigned(i) {
                continue;
            }
            let bytes = self.b.func.sized_stack_slots[slot].size;
            self.group_resets.push((slot, slot, bytes));
        }
        for r in 0..self.group_resets.len() {
            let (work, _, bytes) = self.group_resets[r];
            let init = self
                .b
                .create_sized_stack_slot(StackSlotData::new(StackSlotKind::ExplicitSlot, bytes, 4));
            self.copy_slot(work, init, bytes);
            self.group_resets[r] = (init, work, bytes);
        }
        if let Some((cond, _)) = self.deferred_frame {
            self.deferred_frame = Some((cond, deferred_stores));
        }
        // The frame's address, reloaded per group through this slot (see above).
        let ptr_slot = self
            .b
            .create_sized_stack_slot(StackSlotData::new(StackSlotKind::ExplicitSlot, 8, 3));
        let addr = self.slot_addr(frame_slot);
        let pa = self.slot_addr(ptr_slot);
        self.b.ins().store(mem_flags(), addr, pa, 0);
        self.uniform_frame = Some((frame_slot, ptr_slot));
        Ok(())
    }

    /// Row prologue: evaluate the hoisted terms for row centre `y_f` into the frame's row
    /// section (see [`crate::mid::hoist`]), with the operations the group code would use.
    /// `only`: the expressions the loop's variant lowers (a pass span's; `None`: all).
    pub(super) fn row_hoists(
        &mut self,
        f: &'a Function,
        y_f: ir::Value,
        only: Option<&std::collections::HashSet<ExprId>>,
    ) -> Res<()> {
        let (Some((fs, _)), false) = (self.uniform_frame, self.hoists().is_empty()) else {
            return Ok(());
        };
        if let Some(p) = f.param_by_role(ParamRole::Y) {
            let i = p.local.0 as usize;
            if let (Storage::Vars(vs), Elem::Scalar(sc)) = (&self.frames[0].storage[i], f.local(p.local).ty.elem) {
                let var = vs[0];
                let v = fixed::convert(&mut self.b, Scalar::Float, sc, y_f);
                self.b.def_var(var, v);
            }
        }
        // A row term's uniform operations hoisted once per run (`int(oy * 16)` in
        // `int(Y * 16) - int(oy * 16)`) are read back from the frame, not recomputed per row.
        let addr = self.slot_addr(fs);
        self.prologue_frame = Some((addr, false));
        self.row_local_values.clear();
        let mut stored = Ok(());
        let unstored = &self.pixel_plan()?.unstored_terms;
        for k in 0..self.hoists().len() {
            let h = &self.hoists()[k];
            let id = h.expr;
            let skip = h.per_run || only.is_some_and(|set| !set.contains(&id)) || unstored.contains(&id);
            if !skip {
                stored = self.store_hoist(fs, k);
                if stored.is_err() {
                    break;
                }
            }
        }
        self.prologue_frame = None;
        self.row_local_values.clear();
        stored
    }

    /// Once per kernel run, after setup (render mode): the hoisted uniform operations
    /// (`Hoist::per_run`; pure, so evaluating one a pass does not use changes nothing).
    pub(super) fn run_hoists(&mut self) -> Res<()> {
        let Some((fs, _)) = self.uniform_frame else {
            return Ok(());
        };
        for k in 0..self.hoists().len() {
            if self.hoists()[k].per_run {
                self.store_hoist(fs, k)?;
            }
        }
        Ok(())
    }

    /// Evaluate hoist `k` and store its splatted components in the row section of the
    /// uniform frame `fs`.
    pub(super) fn store_hoist(&mut self, fs: StackSlot, k: usize) -> Res<()> {
        let (expr, view, offset, comps) = {
            let h = &self.hoists()[k];
            (h.expr, h.view.clone(), h.offset, h.comps)
        };
        let saved = std::mem::replace(&mut self.view, view);
        self.substitute_row_locals = true;
        let v = self.eval(expr);
        self.substitute_row_locals = false;
        self.view = saved;
        let v = v?;
        if v.comps.len() != comps as usize {
            return err("hoisted row term has an unexpected number of components");
        }
        let addr = self.slot_addr(fs);
        for (c, &x) in v.comps.iter().enumerate() {
            let x = splat(&mut self.b, v.scalar, x);
            self.b
                .ins()
                .store(mem_flags(), x, addr, (offset + 16 * c as u32) as i32);
        }
        Ok(())
    }

    /// In a group: the value of a hoisted row term, read from the frame's row section.
    /// Also in a pixel loop's prologue while carried terms are evaluated (`prologue_frame`).
    pub(super) fn hoisted(&mut self, e: ExprId) -> Option<Val> {
        let (base, rows_ready) = match (&self.pix, self.prologue_frame) {
            (Some(p), _) => (p.frame_base?, true),
            (None, Some(pf)) => pf,
            (None, None) => return None,
        };
        if self.frames.len() != 1 {
            return None;
        }
        let h = self
            .hoists()
            .iter()
            .find(|h| h.expr == e && h.view == self.view && (rows_ready || h.per_run))?;
        let (offset, comps, scalar) = (h.offset, h.comps, h.scalar);
        let ty = cl_type(scalar, true);
        let comps = (0..comps)
            .map(|c| self.b.ins().load(ty, args_flags(), base, (offset + 16 * c) as i32))
            .collect();
        Some(Val {
            comps,
            scalar,
            varying: true,
        })
    }

    /// In the dispatch block of side `on` of the condition `cond` (`unswitched_loops`): the
    /// frame stores `defer_frame_stores` left for that side, splats included.
    pub(in crate::jit) fn store_deferred_frame(&mut self, cond: ExprId, on: bool) {
        let Some((key, locals)) = self.deferred_frame.take() else {
            return;
        };
        if key == cond {
            if let Some((fs, _)) = self.uniform_frame {
                let addr = self.slot_addr(fs);
                for d in locals.iter().filter(|d| d.on == on) {
                    self.store_frame_words(addr, &d.vars, d.first_word, d.scalar);
                }
            }
        }
        self.deferred_frame = Some((key, locals));
    }

    /// Store a frame local's variables `vars` to its words from `first` in the uniform
    /// frame at `addr`, and (tier 1, not bool) each word's splat to the vector section,
    /// recorded for `drop_unread_splats`. Tier 0 stores no splatted copy: a group splats
    /// the word it reads itself (one instruction per use instead of two stores per uniform
    /// here, which is less code for the tier that runs one frame).
    pub(super) fn store_frame_words(&mut self, addr: ir::Value, vars: &[Variable], first: u32, sc: Scalar) {
        for (c, v) in vars.iter().enumerate() {
            let x = self.b.use_var(*v);
            let w = first + c as u32;
            self.b.ins().store(mem_flags(), x, addr, (4 * w) as i32);
            if sc != Scalar::Bool && !self.tier0() {
                let xv = splat(&mut self.b, sc, x);
                let off = self.vec_section + 16 * w;
                let st = self.b.ins().store(mem_flags(), xv, addr, off as i32);
                self.splat_stores.push((off, st));
            }
        }
    }

    /// Remove the setup's splat stores no group loads from (most words are read only by
    /// row terms, carried terms or other setup code, as scalars). The splats they stored
    /// are then dead, and Cranelift drops them: for screen_triangle with four perspective
    /// parameters ~45 of 57 splats, three instructions each per render call.
    pub(super) fn drop_unread_splats(&mut self) {
        for (off, st) in std::mem::take(&mut self.splat_stores) {
            if !self.splats_read.contains(&off) {
                self.b.func.layout.remove_inst(st);
            }
        }
    }

    /// Broadcast uniform component `c` of scalar type `sc`: a frame word read in this group
    /// loads its splat from the vector section, anything else is splatted here.
    pub(super) fn splat_of(&mut self, sc: Scalar, c: ir::Value) -> ir::Value {
        if self.b.func.dfg.value_type(c).is_vector() {
            return c;
        }
        if let (Some(&off), Some(base)) = (self.splat_src.get(&c), self.pix.as_ref().and_then(|p| p.frame_base)) {
            self.splats_read.insert(off);
            return self.b.ins().load(cl_type(sc, true), args_flags(), base, off as i32);
        }
        splat(&mut self.b, sc, c)
    }

    pub(crate) fn make_varying(&mut self, v: Val) -> Val {
        if v.varying {
            return v;
        }
        let comps = v.comps.iter().map(|&c| self.splat_of(v.scalar, c)).collect();
        Val {
            comps,
            scalar: v.scalar,
            varying: true,
        }
    }
}
