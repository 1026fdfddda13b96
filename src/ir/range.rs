//! Range analysis of uniform `int` values: which index sites of a function's setup provably
//! index inside their array, so code generation may drop their clamp and error record.
//!
//! An abstract interpretation over the structured IR with one interval `[lo, hi]` per
//! uniform scalar `int` local (parameters included: they are never assigned, so a test on
//! them holds for the rest of the run). Declared locals start at 0 (storage is zeroed);
//! parameters start unknown (the whole i32 range). Assignments evaluate the interval of the
//! value: `+ - *` exactly in i64, giving up when a result could leave i32 (the JIT's
//! arithmetic wraps); `/ %` for non-negative operands; `min max clamp abs`; `?:` as the join
//! of each arm under its condition. Conditions refine the locals they compare (`l < e`,
//! `l + c >= e`, `!`, `&&`, `||`), so `if (n > 12) return;` bounds `n` after it and
//! `for (i = 0; i < n; i++)` bounds `i` in the body. A branch whose refinement is empty is
//! not taken; `return`, `break` and `continue` carry their state to where they go. Loops
//! iterate to a fixpoint, widening a bound that still moves from the third round on (a
//! loop's counters first, to +-2^30, then to the end of the i32 range), then take one
//! narrowing step (the state one trip after the fixpoint, which is inductive too and gives
//! back what widening lost); index sites are judged in one more round from there, with
//! the states of every enclosing loop final. A nested loop starts each visit during its
//! parents' ascending rounds from the head it reached last time, so the cost grows with
//! the nesting depth instead of as a power of it (nurb_surface: 3.6 ms, was 9 ms).
//!
//! A site is proven when, at every occurrence (the checker's inlining can copy one site),
//! the index is uniform and its interval lies in `[0, len)` of a fixed-size array. An index
//! inside an arm of `?:` is judged without that arm's condition: the JIT evaluates both
//! arms and selects (the language reports errors of the taken arm only). Only the
//! setup part is analysed: pixel-part sites are never proven. The result is a claim code
//! generation relies on for memory safety, so every rule above errs towards "unknown".

use std::collections::{HashMap, HashSet};

use super::{
    BinOp, Builtin, ConstValue, Elem, Expr, ExprId, ExprKind, Function, LocalId, LoopId, Scalar, SiteId, StmtId,
};
use super::{LocalKind, StmtKind, UnaryOp};

/// An interval of i32 values, `lo <= hi`, as arithmetic on it takes it (exact in i64).
type Range = (i64, i64);
/// An interval as a state stores it: half the bytes of a [`Range`] to copy and join (states
/// are copied at every branch and loop round; nurb_surface's hold 165 locals).
type Stored = (i32, i32);
/// Per local; `None`: this point is not reached.
type State = Option<Vec<Stored>>;

const TOP: Range = (i32::MIN as i64, i32::MAX as i64);

/// `r` as stored: every interval the analysis makes lies in the i32 range; clamping one that
/// did not would still hold every i32 value it held.
fn stored(r: Range) -> Stored {
    (r.0.clamp(TOP.0, TOP.1) as i32, r.1.clamp(TOP.0, TOP.1) as i32)
}

fn range(s: Stored) -> Range {
    (s.0.into(), s.1.into())
}

/// Index sites of `f`'s setup whose index is proven inside its array at every occurrence.
pub fn proven_index_sites(f: &Function) -> HashSet<SiteId> {
    // Uniform scalar int locals get a position in the state; nothing else is tracked.
    let mut slots = Vec::with_capacity(f.locals.len());
    let mut start = vec![];
    for l in &f.locals {
        let int = !l.var.is_varying() && l.ty.is_scalar() && l.ty.elem == Elem::Scalar(Scalar::Int);
        slots.push(int.then_some(start.len()));
        if int {
            start.push(if matches!(l.kind, LocalKind::Param(_)) {
                stored(TOP)
            } else {
                (0, 0)
            });
        }
    }
    let mut a = Analysis {
        f,
        slots,
        loops: vec![],
        verdicts: vec![],
        quiet: false,
        heads: HashMap::new(),
        counters: HashMap::new(),
    };
    a.stmts(&f.setup, Some(start));
    a.verdicts
        .iter()
        .enumerate()
        .filter(|(_, &v)| v == Verdict::Proven)
        .map(|(i, _)| SiteId(i as u32))
        .collect()
}

