//! Block-level culling: decide for a whole block of pixels, from uniform data, that no lane
//! can survive the primitive's leading coverage tests (skip the block), or that every lane
//! passes them (run a variant of the pixel code without those tests), the way hierarchical
//! rasterizers do it, but derived from the pixel-centric source.
//!
//! Two halves:
//! - [`crate::mid::block::prefix`] (compile time, in the plan) finds the *guard prefix* of a
//!   primitive's pixel part: leading assignments of pure expressions to varying scalar
//!   locals, `if (c) return;` guards on varying conditions, and uniform `if`s of such
//!   statements; nothing in it has an effect, so a block where every lane leaves at a guard
//!   does nothing at all.
//! - [`Lower::block_facts`] (run time, once per block) re-evaluates the prefix over the
//!   block's pixel rectangle with interval arithmetic emitted as scalar CLIF, and yields two
//!   flags: `dead` (some guard fires for every lane that reaches it) and `pass` (no
//!   decidable guard fires for any lane). The evaluation is staged: [`Lower::block_cache_row`]
//!   runs once per block row and computes every subexpression that needs no X (uniform
//!   ones, and those whose only varying input is Y) into an [`AbsCache`]; per block only
//!   the X-dependent rest is computed. (Measured: recomputing everything per block was 1020
//!   instructions per block for screen_triangle, a third of a fill frame's kernel work.)
//!   Which guards are decidable ([`BlockFacts::decidable`]) comes out of this evaluation:
//!   a guard is decidable when the evaluator models its condition.
//!
//! Soundness: every float operation used (+, -, *, /, conversions, abs/min/max/floor/ceil)
//! is monotone in each operand once rounded (round-to-nearest is monotone), so evaluating
//! the endpoints with the *same* f32 operations bounds every pixel's value bit for bit; an
//! interval with a non-finite endpoint, a divisor interval containing zero, or an integer
//! interval leaving the i32 range (the pixel code would wrap) is marked not `ok` and decides
//! nothing. Expressions the evaluator does not model (fixed point, Z, selects, ...) are
//! [`Abs::Top`]; a guard on such a condition is *undecidable*: it never makes a block dead or
//! passing and stays in both variants.

use std::collections::{HashMap, HashSet};

use cranelift_codegen::ir::{self, condcodes::FloatCC, condcodes::IntCC, types, Block, InstBuilder};

use super::{elem_scalar, Lower, Res};
use crate::ir::{BinOp, Builtin, Elem, ExprId, ExprKind, Exprs, Function, LocalId, Scalar, UnaryOp};
use crate::jit::fixed;
use crate::mid::block::{no_effect_in_pass, PStmt, Prefix};

fn reads_any(x: &Exprs, e: ExprId, set: &HashSet<LocalId>) -> bool {
    x.reads_any(e, &|l| set.contains(&l))
}

/// The abstract value of a scalar expression over a block (run-time values, all scalar).
#[derive(Clone)]
pub(super) enum Abs {
    /// Nothing known.
    Top,
    /// Every pixel's f32 value lies in [lo, hi] when `ok` (i8) is set.
    F {
        lo: ir::Value,
        hi: ir::Value,
        ok: ir::Value,
    },
    /// Every pixel's i32 value lies in [lo, hi] (i64 endpoints) when `ok` is set.
    I {
        lo: ir::Value,
        hi: ir::Value,
        ok: ir::Value,
    },
    /// Some pixel may see true (`t` != 0) / false (`f` != 0); both i8.
    B { t: ir::Value, f: ir::Value },
}

/// When an abstract value is computed. The row stage's code dominates the block loop of
/// its block row, so its values are reused by every block (through [`AbsCache`]) instead
/// of being recomputed per block.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub(super) enum Stage {
    /// Once per block row: uniform subexpressions and those whose only varying input is Y.
    Row,
    /// Per block: everything else, and the block's facts.
    Block,
}

/// Abstract values computed at an earlier stage, keyed by the expression's id (each prefix
/// expression sits at one program point, so one walk gives it one value).
#[derive(Clone, Default)]
pub(super) struct AbsCache {
    values: HashMap<ExprId, Abs>,
    /// The uniform conditions of the prefix's `if`s (i8), computed at [`Stage::Row`].
    conds: HashMap<ExprId, ir::Value>,
}

/// What the interval evaluation knows while it walks the prefix.
#[derive(Clone)]
pub(super) struct BlockEnv<'a> {
    /// Values of the varying locals the prefix assigned so far; `None`: not computable at
    /// this stage (it depends on X, or on Y before [`Stage::Row`]).
    locals: HashMap<LocalId, Option<Abs>>,
    /// Locals assigned anywhere in the pixel part: their uniform value is not the block's.
    pixel_assigned: &'a HashSet<LocalId>,
    /// The pixel-centre ranges of the block, when the stage knows them.
    x: Option<Abs>,
    y: Option<Abs>,
    x_local: Option<LocalId>,
    y_local: Option<LocalId>,
    stage: Stage,
}

/// The block-level facts and which guards they cover.
pub(super) struct BlockFacts {
    /// i8: no lane of the block survives the prefix.
    pub dead: ir::Value,
    /// i8: no decidable guard fires for any lane of the block.
    pub pass: ir::Value,
    /// Per guard id: the evaluator can decide it (the fast variant drops it).
    pub decidable: Vec<bool>,
}

