//! Statements, the lane masks they run under, fuel, interpolation and primitive calls, as
//! `jit::lower`'s `stmt`, `planes` and `call` lower them (tier 1's control structure).
//!
//! G-buffer stores round the run's floats to f32: the planes are f32 in both precisions.
//!
//! Invariants: setup code runs for all four lanes; pixel code for `exec`, a subset of the
//! group's `alive` lanes. A varying `if` runs each side no lane skips under its mask; a
//! varying loop keeps a mask (and a continue mask) in [`super::LoopCtx`] and runs while it
//! has a live lane; `break`, `continue` and `return` remove lanes, and a group ends when none
//! is alive. Uniform loops and setup `return`s jump ([`Flow`]). Every loop head spends one
//! unit of fuel: the setup's, or in pixel code the group's.

use std::rc::Rc;

use super::args::ArgBlock;
use super::expr::{elem_scalar, Val};
use super::scalar::convert_lane;
use super::{and, any, malformed, Event, Flow, Lanes, LoopCtx, Machine, Mask, Res, NONE};
use crate::abi::{
    interpolator_arg_words, type_words, ArgLayout, BindingKind, ParamSlot, ERR_CALL_DEPTH, ERR_FUEL, MAX_CALL_DEPTH,
};
use crate::ir::{ExprId, FuncId, FuncKind, InterpArm, LoopId, ParamRole, Scalar, SiteId, StmtId, StmtKind};
use crate::mid::view;