/// What the judging rounds saw of one index site.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Verdict {
    Unseen,
    /// In range at every occurrence judged so far.
    Proven,
    /// Out of range (or unknown) at some occurrence.
    Unproven,
}

struct LoopFrame {
    id: LoopId,
    breaks: State,
    continues: State,
}

struct Analysis<'a> {
    f: &'a Function,
    /// Per local: its position in a state, if tracked.
    slots: Vec<Option<usize>>,
    loops: Vec<LoopFrame>,
    /// By site id (dense: a flag vector, not two hash sets, since every occurrence of a
    /// site in every judging round records here).
    verdicts: Vec<Verdict>,
    /// In a round whose states are not final (a loop's ascending rounds, and everything
    /// nested in them): sites are not judged.
    quiet: bool,
    /// Per loop (by id: each names one loop statement), the head it last reached a fixpoint
    /// at while `quiet`: the next quiet visit starts from it joined with its entry, so a
    /// nested loop takes one round per visit instead of being solved from scratch in every
    /// round of every loop around it.
    heads: HashMap<LoopId, Vec<Stored>>,
    /// Per loop, per state position: is the local a counter of the loop (see
    /// `counters_in`)?
    counters: HashMap<LoopId, Vec<bool>>,
}

/// The smallest state both `a` and `b` are in (in place in `a`'s vector: joins run at
/// every branch merge and loop round, and a new vector per join was a quarter of the
/// analysis's instructions).
fn join(a: State, b: State) -> State {
    match (a, b) {
        (None, x) | (x, None) => x,
        (a, b) => join_into(a, &b),
    }
}

/// `join(a, b.clone())` without copying `b` when `a` has a vector to join into.
fn join_into(a: State, b: &State) -> State {
    match (a, b) {
        (Some(mut a), Some(b)) => {
            for (x, y) in a.iter_mut().zip(b) {
                *x = (x.0.min(y.0), x.1.max(y.1));
            }
            Some(a)
        }
        (a, None) => a,
        (None, b) => b.clone(),
    }
}

/// Every state `a` allows, `b` allows too.
fn included(a: &State, b: &State) -> bool {
    match (a, b) {
        (None, _) => true,
        (Some(_), None) => false,
        (Some(a), Some(b)) => a.iter().zip(b).all(|(x, y)| y.0 <= x.0 && x.1 <= y.1),
    }
}

/// Where a bound that still moves at a loop head goes: first to +-2^30 (when it is within),
/// so that `i + c` for a counter `i` does not wrap and a condition such as `i + 1 < n` can
/// still narrow it (at 2^31 - 1, `i + 1` could wrap and satisfy it); if it moves again,
/// to the end of the range.
fn widen(old: Range, new: Range) -> Range {
    const STEP: i64 = 1 << 30;
    let lo = if new.0 >= old.0 {
        new.0
    } else if new.0 >= -STEP {
        -STEP
    } else {
        TOP.0
    };
    let hi = if new.1 <= old.1 {
        new.1
    } else if new.1 <= STEP {
        STEP
    } else {
        TOP.1
    };
    (lo, hi)
}

/// The length of the array the `depth`-th index of a place of type `ty` indexes (`None`:
/// the sequence length): `ty.element()` applied `depth` times, without building the types
/// (a type per assignment and round was a tenth of the analysis's instructions).
fn index_len(ty: &super::Type, depth: usize) -> Option<u32> {
    match (ty.per_seq, depth) {
        (true, 0) => None,
        (true, d) => ty.dims.get(d - 1).copied(),
        (false, d) => ty.dims.get(d).copied(),
    }
}

fn fits(lo: i64, hi: i64) -> Range {
    if lo < TOP.0 || hi > TOP.1 {
        TOP
    } else {
        (lo, hi)
    }
}