/// The facts accumulated while walking at [`Stage::Block`] (`None`: the constant false for
/// `dead`, true for `pass`, so earlier stages emit nothing for them).
struct Flags {
    dead: Option<ir::Value>,
    pass: Option<ir::Value>,
}

impl<'a> Lower<'a, '_> {
    fn block_env(
        &mut self,
        f: &'a Function,
        stage: Stage,
        x: Option<[ir::Value; 2]>,
        y: Option<[ir::Value; 2]>,
    ) -> Res<BlockEnv<'a>> {
        let pixel_assigned = &self.pixel_plan()?.assigned;
        let role = |r| f.params.iter().find(|q| q.role == r).map(|q| q.local);
        let x_local = role(crate::ir::ParamRole::X).filter(|l| elem_scalar(&f.local(*l).ty) == Scalar::Float);
        let y_local = role(crate::ir::ParamRole::Y).filter(|l| elem_scalar(&f.local(*l).ty) == Scalar::Float);
        let mut range = |r: Option<[ir::Value; 2]>| {
            r.map(|[lo, hi]| {
                let ok = self.iconst_here(types::I8, 1);
                Abs::F { lo, hi, ok }
            })
        };
        let (x, y) = (range(x), range(y));
        Ok(BlockEnv {
            locals: HashMap::new(),
            pixel_assigned,
            x,
            y,
            x_local,
            y_local,
            stage,
        })
    }

    /// Once per block row (pixel centres y in [y_lo, y_hi]): the prefix's subexpressions
    /// whose only varying input is Y, and its uniform ones.
    pub(super) fn block_cache_row(&mut self, f: &'a Function, p: &Prefix, y: [ir::Value; 2]) -> Res<AbsCache> {
        let mut env = self.block_env(f, Stage::Row, None, Some(y))?;
        let mut cache = AbsCache::default();
        let mut flags = Flags { dead: None, pass: None };
        let mut decidable = vec![false; p.guards];
        self.abs_stmts(&p.stmts, &mut env, &mut cache, &mut flags, &mut decidable)?;
        Ok(cache)
    }

    /// Evaluate the prefix over pixel centres x in [x_lo, x_hi] and y in [y_lo, y_hi]
    /// (f32 values computed exactly as the pixel code computes X and Y), reusing the row
    /// stage's values for that y range.
    pub(super) fn block_facts(
        &mut self,
        f: &'a Function,
        p: &Prefix,
        row: &AbsCache,
        x: [ir::Value; 2],
        y: [ir::Value; 2],
    ) -> Res<BlockFacts> {
        let mut env = self.block_env(f, Stage::Block, Some(x), Some(y))?;
        let mut cache = row.clone();
        let mut flags = Flags { dead: None, pass: None };
        let mut decidable = vec![false; p.guards];
        self.abs_stmts(&p.stmts, &mut env, &mut cache, &mut flags, &mut decidable)?;
        let dead = match flags.dead {
            Some(d) => d,
            None => self.iconst_here(types::I8, 0),
        };
        let pass = match flags.pass {
            Some(p) => p,
            None => self.iconst_here(types::I8, 1),
        };
        Ok(BlockFacts { dead, pass, decidable })
    }

    fn abs_stmts(
        &mut self,
        stmts: &[PStmt],
        env: &mut BlockEnv<'a>,
        cache: &mut AbsCache,
        flags: &mut Flags,
        decidable: &mut [bool],
    ) -> Res<()> {
        let block = env.stage == Stage::Block;
        for s in stmts {
            match s {
                PStmt::Assign { local, value, .. } => {
                    let v = self.abs_expr(*value, env, cache)?;
                    let to = elem_scalar(&self.frame().func.local(*local).ty);
                    let from = elem_scalar(&self.exprs()[*value].ty);
                    let v = v.map(|v| self.abs_convert(v, from, to));
                    env.locals.insert(*local, v);
                }
                PStmt::Guard { cond, id, .. } => {
                    let v = self.abs_expr(*cond, env, cache)?;
                    if let (true, Some(Abs::B { t, f })) = (block, v) {
                        decidable[*id] = true;
                        let fires_everywhere = self.b.ins().icmp_imm_s(IntCC::Equal, f, 0);
                        flags.dead = Some(match flags.dead {
                            Some(d) => self.b.ins().bor(d, fires_everywhere),
                            None => fires_everywhere,
                        });
                        let never_fires = self.b.ins().icmp_imm_s(IntCC::Equal, t, 0);
                        flags.pass = Some(match flags.pass {
                            Some(p) => self.b.ins().band(p, never_fires),
                            None => never_fires,
                        });
                    }
                }
                PStmt::Kill(_) => {
                    if block {
                        flags.dead = Some(self.iconst_here(types::I8, 1));
                    }
                }
                PStmt::UniformIf { cond, then, otherwise } => {
                    // A condition reading a local the pixel code assigns is read per block
                    // (its value is the one the previous group left); others once, at
                    // the row stage. Before the block stage such a condition is not
                    // known, and neither are the locals its sides assign.
                    let cacheable = !reads_any(self.exprs(), *cond, env.pixel_assigned);
                    let c = match cache.conds.get(&*cond) {
                        Some(&c) => Some(c),
                        None if cacheable || block => {
                            let c = self.eval_uniform(*cond)?;
                            let c = fixed::convert(&mut self.b, c.scalar, Scalar::Bool, c.comps[0]);
                            if cacheable {
                                cache.conds.insert(*cond, c);
                            }
                            Some(c)
                        }
                        None => None,
                    };
                    if let (true, Some(c)) = (block, c) {
                        self.abs_branch(c, then, otherwise, env, cache, flags, decidable)?;
                        continue;
                    }
                    // Before the block stage both sides are walked (their subexpressions
                    // get cached for the block stage, which takes one side only): a branch
                    // here would carry every cached value through a join, and moving them
                    // cost about what the untaken side's Y terms do.
                    let mut sides = vec![];
                    for branch in [then, otherwise] {
                        let mut side_env = env.clone();
                        let mut side_flags = Flags { dead: None, pass: None };
                        self.abs_stmts(branch, &mut side_env, cache, &mut side_flags, decidable)?;
                        sides.push(side_env.locals);
                    }
                    let else_locals = sides.pop().expect("two sides");
                    let then_locals = sides.pop().expect("two sides");
                    let keys: HashSet<LocalId> = then_locals.keys().chain(else_locals.keys()).copied().collect();
                    for k in keys {
                        let merged = match (c, then_locals.get(&k), else_locals.get(&k)) {
                            (None, _, _) => None,
                            (Some(c), Some(Some(a)), Some(Some(b))) => Some(self.abs_select(c, a, b)),
                            (_, Some(None), _) | (_, _, Some(None)) => None,
                            _ => Some(Abs::Top),
                        };
                        env.locals.insert(k, merged);
                    }
                }
            }
        }
        Ok(())
    }

    /// A uniform `if` of the prefix whose condition `c` is known at this stage: only the
    /// side `c` takes is evaluated, behind a real branch (evaluating both and selecting cost
    /// every block the untaken side too: for screen_triangle, the float edge functions of
    /// an exact triangle). At the join, block parameters carry what each side produced:
    /// the flags (block stage), the locals it assigned, and the cache entries a later stage
    /// reads; a side that did not produce a value passes one that knows nothing.
    #[allow(clippy::too_many_arguments)]
    fn abs_branch(
        &mut self,
        c: ir::Value,
        then: &[PStmt],
        otherwise: &[PStmt],
        env: &mut BlockEnv<'a>,
        cache: &mut AbsCache,
        flags: &mut Flags,
        decidable: &mut [bool],
    ) -> Res<()> {
        let block = env.stage == Stage::Block;
        let then_blk = self.b.create_block();
        let else_blk = self.b.create_block();
        let then_tail = self.b.create_block();
        let join = self.b.create_block();
        self.b.ins().brif(c, then_blk, &[], else_blk, &[]);
        let mut sides = vec![];
        for (branch, start) in [(then, then_blk), (otherwise, else_blk)] {
            self.b.switch_to_block(start);
            let before_values: HashSet<ExprId> = cache.values.keys().copied().collect();
            let before_conds: HashSet<ExprId> = cache.conds.keys().copied().collect();
            let mut side_env = env.clone();
            let mut side_flags = Flags { dead: None, pass: None };
            self.abs_stmts(branch, &mut side_env, cache, &mut side_flags, decidable)?;
            // What this side added to the cache is valid on its path only.
            let new_values = take_new(&mut cache.values, &before_values);
            let new_conds = take_new(&mut cache.conds, &before_conds);
            sides.push((side_env.locals, side_flags, new_values, new_conds));
            if start == then_blk {
                // The then side's jump to the join is emitted from `then_tail`, once the
                // join's parameters are known.
                self.b.ins().jump(then_tail, &[]);
            }
        }
        let (else_locals, fe, else_values, else_conds) = sides.pop().expect("two sides");
        let (then_locals, ft, then_values, then_conds) = sides.pop().expect("two sides");

        let mut carried: Vec<Carried> = vec![];
        if block {
            for (dead, a, b) in [(true, ft.dead, fe.dead), (false, ft.pass, fe.pass)] {
                if a.is_some() || b.is_some() {
                    carried.push(Carried {
                        shape: Shape::Flag { dead },
                        parts: [a.map(|v| vec![v]), b.map(|v| vec![v])],
                        to: Carry::Flag { dead },
                    });
                }
            }
        }
        let mut keys: Vec<LocalId> = then_locals.keys().chain(else_locals.keys()).copied().collect();
        keys.sort_by_key(|l| l.0);
        keys.dedup();
        for k in keys {
            match (then_locals.get(&k), else_locals.get(&k)) {
                (Some(Some(a)), Some(Some(b))) if abs_parts(a) == abs_parts(b) && same_shape(a, b) => {
                    // Unchanged by either side (or the same value on both).
                    env.locals.insert(k, Some(a.clone()));
                }
                (Some(Some(a)), Some(Some(b))) if same_shape(a, b) && !matches!(a, Abs::Top) => {
                    carried.push(Carried {
                        shape: Shape::Abs(a.clone()),
                        parts: [Some(abs_parts(a)), Some(abs_parts(b))],
                        to: Carry::Local(k),
                    });
                }
                (Some(None), _) | (_, Some(None)) => {
                    env.locals.insert(k, None);
                }
                _ => {
                    env.locals.insert(k, Some(Abs::Top));
                }
            }
        }
        if !block {
            // A later stage reads these, each computed on one side only.
            for (side, values, conds) in [(0, &then_values, &then_conds), (1, &else_values, &else_conds)] {
                for (k, v) in values {
                    if matches!(v, Abs::Top) {
                        cache.values.insert(*k, Abs::Top);
                        continue;
                    }
                    let mut parts = [None, None];
                    parts[side] = Some(abs_parts(v));
                    carried.push(Carried {
                        shape: Shape::Abs(v.clone()),
                        parts,
                        to: Carry::Value(*k),
                    });
                }
                for (k, v) in conds {
                    let mut parts = [None, None];
                    parts[side] = Some(vec![*v]);
                    carried.push(Carried {
                        shape: Shape::Cond,
                        parts,
                        to: Carry::Cond(*k),
                    });
                }
            }
        }

        self.join_sides(&carried, then_tail, join, env, cache, flags);
        Ok(())
    }

    /// Join the two sides of [`Self::abs_branch`] at `join`: one block parameter per part of
    /// each carried value, passed by the else side (the current block) and then by
    /// `then_tail` (a side that did not produce a value passes one that knows nothing), and
    /// the joined values put where they belong: the flags, `env`'s locals, `cache`.
    fn join_sides(
        &mut self,
        carried: &[Carried],
        then_tail: Block,
        join: Block,
        env: &mut BlockEnv<'a>,
        cache: &mut AbsCache,
        flags: &mut Flags,
    ) {
        let mut params = vec![];
        for cv in carried {
            let first = cv.parts.iter().flatten().next().expect("one side has the value");
            let tys: Vec<ir::Type> = first.iter().map(|v| self.b.func.dfg.value_type(*v)).collect();
            params.push(
                tys.into_iter()
                    .map(|ty| self.b.append_block_param(join, ty))
                    .collect::<Vec<_>>(),
            );
        }
        // The else side's last block is the current one; then `then_tail`.
        for side in [1, 0] {
            if side == 0 {
                self.b.switch_to_block(then_tail);
            }
            let mut args: Vec<ir::BlockArg> = vec![];
            for cv in carried {
                let parts = match &cv.parts[side] {
                    Some(p) => p.clone(),
                    None => self.unknown_parts(&cv.shape),
                };
                args.extend(parts.into_iter().map(ir::BlockArg::from));
            }
            self.b.ins().jump(join, &args);
        }
        self.b.switch_to_block(join);
        for (cv, ps) in carried.iter().zip(params) {
            match (&cv.to, &cv.shape) {
                (Carry::Flag { dead }, _) => {
                    let v = ps[0];
                    let slot = if *dead { &mut flags.dead } else { &mut flags.pass };
                    *slot = Some(match *slot {
                        Some(x) if *dead => self.b.ins().bor(x, v),
                        Some(x) => self.b.ins().band(x, v),
                        None => v,
                    });
                }
                (Carry::Local(k), Shape::Abs(shape)) => {
                    env.locals.insert(*k, Some(abs_from_parts(shape, &ps)));
                }
                (Carry::Value(k), Shape::Abs(shape)) => {
                    cache.values.insert(*k, abs_from_parts(shape, &ps));
                }
                (Carry::Cond(k), _) => {
                    cache.conds.insert(*k, ps[0]);
                }
                _ => {}
            }
        }
    }

    /// SSA values that know nothing, in the form of `shape`: an interval that is not `ok`,
    /// a bool with both outcomes possible, a `dead` flag that is false, a `pass` flag or a
    /// condition... (a condition is only read on the side that computed it).
    fn unknown_parts(&mut self, shape: &Shape) -> Vec<ir::Value> {
        match shape {
            Shape::Flag { dead } => vec![self.iconst_here(types::I8, if *dead { 0 } else { 1 })],
            Shape::Cond => vec![self.iconst_here(types::I8, 0)],
            Shape::Abs(Abs::Top) => vec![],
            Shape::Abs(Abs::F { .. }) => {
                let z = self.f32const_here(0.0);
                let no = self.iconst_here(types::I8, 0);
                vec![z, z, no]
            }
            Shape::Abs(Abs::I { .. }) => {
                let z = self.iconst_here(types::I64, 0);
                let no = self.iconst_here(types::I8, 0);
                vec![z, z, no]
            }
            Shape::Abs(Abs::B { .. }) => {
                let yes = self.iconst_here(types::I8, 1);
                vec![yes, yes]
            }
        }
    }

    fn abs_select(&mut self, c: ir::Value, a: &Abs, b: &Abs) -> Abs {
        let mut sel = |x: ir::Value, y: ir::Value| if x == y { x } else { self.b.ins().select(c, x, y) };
        match (a, b) {
            (Abs::F { lo, hi, ok }, Abs::F { lo: l2, hi: h2, ok: o2 }) => Abs::F {
                lo: sel(*lo, *l2),
                hi: sel(*hi, *h2),
                ok: sel(*ok, *o2),
            },
            (Abs::I { lo, hi, ok }, Abs::I { lo: l2, hi: h2, ok: o2 }) => Abs::I {
                lo: sel(*lo, *l2),
                hi: sel(*hi, *h2),
                ok: sel(*ok, *o2),
            },
            (Abs::B { t, f }, Abs::B { t: t2, f: f2 }) => Abs::B {
                t: sel(*t, *t2),
                f: sel(*f, *f2),
            },
            _ => Abs::Top,
        }
    }

    /// i8: |v| is finite.
    fn finite(&mut self, v: ir::Value) -> ir::Value {
        let a = self.b.ins().fabs(v);
        let inf = self.f32const_here(f32::INFINITY);
        self.b.ins().fcmp(FloatCC::LessThan, a, inf)
    }

    /// i8: the i64 `v` is in the i32 range, i.e. `v + 2^31` (wrapping) in [0, 2^32) as an
    /// unsigned number: one add and one compare instead of two compares and an and (a
    /// block evaluates this for both ends of every integer interval).
    fn fits_i32(&mut self, v: ir::Value) -> ir::Value {
        let shifted = self.b.ins().iadd_imm_s(v, 1i64 << 31);
        self.b
            .ins()
            .icmp_imm_u(IntCC::UnsignedLessThanOrEqual, shifted, u32::MAX as i64)
    }

    fn float_iv(&mut self, lo: ir::Value, hi: ir::Value, ok: ir::Value) -> Abs {
        let a = self.finite(lo);
        let b = self.finite(hi);
        let ok = self.b.ins().band(ok, a);
        let ok = self.b.ins().band(ok, b);
        Abs::F { lo, hi, ok }
    }

    fn int_iv(&mut self, lo: ir::Value, hi: ir::Value, ok: ir::Value) -> Abs {
        let a = self.fits_i32(lo);
        let b = self.fits_i32(hi);
        let ok = self.b.ins().band(ok, a);
        let ok = self.b.ins().band(ok, b);
        Abs::I { lo, hi, ok }
    }

    /// A uniform value as a one-point abstract value.
    fn abs_point(&mut self, sc: Scalar, v: ir::Value) -> Abs {
        match sc {
            Scalar::Float => {
                let ok = self.iconst_here(types::I8, 1);
                self.float_iv(v, v, ok)
            }
            Scalar::Int => {
                let w = self.b.ins().sextend(types::I64, v);
                let ok = self.iconst_here(types::I8, 1);
                Abs::I { lo: w, hi: w, ok }
            }
            Scalar::Bool => {
                let f = self.b.ins().bxor_imm_s(v, 1);
                Abs::B { t: v, f }
            }
            Scalar::Fixed(_) => Abs::Top,
        }
    }

    /// The abstract value of `e`, or `None` when it needs a range a later stage has (X, or
    /// Y before [`Stage::Row`]). Every value computed is cached, so a later stage reuses it.
    fn abs_expr(&mut self, e: ExprId, env: &BlockEnv<'a>, cache: &mut AbsCache) -> Res<Option<Abs>> {
        if let Some(v) = cache.values.get(&e) {
            return Ok(Some(v.clone()));
        }
        let v = self.abs_expr_uncached(e, env, cache)?;
        if let Some(v) = &v {
            cache.values.insert(e, v.clone());
        }
        Ok(v)
    }

    fn abs_expr_uncached(&mut self, e_id: ExprId, env: &BlockEnv<'a>, cache: &mut AbsCache) -> Res<Option<Abs>> {
        let e = &self.exprs()[e_id];
        let sc = elem_scalar(&e.ty);
        let scalar_shape = e.ty.dims.is_empty() && !e.ty.per_seq && matches!(e.ty.elem, Elem::Scalar(_));
        if !scalar_shape {
            return Ok(Some(Abs::Top));
        }
        // A uniform value is one point. (One reading a local the pixel code assigns changes
        // from group to group: it is evaluated structurally below, its leaves unknown.)
        if !e.var.is_varying() && !reads_any(self.exprs(), e_id, env.pixel_assigned) && !matches!(sc, Scalar::Fixed(_))
        {
            let v = self.eval_uniform(e_id)?;
            return Ok(Some(self.abs_point(v.scalar, v.comps[0])));
        }
        Ok(Some(match &e.kind {
            ExprKind::Local(l) => {
                if let Some(v) = env.locals.get(l) {
                    return Ok(v.clone());
                } else if Some(*l) == env.x_local {
                    return Ok(env.x.clone());
                } else if Some(*l) == env.y_local {
                    return Ok(env.y.clone());
                } else {
                    Abs::Top
                }
            }
            ExprKind::Unary { op, expr } => {
                let Some(v) = self.abs_expr(*expr, env, cache)? else {
                    return Ok(None);
                };
                match (op, v) {
                    (UnaryOp::Not, Abs::B { t, f }) => Abs::B { t: f, f: t },
                    (UnaryOp::Neg, Abs::F { lo, hi, ok }) => {
                        let nlo = self.b.ins().fneg(hi);
                        let nhi = self.b.ins().fneg(lo);
                        Abs::F { lo: nlo, hi: nhi, ok }
                    }
                    (UnaryOp::Neg, Abs::I { lo, hi, ok }) => {
                        let nlo = self.b.ins().ineg(hi);
                        let nhi = self.b.ins().ineg(lo);
                        self.int_iv(nlo, nhi, ok)
                    }
                    _ => Abs::Top,
                }
            }
            ExprKind::Convert(inner) => {
                let Some(v) = self.abs_expr(*inner, env, cache)? else {
                    return Ok(None);
                };
                self.abs_convert(v, elem_scalar(&self.exprs()[*inner].ty), sc)
            }
            ExprKind::Binary { op, lhs, rhs } => {
                if elem_scalar(&self.exprs()[*lhs].ty) != elem_scalar(&self.exprs()[*rhs].ty) {
                    return Ok(Some(Abs::Top));
                }
                // Both sides first, so each is cached at the earliest stage it can be.
                let a = self.abs_expr(*lhs, env, cache)?;
                let c = self.abs_expr(*rhs, env, cache)?;
                let (Some(a), Some(c)) = (a, c) else {
                    return Ok(None);
                };
                self.abs_binary(*op, a, c)
            }
            ExprKind::Builtin { func, args } if sc == Scalar::Float => {
                if args.iter().any(|a| elem_scalar(&self.exprs()[*a].ty) != Scalar::Float) {
                    return Ok(Some(Abs::Top));
                }
                let mut vals = vec![];
                for a in args {
                    vals.push(self.abs_expr(*a, env, cache)?);
                }
                let Some(vals) = vals.into_iter().collect::<Option<Vec<_>>>() else {
                    return Ok(None);
                };
                self.abs_builtin(*func, &vals)
            }
            _ => Abs::Top,
        }))
    }

    fn abs_convert(&mut self, v: Abs, from: Scalar, to: Scalar) -> Abs {
        match (v, from, to) {
            (v, a, b) if a == b => v,
            // Truncation and saturation are monotone; `ok` excludes NaN.
            (Abs::F { lo, hi, ok }, Scalar::Float, Scalar::Int) => {
                let l = self.b.ins().fcvt_to_sint_sat(types::I32, lo);
                let h = self.b.ins().fcvt_to_sint_sat(types::I32, hi);
                let l = self.b.ins().sextend(types::I64, l);
                let h = self.b.ins().sextend(types::I64, h);
                Abs::I { lo: l, hi: h, ok }
            }
            (Abs::I { lo, hi, ok }, Scalar::Int, Scalar::Float) => {
                let l = self.b.ins().ireduce(types::I32, lo);
                let h = self.b.ins().ireduce(types::I32, hi);
                let l = self.b.ins().fcvt_from_sint(types::F32, l);
                let h = self.b.ins().fcvt_from_sint(types::F32, h);
                Abs::F { lo: l, hi: h, ok }
            }
            _ => Abs::Top,
        }
    }

    fn abs_binary(&mut self, op: BinOp, a: Abs, c: Abs) -> Abs {
        match (a, c) {
            (Abs::F { lo: al, hi: ah, ok: ao }, Abs::F { lo: cl, hi: ch, ok: co }) => {
                let ok = self.b.ins().band(ao, co);
                match op {
                    BinOp::Add => {
                        let lo = self.b.ins().fadd(al, cl);
                        let hi = self.b.ins().fadd(ah, ch);
                        self.float_iv(lo, hi, ok)
                    }
                    BinOp::Sub => {
                        let lo = self.b.ins().fsub(al, ch);
                        let hi = self.b.ins().fsub(ah, cl);
                        self.float_iv(lo, hi, ok)
                    }
                    BinOp::Mul | BinOp::Div => {
                        let ok = if op == BinOp::Div {
                            // The divisor interval must not contain zero.
                            let zero = self.f32const_here(0.0);
                            let pos = self.b.ins().fcmp(FloatCC::GreaterThan, cl, zero);
                            let neg = self.b.ins().fcmp(FloatCC::LessThan, ch, zero);
                            let nz = self.b.ins().bor(pos, neg);
                            self.b.ins().band(ok, nz)
                        } else {
                            ok
                        };
                        let mut corner = |x, y| {
                            if op == BinOp::Mul {
                                self.b.ins().fmul(x, y)
                            } else {
                                self.b.ins().fdiv(x, y)
                            }
                        };
                        let p = [corner(al, cl), corner(al, ch), corner(ah, cl), corner(ah, ch)];
                        let lo1 = self.b.ins().fmin(p[0], p[1]);
                        let lo2 = self.b.ins().fmin(p[2], p[3]);
                        let lo = self.b.ins().fmin(lo1, lo2);
                        let hi1 = self.b.ins().fmax(p[0], p[1]);
                        let hi2 = self.b.ins().fmax(p[2], p[3]);
                        let hi = self.b.ins().fmax(hi1, hi2);
                        self.float_iv(lo, hi, ok)
                    }
                    BinOp::Lt => self.decide(ok, [al, ah], [cl, ch], Cmp::Lt, true),
                    BinOp::Le => self.decide(ok, [al, ah], [cl, ch], Cmp::Le, true),
                    BinOp::Gt => self.decide(ok, [cl, ch], [al, ah], Cmp::Lt, true),
                    BinOp::Ge => self.decide(ok, [cl, ch], [al, ah], Cmp::Le, true),
                    BinOp::Eq => self.decide(ok, [al, ah], [cl, ch], Cmp::Eq, true),
                    BinOp::Ne => match self.decide(ok, [al, ah], [cl, ch], Cmp::Eq, true) {
                        Abs::B { t, f } => Abs::B { t: f, f: t },
                        other => other,
                    },
                    _ => Abs::Top,
                }
            }
            (Abs::I { lo: al, hi: ah, ok: ao }, Abs::I { lo: cl, hi: ch, ok: co }) => {
                let ok = self.b.ins().band(ao, co);
                match op {
                    BinOp::Add => {
                        let lo = self.b.ins().iadd(al, cl);
                        let hi = self.b.ins().iadd(ah, ch);
                        self.int_iv(lo, hi, ok)
                    }
                    BinOp::Sub => {
                        let lo = self.b.ins().isub(al, ch);
                        let hi = self.b.ins().isub(ah, cl);
                        self.int_iv(lo, hi, ok)
                    }
                    BinOp::Mul => {
                        // i32 * i32 fits i64; a not-ok operand already poisons the result.
                        let p = [
                            self.b.ins().imul(al, cl),
                            self.b.ins().imul(al, ch),
                            self.b.ins().imul(ah, cl),
                            self.b.ins().imul(ah, ch),
                        ];
                        let lo1 = self.b.ins().smin(p[0], p[1]);
                        let lo2 = self.b.ins().smin(p[2], p[3]);
                        let lo = self.b.ins().smin(lo1, lo2);
                        let hi1 = self.b.ins().smax(p[0], p[1]);
                        let hi2 = self.b.ins().smax(p[2], p[3]);
                        let hi = self.b.ins().smax(hi1, hi2);
                        self.int_iv(lo, hi, ok)
                    }
                    BinOp::Lt => self.decide(ok, [al, ah], [cl, ch], Cmp::Lt, false),
                    BinOp::Le => self.decide(ok, [al, ah], [cl, ch], Cmp::Le, false),
                    BinOp::Gt => self.decide(ok, [cl, ch], [al, ah], Cmp::Lt, false),
                    BinOp::Ge => self.decide(ok, [cl, ch], [al, ah], Cmp::Le, false),
                    BinOp::Eq => self.decide(ok, [al, ah], [cl, ch], Cmp::Eq, false),
                    BinOp::Ne => match self.decide(ok, [al, ah], [cl, ch], Cmp::Eq, false) {
                        Abs::B { t, f } => Abs::B { t: f, f: t },
                        other => other,
                    },
                    _ => Abs::Top,
                }
            }
            (Abs::B { t: at, f: af }, Abs::B { t: ct, f: cf }) => match op {
                BinOp::And => Abs::B {
                    t: self.b.ins().band(at, ct),
                    f: self.b.ins().bor(af, cf),
                },
                BinOp::Or => Abs::B {
                    t: self.b.ins().bor(at, ct),
                    f: self.b.ins().band(af, cf),
                },
                _ => Abs::Top,
            },
            _ => Abs::Top,
        }
    }

    /// Tri-state result of `a cmp c` over intervals `a` and `c` (f32 or i64 endpoints).
    /// Not `ok`: both outcomes possible.
    fn decide(&mut self, ok: ir::Value, a: [ir::Value; 2], c: [ir::Value; 2], cmp: Cmp, float: bool) -> Abs {
        let test = |l: &mut Self, fcc: FloatCC, icc: IntCC, x: ir::Value, y: ir::Value| {
            if float {
                l.b.ins().fcmp(fcc, x, y)
            } else {
                l.b.ins().icmp(icc, x, y)
            }
        };
        let (sure_true, sure_false) = match cmp {
            Cmp::Lt => (
                test(self, FloatCC::LessThan, IntCC::SignedLessThan, a[1], c[0]),
                test(
                    self,
                    FloatCC::GreaterThanOrEqual,
                    IntCC::SignedGreaterThanOrEqual,
                    a[0],
                    c[1],
                ),
            ),
            Cmp::Le => (
                test(self, FloatCC::LessThanOrEqual, IntCC::SignedLessThanOrEqual, a[1], c[0]),
                test(self, FloatCC::GreaterThan, IntCC::SignedGreaterThan, a[0], c[1]),
            ),
            Cmp::Eq => {
                let e1 = test(self, FloatCC::Equal, IntCC::Equal, a[0], a[1]);
                let e2 = test(self, FloatCC::Equal, IntCC::Equal, a[1], c[0]);
                let e3 = test(self, FloatCC::Equal, IntCC::Equal, c[0], c[1]);
                let all = self.b.ins().band(e1, e2);
                let all = self.b.ins().band(all, e3);
                let below = test(self, FloatCC::LessThan, IntCC::SignedLessThan, a[1], c[0]);
                let above = test(self, FloatCC::LessThan, IntCC::SignedLessThan, c[1], a[0]);
                (all, self.b.ins().bor(below, above))
            }
        };
        let sure_true = self.b.ins().band(sure_true, ok);
        let sure_false = self.b.ins().band(sure_false, ok);
        Abs::B {
            t: self.b.ins().bxor_imm_s(sure_false, 1),
            f: self.b.ins().bxor_imm_s(sure_true, 1),
        }
    }

    fn abs_builtin(&mut self, func: Builtin, vals: &[Abs]) -> Abs {
        match (func, vals) {
            (Builtin::Floor | Builtin::Ceil, [Abs::F { lo, hi, ok }]) => {
                let (l, h) = if func == Builtin::Floor {
                    (self.b.ins().floor(*lo), self.b.ins().floor(*hi))
                } else {
                    (self.b.ins().ceil(*lo), self.b.ins().ceil(*hi))
                };
                Abs::F { lo: l, hi: h, ok: *ok }
            }
            (Builtin::Abs, [Abs::F { lo, hi, ok }]) => {
                // [lo, hi] above zero: itself; below: mirrored; across: [0, max(-lo, hi)].
                let zero = self.f32const_here(0.0);
                let nlo = self.b.ins().fneg(*hi);
                let nhi = self.b.ins().fneg(*lo);
                let above = self.b.ins().fcmp(FloatCC::GreaterThanOrEqual, *lo, zero);
                let below = self.b.ins().fcmp(FloatCC::LessThanOrEqual, *hi, zero);
                let across_hi = self.b.ins().fmax(nhi, *hi);
                let l = self.b.ins().select(below, nlo, zero);
                let l = self.b.ins().select(above, *lo, l);
                let h = self.b.ins().select(below, nhi, across_hi);
                let h = self.b.ins().select(above, *hi, h);
                Abs::F { lo: l, hi: h, ok: *ok }
            }
            (Builtin::Min | Builtin::Max, [Abs::F { lo, hi, ok }, Abs::F { lo: l2, hi: h2, ok: o2 }]) => {
                let (l, h) = if func == Builtin::Min {
                    (self.b.ins().fmin(*lo, *l2), self.b.ins().fmin(*hi, *h2))
                } else {
                    (self.b.ins().fmax(*lo, *l2), self.b.ins().fmax(*hi, *h2))
                };
                let ok = self.b.ins().band(*ok, *o2);
                Abs::F { lo: l, hi: h, ok }
            }
            _ => Abs::Top,
        }
    }

    /// The pixel statements of the *pass* variant: the prefix with its decidable guards
    /// dropped (the block facts proved they fire for no lane), then the rest as written.
    /// `live` holds the locals the pass variant reads after the prefix (see
    /// [`crate::mid::unswitch::LoopsCopy::rest_live`]).
    pub(super) fn prefix_without_guards(
        &mut self,
        all: &[PStmt],
        stmts: &[PStmt],
        decidable: &[bool],
        live: &HashSet<LocalId>,
    ) -> Res<()> {
        for s in stmts {
            match s {
                PStmt::Assign { stmt, .. } | PStmt::Kill(stmt) => self.stmt(*stmt)?,
                PStmt::Guard { stmt, id, cond } => {
                    if !decidable[*id] {
                        self.stmt(*stmt)?;
                    } else {
                        // Dropped: the block facts proved it fires for no lane of the
                        // block, so every lane has `cond` false here, as after the guard.
                        self.assume_guard(*cond);
                    }
                }
                PStmt::UniformIf { cond, then, otherwise } => {
                    // An `if` left with nothing the pass variant needs (every guard in it
                    // dropped, no kill, its locals read nowhere else) is not emitted: its
                    // assignments would be dead, but the test of its condition would stay
                    // in every group.
                    if no_effect_in_pass(self.exprs(), all, s, decidable, live) {
                        continue;
                    }
                    let c = self.eval_uniform(*cond)?;
                    let c = fixed::convert(&mut self.b, c.scalar, Scalar::Bool, c.comps[0]);
                    let then_blk = self.b.create_block();
                    let else_blk = self.b.create_block();
                    let join = self.b.create_block();
                    self.b.ins().brif(c, then_blk, &[], else_blk, &[]);
                    // A side's guard facts end with it (as a statement list's do).
                    let mark = self.guard_facts.mark();
                    self.b.switch_to_block(then_blk);
                    self.prefix_without_guards(all, then, decidable, live)?;
                    self.guard_facts.truncate(mark);
                    self.b.ins().jump(join, &[]);
                    self.b.switch_to_block(else_blk);
                    self.prefix_without_guards(all, otherwise, decidable, live)?;
                    self.guard_facts.truncate(mark);
                    self.b.ins().jump(join, &[]);
                    self.b.switch_to_block(join);
                }
            }
        }
        Ok(())
    }
}

