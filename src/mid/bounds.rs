//! Value bounds of float expressions, so a float -> int conversion that cannot see NaN or a
//! value outside i32 needs none of its saturation fix-ups (one `cvttps2dq` instead of eight
//! instructions on x86_64; see `fixed::convert_bounded`).
//!
//! What is bounded: the pixel centre `X`, `Y` parameters (the runtime renders into frames of
//! at most `MAX_IMAGE_SIDE` pixels a side, and lanes past a rectangle's end stay within a
//! group of it), float and int constants, and what `+ - * /`, negation, `?:`, and the
//! built-ins `abs min max clamp floor ceil round sqrt sign step mix sin cos` make of bounded
//! operands. Everything else (other parameters, loads of anything not a float local, int
//! arithmetic, libm calls that can overflow) is unbounded.
//!
//! Locals are bounded flow-insensitively: a float local's bound is the union over *every*
//! assignment to it anywhere in the function (setup and pixel code, every `if` side and loop
//! body), plus zero (a declaration without an initialiser assigns zero; a read before any
//! assignment sees zero). So a pixel-code assignment of something unbounded to a local that
//! first held `X` makes it unbounded, and helper parameters (the checker's temporaries,
//! assigned from the arguments) carry the arguments' bounds. Assignments are joined until
//! nothing changes; a local still growing after `WIDEN_AFTER` rounds (`x = x + 1` in a
//! loop) becomes unbounded, so the walk ends.
//!
//! Invariant the users rely on: if `expr` gives `Some(b)`, every lane value the JIT can
//! compute for that expression is a finite, non-NaN `f32` in `[b.lo, b.hi]`. Interval
//! ends are kept in f64 and every rounded operation widens them outward by more than one
//! f32 rounding step; a bound past `MAX_FINITE` is dropped (the f32 operation could
//! overflow to infinity, and infinity minus infinity is NaN).
//!
//! Guards refine this flow-sensitively ([`GuardFacts`], asked through
//! [`LocalBounds::expr_here`]): after `if (c) return;` in pixel code every lane still
//! executing has `c` false, so comparisons of a scalar float local with constants that `c`
//! being false makes true (`!(z >= 0 && z <= 1)` gives z in [0, 1]; `||` that is false and
//! `&&` that is true give both sides; a comparison that is false gives nothing, since NaN
//! fails every ordered comparison) bound that local, not NaN, one end possibly infinite.
//! A fact lasts until the statement list holding the guard ends (a varying or uniform
//! `if`'s side, a loop body, the group body) or the local is assigned; a loop first ends
//! the facts about every local its body or step assigns (the body runs again after them).
//! Facts belong to the frame (inlined interpolator) they were made in. A guard the block
//! walk's pass variant drops (see `block`) gives the same facts: the block facts proved it
//! fires for no lane of the block, which is what a lowered guard ensures for the lanes that
//! go on.
//!
//! Why this is sound although the facts hold for executing lanes only: a conversion
//! narrowed by them computes, in a lane that is retired or outside the current `if` side,
//! some value other than the saturating one. Such lanes' values never matter, as already
//! for every other operation there (a retired lane's `z` may be NaN or anything; so its
//! converted value was already arbitrary): the depth test and every guard combine their
//! condition with the executing mask (`alive & !(entry & c)`), Z is written back only for
//! lanes that assigned it while executing, G-buffer stores and `interpolator_return`
//! blend under the mask, any/all-lane tests read masks, not values, and an index computed
//! from such a value is clamped into its array (only `ir::range`'s proofs skip the clamp,
//! and they know nothing of guards). Tier 0 numbers conversions by value: one narrowed by
//! facts is not recorded, so a later one of the same value where the facts do not hold
//! (the other side of a varying `if` in the same block, flat code) computes its own.
//! Tier 1's e-graph may move or merge the narrowed conversion, but only its users that
//! run where the facts hold read it.

use crate::ir::{
    for_each_assign, BinOp, Builtin, ConstValue, Elem, ExprId, ExprKind, Exprs, Function, LocalId, ParamRole, Scalar,
    UnaryOp,
};

/// Pixel centres the runtime can hand to pixel code, with a wide margin: frames are at most
/// `runtime::MAX_IMAGE_SIDE` (16384) pixels a side and a group's lanes past the rectangle
/// are at most three pixels further (tile-aligned groups of 4).
pub(crate) const PIXEL_CENTRE_LIMIT: f64 = 65536.0;

/// Bounds larger than this are dropped: an f32 operation on values within it cannot
/// overflow to infinity after one rounding.
const MAX_FINITE: f64 = 1e37;