impl Analysis<'_> {
    /// A uniform scalar int local: the ones with an interval.
    fn tracked(&self, l: LocalId) -> bool {
        self.slot(l).is_some()
    }

    /// The position of a tracked local in a state.
    fn slot(&self, l: LocalId) -> Option<usize> {
        self.slots.get(l.0 as usize).copied().flatten()
    }

    fn stmts(&mut self, list: &[StmtId], mut st: State) -> State {
        for &s in list {
            st.as_ref()?;
            st = self.stmt(s, st);
        }
        st
    }

    fn stmt(&mut self, s: StmtId, st: State) -> State {
        let f = self.f;
        if let StmtKind::Assign { place, value } = &f.stmts[s] {
            let mut env = st?;
            if let Some(local) = self.f.locals.get(place.local.0 as usize) {
                for (depth, (index, site)) in place.indices.iter().enumerate() {
                    self.judge(index_len(&local.ty, depth), *index, *site, &env);
                }
            }
            for (index, _) in &place.indices {
                self.visit(*index, &env);
            }
            self.visit(*value, &env);
            if place.indices.is_empty() && self.tracked(place.local) {
                let v = self.eval(*value, &env);
                if let Some(at) = self.slot(place.local) {
                    env[at] = stored(v);
                }
            }
            return Some(env);
        }
        let env = st.as_ref()?;
        match &f.stmts[s] {
            // Handled above (it takes the state by value).
            StmtKind::Assign { .. } => st,
            StmtKind::If { cond, then, otherwise } => {
                self.visit(*cond, env);
                let t = self.refine(st.clone(), *cond, true);
                let e = self.refine(st, *cond, false);
                let t = self.stmts(then, t);
                let e = self.stmts(otherwise, e);
                join(t, e)
            }
            StmtKind::Loop {
                id, cond, body, step, ..
            } => self.lower_loop(*id, *cond, body, step, st),
            StmtKind::Break(id) | StmtKind::Continue(id) => {
                let is_break = matches!(f.stmts[s], StmtKind::Break(_));
                if let Some(frame) = self.loops.iter_mut().rev().find(|l| l.id == *id) {
                    let slot = if is_break {
                        &mut frame.breaks
                    } else {
                        &mut frame.continues
                    };
                    *slot = join(slot.take(), st);
                }
                None
            }
            StmtKind::Return => None,
            StmtKind::Interpolation { arms } => {
                // Any subset of the arms may run (none, in a variant without their kinds).
                let mut out = st.clone();
                for arm in arms {
                    let after = self.stmts(&arm.body, st.clone());
                    out = join(out, after);
                }
                out
            }
            StmtKind::InterpolatorReturn(e) => {
                if let Some(e) = e {
                    self.visit(*e, env);
                }
                st
            }
            StmtKind::Bound(es) => {
                es.iter().for_each(|e| self.visit(*e, env));
                st
            }
            StmtKind::CallPrimitive { args, .. } => {
                args.iter().for_each(|e| self.visit(*e, env));
                st
            }
        }
    }

    /// The state after loop `id`.
    ///
    /// Ascending rounds from the entry (widening a bound that still moves from the third
    /// round on) reach a head `h` with `next = entry ⊔ F(h) ⊆ h`; then `next` is inductive too
    /// (`F(next) ⊆ F(h) ⊆ next`, F monotone) and tighter: one narrowing step, which gives back
    /// bounds that widening threw away (`k = i` in a loop `i < count` ends at `count - 1`, not
    /// at 2^31 - 1). The ascending rounds are quiet; sites are judged in one more round from
    /// `next`, whose states cover every trip. A quiet visit (inside another loop's ascending
    /// rounds) returns the last ascending round's exit and skips that round.
    fn lower_loop(
        &mut self,
        id: LoopId,
        cond: Option<ExprId>,
        body: &[StmtId],
        step: &[StmtId],
        entry: State,
    ) -> State {
        let judging = !self.quiet;
        if judging {
            // A fresh solve: heads cached by earlier ascending rounds came from larger
            // states than this one's (before narrowing) and would cost precision.
            self.heads.clear();
        }
        self.quiet = true;
        let mut head = match (self.heads.get(&id), &entry) {
            (Some(cached), Some(_)) => join(entry.clone(), Some(cached.clone())),
            _ => entry.clone(),
        };
        let counters = match self.counters.get(&id) {
            Some(c) => c.clone(),
            None => {
                let mut c = vec![false; self.slots.len()];
                counters_in(self.f, body, &mut c);
                counters_in(self.f, step, &mut c);
                let c: Vec<bool> = (0..self.slots.len())
                    .filter_map(|l| self.slots[l].map(|_| c[l]))
                    .collect();
                self.counters.insert(id, c.clone());
                c
            }
        };
        let mut round = 0;
        let (narrowed, exit) = loop {
            let (back, exit) = self.loop_round(id, cond, body, step, head.clone());
            let next = join_into(back, &entry);
            if included(&next, &head) {
                break (next, exit);
            }
            round += 1;
            head = if round >= 2 {
                // Widen: a bound still moving goes to +-2^30, then to the end of the range.
                // Counters first (locals assigned from themselves, `i = i + 1`): a local
                // that only copies a bounded one (`k = i` under `i < count`) then settles
                // by itself, where widened at once it would keep its widened bound (its
                // own value flows round the loop unchanged, so narrowing cannot help).
                let all = round >= 4;
                match (head, next) {
                    (Some(h), Some(n)) => Some(
                        h.iter()
                            .zip(&n)
                            .zip(&counters)
                            .map(|((o, n), &c)| {
                                if all || c {
                                    stored(widen(range(*o), range(*n)))
                                } else {
                                    *n
                                }
                            })
                            .collect(),
                    ),
                    (_, n) => n,
                }
            } else {
                next
            };
            if round > 12 {
                // Cannot happen after widening; give up on the loop's facts all the same.
                head = head.map(|h| h.iter().map(|_| stored(TOP)).collect());
            }
        };
        if let Some(h) = &narrowed {
            self.heads.insert(id, h.clone());
        }
        self.quiet = !judging;
        if !judging {
            return exit;
        }
        let (_, exit) = self.loop_round(id, cond, body, step, narrowed);
        exit
    }

    /// One trip from the loop head: the state back at the head, and the state at the exit.
    fn loop_round(
        &mut self,
        id: LoopId,
        cond: Option<ExprId>,
        body: &[StmtId],
        step: &[StmtId],
        head: State,
    ) -> (State, State) {
        let (into, out) = match cond {
            Some(c) => {
                if let Some(h) = &head {
                    self.visit(c, h);
                }
                (self.refine(head.clone(), c, true), self.refine(head, c, false))
            }
            None => (head, None),
        };
        self.loops.push(LoopFrame {
            id,
            breaks: None,
            continues: None,
        });
        let after_body = self.stmts(body, into);
        let frame = self.loops.pop().expect("pushed above");
        let before_step = join(after_body, frame.continues);
        self.loops.push(LoopFrame {
            id,
            breaks: None,
            continues: None,
        });
        let back = self.stmts(step, before_step);
        let step_frame = self.loops.pop().expect("pushed above");
        let exit = join(join(out, frame.breaks), step_frame.breaks);
        (back, exit)
    }

    /// Judge every index site in `e` under `env` (nothing to do in a quiet round).
    fn visit(&mut self, e_id: ExprId, env: &[Stored]) {
        let e = &self.f.exprs[e_id];
        if self.quiet {
            return;
        }
        match &e.kind {
            ExprKind::Index { base, index, site } => {
                self.judge(index_len(&self.f.exprs[*base].ty, 0), *index, *site, env);
                self.visit(*base, env);
                self.visit(*index, env);
            }
            ExprKind::Const(_) | ExprKind::Local(_) | ExprKind::SeqCount | ExprKind::ClipFlag => {}
            ExprKind::Unary { expr, .. } | ExprKind::Convert(expr) | ExprKind::Splat(expr) => self.visit(*expr, env),
            ExprKind::Binary { lhs, rhs, .. } | ExprKind::MatMul { lhs, rhs } => {
                self.visit(*lhs, env);
                self.visit(*rhs, env);
            }
            ExprKind::Select { cond, then, otherwise } => {
                // The JIT evaluates both arms whatever the condition (and selects), so an
                // index in either arm runs under the unrefined state: judged there.
                self.visit(*cond, env);
                self.visit(*then, env);
                self.visit(*otherwise, env);
            }
            ExprKind::Builtin { args, .. } | ExprKind::List(args) => args.iter().for_each(|a| self.visit(*a, env)),
        }
    }

    /// `len`: the indexed array's length (`None`: the sequence length, not fixed).
    fn judge(&mut self, len: Option<u32>, index_id: ExprId, site: SiteId, env: &[Stored]) {
        let index = &self.f.exprs[index_id];
        if self.quiet {
            return;
        }
        let (lo, hi) = self.eval(index_id, env);
        let ok = !index.var.is_varying() && len.is_some_and(|n| lo >= 0 && hi < n as i64);
        let at = site.0 as usize;
        if self.verdicts.len() <= at {
            self.verdicts.resize(at + 1, Verdict::Unseen);
        }
        let v = &mut self.verdicts[at];
        *v = match (*v, ok) {
            (Verdict::Unproven, _) | (_, false) => Verdict::Unproven,
            _ => Verdict::Proven,
        };
    }

    /// The interval of a uniform int expression (TOP for anything else).
    fn eval(&self, e_id: ExprId, env: &[Stored]) -> Range {
        let e = &self.f.exprs[e_id];
        if e.var.is_varying() || !e.ty.is_scalar() || e.ty.elem != Elem::Scalar(Scalar::Int) {
            return TOP;
        }
        match &e.kind {
            ExprKind::Const(ConstValue::Int(v)) => (*v as i64, *v as i64),
            ExprKind::Local(l) => self.slot(*l).and_then(|at| env.get(at).copied()).map_or(TOP, range),
            ExprKind::Unary { op: UnaryOp::Neg, expr } => {
                let (lo, hi) = self.eval(*expr, env);
                fits(-hi, -lo)
            }
            ExprKind::Binary { op, lhs, rhs } => {
                let (a, b) = (self.eval(*lhs, env), self.eval(*rhs, env));
                match op {
                    BinOp::Add => fits(a.0 + b.0, a.1 + b.1),
                    BinOp::Sub => fits(a.0 - b.1, a.1 - b.0),
                    BinOp::Mul => {
                        let p = [a.0 * b.0, a.0 * b.1, a.1 * b.0, a.1 * b.1];
                        fits(*p.iter().min().expect("4"), *p.iter().max().expect("4"))
                    }
                    BinOp::Div if a.0 >= 0 && b.0 >= 1 => (a.0 / b.1, a.1 / b.0),
                    BinOp::Rem if a.0 >= 0 && b.0 >= 1 => (0, a.1.min(b.1 - 1)),
                    _ => TOP,
                }
            }
            ExprKind::Select { cond, then, otherwise } if !refines_nothing(&self.f.exprs[*cond]) => {
                let st = Some(env.to_vec());
                let t = self.refine(st.clone(), *cond, true).map(|t| self.eval(*then, &t));
                let o = self.refine(st, *cond, false).map(|o| self.eval(*otherwise, &o));
                match (t, o) {
                    (Some(t), Some(o)) => (t.0.min(o.0), t.1.max(o.1)),
                    (Some(x), None) | (None, Some(x)) => x,
                    (None, None) => TOP,
                }
            }
            ExprKind::Select { then, otherwise, .. } => {
                let (t, o) = (self.eval(*then, env), self.eval(*otherwise, env));
                (t.0.min(o.0), t.1.max(o.1))
            }
            ExprKind::Builtin { func, args } => {
                let r: Vec<Range> = args.iter().map(|a| self.eval(*a, env)).collect();
                match (func, r.as_slice()) {
                    (Builtin::Min, [a, b]) => (a.0.min(b.0), a.1.min(b.1)),
                    (Builtin::Max, [a, b]) => (a.0.max(b.0), a.1.max(b.1)),
                    (Builtin::Clamp, [x, lo, hi]) if lo.1 <= hi.0 => (x.0.max(lo.0).min(hi.0), x.1.max(lo.1).min(hi.1)),
                    (Builtin::Abs, [a]) if a.0 > TOP.0 => {
                        if a.0 >= 0 {
                            *a
                        } else if a.1 <= 0 {
                            (-a.1, -a.0)
                        } else {
                            (0, a.1.max(-a.0))
                        }
                    }
                    _ => TOP,
                }
            }
            _ => TOP,
        }
    }

    /// `st` where `cond` evaluates to `truth` (None: it cannot).
    fn refine(&self, st: State, cond_id: ExprId, truth: bool) -> State {
        let cond = &self.f.exprs[cond_id];
        st.as_ref()?;
        if let ExprKind::Const(ConstValue::Bool(b)) = cond.kind {
            return if b == truth { st } else { None };
        }
        match &cond.kind {
            ExprKind::Unary { op: UnaryOp::Not, expr } => self.refine(st, *expr, !truth),
            ExprKind::Binary {
                op: BinOp::And,
                lhs,
                rhs,
            } if truth => {
                let st = self.refine(st, *lhs, true);
                self.refine(st, *rhs, true)
            }
            ExprKind::Binary {
                op: BinOp::Or,
                lhs,
                rhs,
            } if !truth => {
                let st = self.refine(st, *lhs, false);
                self.refine(st, *rhs, false)
            }
            ExprKind::Binary {
                op: BinOp::And | BinOp::Or,
                lhs,
                rhs,
            } => join(self.refine(st.clone(), *lhs, truth), self.refine(st, *rhs, truth)),
            ExprKind::Binary { op, lhs, rhs }
                if is_int(&self.f.exprs[*lhs]) && is_int(&self.f.exprs[*rhs]) && !cond.var.is_varying() =>
            {
                // As `lhs OP rhs` holding: `lt` with `lhs < rhs`, `le` with `<=`, `eq`, `ne`.
                let op = match (op, truth) {
                    (BinOp::Lt, true) | (BinOp::Ge, false) => Cmp::Lt,
                    (BinOp::Le, true) | (BinOp::Gt, false) => Cmp::Le,
                    (BinOp::Gt, true) | (BinOp::Le, false) => Cmp::Gt,
                    (BinOp::Ge, true) | (BinOp::Lt, false) => Cmp::Ge,
                    (BinOp::Eq, true) | (BinOp::Ne, false) => Cmp::Eq,
                    _ => return st,
                };
                let mut next = st?;
                let (a, b) = (self.eval(*lhs, &next), self.eval(*rhs, &next));
                // lhs OP b, and rhs OP' a (the mirrored comparison).
                let mirrored = match op {
                    Cmp::Lt => Cmp::Gt,
                    Cmp::Le => Cmp::Ge,
                    Cmp::Gt => Cmp::Lt,
                    Cmp::Ge => Cmp::Le,
                    Cmp::Eq => Cmp::Eq,
                };
                let ok = self.narrow(&mut next, *lhs, op, b) && self.narrow(&mut next, *rhs, mirrored, a);
                ok.then_some(next)
            }
            _ => st,
        }
    }

    /// Narrow the local in `e` (`l`, `l + c` or `l - c`) so that `e OP other` can hold;
    /// false if it cannot.
    fn narrow(&self, env: &mut [Stored], e_id: ExprId, op: Cmp, other: Range) -> bool {
        let e = &self.f.exprs[e_id];
        let (l, offset) = match &e.kind {
            ExprKind::Local(l) => (*l, 0),
            ExprKind::Binary {
                op: bop @ (BinOp::Add | BinOp::Sub),
                lhs,
                rhs,
            } => match (&self.f.exprs[*lhs].kind, &self.f.exprs[*rhs].kind) {
                (ExprKind::Local(l), ExprKind::Const(ConstValue::Int(c))) => {
                    (*l, if *bop == BinOp::Add { *c as i64 } else { -(*c as i64) })
                }
                _ => return true,
            },
            _ => return true,
        };
        let Some(at) = self.slot(l) else {
            return true;
        };
        let Some(cur) = env.get(at).copied().map(range) else {
            return true;
        };
        // `l + offset` must not wrap for the shift to be exact.
        if cur.0 + offset < TOP.0 || cur.1 + offset > TOP.1 {
            return true;
        }
        let (lo, hi) = (cur.0 + offset, cur.1 + offset);
        let (lo, hi) = match op {
            Cmp::Lt => (lo, hi.min(other.1 - 1)),
            Cmp::Le => (lo, hi.min(other.1)),
            Cmp::Gt => (lo.max(other.0 + 1), hi),
            Cmp::Ge => (lo.max(other.0), hi),
            Cmp::Eq => (lo.max(other.0), hi.min(other.1)),
        };
        if lo > hi {
            return false;
        }
        env[at] = stored((lo - offset, hi - offset));
        true
    }
}