/// A value carried from the sides of a branching uniform `if` to its join.
struct Carried {
    shape: Shape,
    /// Its SSA parts on the then side and on the else side (`None`: that side has none).
    parts: [Option<Vec<ir::Value>>; 2],
    to: Carry,
}

/// The form of a carried value.
enum Shape {
    Abs(Abs),
    Flag { dead: bool },
    Cond,
}

/// Where a carried value goes at the join.
enum Carry {
    Flag { dead: bool },
    Local(LocalId),
    Value(ExprId),
    Cond(ExprId),
}

/// An abstract value's SSA parts (block parameters carry them).
fn abs_parts(a: &Abs) -> Vec<ir::Value> {
    match a {
        Abs::Top => vec![],
        Abs::F { lo, hi, ok } | Abs::I { lo, hi, ok } => vec![*lo, *hi, *ok],
        Abs::B { t, f } => vec![*t, *f],
    }
}

/// `shape` rebuilt from `parts` (as [`abs_parts`] lists them).
fn abs_from_parts(shape: &Abs, parts: &[ir::Value]) -> Abs {
    match shape {
        Abs::Top => Abs::Top,
        Abs::F { .. } => Abs::F {
            lo: parts[0],
            hi: parts[1],
            ok: parts[2],
        },
        Abs::I { .. } => Abs::I {
            lo: parts[0],
            hi: parts[1],
            ok: parts[2],
        },
        Abs::B { .. } => Abs::B {
            t: parts[0],
            f: parts[1],
        },
    }
}

fn same_shape(a: &Abs, b: &Abs) -> bool {
    std::mem::discriminant(a) == std::mem::discriminant(b)
}

/// Remove and return the entries of `map` whose keys are not in `before`, sorted by key
/// (so the join's parameters come in a deterministic order).
fn take_new<V>(map: &mut HashMap<ExprId, V>, before: &HashSet<ExprId>) -> Vec<(ExprId, V)> {
    let mut new_keys: Vec<ExprId> = map.keys().filter(|k| !before.contains(k)).copied().collect();
    new_keys.sort_unstable();
    new_keys
        .into_iter()
        .filter_map(|k| map.remove(&k).map(|v| (k, v)))
        .collect()
}

#[derive(Clone, Copy)]
enum Cmp {
    Lt,
    Le,
    Eq,
}