impl<'p> Machine<'p, '_> {
    pub(crate) fn stmts(&mut self, stmts: &'p [StmtId]) -> Res<Flow> {
        for &s in stmts {
            self.enter()?;
            let flow = self.stmt(s);
            self.leave();
            match flow? {
                Flow::Normal => {}
                other => return Ok(other),
            }
        }
        Ok(Flow::Normal)
    }

    fn stmt(&mut self, s: StmtId) -> Res<Flow> {
        if self.watched_lane().is_some() {
            let func = self.frame()?.func;
            self.notify(Event::Stmt { func, stmt: s });
        }
        match &self.stmt_nodes()[s] {
            StmtKind::Assign { place, value } => {
                self.assign(place, *value)?;
                Ok(Flow::Normal)
            }
            StmtKind::If { cond, then, otherwise } => self.if_(*cond, then, otherwise),
            StmtKind::Loop {
                id,
                cond,
                body,
                step,
                varying,
                site,
            } => {
                if *varying && self.pix.is_some() {
                    self.varying_loop(*id, *cond, body, step, *site)
                } else {
                    self.uniform_loop(*id, *cond, body, step, *site)
                }
            }
            StmtKind::Break(id) => self.break_continue(*id, true),
            StmtKind::Continue(id) => self.break_continue(*id, false),
            StmtKind::Return => {
                let func = self.frame()?.func;
                if func.kind == FuncKind::Primitive && self.watched_lane().is_some() {
                    self.notify(Event::Return { func, stmt: s });
                }
                self.return_()
            }
            StmtKind::Interpolation { arms } => self.interpolation(arms),
            StmtKind::InterpolatorReturn(e) => self.interpolator_return(*e),
            StmtKind::Bound(es) => {
                if self.pix.is_some() || self.frames.len() != self.kernel()?.frame + 1 {
                    return malformed("`bound` in per-pixel code");
                }
                // Lane words of the run's precision (0 is 0.0 in both).
                let mut r = [0u64; 4];
                for (i, e) in es.iter().enumerate() {
                    let v = self.eval(*e)?.converted(Scalar::Float, self.precision);
                    let Some(c) = v.comps.first() else {
                        return malformed("a bound without components");
                    };
                    match r.get_mut(i) {
                        Some(slot) => *slot = c[0],
                        None => return malformed("a bound of more than 4 values"),
                    }
                }
                if let Some(k) = self.kernels.last_mut() {
                    k.bound = Some(r);
                }
                Ok(Flow::Normal)
            }
            StmtKind::CallPrimitive { callee, args, site } => {
                if self.pix.is_some() || self.frames.len() != self.kernel()?.frame + 1 {
                    return malformed("primitive call in per-pixel code");
                }
                self.call(*callee, args, *site)
            }
        }
    }

    fn pix_mut(&mut self) -> Res<&mut super::Pix> {
        match &mut self.pix {
            Some(p) => Ok(p),
            None => malformed("varying control flow outside per-pixel code"),
        }
    }

    fn if_(&mut self, cond_id: ExprId, then: &'p [StmtId], otherwise: &'p [StmtId]) -> Res<Flow> {
        let cond = &self.exprs()[cond_id];
        let c = self.eval(cond_id)?;
        let p = self.precision;
        let Some(c) = c
            .comps
            .first()
            .map(|w| w.map(|x| convert_lane(p, c.sc, Scalar::Bool, x)))
        else {
            return malformed("a condition without components");
        };
        if let Some(l) = self.watched_lane() {
            let taken = c[if cond.var.is_varying() { l } else { 0 }] != 0;
            self.notify(Event::Branch { taken });
        }
        if !cond.var.is_varying() || self.pix.is_none() {
            // Uniform: every lane holds the same value.
            return self.stmts(if c[0] != 0 { then } else { otherwise });
        }
        let entry = self.exec;
        let then_mask: Mask = std::array::from_fn(|l| entry[l] && c[l] != 0);
        let else_mask: Mask = std::array::from_fn(|l| entry[l] && c[l] == 0);
        self.pix_mut()?.depth += 1;
        let mut then_out = then_mask;
        if any(then_mask) {
            self.exec = then_mask;
            let flow = self.stmts(then)?;
            if flow != Flow::Normal {
                return Ok(flow);
            }
            then_out = self.exec;
        }
        let mut else_out = else_mask;
        if !otherwise.is_empty() && any(else_mask) {
            self.exec = else_mask;
            let flow = self.stmts(otherwise)?;
            if flow != Flow::Normal {
                return Ok(flow);
            }
            else_out = self.exec;
        }
        self.pix_mut()?.depth -= 1;
        self.exec = std::array::from_fn(|l| then_out[l] || else_out[l]);
        Ok(Flow::Normal)
    }

    /// Spend one unit of fuel at a loop head: false when there was none (pixel code: the
    /// group's fuel, `ERR_FUEL` counted the first time; setup: the run ends).
    fn spend_fuel(&mut self, site: SiteId) -> Res<bool> {
        let watched_group = match (&self.watch, &self.pix) {
            (Some(w), Some(p)) => self.lane_of(w, p).is_some(),
            _ => false,
        };
        if let Some(p) = &mut self.pix {
            if p.fuel <= 0 {
                let first = p.fuel == 0;
                p.fuel = -1;
                if first {
                    self.record(ERR_FUEL, site.0, true)?;
                    if watched_group {
                        self.notify(Event::FuelOut { site, setup: false });
                    }
                }
                return Ok(false);
            }
            p.fuel -= 1;
            return Ok(true);
        }
        if self.fuel <= 0 {
            self.record(ERR_FUEL, site.0, false)?;
            self.notify(Event::FuelOut { site, setup: true });
            self.fuel = -2 - i64::from(site.0);
            return Ok(false);
        }
        self.fuel -= 1;
        Ok(true)
    }

    fn uniform_loop(
        &mut self,
        id: LoopId,
        cond: Option<ExprId>,
        body: &'p [StmtId],
        step: &'p [StmtId],
        site: SiteId,
    ) -> Res<Flow> {
        let frame = self.frames.len() - 1;
        let repeats = crate::ir::loop_repeats(self.stmt_nodes(), id, body);
        loop {
            if repeats && !self.spend_fuel(site)? {
                return Ok(if self.pix.is_some() {
                    Flow::Normal
                } else {
                    Flow::FuelOut
                });
            }
            if let Some(c) = cond {
                let v = self.eval(c)?;
                let Some(w) = v.comps.first() else {
                    return malformed("a loop condition without components");
                };
                if convert_lane(self.precision, v.sc, Scalar::Bool, w[0]) == 0 {
                    return Ok(Flow::Normal);
                }
            }
            self.loops.push(LoopCtx {
                frame,
                id: Some(id),
                mask: None,
                cont: NONE,
            });
            let flow = self.stmts(body);
            self.loops.pop();
            match flow? {
                Flow::Normal => {}
                Flow::Continue(l) if l == id => {}
                Flow::Break(l) if l == id => return Ok(Flow::Normal),
                other => return Ok(other),
            }
            // The step runs outside the loop's own context, as the JIT lowers it.
            match self.stmts(step)? {
                Flow::Normal => {}
                other => return Ok(other),
            }
        }
    }

    fn varying_loop(
        &mut self,
        id: LoopId,
        cond: Option<ExprId>,
        body: &'p [StmtId],
        step: &'p [StmtId],
        site: SiteId,
    ) -> Res<Flow> {
        let entry = self.exec;
        let frame = self.frames.len() - 1;
        self.loops.push(LoopCtx {
            frame,
            id: Some(id),
            mask: Some(entry),
            cont: NONE,
        });
        let li = self.loops.len() - 1;
        self.pix_mut()?.depth += 1;
        let flow = self.varying_trips(li, cond, body, step, site);
        self.loops.truncate(li);
        let flow = flow?;
        if flow != Flow::Normal {
            return Ok(flow);
        }
        self.pix_mut()?.depth -= 1;
        self.restore_exec(entry)?;
        Ok(Flow::Normal)
    }

    fn varying_trips(
        &mut self,
        li: usize,
        cond: Option<ExprId>,
        body: &'p [StmtId],
        step: &'p [StmtId],
        site: SiteId,
    ) -> Res<Flow> {
        let repeats = self.loops[li]
            .id
            .is_none_or(|id| crate::ir::loop_repeats(self.stmt_nodes(), id, body));
        loop {
            let alive = self.pix_mut()?.alive;
            let mask = and(self.loops[li].mask.unwrap_or(NONE), alive);
            self.loops[li].mask = Some(mask);
            if !any(mask) || (repeats && !self.spend_fuel(site)?) {
                return Ok(Flow::Normal);
            }
            self.loops[li].cont = NONE;
            self.exec = mask;
            if let Some(c) = cond {
                let v = self.eval(c)?;
                let Some(w) = v.comps.first() else {
                    return malformed("a loop condition without components");
                };
                let p = self.precision;
                let taken: Mask = std::array::from_fn(|l| mask[l] && convert_lane(p, v.sc, Scalar::Bool, w[l]) != 0);
                self.loops[li].mask = Some(taken);
                self.exec = taken;
                if !any(taken) {
                    return Ok(Flow::Normal);
                }
            }
            match self.stmts(body)? {
                Flow::Normal => {}
                other => return Ok(other),
            }
            // Continued lanes come back for the step; broken and retired ones do not.
            let alive = self.pix_mut()?.alive;
            self.exec = and(self.loops[li].mask.unwrap_or(NONE), alive);
            self.loops[li].cont = NONE;
            match self.stmts(step)? {
                Flow::Normal => {}
                other => return Ok(other),
            }
        }
    }

    /// `exec` after leaving a construct entered with `entry`: the entry lanes still alive
    /// that have not left an enclosing varying loop.
    fn restore_exec(&mut self, entry: Mask) -> Res<()> {
        let alive = self.pix_mut()?.alive;
        let mut m = and(entry, alive);
        for lp in &self.loops {
            if let Some(mask) = lp.mask {
                m = std::array::from_fn(|l| m[l] && mask[l] && !lp.cont[l]);
            }
        }
        self.exec = m;
        Ok(())
    }

    fn break_continue(&mut self, id: LoopId, is_break: bool) -> Res<Flow> {
        let frame = self.frames.len() - 1;
        let Some(pos) = self.loops.iter().rposition(|l| l.frame == frame && l.id == Some(id)) else {
            return malformed(format!("break/continue of loop {} outside it", id.0));
        };
        if self.loops[pos].mask.is_none() {
            return Ok(if is_break { Flow::Break(id) } else { Flow::Continue(id) });
        }
        let exec = self.exec;
        for (k, lp) in self.loops[pos..].iter_mut().enumerate() {
            if k == 0 && !is_break {
                lp.cont = std::array::from_fn(|l| lp.cont[l] || exec[l]);
            } else if let Some(m) = &mut lp.mask {
                *m = std::array::from_fn(|l| m[l] && !exec[l]);
            }
        }
        self.exec = NONE;
        Ok(Flow::Normal)
    }

    /// The end of an inlined interpolator for the executing lanes (its `return`).
    fn leave_interpolator(&mut self) -> Flow {
        let frame = self.frames.len() - 1;
        let exec = self.exec;
        for lp in self.loops.iter_mut().filter(|l| l.frame == frame) {
            if let Some(m) = &mut lp.mask {
                *m = std::array::from_fn(|l| m[l] && !exec[l]);
            }
        }
        self.exec = NONE;
        Flow::Normal
    }

    fn return_(&mut self) -> Res<Flow> {
        if self.frame()?.interp_binding.is_some() {
            return Ok(self.leave_interpolator());
        }
        let exec = self.exec;
        let Some(p) = &mut self.pix else {
            return Ok(Flow::Return);
        };
        p.alive = std::array::from_fn(|l| p.alive[l] && !exec[l]);
        let gone = p.depth == 0 || !any(p.alive);
        self.exec = NONE;
        Ok(if gone { Flow::GroupEnd } else { Flow::Normal })
    }

    fn interpolation(&mut self, arms: &'p [InterpArm]) -> Res<Flow> {
        let named = view::named_kinds(arms);
        for arm in arms {
            let Some((v, bindings)) = view::arm_view(self.key, &named, arm) else {
                continue;
            };
            let saved_view = std::mem::replace(&mut self.view, v);
            let saved_arm = self.arm.replace(bindings);
            let flow = self.stmts(&arm.body);
            self.view = saved_view;
            self.arm = saved_arm;
            match flow? {
                Flow::Normal => {}
                other => return Ok(other),
            }
        }
        Ok(Flow::Normal)
    }

    /// `(global component, float value)` stores into the G-buffer for the executing lanes,
    /// rounded to f32; a plane the tile lacks is not written.
    fn store_planes(&mut self, stores: &[(u32, Lanes)]) -> Res<()> {
        let (gx, y) = match &self.pix {
            Some(p) => (p.gx, p.y),
            None => return malformed("G-buffer store outside per-pixel code"),
        };
        let k = self.kernel()?;
        let table = k.layout.plane_table as usize;
        let args = self.frames[k.frame].args.clone();
        let watched = self.watched_lane();
        for &(g, v) in stores {
            let Some(plane) = args.word(table + g as usize) else {
                return malformed("plane table past the argument block");
            };
            if plane as usize >= self.tile.num_planes {
                continue;
            }
            let exec = self.exec;
            for (l, &on) in exec.iter().enumerate() {
                if !on {
                    continue;
                }
                let Some(i) = self.tile.index(gx + l as i32, y) else {
                    return malformed("an executing lane outside the tile");
                };
                let value = self.precision.to_f32(v[l]);
                self.tile.planes[plane as usize * self.tile.plane_stride + i] = value;
                if watched == Some(l) {
                    self.notify(Event::Plane { plane, value });
                }
            }
        }
        Ok(())
    }

    /// The first global component of binding `bi`.
    fn global_offset(&self, bi: usize) -> u32 {
        self.key.bindings[..bi].iter().map(|b| b.components).sum()
    }

    fn interpolator_return(&mut self, e: Option<ExprId>) -> Res<Flow> {
        if self.pix.is_none() {
            return malformed("`interpolator_return` outside per-pixel code");
        }
        if let Some(bi) = self.frame()?.interp_binding {
            if let Some(e) = e {
                let v = self.eval(e)?.converted(Scalar::Float, self.precision);
                let comps = self.key.bindings[bi].components as usize;
                let g0 = self.global_offset(bi);
                if v.comps.len() == 1 || v.comps.len() == comps {
                    let batch: Vec<(u32, Lanes)> = (0..comps)
                        .map(|c| (g0 + c as u32, v.comps[if v.comps.len() == 1 { 0 } else { c }]))
                        .collect();
                    self.store_planes(&batch)?;
                }
            }
            return Ok(self.leave_interpolator());
        }
        match e {
            Some(e) => self.store_kind_bindings(e)?,
            None => self.run_shared_and_constants()?,
        }
        Ok(Flow::Normal)
    }

    /// `interpolator_return(e)` of a primitive: `e` into the parameters of the arm's kinds
    /// (outside an arm, of every kind); a binding whose components `e` does not match is
    /// not written (the JIT warns).
    fn store_kind_bindings(&mut self, e_id: ExprId) -> Res<()> {
        let e = &self.exprs()[e_id];
        let is_interp = e.ty.elem == crate::ir::Elem::Interp && e.ty.dims.is_empty();
        let v: Val = self.eval(e_id)?.converted(Scalar::Float, self.precision);
        let mut offsets = vec![];
        let (mut ic, mut gc) = (0u32, 0u32);
        for (i, b) in self.key.bindings.iter().enumerate() {
            if matches!(b.kind, BindingKind::Kind(_)) {
                offsets.push((i, ic, gc));
                ic += b.components;
            }
            gc += b.components;
        }
        let bindings: Vec<usize> = match &self.arm {
            Some(a) => a.clone(),
            None => offsets.iter().map(|o| o.0).collect(),
        };
        let mut batch = vec![];
        for bi in bindings {
            let Some(&(_, ic, gc)) = offsets.iter().find(|o| o.0 == bi) else {
                continue;
            };
            let comps = self.key.bindings[bi].components;
            let vals: Option<Vec<Lanes>> = (0..comps)
                .map(|c| {
                    if is_interp {
                        self.view
                            .iter()
                            .position(|&k| k == ic + c)
                            .and_then(|p| v.comps.get(p).copied())
                    } else if v.comps.len() == 1 && e.ty.dims.is_empty() {
                        Some(v.comps[0])
                    } else if v.comps.len() == comps as usize && e.ty.elem != crate::ir::Elem::Interp {
                        Some(v.comps[c as usize])
                    } else {
                        None
                    }
                })
                .collect();
            if let Some(vals) = vals {
                batch.extend(vals.into_iter().enumerate().map(|(c, x)| (gc + c as u32, x)));
            }
        }
        self.store_planes(&batch)
    }

    /// `interpolator_return;`: the constants and shared interpolators of the key.
    fn run_shared_and_constants(&mut self) -> Res<()> {
        let key = self.key;
        for (bi, b) in key.bindings.iter().enumerate() {
            match &b.kind {
                BindingKind::Kind(_) => {}
                BindingKind::Constant => {
                    let k = self.kernel()?;
                    let Some(Some(data)) = k.layout.binding_data.get(bi).copied() else {
                        continue;
                    };
                    let args = self.frames[k.frame].args.clone();
                    let g0 = self.global_offset(bi);
                    for c in 0..b.components {
                        let Some(w) = args.float((data + c) as usize, self.precision) else {
                            return malformed("constant binding past the argument block");
                        };
                        self.store_planes(&[(g0 + c, [w; 4])])?;
                    }
                }
                BindingKind::Shared(name) => self.inline_interpolator(bi, name)?,
            }
        }
        Ok(())
    }

    /// Shared interpolator `name` for binding `bi`, for the executing lanes: its setup and
    /// pixel statements in a one-trip masked loop its `return` leaves.
    fn inline_interpolator(&mut self, bi: usize, name: &str) -> Res<()> {
        let program = self.program;
        let Some(id) = program.find(name) else {
            return Ok(());
        };
        let f = program.func(id);
        if f.kind != FuncKind::Interpolator {
            return Ok(());
        }
        if self.frames.iter().any(|fr| std::ptr::eq(fr.func, f)) {
            return malformed(format!("shared interpolator `{name}` inlined into itself"));
        }
        let k = self.kernel()?;
        let Some(Some(data)) = k.layout.binding_data.get(bi).copied() else {
            return malformed(format!("no argument words for shared interpolator `{name}`"));
        };
        let _ = interpolator_arg_words(program, id);
        let mut at = data;
        let mut slots = vec![];
        for p in &f.params {
            match p.role {
                ParamRole::X | ParamRole::Y | ParamRole::Z => slots.push(ParamSlot::Pixel),
                _ => {
                    let words = type_words(&f.local(p.local).ty, 0);
                    slots.push(ParamSlot::Fixed { offset: at, words });
                    at += words;
                }
            }
        }
        let kf = k.frame;
        let args = self.frames[kf].args.clone();
        let frame = self.new_frame(f, args, slots, at, Some(bi))?;
        let (x_f, y_f, z_raw) = match &self.pix {
            Some(p) => (p.x_f, p.y_f, p.z_raw),
            None => return malformed("a shared interpolator outside per-pixel code"),
        };
        let prim = self.frames[kf].func;
        let prim_z = prim.param_by_role(ParamRole::Z).map(|p| {
            let v = self.frames[kf].locals[p.local.0 as usize]
                .first()
                .copied()
                .unwrap_or([0; 4]);
            (v, elem_scalar(&prim.local(p.local).ty))
        });
        self.frames.push(frame);
        let fi = self.frames.len() - 1;
        let bound = self.bind_pixel_params(fi, x_f, y_f, z_raw, prim_z);
        let entry = self.exec;
        self.loops.push(LoopCtx {
            frame: fi,
            id: None,
            mask: Some(entry),
            cont: NONE,
        });
        let li = self.loops.len() - 1;
        let saved_view = std::mem::replace(&mut self.view, (0..self.n_interp).collect());
        let saved_depth = {
            let p = self.pix_mut()?;
            p.depth += 1;
            p.depth - 1
        };
        let flow = bound.and_then(|()| match self.stmts(&f.setup)? {
            Flow::Normal => self.stmts(&f.pixel),
            other => Ok(other),
        });
        self.view = saved_view;
        self.pix_mut()?.depth = saved_depth;
        self.loops.truncate(li);
        self.frames.pop();
        match flow? {
            Flow::Normal => {}
            other => return malformed(format!("shared interpolator `{name}` ended by {other:?}")),
        }
        self.restore_exec(entry)
    }

    /// A primitive call: the callee's argument block built as the JIT builds it, then a
    /// kernel run of the callee on the same tile, sharing the setup fuel.
    fn call(&mut self, callee: FuncId, args: &'p [ExprId], site: SiteId) -> Res<Flow> {
        let program = self.program;
        let Some(cf) = program.functions.get(callee.0 as usize) else {
            return malformed(format!("call of unknown function {}", callee.0));
        };
        if cf.kind != FuncKind::Primitive || args.len() != cf.params.len() {
            return malformed(format!("a call of `{}` that does not fit it", cf.name));
        }
        let layout = ArgLayout::new(program, callee, self.key);
        let mut n_seq = 1u32;
        for (i, slot) in layout.params.iter().enumerate() {
            if let ParamSlot::Seq { .. } = slot {
                let a = &self.exprs()[args[i]];
                if a.ty.per_seq || a.ty.dims.is_empty() {
                    return malformed("a per-sequence-point parameter given no fixed-size array");
                }
                n_seq = a.ty.dims[0];
                break;
            }
        }
        let words = layout.words(n_seq);
        if words > 1 << 26 {
            return Err(super::EvalError::Unsupported(
                "a call's argument block over 2^26 words".into(),
            ));
        }
        let mut block = ArgBlock::new(vec![0u32; words.max(1)]);
        block.set(0, n_seq);
        let key = self.key;
        let prefix_end = 1
            + key.total_components()
            + key
                .bindings
                .iter()
                .map(|b| match &b.kind {
                    BindingKind::Kind(_) => 0,
                    BindingKind::Constant => b.components,
                    BindingKind::Shared(n) => program
                        .find(n)
                        .map(|id| interpolator_arg_words(program, id))
                        .unwrap_or(0),
                })
                .sum::<u32>();
        let k = self.kernel()?;
        let caller_args = self.frames[k.frame].args.clone();
        let caller_spaces = k.layout.spaces;
        let copy = |block: &mut ArgBlock, from: usize, to: usize| -> Res<()> {
            if block.copy(&caller_args, from, to) {
                Ok(())
            } else {
                malformed("a call's argument block past its end")
            }
        };
        for w in 1..prefix_end as usize {
            copy(&mut block, w, w)?;
        }
        if let Some(dst) = layout.spaces {
            for w in 0..96usize {
                match caller_spaces {
                    Some(src) => copy(&mut block, src as usize + w, dst as usize + w)?,
                    None => {
                        let one = if (w % 16) % 5 == 0 { 1.0f32 } else { 0.0 };
                        block.set(dst as usize + w, one.to_bits());
                    }
                }
            }
        }
        for (i, pslot) in layout.params.iter().enumerate() {
            let (start, words, elems) = match pslot {
                ParamSlot::Pixel => continue,
                ParamSlot::Fixed { offset, words } => (*offset, *words, 1),
                ParamSlot::Seq { seq_offset, words } => (layout.fixed_words + n_seq * seq_offset, *words, n_seq),
            };
            let v = self.eval(args[i])?;
            for w in 0..(words * elems) as usize {
                let word = v.comps.get(w).map_or(0, |c| c[0]);
                let at = start as usize + w;
                let set = if v.sc == Scalar::Float {
                    block.set_float(at, word, self.precision)
                } else {
                    block.set(at, word as u32)
                };
                if !set {
                    return malformed("a call's argument past its block");
                }
            }
        }
        self.call_depth = self.call_depth.wrapping_add(1);
        let r = if self.call_depth > MAX_CALL_DEPTH {
            self.record(ERR_CALL_DEPTH, site.0, true)
        } else {
            self.invoke(callee, Rc::new(block)).map(|_| ())
        };
        self.call_depth = self.call_depth.wrapping_sub(1);
        r?;
        // A callee whose setup ran out of fuel ends its callers' runs too.
        Ok(if self.fuel < 0 { Flow::FuelOut } else { Flow::Normal })
    }
}