/// Rounds of joining before a still-growing local is made unbounded.
const WIDEN_AFTER: usize = 8;

/// A closed range holding every value an expression can take; never NaN, never infinite.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Interval {
    pub lo: f64,
    pub hi: f64,
}

impl Interval {
    fn point(x: f64) -> Option<Interval> {
        Interval::new(x, x)
    }

    /// `None` unless both ends are finite, ordered and within `MAX_FINITE`.
    pub fn new(lo: f64, hi: f64) -> Option<Interval> {
        (lo <= hi && lo >= -MAX_FINITE && hi <= MAX_FINITE).then_some(Interval { lo, hi })
    }

    fn join(self, other: Interval) -> Interval {
        Interval {
            lo: self.lo.min(other.lo),
            hi: self.hi.max(other.hi),
        }
    }

    /// Outward by more than the rounding of one f32 operation (2^-24 relative, plus the
    /// smallest subnormal step), and of the f64 arithmetic that computed the ends.
    fn rounded(lo: f64, hi: f64) -> Option<Interval> {
        let slack = |x: f64| x.abs() * (1.0 / (1u64 << 20) as f64) + 1e-40;
        Interval::new(lo - slack(lo), hi + slack(hi))
    }

    /// Apply a monotone non-decreasing exact function (floor, ceil, round) to both ends.
    fn monotone(self, f: impl Fn(f64) -> f64) -> Option<Interval> {
        Interval::new(f(self.lo), f(self.hi))
    }
}

/// The hull of `f` applied to every pair of ends (for `*` and `/`, whose extremes are at
/// the corners), rounded outward.
pub fn corners(a: Interval, b: Interval, f: impl Fn(f64, f64) -> f64) -> Option<Interval> {
    let c = [f(a.lo, b.lo), f(a.lo, b.hi), f(a.hi, b.lo), f(a.hi, b.hi)];
    let lo = c.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = c.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    Interval::rounded(lo, hi)
}

/// Bounds of every float local of one function (see the module doc).
pub(crate) struct LocalBounds {
    /// Per local: `None` for unbounded (and for every local that is not a float).
    locals: Vec<Option<Interval>>,
}

impl LocalBounds {
    pub(crate) fn of_function(f: &Function) -> LocalBounds {
        let is_float = |i: usize| f.locals[i].ty.elem == Elem::Scalar(Scalar::Float);
        let mut locals: Vec<Option<Interval>> = (0..f.locals.len())
            .map(|i| is_float(i).then_some(Interval { lo: 0.0, hi: 0.0 }))
            .collect();
        for p in &f.params {
            let i = p.local.0 as usize;
            if i < locals.len() {
                locals[i] = match p.role {
                    ParamRole::X | ParamRole::Y if is_float(i) => Some(Interval {
                        lo: -PIXEL_CENTRE_LIMIT,
                        hi: PIXEL_CENTRE_LIMIT,
                    }),
                    // The runtime fills these: anything at all.
                    _ => None,
                };
            }
        }
        let mut table = LocalBounds { locals };
        let mut rounds = 0;
        loop {
            let mut changed = vec![false; table.locals.len()];
            for stmts in [&f.setup, &f.pixel] {
                for_each_assign(&f.stmts, stmts, &mut |place, value| {
                    let i = place.local.0 as usize;
                    let Some(Some(old)) = table.locals.get(i).copied() else {
                        return;
                    };
                    let new = table.expr(&f.exprs, value).map(|v| old.join(v));
                    if new != Some(old) {
                        table.locals[i] = new;
                        changed[i] = true;
                    }
                });
            }
            if !changed.contains(&true) {
                return table;
            }
            rounds += 1;
            if rounds >= WIDEN_AFTER {
                for (i, c) in changed.iter().enumerate() {
                    if *c {
                        table.locals[i] = None;
                    }
                }
            }
        }
    }

    /// The bound of `e`'s every component, or `None` if unbounded or not a float.
    pub(crate) fn expr(&self, x: &Exprs, e: ExprId) -> Option<Interval> {
        self.expr_with(x, e, &|_| None)
    }