/// Mark (by local) the locals that `list` assigns whole from a value that reads them
/// (`i = i + 1`, `n = max(n, m)`): the loop counters, widened before other locals.
fn counters_in(f: &Function, list: &[StmtId], out: &mut [bool]) {
    super::for_each_assign(&f.stmts, list, &mut |place, value| {
        if place.indices.is_empty() && f.exprs.reads_any(value, &|l| l == place.local) {
            if let Some(c) = out.get_mut(place.local.0 as usize) {
                *c = true;
            }
        }
    });
}

#[derive(Clone, Copy)]
enum Cmp {
    Lt,
    Le,
    Gt,
    Ge,
    Eq,
}

/// Whether `refine` leaves every state as it is under `cond` (either way), so a `?:` on it
/// need not copy its state per arm: a condition that is not a constant, `!`, `&&`, `||` or
/// a comparison (a `bool` local, a call).
fn refines_nothing(cond: &Expr) -> bool {
    !matches!(
        cond.kind,
        ExprKind::Const(ConstValue::Bool(_)) | ExprKind::Unary { op: UnaryOp::Not, .. } | ExprKind::Binary { .. }
    )
}

fn is_int(e: &Expr) -> bool {
    e.ty.is_scalar() && e.ty.elem == Elem::Scalar(Scalar::Int)
}
