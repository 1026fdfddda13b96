//! Where locals live, and reading and writing them: frames, places and accesses.
//!
//! A [`super::Frame`] is one function being lowered (the primitive, or a shared
//! interpolator inlined into it). Its locals live in SSA variables (one per flattened
//! component, up to `MAX_LOCAL_VAR_WORDS` per local and `MAX_VAR_WORDS` per kernel), in
//! stack slots (locals indexed with a non-constant index: 4 bytes per uniform component,
//! 16 per varying one), in the uniform frame (see [`super::spill`]), or are the primitive's
//! Z or a parameter read from the argument block ([`super::Storage`]). The primitive's
//! frame takes the homes the plan gives ([`crate::mid::homes`]); an inlined interpolator's
//! locals take SSA variables from what the kernel's budget has left when it is inlined.
//!
//! An [`super::Access`] is a (possibly indexed) value not yet loaded: [`Lower::resolve`]
//! builds one from an expression, [`Lower::index_access`] applies an index,
//! [`Lower::read_at`] loads components and [`Lower::assign_at`] stores them, blending
//! with the old value for the executing lanes when control flow is varying.
//!
//! Safety invariant: every index is clamped into its array, and the error recorded (in
//! tier 1 from a cold block; see [`super::frame`]), unless [`crate::ir::range`] proved it
//! in range. A stack array some read may reach before it is assigned is zeroed at kernel
//! entry ([`crate::mid::init`]), so no run reads stale stack memory.

use cranelift_codegen::ir::{self, condcodes::IntCC, types, InstBuilder, StackSlot, StackSlotData, StackSlotKind};
use cranelift_frontend::Variable;

use super::{
    all_zero_bits, const_int, elem_scalar, err, Access, AccessTy, Dyn, Frame, I32X4_or, Lower, Res, Root, Storage,
    ZERO_LOOP_BYTES, ZERO_LOOP_PIXEL_BYTES,
};
use crate::abi::{type_words, ParamSlot, ERR_INDEX};
use crate::ir::{Elem, ExprId, ExprKind, Exprs, FuncId, Function, LocalId, ParamRole, Place, Scalar, SiteId};
use crate::jit::fixed;
use crate::jit::value::{
    args_flags, blend, cl_type, comp_bytes, mask_const, mem_flags, splat, zero, Val, VnKey, I32X4,
};
use crate::jit::JitError;
use crate::mid::homes::{Home, MAX_LOCAL_VAR_WORDS, MAX_VAR_WORDS};

impl<'a, 'b> Lower<'a, 'b> {
    /// Whether a local of `words` components may live in SSA variables (one each), counted
    /// against the kernel's budget of [`MAX_VAR_WORDS`]: otherwise it goes to the stack
    /// like a dynamically indexed one. Cranelift allows at most 65535 parameters per block,
    /// and a loop header can carry every variable (a `float a[65535]` read at constant
    /// indices panicked the SSA builder); SSA over that many values compiles slowly anyway.
    pub(super) fn take_var_words(&mut self, words: u32) -> bool {
        let fits = words <= MAX_LOCAL_VAR_WORDS && self.var_words + words <= MAX_VAR_WORDS;
        if fits {
            self.var_words += words;
        }
        fits
    }