    /// The bound of float expression `e` at a point of the pixel code where `facts` holds
    /// (see [`GuardFacts`]), as `(lo, hi)`: every executing lane's value is a non-NaN `f32`
    /// in `[lo, hi]`. An end may be infinite when `e` is a local bounded on one side only
    /// by a guard (`z >= 0`); inside arithmetic only finite bounds are used.
    pub(crate) fn expr_here(&self, x: &Exprs, e: ExprId, facts: &GuardFacts, frame: usize) -> Option<(f64, f64)> {
        if x[e].ty.elem != Elem::Scalar(Scalar::Float) {
            return self.expr(x, e).map(|b| (b.lo, b.hi));
        }
        if let ExprKind::Local(l) = x[e].kind {
            let whole = self.locals.get(l.0 as usize).copied().flatten();
            return match (facts.range(frame, l), whole) {
                (Some((lo, hi)), Some(w)) => {
                    let (lo, hi) = (lo.max(w.lo), hi.min(w.hi));
                    // An empty intersection: no executing lane reaches here; any bound is
                    // true of none of them, and the local's own bound is the safe choice.
                    if lo <= hi {
                        Some((lo, hi))
                    } else {
                        Some((w.lo, w.hi))
                    }
                }
                (Some(r), None) => Some(r),
                (None, w) => w.map(|w| (w.lo, w.hi)),
            };
        }
        let refined = |l: LocalId| {
            let (lo, hi) = facts.range(frame, l)?;
            let (lo, hi) = match self.locals.get(l.0 as usize).copied().flatten() {
                Some(w) => (lo.max(w.lo), hi.min(w.hi)),
                None => (lo, hi),
            };
            Interval::new(lo, hi)
        };
        self.expr_with(x, e, &refined).map(|b| (b.lo, b.hi))
    }

    /// [`Self::expr`] with `refined` answering first for scalar locals it knows.
    fn expr_with(&self, x: &Exprs, e: ExprId, refined: &dyn Fn(LocalId) -> Option<Interval>) -> Option<Interval> {
        let e = &x[e];
        match e.ty.elem {
            Elem::Scalar(Scalar::Float) => {}
            // An int constant converted to float (`X * 16`).
            Elem::Scalar(Scalar::Int) => {
                return match e.kind {
                    ExprKind::Const(ConstValue::Int(i)) => Interval::point(i as f64),
                    _ => None,
                }
            }
            _ => return None,
        }
        match &e.kind {
            ExprKind::Const(ConstValue::Float(x)) => Interval::point(*x as f64),
            ExprKind::Const(_) => None,
            ExprKind::Local(l) => refined(*l).or_else(|| self.locals.get(l.0 as usize).copied().flatten()),
            ExprKind::Index { base, .. } => {
                // Every element of a local shares its bound.
                let mut root = &x[*base];
                while let ExprKind::Index { base, .. } = &root.kind {
                    root = &x[*base];
                }
                match root.kind {
                    ExprKind::Local(l) => self.locals.get(l.0 as usize).copied().flatten(),
                    _ => None,
                }
            }
            ExprKind::Unary { op: UnaryOp::Neg, expr } => self
                .expr_with(x, *expr, refined)
                .and_then(|a| Interval::new(-a.hi, -a.lo)),
            ExprKind::Unary { .. } => None,
            ExprKind::Binary { op, lhs, rhs } => {
                let (a, b) = (self.expr_with(x, *lhs, refined)?, self.expr_with(x, *rhs, refined)?);
                match op {
                    BinOp::Add => Interval::rounded(a.lo + b.lo, a.hi + b.hi),
                    BinOp::Sub => Interval::rounded(a.lo - b.hi, a.hi - b.lo),
                    BinOp::Mul => corners(a, b, |x, y| x * y),
                    // A divisor interval holding zero could give infinity or 0/0.
                    BinOp::Div if b.lo > 0.0 || b.hi < 0.0 => corners(a, b, |x, y| x / y),
                    _ => None,
                }
            }
            // Int -> float rounds to nearest (only int constants are bounded, above).
            ExprKind::Convert(inner) => self
                .expr_with(x, *inner, refined)
                .and_then(|a| Interval::rounded(a.lo, a.hi)),
            ExprKind::Select { then, otherwise, .. } => Some(
                self.expr_with(x, *then, refined)?
                    .join(self.expr_with(x, *otherwise, refined)?),
            ),
            ExprKind::Builtin { func, args } => self.builtin(x, *func, args, refined),
            ExprKind::List(items) => {
                let mut all: Option<Interval> = None;
                for it in items {
                    let b = self.expr_with(x, *it, refined)?;
                    all = Some(all.map_or(b, |a| a.join(b)));
                }
                all
            }
            ExprKind::Splat(item) => self.expr_with(x, *item, refined),
            ExprKind::MatMul { .. } | ExprKind::SeqCount | ExprKind::ClipFlag => None,
        }
    }

    fn builtin(
        &self,
        x: &Exprs,
        func: Builtin,
        args: &[ExprId],
        refined: &dyn Fn(LocalId) -> Option<Interval>,
    ) -> Option<Interval> {
        let arg = |i: usize| args.get(i).and_then(|a| self.expr_with(x, *a, refined));
        let unit = Interval { lo: -1.0, hi: 1.0 };
        match func {
            Builtin::Abs => {
                let a = arg(0)?;
                let hi = a.lo.abs().max(a.hi.abs());
                let lo = if a.lo <= 0.0 && a.hi >= 0.0 {
                    0.0
                } else {
                    a.lo.abs().min(a.hi.abs())
                };
                Interval::new(lo, hi)
            }
            Builtin::Floor => arg(0)?.monotone(f64::floor),
            Builtin::Ceil => arg(0)?.monotone(f64::ceil),
            // Ties to even or away: both within [floor, ceil].
            Builtin::Round => Interval::new(arg(0)?.lo.floor(), arg(0)?.hi.ceil()),
            Builtin::Min => {
                let (a, b) = (arg(0)?, arg(1)?);
                Interval::new(a.lo.min(b.lo), a.hi.min(b.hi))
            }
            Builtin::Max => {
                let (a, b) = (arg(0)?, arg(1)?);
                Interval::new(a.lo.max(b.lo), a.hi.max(b.hi))
            }
            // min(max(x, lo), hi), monotone in each argument.
            Builtin::Clamp => {
                let (x, lo, hi) = (arg(0)?, arg(1)?, arg(2)?);
                Interval::new(x.lo.max(lo.lo).min(hi.lo), x.hi.max(lo.hi).min(hi.hi))
            }
            Builtin::Sqrt => {
                let a = arg(0)?;
                (a.lo >= 0.0).then(|| Interval::rounded(a.lo.sqrt(), a.hi.sqrt()))?
            }
            // Comparisons select between constants: NaN in gives one of them too.
            Builtin::Sign => Some(unit),
            // Never NaN: non-finite coordinates are taken as 0 (`ir::noise`).
            Builtin::Step | Builtin::Noise | Builtin::CellNoise => Some(Interval { lo: 0.0, hi: 1.0 }),
            // Finite in, within [-1, 1] out (libm's sin and cos of infinity are NaN).
            Builtin::Sin | Builtin::Cos => arg(0).map(|_| unit),
            Builtin::Mix => {
                // a + (b - a) * t, as the JIT computes it.
                let (a, b, t) = (arg(0)?, arg(1)?, arg(2)?);
                let d = Interval::rounded(b.lo - a.hi, b.hi - a.lo)?;
                let p = corners(d, t, |x, y| x * y)?;
                Interval::rounded(a.lo + p.lo, a.hi + p.hi)
            }
            _ => None,
        }
    }
}

/// One fact a guard established: every executing lane's value of scalar float local
/// `local` (of the frame at depth `frame`) is a non-NaN `f32` in `[lo, hi]` (ends may be
/// infinite). `live` turns false when the local is assigned again.
#[derive(Clone, Copy, Debug)]
struct Fact {
    frame: usize,
    local: LocalId,
    lo: f64,
    hi: f64,
    live: bool,
}

/// Flow-sensitive bounds from the pixel code's guards (see the module doc): facts about
/// float locals that hold at the statement being lowered. Facts only ever get added at the
/// end and are cut back to a mark when the statement list that established them ends, and
/// an assignment only turns facts off: so a fact a nested list killed stays killed after it.
#[derive(Default)]
pub(crate) struct GuardFacts {
    facts: Vec<Fact>,
}

impl GuardFacts {
    /// How many facts there are, to [`Self::truncate`] back to when a statement list ends.
    pub(crate) fn mark(&self) -> usize {
        self.facts.len()
    }

    pub(crate) fn truncate(&mut self, mark: usize) {
        self.facts.truncate(mark);
    }

    /// No fact recorded (always so outside a group body): nothing to end.
    pub(crate) fn is_empty(&self) -> bool {
        self.facts.is_empty()
    }

    pub(crate) fn clear(&mut self) {
        self.facts.clear();
    }

    /// `local` of frame `frame` is assigned: nothing known about it holds any more.
    pub(crate) fn kill(&mut self, frame: usize, local: LocalId) {
        for f in &mut self.facts {
            if f.frame == frame && f.local == local {
                f.live = false;
            }
        }
    }