    pub(super) fn make_frame(
        &mut self,
        f: &'a Function,
        id: FuncId,
        slots: Vec<ParamSlot>,
        fixed_words: u32,
        interp_binding: Option<usize>,
    ) -> Res<Frame<'a>> {
        // The primitive's own frame: the homes the plan gives, where only arrays some read
        // may reach before a whole assignment are cleared at entry (see
        // [`crate::mid::init`]). An inlined interpolator's frame: its locals indexed with a
        // non-constant index on the stack, the others in SSA variables while the kernel's
        // budget lasts; it clears all of its arrays.
        let plan = self.plan;
        let homes = interp_binding.is_none().then_some(&plan.homes);
        let dynamic: &[bool] = match (homes, plan.interpolators.get(&id)) {
            (Some(_), _) => &[],
            (None, Some(g)) => &g.dynamic,
            (None, None) => return err(format!("shared interpolator `{}` is not in the plan", f.name)),
        };
        let mut storage = Vec::with_capacity(f.locals.len());
        for (i, local) in f.locals.iter().enumerate() {
            let param_role = f.params.iter().find(|p| p.local.0 as usize == i).map(|p| p.role);
            let varying = local.var.is_varying();
            let sc = elem_scalar(&local.ty);
            let st = match param_role {
                Some(ParamRole::Z) if interp_binding.is_none() => Storage::Z(self.declare_var(I32X4_or(sc))),
                Some(ParamRole::X | ParamRole::Y | ParamRole::Z) => Storage::Vars(vec![self.declare_var(I32X4_or(sc))]),
                Some(_) => Storage::Args,
                None => {
                    if local.ty.per_seq {
                        return err(format!("local `{}` has a per-sequence-point type", local.name));
                    }
                    let n = type_words(&local.ty, self.n_interp);
                    let (on_stack, clear) = match homes.map(|h| h.locals[i]) {
                        Some(Home::Stack { clear }) => (true, clear),
                        Some(_) => (false, false),
                        None => (
                            dynamic.get(i).copied().unwrap_or(false) || !self.take_var_words(n),
                            true,
                        ),
                    };
                    if on_stack {
                        let bytes = n.max(1) * comp_bytes(varying);
                        let slot =
                            self.b
                                .create_sized_stack_slot(StackSlotData::new(StackSlotKind::ExplicitSlot, bytes, 4));
                        // Zero it so no run reads stale stack memory, unless every read
                        // comes after a whole assignment.
                        if clear {
                            let addr = self.slot_addr(slot);
                            self.zero_stack_bytes(addr, 0, bytes, None);
                        }
                        Storage::Stack(slot)
                    } else {
                        let ty = cl_type(sc, varying);
                        let vars = if !self.tier0() {
                            let z = zero(&mut self.b, sc, varying);
                            (0..n)
                                .map(|_| {
                                    let v = self.declare_var(ty);
                                    self.b.def_var(v, z);
                                    v
                                })
                                .collect()
                        } else {
                            // Tier 0: no explicit zero. A variable read where no assignment
                            // reaches is zero all the same (the SSA builder materialises
                            // zero there), without ~100 constants at entry and the block
                            // parameters they feed.
                            (0..n).map(|_| self.declare_var(ty)).collect()
                        };
                        Storage::Vars(vars)
                    }
                }
            };
            storage.push(st);
        }
        if let Some(h) = homes {
            self.var_words += h.var_words;
        }
        Ok(Frame {
            func: f,
            id,
            slots,
            fixed_words,
            storage,
            loops: vec![],
            interp_binding,
        })
    }

    /// The expression arena of the function being lowered (the innermost frame's): the one
    /// every `ExprId` of the statements at hand refers to.
    pub(crate) fn exprs(&self) -> &'a Exprs {
        let f: &'a Function = self.frame().func;
        &f.exprs
    }

    /// The statement arena of the function the innermost frame lowers.
    pub(crate) fn stmt_nodes(&self) -> &'a crate::ir::Stmts {
        let f: &'a Function = self.frame().func;
        &f.stmts
    }

    pub(super) fn frame(&self) -> &Frame<'a> {
        self.frames.last().expect("a frame is always pushed while lowering")
    }

    pub(super) fn frame_mut(&mut self) -> &mut Frame<'a> {
        self.frames.last_mut().expect("a frame is always pushed while lowering")
    }

    pub(super) fn local_access(&self, local: LocalId) -> Res<Access<'a>> {
        let f = self.frame().func;
        let Some(l) = f.locals.get(local.0 as usize) else {
            return err(format!("unknown local {}", local.0));
        };
        Ok(Access {
            root: Root::Local {
                frame: self.frames.len() - 1,
                local,
            },
            ty: AccessTy::of(&l.ty),
            scalar: elem_scalar(&l.ty),
            base: 0,
            dyn_off: Dyn::None,
            compact: false,
        })
    }

    /// Components in storage of one value of `fixed_len` elements of `elem` (`compact`:
    /// Interp holds only the view).
    pub(super) fn value_comps(&self, elem: Elem, fixed_len: u32, compact: bool) -> u32 {
        match elem {
            Elem::Scalar(_) => fixed_len,
            Elem::Interp => fixed_len * if compact { self.view.len() as u32 } else { self.n_interp },
        }
    }

    /// Offsets of the components a value of `fixed_len` elements of `elem` shows (Interp:
    /// only the view's). The list comes from `offs_spare` when it has one: give it back when done
    /// ([`Self::give_back_offsets`]), so an access allocates no list.
    pub(super) fn comp_offsets(&mut self, elem: Elem, fixed_len: u32, compact: bool) -> Vec<u32> {
        let mut out = self.offs_spare.pop().unwrap_or_default();
        out.clear();
        match elem {
            Elem::Scalar(_) => out.extend(0..fixed_len),
            Elem::Interp => {
                let per = if compact { self.view.len() as u32 } else { self.n_interp };
                for e in 0..fixed_len {
                    for (j, &v) in self.view.iter().enumerate() {
                        out.push(e * per + if compact { j as u32 } else { v });
                    }
                }
            }
        }
        out
    }

    pub(super) fn give_back_offsets(&mut self, offs: Vec<u32>) {
        if self.offs_spare.len() < 4 {
            self.offs_spare.push(offs);
        }
    }

    pub(super) fn seq_len(&mut self) -> ir::Value {
        // Tier 0: once per block (the NURB setup read it ~40 times, a load and a umax each).
        self.once_per_block(VnKey::SeqLen, |l| {
            let n = l.b.ins().load(types::I32, args_flags(), l.args, 0);
            let one = l.b.ins().iconst(types::I32, 1);
            l.b.ins().umax(n, one)
        })
    }

    /// Apply one index to an access (clamping it, recording ERR_INDEX when out of range).
    pub(super) fn index_access(&mut self, mut acc: Access<'a>, index: ExprId, site: SiteId) -> Res<Access<'a>> {
        let base_ty = acc.ty;
        if base_ty.dims().is_empty() && !base_ty.per_seq {
            return err("indexing a scalar");
        }
        let elem_ty = base_ty.element();
        let stride = self.value_comps(elem_ty.elem(), elem_ty.fixed_len(), acc.compact);
        let static_len = if base_ty.per_seq { None } else { Some(base_ty.dims()[0]) };
        if let (Some(len), Some(k)) = (static_len, const_int(self.exprs(), index)) {
            let clamped = k.clamp(0, len as i64 - 1) as u32;
            if k < 0 || k >= len as i64 {
                self.defer_error(ERR_INDEX, site, None);
            }
            acc.base += clamped * stride;
            acc.ty = elem_ty;
            return Ok(acc);
        }
        let idx = self.eval(index)?;
        let idx_comp = fixed::convert(&mut self.b, idx.scalar, Scalar::Int, idx.comps[0]);
        // A dynamic index into a temporary: spill it so it can be addressed.
        if let Root::Temp(v) = &acc.root {
            let v = v.clone();
            let bytes = comp_bytes(v.varying);
            let slot = self.b.create_sized_stack_slot(StackSlotData::new(
                StackSlotKind::ExplicitSlot,
                (v.comps.len() as u32).max(1) * bytes,
                4,
            ));
            for (i, &c) in v.comps.iter().enumerate() {
                let addr = self.slot_addr(slot);
                self.b.ins().store(mem_flags(), c, addr, (i as u32 * bytes) as i32);
            }
            acc.root = Root::Stack {
                slot,
                varying: v.varying,
            };
        }
        let off = if idx.varying {
            let (len, last) = self.len_and_last(static_len);
            let len_v = self.b.ins().splat(I32X4, len);
            let bad = self.b.ins().icmp(IntCC::UnsignedGreaterThanOrEqual, idx_comp, len_v);
            let bad = match self.exec() {
                Some(e) => self.b.ins().band(bad, e),
                None => bad,
            };
            let any = self.b.ins().vany_true(bad);
            self.record_error(ERR_INDEX, site.0, Some(any));
            let zero_v = mask_const(&mut self.b, false);
            let last_v = self.b.ins().splat(I32X4, last);
            let c = self.b.ins().smax(idx_comp, zero_v);
            let c = self.b.ins().smin(c, last_v);
            let stride_s = self.iconst_here(types::I32, stride as i64);
            let stride_v = self.b.ins().splat(I32X4, stride_s);
            let c = self.b.ins().imul(c, stride_v);
            match acc.dyn_off {
                Dyn::None => Dyn::Varying(c),
                Dyn::Uniform(u) => {
                    let us = self.b.ins().splat(I32X4, u);
                    Dyn::Varying(self.b.ins().iadd(us, c))
                }
                Dyn::Varying(v) => Dyn::Varying(self.b.ins().iadd(v, c)),
            }
        } else {
            // Proven in range for this frame's function (the primitive's own body only:
            // inlined interpolators have sites of their own, never in the set).
            let proven = self.frames.len() == 1 && self.site_proven(site);
            let c = if proven {
                idx_comp
            } else {
                self.checked_uniform_index(idx_comp, static_len, site)
            };
            let c = self.scaled(c, stride);
            match acc.dyn_off {
                Dyn::None => Dyn::Uniform(c),
                Dyn::Uniform(u) => Dyn::Uniform(self.b.ins().iadd(u, c)),
                Dyn::Varying(v) => {
                    let cs = self.b.ins().splat(I32X4, c);
                    Dyn::Varying(self.b.ins().iadd(v, cs))
                }
            }
        };
        acc.dyn_off = off;
        acc.ty = elem_ty;
        Ok(acc)
    }

    /// The length of an indexed array (`static_len`, or the sequence length) and its last
    /// index, built only where an index is checked: a proven site needs neither (tier 0
    /// has no pass that would drop them: they were ~1000 dead instructions of the NURB
    /// kernel's CLIF).
    pub(super) fn len_and_last(&mut self, static_len: Option<u32>) -> (ir::Value, ir::Value) {
        match static_len {
            Some(n) => (
                self.iconst_here(types::I32, i64::from(n)),
                self.iconst_here(types::I32, i64::from(n) - 1),
            ),
            None => {
                let len = self.seq_len();
                (len, self.b.ins().iadd_imm_s(len, -1))
            }
        }
    }

    /// `x * k` for a non-negative `k`: nothing for 1, a shift for a power of two (which
    /// the x64 backend folds into an address as a scaled index), a multiply otherwise.
    pub(super) fn scaled(&mut self, x: ir::Value, k: u32) -> ir::Value {
        match k {
            1 => x,
            k if k.is_power_of_two() => {
                let ty = self.b.func.dfg.value_type(x);
                let amount = self.iconst_here(ty, i64::from(k.trailing_zeros()));
                self.b.ins().ishl(x, amount)
            }
            k => self.b.ins().imul_imm_s(x, k as i64),
        }
    }

    /// The uniform component offset `u` as a byte offset (`u * bytes`, widened to i64);
    /// tier 0 computes it once per block.
    pub(super) fn byte_offset(&mut self, u: ir::Value, bytes: u32) -> ir::Value {
        self.once_per_block(VnKey::ByteOffset(u, bytes), |l| {
            let wide = l.b.ins().uextend(types::I64, u);
            l.scaled(wide, bytes)
        })
    }

    /// Is `site` of the primitive's own body proven in range (see
    /// [`crate::mid::Plan::proven_sites`])?
    pub(super) fn site_proven(&mut self, site: SiteId) -> bool {
        debug_assert!(
            self.plan.proven_sites.is_some(),
            "the plan judged no index site (mid::sites::needs_range), the lowering asks about one"
        );
        self.plan.proven_sites.is_some_and(|p| p.contains(&site))
    }

    /// A uniform index `idx` into `len` elements (`last` = `len - 1`), clamped, with
    /// ERR_INDEX recorded at `site` when it is out of range. The in-range path is one
    /// unsigned compare and a branch; the clamp and the error record sit in a cold block.
    /// (Recorded inline with selects, the check was two loads, two stores and ten more
    /// instructions on every access: most of the NURB tessellation's time.)
    /// Tier 0 records inline with selects instead (same results): two blocks per access
    /// doubled the NURB kernel's tier-0 compile time; in setup code it records into the
    /// kernel's pending error (see [`Self::defer_error`]), not into `ctx`. And it checks an
    /// index once per block: checked again against the same length under the same error
    /// guard (or after an unguarded check), it is the first check's clamped value, since
    /// that check fails whenever this one would, and first, and the first error is the one
    /// kept (the NURB tessellation's de Boor loops checked each index up to five times in
    /// a row; -6 % of its tier-0 instructions); only its count is added (a compare and
    /// the add). Not in pixel code, where a record also depends on the lanes executing
    /// ([`Self::and_some_lane`]), so an earlier check may have recorded nothing.
    pub(super) fn checked_uniform_index(&mut self, idx: ir::Value, static_len: Option<u32>, site: SiteId) -> ir::Value {
        if self.tier0() {
            let key = VnKey::CheckedIndex(idx, static_len, self.error_guard);
            let reusable = self.pix.is_none();
            if reusable {
                let earlier = self
                    .numbered(key)
                    .or_else(|| self.numbered(VnKey::CheckedIndex(idx, static_len, None)));
                if let Some(c) = earlier {
                    // This access fails whenever the earlier one did, whose record stands
                    // for it; its own count is added here.
                    let len = match static_len {
                        Some(n) => self.iconst_here(types::I32, i64::from(n)),
                        None => self.seq_len(),
                    };
                    let bad = self.b.ins().icmp(IntCC::UnsignedGreaterThanOrEqual, idx, len);
                    let happened = self.error_condition(Some(bad));
                    self.count_error(ERR_INDEX, site.0, happened);
                    return c;
                }
            }
            let (len, last) = self.len_and_last(static_len);
            let bad = self.b.ins().icmp(IntCC::UnsignedGreaterThanOrEqual, idx, len);
            let bad = self.and_some_lane(Some(bad));
            self.defer_error(ERR_INDEX, site, bad);
            let zero_s = self.iconst_here(types::I32, 0);
            let c = self.b.ins().smax(idx, zero_s);
            let c = self.b.ins().smin(c, last);
            if reusable {
                self.number(key, c);
            }
            return c;
        }
        let (len, last) = self.len_and_last(static_len);
        let bad = self.b.ins().icmp(IntCC::UnsignedGreaterThanOrEqual, idx, len);
        let cold = self.b.create_block();
        let in_range = self.b.create_block();
        let checked = self.b.append_block_param(in_range, types::I32);
        self.b.ins().brif(bad, cold, &[], in_range, &[idx.into()]);
        self.b.set_cold_block(cold);
        self.b.switch_to_block(cold);
        let failed = self.and_some_lane(None);
        self.defer_error(ERR_INDEX, site, failed);
        let zero_s = self.iconst_here(types::I32, 0);
        let c = self.b.ins().smax(idx, zero_s);
        let c = self.b.ins().smin(c, last);
        self.b.ins().jump(in_range, &[c.into()]);
        self.b.switch_to_block(in_range);
        checked
    }

    pub(super) fn resolve(&mut self, e_id: ExprId) -> Res<Access<'a>> {
        let e = &self.exprs()[e_id];
        match &e.kind {
            ExprKind::Local(l) => self.local_access(*l),
            ExprKind::Index { base, index, site } => {
                let acc = self.resolve(*base)?;
                self.index_access(acc, *index, *site)
            }
            _ => {
                let v = self.eval(e_id)?;
                Ok(Access {
                    root: Root::Temp(v.clone()),
                    ty: AccessTy::of(&e.ty),
                    scalar: v.scalar,
                    base: 0,
                    dyn_off: Dyn::None,
                    compact: true,
                })
            }
        }
    }

    /// The address of stack slot `slot`. Tier 0 has no pass that would merge repeated
    /// `stack_addr`s (one per array access: ~350 in the NURB kernel), so within one block
    /// the first is reused.
    pub(super) fn slot_addr(&mut self, slot: StackSlot) -> ir::Value {
        self.once_per_block(VnKey::SlotAddr(slot), |l| match l.inherited_slot_addr(slot) {
            Some(addr) => addr,
            None => l.b.ins().stack_addr(types::I64, slot, 0),
        })
    }

    /// Copy `bytes` (a multiple of 4) from stack slot `from` to `to`, 16 bytes per load where
    /// they fit; past [`Self::loop_bytes`] a loop of four loads and stores per trip (a group
    /// resetting a uniform `float a[65536]` the pixel code assigns was 32768 instructions).
    pub(super) fn copy_slot(&mut self, from: StackSlot, to: StackSlot, bytes: u32) {
        let src = self.slot_addr(from);
        let dst = self.slot_addr(to);
        let mut off = 0;
        if self.loop_bytes().is_some_and(|n| bytes > n) {
            off = bytes / 64 * 64;
            self.byte_loop(&[src, dst], off, |l, p| {
                for k in 0..4 {
                    let v = l.b.ins().load(I32X4, mem_flags(), p[0], 16 * k);
                    l.b.ins().store(mem_flags(), v, p[1], 16 * k);
                }
            });
        }
        while off + 4 <= bytes {
            let ty = if bytes - off >= 16 { I32X4 } else { types::I32 };
            let v = self.b.ins().load(ty, mem_flags(), src, off as i32);
            self.b.ins().store(mem_flags(), v, dst, off as i32);
            off += ty.bytes();
        }
    }

    /// Clears and copies of more bytes than this are loops ([`Self::byte_loop`]): in setup
    /// code [`ZERO_LOOP_BYTES`], in pixel code [`ZERO_LOOP_PIXEL_BYTES`]; `None` in flat pixel
    /// code, which has no blocks (`mid::flat` keeps big arrays out of it).
    fn loop_bytes(&self) -> Option<u32> {
        if self.pix.is_none() {
            Some(ZERO_LOOP_BYTES)
        } else {
            (!self.flat).then_some(ZERO_LOOP_PIXEL_BYTES)
        }
    }

    /// A counted loop over `bytes` (a multiple of 64, at least 64) from each address of
    /// `bases`: `trip(l, p)` emits one trip's 64 bytes at `p` (the addresses, each 64 bytes
    /// further every trip). Code after it continues in the loop's exit block.
    fn byte_loop(&mut self, bases: &[ir::Value], bytes: u32, mut trip: impl FnMut(&mut Self, &[ir::Value])) {
        let last = self.b.ins().iadd_imm_s(bases[0], bytes as i64);
        let trip_blk = self.b.create_block();
        let after = self.b.create_block();
        let p: Vec<ir::Value> = bases
            .iter()
            .map(|_| self.b.append_block_param(trip_blk, types::I64))
            .collect();
        let args: Vec<ir::BlockArg> = bases.iter().map(|&v| v.into()).collect();
        self.b.ins().jump(trip_blk, &args);
        self.b.switch_to_block(trip_blk);
        trip(self, &p);
        let next: Vec<ir::Value> = p.iter().map(|&v| self.b.ins().iadd_imm_s(v, 64)).collect();
        let more = self.b.ins().icmp(IntCC::UnsignedLessThan, next[0], last);
        let next_args: Vec<ir::BlockArg> = next.iter().map(|&v| v.into()).collect();
        self.b.ins().brif(more, trip_blk, &next_args, after, &[]);
        self.seal_now(trip_blk);
        self.seal_now(after);
        self.b.switch_to_block(after);
    }

    /// A new SSA variable of type `ty` (its type recorded for [`super::outline`]).
    pub(super) fn declare_var(&mut self, ty: ir::Type) -> Variable {
        self.var_types.push(ty);
        self.b.declare_var(ty)
    }

    /// Load a scalar of `sc` from `addr + off` bytes in uniform form (bools stored as bytes
    /// or words: any non-zero is true).
    pub(crate) fn load_uniform(
        &mut self,
        sc: Scalar,
        addr: ir::Value,
        off: i32,
        word_bools: bool,
        ro: bool,
    ) -> ir::Value {
        // Tier 0 has no e-graph pass to merge repeated loads of the same argument word (the
        // argument block is read-only while the kernel runs): within one block, reuse the
        // first load.
        if !(ro && addr == self.args) {
            return self.load_uniform_uncached(sc, addr, off, word_bools, ro);
        }
        self.once_per_block(VnKey::ArgLoad(off, sc, word_bools), |l| {
            l.load_uniform_uncached(sc, addr, off, word_bools, ro)
        })
    }

    pub(super) fn load_uniform_uncached(
        &mut self,
        sc: Scalar,
        addr: ir::Value,
        off: i32,
        word_bools: bool,
        ro: bool,
    ) -> ir::Value {
        let flags = if ro { args_flags() } else { mem_flags() };
        match sc {
            Scalar::Float => self.b.ins().load(types::F32, flags, addr, off),
            Scalar::Bool => {
                let ty = if word_bools { types::I32 } else { types::I8 };
                let raw = self.b.ins().load(ty, flags, addr, off);
                self.b.ins().icmp_imm_s(IntCC::NotEqual, raw, 0)
            }
            _ => self.b.ins().load(types::I32, flags, addr, off),
        }
    }

    /// Read `count` uniform components laid out `bytes` apart from `base_addr` starting at
    /// component `first` (+ dynamic offset). A varying offset gathers lane by lane.
    /// Dynamic offsets are clamped indices times strides, never negative, so they widen
    /// to addresses by zero extension (free on x86_64 after a 32-bit operation; a sign
    /// extension was one `movslq` per indexed access).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn read_memory(
        &mut self,
        base_addr: ir::Value,
        sc: Scalar,
        varying_storage: bool,
        offs: &[u32],
        first: u32,
        dyn_off: Dyn,
        word_bools: bool,
        ro: bool,
    ) -> Val {
        let bytes = comp_bytes(varying_storage) as i64;
        let mut comps = Vec::with_capacity(offs.len());
        let out_varying = varying_storage || matches!(dyn_off, Dyn::Varying(_));
        // One address for every component of a uniform offset.
        let uniform_addr = match dyn_off {
            Dyn::Uniform(u) => self.uniform_dyn_addr(base_addr, u, bytes),
            _ => base_addr,
        };
        for &o in offs {
            let off = ((first + o) as i64 * bytes) as i32;
            let c = match dyn_off {
                Dyn::None | Dyn::Uniform(_) => {
                    let addr = uniform_addr;
                    if varying_storage {
                        let ty = cl_type(sc, true);
                        self.b.ins().load(ty, mem_flags(), addr, off)
                    } else {
                        self.load_uniform(sc, addr, off, word_bools, ro)
                    }
                }
                Dyn::Varying(dv) => {
                    let mut acc: Option<ir::Value> = None;
                    for lane in 0..4u8 {
                        let d = self.b.ins().extractlane(dv, lane);
                        let d64 = self.b.ins().uextend(types::I64, d);
                        let db = self.b.ins().imul_imm_s(d64, bytes);
                        let addr = self.b.ins().iadd(base_addr, db);
                        let lane_off = off + if varying_storage { 4 * lane as i32 } else { 0 };
                        let x = if varying_storage {
                            let lt = if sc == Scalar::Float { types::F32 } else { types::I32 };
                            self.b.ins().load(lt, mem_flags(), addr, lane_off)
                        } else {
                            let u = self.load_uniform(sc, addr, lane_off, word_bools, ro);
                            if sc == Scalar::Bool {
                                let w = self.b.ins().uextend(types::I32, u);
                                self.b.ins().ineg(w)
                            } else {
                                u
                            }
                        };
                        let vt = cl_type(sc, true);
                        acc = Some(match acc {
                            None => self.b.ins().scalar_to_vector(vt, x),
                            Some(a) => self.b.ins().insertlane(a, x, lane),
                        });
                    }
                    acc.expect("four lanes")
                }
            };
            comps.push(c);
        }
        Val {
            comps,
            scalar: sc,
            varying: out_varying,
        }
    }

    pub(super) fn read(&mut self, acc: Access<'a>) -> Res<Val> {
        if acc.ty.per_seq {
            return err("a whole per-sequence-point array used as a value");
        }
        let offs = self.comp_offsets(acc.ty.elem(), acc.ty.fixed_len(), acc.compact);
        let v = self.read_at(acc, &offs);
        self.give_back_offsets(offs);
        v
    }

    /// [`Self::read`] of the components at `offs`.
    pub(super) fn read_at(&mut self, acc: Access<'a>, offs: &[u32]) -> Res<Val> {
        let sc = acc.scalar;
        match acc.root {
            Root::Temp(v) => {
                let comps = offs
                    .iter()
                    .map(|&o| v.comps.get((acc.base + o) as usize).copied())
                    .collect::<Option<Vec<_>>>()
                    .ok_or_else(|| JitError {
                        message: "component out of range in a temporary".into(),
                    })?;
                Ok(Val {
                    comps,
                    scalar: v.scalar,
                    varying: v.varying,
                })
            }
            Root::Stack { slot, varying } => {
                let addr = self.slot_addr(slot);
                Ok(self.read_memory(addr, sc, varying, offs, acc.base, acc.dyn_off, false, false))
            }
            Root::Local { frame, local } => {
                let fr = &self.frames[frame];
                let varying = fr.func.local(local).var.is_varying();
                let at = local.0 as usize;
                if let Storage::Vars(_) = &fr.storage[at] {
                    if !matches!(acc.dyn_off, Dyn::None) {
                        return err("dynamic index into a register local");
                    }
                    // Each variable is looked up where it is read: cloning the local's
                    // variable list was an allocation per read.
                    let mut comps = Vec::with_capacity(offs.len());
                    for &o in offs {
                        let var = match &self.frames[frame].storage[at] {
                            Storage::Vars(vars) => vars.get((acc.base + o) as usize).copied(),
                            _ => None,
                        };
                        let Some(v) = var else {
                            return err("component out of range");
                        };
                        comps.push(self.b.use_var(v));
                    }
                    return Ok(Val {
                        comps,
                        scalar: sc,
                        varying,
                    });
                }
                match fr.storage[at].clone() {
                    Storage::Vars(_) => err("register local read as memory"),
                    Storage::Z(v) => Ok(Val::one(self.b.use_var(v), sc, true)),
                    Storage::Stack(slot) => {
                        let addr = self.slot_addr(slot);
                        Ok(self.read_memory(addr, sc, varying, offs, acc.base, acc.dyn_off, false, false))
                    }
                    Storage::Frame(word) => {
                        let in_group = self.pix.as_ref().and_then(|p| p.frame_base);
                        let (addr, pure) = match (in_group, self.uniform_frame) {
                            (Some(base), _) => (base, true),
                            (None, Some((fs, _))) => (self.slot_addr(fs), false),
                            (None, None) => return err("uniform frame missing"),
                        };
                        let v = self.read_memory(addr, sc, false, offs, word + acc.base, acc.dyn_off, false, pure);
                        // Tier 0 keeps no splatted copies (see `spill_uniforms`).
                        if pure && sc != Scalar::Bool && matches!(acc.dyn_off, Dyn::None) && !self.tier0() {
                            for (&c, &o) in v.comps.iter().zip(offs) {
                                let w = word + acc.base + o;
                                self.splat_src.insert(c, self.vec_section + 16 * w);
                            }
                        }
                        Ok(v)
                    }
                    Storage::Args => {
                        let pi = fr
                            .func
                            .params
                            .iter()
                            .position(|p| p.local == local)
                            .ok_or_else(|| JitError {
                                message: "parameter storage for a non-parameter".into(),
                            })?;
                        let slot = fr.slots.get(pi).cloned().unwrap_or(ParamSlot::Pixel);
                        let fixed_words = fr.fixed_words;
                        let (addr, first) = match slot {
                            ParamSlot::Fixed { offset, .. } => (self.args, offset + acc.base),
                            // The first sequence array starts right after the fixed words.
                            ParamSlot::Seq { seq_offset: 0, .. } => (self.args, fixed_words + acc.base),
                            ParamSlot::Seq { seq_offset, .. } => {
                                // fixed_words + max(n_seq,1) * seq_offset, in words.
                                let n = self.seq_len();
                                let n64 = self.b.ins().uextend(types::I64, n);
                                let w = self.b.ins().imul_imm_s(n64, seq_offset as i64);
                                let w = self.b.ins().iadd_imm_s(w, fixed_words as i64);
                                let bytes = self.b.ins().ishl_imm_u(w, 2);
                                (self.b.ins().iadd(self.args, bytes), acc.base)
                            }
                            ParamSlot::Pixel => return err("pixel parameter read from the argument block"),
                        };
                        Ok(self.read_memory(addr, sc, false, offs, first, acc.dyn_off, true, true))
                    }
                }
            }
        }
    }

    pub(super) fn assign(&mut self, place: &'a Place, value: ExprId) -> Res<()> {
        let frame = self.frames.len() - 1;
        self.guard_facts.kill(frame, place.local);
        let mut acc = self.local_access(place.local)?;
        for (idx, site) in &place.indices {
            acc = self.index_access(acc, *idx, *site)?;
        }
        if self.zero_array(place.local, &acc, value) {
            return Ok(());
        }
        let v = self.eval(value)?;
        let target = acc.scalar;
        let comps: Vec<ir::Value> = v
            .comps
            .iter()
            .map(|&c| fixed::convert(&mut self.b, v.scalar, target, c))
            .collect();
        let offs = self.comp_offsets(acc.ty.elem(), acc.ty.fixed_len(), false);
        let done = self.assign_at(place, acc, comps, &offs);
        self.give_back_offsets(offs);
        done
    }

    /// [`Self::assign`] of `comps` (converted to the place's scalar type) to the components
    /// of `acc` at `offs`.
    pub(super) fn assign_at(
        &mut self,
        place: &'a Place,
        acc: Access<'a>,
        comps: Vec<ir::Value>,
        offs: &[u32],
    ) -> Res<()> {
        let frame = self.frames.len() - 1;
        self.guard_facts.kill(frame, place.local);
        let target = acc.scalar;
        let comps = if comps.len() == 1 && offs.len() != 1 {
            vec![comps[0]; offs.len()]
        } else {
            comps
        };
        if comps.len() != offs.len() {
            return err(format!(
                "assignment of {} components to a place of {}",
                comps.len(),
                offs.len()
            ));
        }
        let frame_i = self.frames.len() - 1;
        let fr = &self.frames[frame_i];
        let local = fr.func.local(place.local);
        let varying = local.var.is_varying();
        // A register local's variables are looked up per component below (no clone of
        // its variable list per assignment).
        let at = place.local.0 as usize;
        let storage = match &fr.storage[at] {
            Storage::Vars(_) => Storage::Vars(vec![]),
            other => other.clone(),
        };
        let masked = self.masked();
        match storage {
            Storage::Args => err(format!("assignment to parameter `{}`", local.name)),
            Storage::Frame(_) => err(format!(
                "assignment to `{}`, which the pixel part never assigns",
                local.name
            )),
            Storage::Vars(_) => {
                for (o, c) in offs.iter().zip(comps) {
                    let var = match &self.frames[frame_i].storage[at] {
                        Storage::Vars(vars) => vars.get((acc.base + o) as usize).copied(),
                        _ => None,
                    };
                    let Some(var) = var else {
                        return err("component out of range");
                    };
                    let new = if varying {
                        let c = splat(&mut self.b, target, c);
                        if masked {
                            let old = self.b.use_var(var);
                            let exec = self.exec().expect("pixel context");
                            blend(&mut self.b, exec, c, old)
                        } else {
                            c
                        }
                    } else {
                        if self.b.func.dfg.value_type(c).is_vector() {
                            return err(format!("varying value assigned to uniform `{}`", local.name));
                        }
                        c
                    };
                    self.b.def_var(var, new);
                }
                Ok(())
            }
            Storage::Z(var) => {
                let c = splat(&mut self.b, target, comps[0]);
                let exec = self.exec().ok_or_else(|| JitError {
                    message: "Z assigned outside per-pixel code".into(),
                })?;
                let old = self.b.use_var(var);
                let new = blend(&mut self.b, exec, c, old);
                self.b.def_var(var, new);
                let zw = self.pix.as_ref().expect("pixel context").z_written;
                let w = self.b.use_var(zw);
                let w = self.b.ins().bor(w, exec);
                self.b.def_var(zw, w);
                Ok(())
            }
            Storage::Stack(slot) => {
                let base_addr = self.slot_addr(slot);
                let bytes = comp_bytes(varying) as i64;
                for (o, c) in offs.iter().zip(comps) {
                    let off = ((acc.base + o) as i64 * bytes) as i32;
                    if !varying {
                        if self.b.func.dfg.value_type(c).is_vector() {
                            return err(format!("varying value assigned to uniform `{}`", local.name));
                        }
                        let addr = self.dyn_addr(base_addr, acc.dyn_off, bytes)?;
                        self.b.ins().store(mem_flags(), c, addr, off);
                        continue;
                    }
                    let c = splat(&mut self.b, target, c);
                    match acc.dyn_off {
                        Dyn::Varying(dv) => {
                            // Scatter lane by lane; lanes not executing keep their old value.
                            let exec = self.exec();
                            for lane in 0..4u8 {
                                let d = self.b.ins().extractlane(dv, lane);
                                let d64 = self.b.ins().uextend(types::I64, d);
                                let db = self.b.ins().imul_imm_s(d64, bytes);
                                let addr = self.b.ins().iadd(base_addr, db);
                                let lt = if target == Scalar::Float {
                                    types::F32
                                } else {
                                    types::I32
                                };
                                let lane_off = off + 4 * lane as i32;
                                let x = self.b.ins().extractlane(c, lane);
                                let x = match exec {
                                    Some(e) => {
                                        let m = self.b.ins().extractlane(e, lane);
                                        let on = self.b.ins().icmp_imm_s(IntCC::NotEqual, m, 0);
                                        let old = self.b.ins().load(lt, mem_flags(), addr, lane_off);
                                        self.b.ins().select(on, x, old)
                                    }
                                    None => x,
                                };
                                self.b.ins().store(mem_flags(), x, addr, lane_off);
                            }
                        }
                        d => {
                            let addr = self.dyn_addr(base_addr, d, bytes)?;
                            let ty = cl_type(target, true);
                            let new = if masked {
                                let old = self.b.ins().load(ty, mem_flags(), addr, off);
                                let exec = self.exec().expect("pixel context");
                                blend(&mut self.b, exec, c, old)
                            } else {
                                c
                            };
                            self.b.ins().store(mem_flags(), new, addr, off);
                        }
                    }
                }
                Ok(())
            }
        }
    }

    /// A stack array set whole to all zeros (a declaration without initialiser, or
    /// `{0, ...}`): cleared 16 bytes per store, since all-zero bits are zero in every scalar
    /// type (the NURB tessellation zeroes ~480 words per vertex), by [`Self::zero_stack_bytes`]
    /// (a loop past a size). Uniform arrays of 8 words or more; varying ones past
    /// [`ZERO_LOOP_PIXEL_BYTES`] (smaller ones stay on the general path, a store per
    /// component), under the executing lanes where control flow is varying. Decided before
    /// the value is evaluated: evaluating it first left one dead constant per component
    /// (5700 of the NURB kernel's 32000 tier-0 CLIF lines) for Cranelift to process; a
    /// varying `float a[65536]` was 65536 splats and stores. False (nothing emitted) when the
    /// assignment is not such a clear.
    pub(super) fn zero_array(&mut self, local: LocalId, acc: &Access<'a>, value_id: ExprId) -> bool {
        let value = &self.exprs()[value_id];
        // Cheap tests first: this runs for every assignment.
        if !all_zero_bits(self.exprs(), value_id) {
            return false;
        }
        let fr = &self.frames[self.frames.len() - 1];
        let varying = fr.func.local(local).var.is_varying();
        let Some(&Storage::Stack(slot)) = fr.storage.get(local.0 as usize) else {
            return false;
        };
        // interpolation_data counts too when the view is every component (outside the
        // arms that narrow it): `interpolation_data known_data[1280]` of the NURB tessellation
        // was 3840 one-word stores, 39 % of its kernel's tier-0 CLIF.
        // (A view holds distinct components: as many as the data has is all of them.)
        let whole = matches!(acc.dyn_off, Dyn::None)
            && !acc.compact
            && (matches!(acc.ty.elem(), Elem::Scalar(_)) || self.view.len() as u32 == self.n_interp);
        let words = self.value_comps(acc.ty.elem(), acc.ty.fixed_len(), false);
        // The value must cover the place exactly (or be one scalar, broadcast), as the
        // general path checks.
        let fits = value.ty.is_scalar()
            || match acc.ty.elem() {
                Elem::Scalar(_) => value.ty.fixed_len() == words,
                Elem::Interp => value.ty.elem == Elem::Interp && value.ty.fixed_len() == acc.ty.fixed_len(),
            };
        let bytes = comp_bytes(varying);
        let big_enough = if varying {
            // Flat pixel code has none (`mid::flat`); it would need its blocks.
            words * bytes > ZERO_LOOP_PIXEL_BYTES && !self.flat
        } else {
            words >= 8
        };
        if !whole || !big_enough || !fits {
            return false;
        }
        let lanes = if varying && self.masked() { self.exec() } else { None };
        let base_addr = self.slot_addr(slot);
        self.zero_stack_bytes(base_addr, acc.base * bytes, (acc.base + words) * bytes, lanes);
        true
    }

    /// Store zeros to bytes `start..end` (multiples of 4; of 16 with `lanes`) from
    /// `base_addr`, a stack slot's address; with `lanes` (a varying array's), only to the
    /// lanes it sets, the rest keeping their bytes. All-zero bits are zero in every scalar
    /// type, so 16 bytes per store (a word per store was a quarter of the NURB kernel's
    /// CLIF). A clear of more than [`ZERO_LOOP_BYTES`] in setup code, or of more than
    /// [`ZERO_LOOP_PIXEL_BYTES`] in pixel code that is not flat, is a counted loop of four
    /// such stores per trip ([`Self::byte_loop`]; the NURB kernel's 2 KB tessellation arrays
    /// were 128 stores each: one CLIF instruction per 16 bytes to build, allocate and emit,
    /// for a clear that runs once per primitive). Flat pixel code keeps straight stores: it
    /// has no blocks.
    pub(super) fn zero_stack_bytes(&mut self, base_addr: ir::Value, start: u32, end: u32, lanes: Option<ir::Value>) {
        let zero_vec = mask_const(&mut self.b, false);
        let clear = |l: &mut Self, addr: ir::Value, off: i32| {
            let v = match lanes {
                Some(m) => {
                    let old = l.b.ins().load(I32X4, mem_flags(), addr, off);
                    l.b.ins().band_not(old, m)
                }
                None => zero_vec,
            };
            l.b.ins().store(mem_flags(), v, addr, off);
        };
        let mut at = start;
        if self.loop_bytes().is_some_and(|n| end - start > n) {
            let loop_bytes = (end - start) / 64 * 64;
            let first = self.b.ins().iadd_imm_s(base_addr, start as i64);
            self.byte_loop(&[first], loop_bytes, |l, p| {
                for k in 0..4 {
                    clear(l, p[0], 16 * k);
                }
            });
            at = start + loop_bytes;
        }
        while at + 16 <= end {
            clear(self, base_addr, at as i32);
            at += 16;
        }
        if at < end {
            let zero_word = self.iconst_here(types::I32, 0);
            while at < end {
                self.b.ins().store(mem_flags(), zero_word, base_addr, at as i32);
                at += 4;
            }
        }
    }

    /// `base + d * bytes` for a uniform dynamic offset `d` (see [`Self::read_memory`] on
    /// the zero extension). Tier 0 computes it once per block and offset: an access to
    /// `float p[4]` at a dynamic row reads or writes four components at one address, and
    /// the NURB setup reads the same element several times (tier 0 has no pass that would
    /// merge the copies: ~250 `uextend`s, shifts and adds of its CLIF).
    pub(super) fn dyn_addr(&mut self, base: ir::Value, d: Dyn, bytes: i64) -> Res<ir::Value> {
        match d {
            Dyn::None => Ok(base),
            Dyn::Uniform(u) => Ok(self.uniform_dyn_addr(base, u, bytes)),
            Dyn::Varying(_) => err("varying index into a uniform local"),
        }
    }

    /// [`Self::dyn_addr`] of a uniform offset `u`.
    pub(super) fn uniform_dyn_addr(&mut self, base: ir::Value, u: ir::Value, bytes: i64) -> ir::Value {
        self.once_per_block(VnKey::DynAddr(base, u, bytes as u32), |l| {
            let db = l.byte_offset(u, bytes as u32);
            l.b.ins().iadd(base, db)
        })
    }
}