    /// Frames from depth `frame` on are gone (or new): their locals are other variables.
    pub(crate) fn kill_frames_from(&mut self, frame: usize) {
        for f in &mut self.facts {
            if f.frame >= frame {
                f.live = false;
            }
        }
    }

    /// The intersection of the live facts about `local`, if any.
    pub(crate) fn range(&self, frame: usize, local: LocalId) -> Option<(f64, f64)> {
        let mut out: Option<(f64, f64)> = None;
        for f in &self.facts {
            if f.live && f.frame == frame && f.local == local {
                out = Some(match out {
                    Some((lo, hi)) => (lo.max(f.lo), hi.min(f.hi)),
                    None => (f.lo, f.hi),
                });
            }
        }
        out
    }

    /// Every lane executing from here on has `cond` equal to `holds`: record what that says
    /// about float locals. Only comparisons that exclude NaN give a fact: a comparison
    /// other than `!=` that holds, or a `!=` that does not (NaN compares unordered, so
    /// `!(z < 0)` lets NaN through and says nothing); `&&` that holds and `||` that does not
    /// give both sides' facts, `!` flips. Anything else says nothing.
    pub(crate) fn assume(&mut self, x: &Exprs, frame: usize, cond: ExprId, holds: bool) {
        match &x[cond].kind {
            ExprKind::Unary { op: UnaryOp::Not, expr } => self.assume(x, frame, *expr, !holds),
            ExprKind::Binary {
                op: BinOp::And,
                lhs,
                rhs,
            } if holds => {
                self.assume(x, frame, *lhs, true);
                self.assume(x, frame, *rhs, true);
            }
            ExprKind::Binary {
                op: BinOp::Or,
                lhs,
                rhs,
            } if !holds => {
                self.assume(x, frame, *lhs, false);
                self.assume(x, frame, *rhs, false);
            }
            ExprKind::Binary { op, lhs, rhs } => {
                // `local op c` or `c op local`, the latter read as `local op' c`.
                let (local, c, op) = match (scalar_float_local(&x[*lhs]), float_const(x, *rhs)) {
                    (Some(l), Some(c)) => (l, c, *op),
                    _ => match (float_const(x, *lhs), scalar_float_local(&x[*rhs])) {
                        (Some(c), Some(l)) => (l, c, mirrored(*op)),
                        _ => return,
                    },
                };
                let inf = f64::INFINITY;
                let range = match (op, holds) {
                    // z < c holds: z <= c (closed ends are the bound's form; still true).
                    (BinOp::Lt | BinOp::Le, true) => (-inf, c),
                    (BinOp::Gt | BinOp::Ge, true) => (c, inf),
                    (BinOp::Eq, true) | (BinOp::Ne, false) => (c, c),
                    _ => return,
                };
                self.facts.push(Fact {
                    frame,
                    local,
                    lo: range.0,
                    hi: range.1,
                    live: true,
                });
            }
            _ => {}
        }
    }
}

/// `c op x` as `x op' c`.
fn mirrored(op: BinOp) -> BinOp {
    match op {
        BinOp::Lt => BinOp::Gt,
        BinOp::Le => BinOp::Ge,
        BinOp::Gt => BinOp::Lt,
        BinOp::Ge => BinOp::Le,
        other => other,
    }
}

/// A plain scalar float local (not an element, not a vector).
fn scalar_float_local(e: &crate::ir::Expr) -> Option<LocalId> {
    match e.kind {
        ExprKind::Local(l) if e.ty.elem == Elem::Scalar(Scalar::Float) && e.ty.is_scalar() => Some(l),
        _ => None,
    }
}

/// A float-typed constant (a float literal, or an int literal compared as a float) whose
/// value is exact in f32; `None` for anything else.
fn float_const(x: &Exprs, id: ExprId) -> Option<f64> {
    let e = &x[id];
    let v = match &e.kind {
        ExprKind::Const(ConstValue::Float(v)) => *v as f64,
        ExprKind::Const(ConstValue::Int(i)) if e.ty.elem == Elem::Scalar(Scalar::Float) => *i as f64,
        ExprKind::Convert(inner) if e.ty.elem == Elem::Scalar(Scalar::Float) => match x[*inner].kind {
            ExprKind::Const(ConstValue::Int(i)) => i as f64,
            _ => return None,
        },
        ExprKind::Unary { op: UnaryOp::Neg, expr } => -float_const(x, *expr)?,
        _ => return None,
    };
    // The comparison is made in f32: the constant must be the value the lanes compare with.
    (e.ty.elem == Elem::Scalar(Scalar::Float) && (v as f32) as f64 == v && v.is_finite()).then_some(v)
}
