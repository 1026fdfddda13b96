//! The IR validator: every rule code generation relies on, stated once and checked.
//!
//! [`validate`] checks a whole [`Program`]; [`validate_function`] checks one function body
//! against its program (a body a pass rewrote, whose callees are still the program's). Each
//! rule is a [`Rule`] with a doc line saying what holds; a failure names the rule, the
//! function and the statement or expression where it failed, with its span.
//!
//! Where it runs (in builds with debug assertions, as `cargo test` makes them): at the
//! end of [`crate::check::check`] (after lowering, variability and [`super::split`]), and
//! where the middle end makes a kernel body ([`crate::mid::body`]), after
//! [`super::forward`] and after `mid::unroll`. A failure there is reported as an internal
//! compiler error (a diagnostic from the checker, a `JitError` from the JIT), never a
//! panic. Release builds skip it: the back end may assume what the validator proved, and
//! the checker's output is validated by every test build.
//!
//! The rules, by theme (the module doc of [`crate::ir`] states them in prose):
//! - **index facts**: locals, loop ids, sites and callees in range; each loop id belongs
//!   to one loop; the statement and expression arenas hold trees, numbered densely in pre-order;
//!   `break`/`continue` leave an enclosing loop; parameter `i` is local `i`;
//! - **types**: each expression's type follows from its operands exactly as the checker
//!   builds it (`Binary` operands of one scalar element and shape, or a scalar broadcast;
//!   conversions between numbers; built-ins on floats of the shapes they take), an
//!   assignment's value has its place's type, conditions are scalar bools;
//! - **variability**: an expression is varying iff an operand is (a `Local` as its local);
//!   no uniform local is assigned a varying value, at a varying index or under varying
//!   control flow; a loop left by a jump under varying control flow is a varying loop;
//! - **setup/pixel split**: the setup part is uniform (a primitive call's X, Y, Z
//!   pass-through excepted) and holds every primitive call and `bound`;
//!   `interpolator_return` only in the pixel part; an interpolator is all pixel part;
//! - **interpolation data**: `interpolation` only in a primitive, not nested, arms of
//!   distinct kinds and at most one `default`; `interpolator_return(e)` only in an arm (or
//!   a shared interpolator), without a value never in a named arm; a list of numbers
//!   becomes interpolation data only in a named arm;
//! - **primitive calls**: one argument per callee parameter, of its type (a fixed-size
//!   array for a per-sequence-point one), uniform, X, Y and Z passed through as the
//!   caller's own;
//! - **what lowering asserts besides**: no value of a per-sequence-point type other than
//!   as the array indexed, only parameters have such types, only Z among the parameters
//!   is assigned, parameter roles fit their types, transforms only in a function marked
//!   `uses_spaces`.

use std::fmt;

use super::{
    ArmKind, BinOp, Builtin, ConstValue, Elem, Expr, ExprId, ExprKind, FuncKind, Function, LocalId, LocalKind, LoopId,
    Param, ParamRole, Place, Program, Scalar, SiteId, StmtId, StmtKind, Type, UnaryOp, Variability,
};
use crate::diag::Span;

/// A rule of a valid program. The doc line of each says what holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Rule {
    // ---- index facts
    /// Every `LocalId` (expression or place) is below `locals.len()`.
    LocalInRange,
    /// Every `SiteId` (index, place index, loop) is below `program.sites.len()`.
    SiteInRange,
    /// Every `LoopId` is below `function.loops`.
    LoopIdInRange,
    /// Each `LoopId` is the id of at most one `Loop` statement.
    LoopIdUnique,
    /// The statement arena holds the setup and pixel blocks as trees: every id in a block
    /// is in range, each statement is in exactly one block, and the ids are
    /// `0..stmts.len()` in pre-order (see [`super::number`]), so none is unreachable.
    StmtTree,
    /// The arena holds one tree per statement expression: every operand id is in range,
    /// each node is the operand or statement expression of exactly one parent, and the ids
    /// are `0..exprs.len()` in pre-order (see [`super::number`]), so none is unreachable.
    ExprTree,
    /// `break` and `continue` name a loop that encloses them.
    JumpTarget,
    /// Parameter i is `LocalId(i)`, whose kind is `Param(i)`; no other local is a parameter.
    ParamLayout,
    /// A primitive call names an existing function that is a primitive.
    CallCallee,
    // ---- types
    /// A constant is a scalar whose type is its value's kind.
    ConstType,
    /// A `Local` expression has its local's type.
    LocalType,
    /// An index goes into an array (fixed-size or per sequence point) with an `int` scalar
    /// and gives the array's element type.
    IndexType,
    /// `-` keeps a number (or interpolation data) type; `!` takes and gives a bool scalar.
    UnaryType,
    /// `Binary` operands have one scalar element and one shape, or one side is a scalar
    /// broadcast over the other (interpolation data: with itself or a float scalar);
    /// comparisons are of scalars and give bool, `&&`/`||` take and give bool.
    BinaryType,
    /// `Convert` changes a number's element to another number's, shape unchanged, or a
    /// float scalar (a float list, see `InterpFromList`) into interpolation data.
    ConvertType,
    /// A list of numbers becomes interpolation data only inside a named interpolation arm
    /// (the arm's kind gives the data its length).
    InterpFromList,
    /// `?:` takes a bool scalar and two values of its own type.
    SelectType,
    /// A built-in has its arity, float arguments and the shapes the checker gives it.
    BuiltinType,
    /// A list is a non-empty array whose items have its element type.
    ListType,
    /// A splat repeats a scalar of its element kind into a fixed-size array.
    SplatType,
    /// A matrix product is `float[n][m] * float[m]` -> `float[n]` or `* float[m][k]` ->
    /// `float[n][k]`.
    MatMulType,
    /// `len` of a per-sequence-point array is an `int`, `clipping()` a `bool`.
    QueryType,
    /// The condition of an `if` or a loop is a bool scalar.
    ConditionType,
    /// An assignment's value has the type of its place.
    AssignType,
    /// `bound` takes four float scalars.
    BoundType,
    /// No expression has a per-sequence-point type except such a parameter indexed.
    PerSeqValue,
    /// Only parameters have per-sequence-point types.
    PerSeqLocal,
    /// Parameter roles fit: X, Y, Z are varying number scalars (Z float or fixed), every
    /// other parameter uniform; interpolation data has that element, per-sequence-point
    /// parameters that shape; an interpolator has neither; one parameter per pixel role.
    ParamRoles,
    /// Parameters other than Z are never assigned.
    AssignReadOnly,
    /// A transform built-in occurs only in a function marked `uses_spaces`.
    SpacesUsed,
    // ---- variability
    /// An expression is varying iff one of its operands is; a `Local` has its local's
    /// variability; constants, `len` and `clipping()` are uniform.
    ExprVariability,
    /// A uniform local is never assigned a varying value or at a varying index.
    VaryingIntoUniform,
    /// A uniform local is never assigned under varying control flow (a varying `if`, or a
    /// loop whose condition or a `break`/`continue` of it is varying).
    UniformUnderVaryingControl,
    /// A loop with a varying condition, or left by a `break`, `continue` or `return` under
    /// varying control flow introduced inside it, is marked varying.
    LoopVarying,
    // ---- setup/pixel split
    /// The setup part is uniform: no varying expression (a primitive call's X, Y, Z
    /// pass-through excepted), so no varying `if`, loop or `return` either.
    SetupUniform,
    /// No primitive call and no `bound` in the pixel part.
    PixelPart,
    /// An interpolator is all pixel part and has no `bound`, primitive call or
    /// `interpolation` construct.
    InterpolatorBody,
    // ---- interpolation data
    /// `interpolation` occurs only in a primitive, not inside another one.
    InterpolationPlacement,
    /// The arms of one `interpolation` have distinct, non-empty kinds and at most one
    /// `default`.
    ArmKinds,
    /// `interpolator_return` is in the pixel part; in a primitive, with a value only
    /// inside an arm and without one never in a named arm; in an interpolator, always with
    /// a value.
    InterpolatorReturnPlacement,
    /// `interpolator_return` stores a float scalar or aggregate, or (in a primitive's arm)
    /// an interpolation data scalar.
    InterpolatorReturnType,
    // ---- primitive calls
    /// A primitive call passes one argument per callee parameter.
    CallArity,
    /// Each argument has its parameter's type; a per-sequence-point parameter takes a
    /// fixed-size array of its elements.
    CallArgType,
    /// A callee's X, Y and Z receive the caller's own X, Y and Z parameters.
    CallPixelArgs,
    /// Every other argument is uniform.
    CallArgVarying,
}

impl Rule {
    /// One line saying what the rule requires.
    pub fn description(self) -> &'static str {
        use Rule::*;
        match self {
            LocalInRange => "every local id is in range",
            SiteInRange => "every site id is in range",
            LoopIdInRange => "every loop id is in range",
            LoopIdUnique => "each loop id belongs to one loop",
            StmtTree => "statements form trees numbered 0..stmts in pre-order",
            ExprTree => "expressions form trees numbered 0..exprs in pre-order",
            JumpTarget => "break/continue leave an enclosing loop",
            ParamLayout => "parameter i is local i, of kind Param(i)",
            CallCallee => "a primitive call names a primitive",
            ConstType => "a constant is a scalar of its value's kind",
            LocalType => "a local read has the local's type",
            IndexType => "an int index into an array gives its element",
            UnaryType => "`-` keeps a number type, `!` is bool to bool",
            BinaryType => "binary operands share element and shape (or broadcast a scalar)",
            ConvertType => "a conversion is between numbers of one shape, or float to interpolation data",
            InterpFromList => "a list becomes interpolation data only in a named arm",
            SelectType => "`?:` has a bool condition and two values of its type",
            BuiltinType => "a built-in has its arity, float arguments and shapes",
            ListType => "a list's items have its element type",
            SplatType => "a splat repeats a scalar of its element kind",
            MatMulType => "a matrix product has matching float shapes",
            QueryType => "`len` is an int, `clipping()` a bool",
            ConditionType => "a condition is a bool scalar",
            AssignType => "an assigned value has its place's type",
            BoundType => "`bound` takes four float scalars",
            PerSeqValue => "a per-sequence-point array is only indexed",
            PerSeqLocal => "only parameters are per sequence point",
            ParamRoles => "parameter roles fit their types and variabilities",
            AssignReadOnly => "only Z among the parameters is assigned",
            SpacesUsed => "a transform needs `uses_spaces`",
            ExprVariability => "an expression is varying iff an operand is",
            VaryingIntoUniform => "no varying value or index into a uniform local",
            UniformUnderVaryingControl => "no uniform local assigned under varying control flow",
            LoopVarying => "a loop with varying control of its exit is varying",
            SetupUniform => "the setup part is uniform",
            PixelPart => "no primitive call or `bound` in the pixel part",
            InterpolatorBody => "an interpolator is pixel code without bound, calls or interpolation",
            InterpolationPlacement => "`interpolation` only in a primitive, not nested",
            ArmKinds => "interpolation arms have distinct kinds, at most one default",
            InterpolatorReturnPlacement => "`interpolator_return` where its form is allowed",
            InterpolatorReturnType => "`interpolator_return` stores floats or interpolation data",
            CallArity => "a primitive call passes one argument per parameter",
            CallArgType => "each argument has its parameter's type",
            CallPixelArgs => "X, Y, Z are passed through as the caller's own",
            CallArgVarying => "arguments other than X, Y, Z are uniform",
        }
    }
}

/// A broken rule: which, in which function, at which statement or expression.
#[derive(Clone, Debug, PartialEq)]
pub struct ValidationError {
    pub rule: Rule,
    /// The function's name.
    pub function: String,
    /// What failed: "expression `Binary`", "statement `Assign`", "parameter `X`", ...
    pub node: String,
    pub span: Span,
    /// What was found.
    pub detail: String,
}

impl fmt::Display for ValidationError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "IR rule `{:?}` ({}) broken in `{}` at {} (file {}, bytes {}..{}): {}",
            self.rule,
            self.rule.description(),
            self.function,
            self.node,
            self.span.file,
            self.span.start,
            self.span.end,
            self.detail
        )
    }
}

impl std::error::Error for ValidationError {}

type Res = Result<(), ValidationError>;

/// Check every function of `program`.
pub fn validate(program: &Program) -> Res {
    for f in &program.functions {
        validate_function(program, f)?;
    }
    Ok(())
}

/// Check `f` (a function of `program`, possibly rewritten by a pass) against `program`
/// (its callees and sites).
pub fn validate_function(program: &Program, f: &Function) -> Res {
    let mut v = Validator {
        program,
        f,
        loop_varying: vec![None; f.loops as usize],
        loop_ctl: vec![],
        pixel: false,
        loops: vec![],
        conds: vec![],
        arm: None,
    };
    v.params()?;
    v.stmt_ids()?;
    v.loop_ids()?;
    v.expr_ids()?;
    v.loop_ctl = control_loops(f);
    if f.kind == FuncKind::Interpolator {
        if let Some(&s) = f.setup.first() {
            return v.fail(
                Rule::InterpolatorBody,
                stmt_node(&f.stmts[s]),
                f.stmts.span(s),
                "an interpolator has a setup part",
            );
        }
    }
    v.stmts(&f.setup)?;
    v.pixel = true;
    v.loops.clear();
    v.conds.clear();
    v.stmts(&f.pixel)
}

struct Validator<'a> {
    program: &'a Program,
    f: &'a Function,
    /// Each loop id's `varying` flag, from its `Loop` statement.
    loop_varying: Vec<Option<bool>>,
    /// Loops whose body is varying control flow (see [`control_loops`]).
    loop_ctl: Vec<bool>,
    /// Walking the pixel part.
    pixel: bool,
    /// Enclosing loops, outermost first.
    loops: Vec<LoopId>,
    /// Varying control flow in effect: the loop depth each was introduced at.
    conds: Vec<usize>,
    /// Inside an interpolation arm: `Some(is_default)`.
    arm: Option<bool>,
}

fn stmt_node(s: &StmtKind) -> String {
    format!("statement `{}`", s.name())
}

fn expr_node(e: &Expr) -> String {
    let k = match &e.kind {
        ExprKind::Const(_) => "Const",
        ExprKind::Local(_) => "Local",
        ExprKind::Index { .. } => "Index",
        ExprKind::Unary { .. } => "Unary",
        ExprKind::Binary { .. } => "Binary",
        ExprKind::Convert(_) => "Convert",
        ExprKind::Select { .. } => "Select",
        ExprKind::Builtin { .. } => "Builtin",
        ExprKind::List(_) => "List",
        ExprKind::Splat(_) => "Splat",
        ExprKind::MatMul { .. } => "MatMul",
        ExprKind::SeqCount => "SeqCount",
        ExprKind::ClipFlag => "ClipFlag",
    };
    format!("expression `{k}`")
}

fn is_number(s: Scalar) -> bool {
    s != Scalar::Bool
}

fn float_ty(dims: Vec<u32>) -> Type {
    Type::array(Elem::Scalar(Scalar::Float), dims)
}

fn is_float(t: &Type) -> bool {
    t.elem == Elem::Scalar(Scalar::Float) && !t.per_seq
}

/// The loops whose body is varying control flow, as the checker's variability pass decides
/// it: a loop with a varying condition, or one left by a `break`/`continue` under varying
/// control flow introduced inside it (a varying `if`, or another such loop). Found to a
/// fixpoint, since a loop found so makes jumps inside it varying in turn.
fn control_loops(f: &Function) -> Vec<bool> {
    struct Ctl<'f> {
        st: &'f super::Stmts,
        x: &'f super::Exprs,
        ctl: Vec<bool>,
        loops: Vec<LoopId>,
        conds: Vec<usize>,
        changed: bool,
    }
    impl Ctl<'_> {
        fn set(&mut self, id: LoopId) {
            if let Some(c) = self.ctl.get_mut(id.0 as usize) {
                if !*c {
                    *c = true;
                    self.changed = true;
                }
            }
        }
        fn stmts(&mut self, ss: &[StmtId]) {
            let st = self.st;
            for &s in ss {
                match &st[s] {
                    StmtKind::If { cond, then, otherwise } => {
                        let pushed = self.x[*cond].var.is_varying();
                        if pushed {
                            self.conds.push(self.loops.len());
                        }
                        self.stmts(then);
                        self.stmts(otherwise);
                        if pushed {
                            self.conds.pop();
                        }
                    }
                    StmtKind::Loop {
                        id, cond, body, step, ..
                    } => {
                        self.loops.push(*id);
                        if cond.is_some_and(|c| self.x[c].var.is_varying()) {
                            self.set(*id);
                        }
                        let pushed = self.ctl.get(id.0 as usize).copied().unwrap_or(false);
                        if pushed {
                            self.conds.push(self.loops.len());
                        }
                        self.stmts(body);
                        self.stmts(step);
                        if pushed {
                            self.conds.pop();
                        }
                        self.loops.pop();
                    }
                    StmtKind::Break(id) | StmtKind::Continue(id) => {
                        if let (Some(p), Some(&d)) = (self.loops.iter().position(|l| l == id), self.conds.iter().max())
                        {
                            for q in p..d.min(self.loops.len()) {
                                self.set(self.loops[q]);
                            }
                        }
                    }
                    StmtKind::Interpolation { arms } => arms.iter().for_each(|a| self.stmts(&a.body)),
                    _ => {}
                }
            }
        }
    }
    let mut c = Ctl {
        st: &f.stmts,
        x: &f.exprs,
        ctl: vec![false; f.loops as usize],
        loops: vec![],
        conds: vec![],
        changed: true,
    };
    while c.changed {
        c.changed = false;
        for part in [&f.setup, &f.pixel] {
            c.loops.clear();
            c.conds.clear();
            c.stmts(part);
        }
    }
    c.ctl
}

impl<'a> Validator<'a> {
    fn fail(&self, rule: Rule, node: impl Into<String>, span: Span, detail: impl Into<String>) -> Res {
        Err(ValidationError {
            rule,
            function: self.f.name.clone(),
            node: node.into(),
            span,
            detail: detail.into(),
        })
    }

    fn check(&self, ok: bool, rule: Rule, e_id: ExprId, detail: impl FnOnce() -> String) -> Res {
        let e = &self.f.exprs[e_id];
        if ok {
            Ok(())
        } else {
            self.fail(rule, expr_node(e), self.f.exprs.span(e_id), detail())
        }
    }

    fn check_stmt(&self, ok: bool, rule: Rule, s: StmtId, detail: impl FnOnce() -> String) -> Res {
        if ok {
            Ok(())
        } else {
            self.fail_stmt(rule, s, detail())
        }
    }

    fn fail_stmt(&self, rule: Rule, s: StmtId, detail: impl Into<String>) -> Res {
        self.fail(rule, stmt_node(&self.f.stmts[s]), self.f.stmts.span(s), detail)
    }

    fn site(&self, site: SiteId, node: impl Into<String>, span: Span) -> Res {
        if (site.0 as usize) < self.program.sites.len() {
            Ok(())
        } else {
            self.fail(
                Rule::SiteInRange,
                node,
                span,
                format!("site {} of {}", site.0, self.program.sites.len()),
            )
        }
    }

    fn local(&self, l: LocalId, node: impl Into<String>, span: Span) -> Result<&'a super::Local, ValidationError> {
        match self.f.locals.get(l.0 as usize) {
            Some(local) => Ok(local),
            None => Err(ValidationError {
                rule: Rule::LocalInRange,
                function: self.f.name.clone(),
                node: node.into(),
                span,
                detail: format!("local {} of {}", l.0, self.f.locals.len()),
            }),
        }
    }

    fn param_of(&self, l: LocalId) -> Option<&'a Param> {
        match self.f.locals.get(l.0 as usize)?.kind {
            LocalKind::Param(i) => self.f.params.get(i as usize),
            _ => None,
        }
    }

    // ---- parameters and loops

    fn params(&self) -> Res {
        let f = self.f;
        let node = |p: &Param| format!("parameter `{}`", p.name);
        for (i, p) in f.params.iter().enumerate() {
            let local = f.locals.get(i);
            if p.local.0 as usize != i || local.map(|l| l.kind) != Some(LocalKind::Param(i as u32)) {
                return self.fail(
                    Rule::ParamLayout,
                    node(p),
                    p.span,
                    format!(
                        "parameter {i} is local {} of kind {:?}",
                        p.local.0,
                        local.map(|l| l.kind)
                    ),
                );
            }
            let l = &f.locals[i];
            let pixel = matches!(p.role, ParamRole::X | ParamRole::Y | ParamRole::Z);
            let want_var = if pixel {
                Variability::Varying
            } else {
                Variability::Uniform
            };
            let ty_ok = match p.role {
                ParamRole::X | ParamRole::Y => l.ty.is_scalar() && matches!(l.ty.elem, Elem::Scalar(s) if is_number(s)),
                ParamRole::Z => l.ty.is_scalar() && matches!(l.ty.elem, Elem::Scalar(Scalar::Float | Scalar::Fixed(_))),
                ParamRole::InterpData => l.ty.elem == Elem::Interp && f.kind == FuncKind::Primitive,
                ParamRole::PerSequencePoint => {
                    l.ty.per_seq && matches!(l.ty.elem, Elem::Scalar(_)) && f.kind == FuncKind::Primitive
                }
                ParamRole::PerPrimitive => !l.ty.per_seq && matches!(l.ty.elem, Elem::Scalar(_)),
            };
            let unique = !pixel || f.params.iter().filter(|q| q.role == p.role).count() == 1;
            if l.var != want_var || !ty_ok || !unique || (l.ty.per_seq && f.kind != FuncKind::Primitive) {
                return self.fail(
                    Rule::ParamRoles,
                    node(p),
                    p.span,
                    format!(
                        "role {:?} with a {:?} {:?}{}",
                        p.role,
                        l.var,
                        l.ty,
                        if unique { "" } else { " (role given twice)" }
                    ),
                );
            }
        }
        for (i, l) in f.locals.iter().enumerate() {
            let is_param = i < f.params.len();
            if matches!(l.kind, LocalKind::Param(_)) != is_param {
                return self.fail(
                    Rule::ParamLayout,
                    format!("local `{}`", l.name),
                    l.span,
                    format!("local {i} of kind {:?} with {} parameters", l.kind, f.params.len()),
                );
            }
            if !is_param && l.ty.per_seq {
                return self.fail(
                    Rule::PerSeqLocal,
                    format!("local `{}`", l.name),
                    l.span,
                    "a local of a per-sequence-point type",
                );
            }
        }
        Ok(())
    }

    /// The statement arena is a set of trees numbered in pre-order ([`Rule::StmtTree`]):
    /// walking the blocks from `setup` and `pixel` must meet ids 0, 1, 2, ... exactly, and
    /// then have met every node. A statement in two blocks, or out of range, breaks the
    /// count where it is met; an unreachable one leaves the count short. Runs before every
    /// other walk of the statements, which may then index the arena.
    fn stmt_ids(&self) -> Res {
        let f = self.f;
        let st = &f.stmts;
        /// Walk `block` expecting pre-order id `*next`; the first mismatch found, with the
        /// statement holding the block (`None`: the setup or pixel part).
        fn walk(
            st: &super::Stmts,
            holder: Option<StmtId>,
            block: &[StmtId],
            next: &mut u32,
        ) -> Result<(), (Option<StmtId>, String)> {
            for &id in block {
                let Some(s) = st.get(id) else {
                    return Err((holder, format!("statement id {} of {}", id.0, st.len())));
                };
                if id.0 != *next {
                    let why = if id.0 < *next {
                        format!("statement id {} is used twice (or out of pre-order)", id.0)
                    } else {
                        format!("statement id {} where pre-order gives {}", id.0, *next)
                    };
                    return Err((Some(id), why));
                }
                *next += 1;
                let mut r = Ok(());
                s.for_each_block(|b| {
                    if r.is_ok() {
                        r = walk(st, Some(id), b, next);
                    }
                });
                r?;
            }
            Ok(())
        }
        let mut next = 0;
        for part in [&f.setup, &f.pixel] {
            if let Err((at, detail)) = walk(st, None, part, &mut next) {
                return match at {
                    Some(s) if st.get(s).is_some() => self.fail_stmt(Rule::StmtTree, s, detail),
                    _ => self.fail(Rule::StmtTree, "function", f.span, detail),
                };
            }
        }
        if next != st.len() {
            return self.fail(
                Rule::StmtTree,
                "function",
                f.span,
                format!("{next} statements reachable of the {} in the arena", st.len()),
            );
        }
        Ok(())
    }

    /// Loop ids in range and unique; remembers each loop's `varying` flag.
    fn loop_ids(&mut self) -> Res {
        let f = self.f;
        let mut flags = vec![None; f.loops as usize];
        let mut found: Option<(Rule, StmtId, String)> = None;
        for part in [&f.setup, &f.pixel] {
            super::for_each_stmt(&f.stmts, part, &mut |s, kind| {
                if found.is_some() {
                    return;
                }
                let (id, varying) = match kind {
                    StmtKind::Loop { id, varying, .. } => (*id, Some(*varying)),
                    StmtKind::Break(id) | StmtKind::Continue(id) => (*id, None),
                    _ => return,
                };
                let Some(slot) = flags.get_mut(id.0 as usize) else {
                    found = Some((Rule::LoopIdInRange, s, format!("loop {} of {}", id.0, f.loops)));
                    return;
                };
                if let Some(v) = varying {
                    if slot.is_some() {
                        found = Some((Rule::LoopIdUnique, s, format!("loop {} is defined twice", id.0)));
                        return;
                    }
                    *slot = Some(v);
                }
            });
        }
        if let Some((rule, s, detail)) = found {
            return self.fail_stmt(rule, s, detail);
        }
        self.loop_varying = flags;
        Ok(())
    }

    /// The arena is a set of trees numbered in pre-order ([`Rule::ExprTree`]): walking
    /// the statements' expressions in that order must meet ids 0, 1, 2, ... exactly, and
    /// then have met every node. A node shared by two parents, or out of range, breaks the
    /// count where it is met; an unreachable node leaves the count short.
    fn expr_ids(&self) -> Res {
        let f = self.f;
        let x = &f.exprs;
        /// Walk the tree at `id` expecting pre-order id `*next`; the first mismatch found.
        fn walk(x: &super::Exprs, id: ExprId, next: &mut u32) -> Result<(), (Option<ExprId>, String)> {
            let Some(e) = x.get(id) else {
                return Err((None, format!("operand id {} of {}", id.0, x.len())));
            };
            if id.0 != *next {
                let why = if id.0 < *next {
                    format!("id {} is used twice (or out of pre-order)", id.0)
                } else {
                    format!("id {} where pre-order gives {}", id.0, *next)
                };
                return Err((Some(id), why));
            }
            *next += 1;
            let mut k = 0;
            while let Some(c) = e.child(k) {
                walk(x, c, next)?;
                k += 1;
            }
            Ok(())
        }
        let mut next = 0;
        let mut found: Option<(Option<ExprId>, StmtId, String)> = None;
        for part in [&f.setup, &f.pixel] {
            super::for_each_stmt(&f.stmts, part, &mut |s, kind| {
                kind.for_each_expr(|e| {
                    if found.is_none() {
                        if let Err((at, why)) = walk(x, *e, &mut next) {
                            found = Some((at, s, why));
                        }
                    }
                })
            });
        }
        if let Some((at, s, detail)) = found {
            return match at {
                Some(id) => self.fail(Rule::ExprTree, expr_node(&x[id]), x.span(id), detail),
                None => self.fail_stmt(Rule::ExprTree, s, detail),
            };
        }
        if next != x.len() {
            return self.fail(
                Rule::ExprTree,
                "function",
                f.span,
                format!("{next} expressions reachable of the {} in the arena", x.len()),
            );
        }
        Ok(())
    }

    // ---- statements

    fn stmts(&mut self, ss: &'a [StmtId]) -> Res {
        ss.iter().try_for_each(|&s| self.stmt(s))
    }

    /// An expression standing on its own in a statement: checked, not a per-sequence-point
    /// array, and uniform in the setup part.
    fn root(&mut self, e_id: ExprId) -> Res {
        let e = &self.f.exprs[e_id];
        self.expr(e_id)?;
        self.check(!e.ty.per_seq, Rule::PerSeqValue, e_id, || {
            "a whole per-sequence-point array used as a value".into()
        })?;
        self.check(self.pixel || !e.var.is_varying(), Rule::SetupUniform, e_id, || {
            "a varying expression in the setup part".into()
        })
    }

    fn condition(&mut self, c_id: ExprId) -> Res {
        let c = &self.f.exprs[c_id];
        self.root(c_id)?;
        self.check(c.ty == Type::bool(), Rule::ConditionType, c_id, || {
            format!("a condition of type {:?}", c.ty)
        })
    }

    /// A `break`, `continue` (`target`: the position of the loop left) or `return` (0)
    /// under varying control flow leaves varying loops only.
    fn jump(&self, s: StmtId, target: usize) -> Res {
        let Some(&d) = self.conds.iter().max() else {
            return Ok(());
        };
        for q in target..d.min(self.loops.len()) {
            let id = self.loops[q];
            if self.loop_varying[id.0 as usize] != Some(true) {
                return self.fail_stmt(
                    Rule::LoopVarying,
                    s,
                    format!("leaves uniform loop {} under varying control flow", id.0),
                );
            }
        }
        Ok(())
    }

    fn stmt(&mut self, s: StmtId) -> Res {
        let f = self.f;
        match &f.stmts[s] {
            StmtKind::Assign { place, value } => self.assign(s, place, *value),
            StmtKind::If { cond, then, otherwise } => {
                self.condition(*cond)?;
                let pushed = f.exprs[*cond].var.is_varying();
                if pushed {
                    self.conds.push(self.loops.len());
                }
                self.stmts(then)?;
                self.stmts(otherwise)?;
                if pushed {
                    self.conds.pop();
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
                self.site(*site, stmt_node(&f.stmts[s]), f.stmts.span(s))?;
                if let Some(c) = *cond {
                    self.condition(c)?;
                    self.check_stmt(!f.exprs[c].var.is_varying() || *varying, Rule::LoopVarying, s, || {
                        format!("loop {} has a varying condition but is not varying", id.0)
                    })?;
                }
                self.check_stmt(self.pixel || !*varying, Rule::SetupUniform, s, || {
                    format!("varying loop {} in the setup part", id.0)
                })?;
                self.loops.push(*id);
                let pushed = self.loop_ctl[id.0 as usize];
                if pushed {
                    self.conds.push(self.loops.len());
                }
                self.stmts(body)?;
                self.stmts(step)?;
                if pushed {
                    self.conds.pop();
                }
                self.loops.pop();
                Ok(())
            }
            StmtKind::Break(id) | StmtKind::Continue(id) => match self.loops.iter().position(|l| l == id) {
                Some(p) => self.jump(s, p),
                None => self.fail_stmt(Rule::JumpTarget, s, format!("loop {} does not enclose it", id.0)),
            },
            StmtKind::Return => self.jump(s, 0),
            StmtKind::Interpolation { arms } => {
                self.check_stmt(f.kind == FuncKind::Primitive, Rule::InterpolatorBody, s, || {
                    "`interpolation` in an interpolator".into()
                })?;
                self.check_stmt(self.arm.is_none(), Rule::InterpolationPlacement, s, || {
                    "`interpolation` inside an interpolation arm".into()
                })?;
                for (i, a) in arms.iter().enumerate() {
                    let twice = arms[..i].iter().any(|b| b.kind == a.kind);
                    let empty = a.kind == ArmKind::Named(String::new());
                    if twice || empty {
                        return self.fail(Rule::ArmKinds, "interpolation arm", a.span, format!("arm {:?}", a.kind));
                    }
                }
                for a in arms {
                    let saved = self.arm.replace(a.kind == ArmKind::Default);
                    let r = self.stmts(&a.body);
                    self.arm = saved;
                    r?;
                }
                Ok(())
            }
            StmtKind::InterpolatorReturn(v) => self.interpolator_return(s, *v),
            StmtKind::Bound(args) => {
                self.check_stmt(f.kind == FuncKind::Primitive, Rule::InterpolatorBody, s, || {
                    "`bound` in an interpolator".into()
                })?;
                self.check_stmt(!self.pixel, Rule::PixelPart, s, || "`bound` in the pixel part".into())?;
                for &a in args.iter() {
                    self.root(a)?;
                    let ty = &f.exprs[a].ty;
                    self.check(*ty == Type::float(), Rule::BoundType, a, || {
                        format!("a bound of type {ty:?}")
                    })?;
                }
                Ok(())
            }
            StmtKind::CallPrimitive { callee, args, site } => {
                self.site(*site, stmt_node(&self.f.stmts[s]), self.f.stmts.span(s))?;
                self.call(s, *callee, args)
            }
        }
    }

    /// An assignment: its place's local, read-only parameters, index types, the value's
    /// type, and what a uniform local may be assigned.
    fn assign(&mut self, s: StmtId, place: &'a Place, value_id: ExprId) -> Res {
        let value = &self.f.exprs[value_id];
        self.root(value_id)?;
        let local = self.local(place.local, stmt_node(&self.f.stmts[s]), place.span)?;
        if let Some(p) = self.param_of(place.local) {
            self.check_stmt(p.role == ParamRole::Z, Rule::AssignReadOnly, s, || {
                format!("assignment to parameter `{}`", p.name)
            })?;
        }
        let mut ty = local.ty.clone();
        let mut index_var = Variability::Uniform;
        for &(i, site) in &place.indices {
            self.root(i)?;
            self.site(site, stmt_node(&self.f.stmts[s]), place.span)?;
            self.check(
                self.f.exprs[i].ty == Type::int() && (!ty.dims.is_empty() || ty.per_seq),
                Rule::IndexType,
                i,
                || format!("index of type {:?} into a place of type {:?}", self.f.exprs[i].ty, ty),
            )?;
            ty = ty.element();
            index_var = index_var.join(self.f.exprs[i].var);
        }
        self.check_stmt(ty == value.ty, Rule::AssignType, s, || {
            format!("a value of type {:?} assigned to a place of type {:?}", value.ty, ty)
        })?;
        if !local.var.is_varying() {
            self.check_stmt(
                !value.var.is_varying() && !index_var.is_varying(),
                Rule::VaryingIntoUniform,
                s,
                || format!("a varying value or index into uniform `{}`", local.name),
            )?;
            self.check_stmt(self.conds.is_empty(), Rule::UniformUnderVaryingControl, s, || {
                format!("uniform `{}` assigned under varying control flow", local.name)
            })?;
        }
        Ok(())
    }

    /// `interpolator_return`: where it may stand, with or without a value, and its type.
    fn interpolator_return(&mut self, s: StmtId, v: Option<ExprId>) -> Res {
        let f = self.f;
        self.check_stmt(self.pixel, Rule::InterpolatorReturnPlacement, s, || {
            "`interpolator_return` in the setup part".into()
        })?;
        let placed = match (f.kind, v) {
            (FuncKind::Interpolator, v) => v.is_some(),
            (FuncKind::Primitive, None) => self.arm != Some(false),
            (FuncKind::Primitive, Some(_)) => self.arm.is_some(),
        };
        self.check_stmt(placed, Rule::InterpolatorReturnPlacement, s, || {
            format!(
                "`interpolator_return` {} value in {:?} (arm {:?})",
                if v.is_some() { "with a" } else { "without a" },
                f.kind,
                self.arm
            )
        })?;
        if let Some(e) = v {
            self.root(e)?;
            let ty = &f.exprs[e].ty;
            let ok = match ty.elem {
                Elem::Interp => f.kind == FuncKind::Primitive && ty.dims.is_empty(),
                Elem::Scalar(sc) => sc == Scalar::Float,
            };
            self.check(ok, Rule::InterpolatorReturnType, e, || format!("stores a {ty:?}"))?;
        }
        Ok(())
    }

    fn call(&mut self, s: StmtId, callee: super::FuncId, args: &'a [ExprId]) -> Res {
        let f = self.f;
        self.check_stmt(f.kind == FuncKind::Primitive, Rule::InterpolatorBody, s, || {
            "a primitive call in an interpolator".into()
        })?;
        self.check_stmt(!self.pixel, Rule::PixelPart, s, || {
            "a primitive call in the pixel part".into()
        })?;
        let Some(cf) = self
            .program
            .functions
            .get(callee.0 as usize)
            .filter(|cf| cf.kind == FuncKind::Primitive)
        else {
            return self.fail_stmt(
                Rule::CallCallee,
                s,
                format!("function {} is not a primitive of the program", callee.0),
            );
        };
        self.check_stmt(args.len() == cf.params.len(), Rule::CallArity, s, || {
            format!(
                "{} arguments for the {} parameters of `{}`",
                args.len(),
                cf.params.len(),
                cf.name
            )
        })?;
        for (&a_id, p) in args.iter().zip(&cf.params) {
            self.expr(a_id)?;
            let a = &f.exprs[a_id];
            let pty = &cf.locals.get(p.local.0 as usize).map(|l| &l.ty);
            let Some(pty) = pty else {
                return self.fail_stmt(
                    Rule::CallCallee,
                    s,
                    format!("`{}` has no local for parameter `{}`", cf.name, p.name),
                );
            };
            if matches!(p.role, ParamRole::X | ParamRole::Y | ParamRole::Z) {
                let own = f.param_by_role(p.role).map(|q| q.local);
                let ok = matches!(a.kind, ExprKind::Local(l) if Some(l) == own) && a.ty == **pty;
                self.check(ok, Rule::CallPixelArgs, a_id, || {
                    format!(
                        "`{}` of `{}` does not receive this function's own {:?}",
                        p.name, cf.name, p.role
                    )
                })?;
                continue;
            }
            self.check(!a.var.is_varying(), Rule::CallArgVarying, a_id, || {
                format!("a varying argument for `{}` of `{}`", p.name, cf.name)
            })?;
            let ok = if pty.per_seq {
                !a.ty.per_seq && a.ty.elem == pty.elem && a.ty.dims.get(1..) == Some(&pty.dims[..])
            } else {
                a.ty == **pty
            };
            self.check(ok, Rule::CallArgType, a_id, || {
                format!("an argument of type {:?} for `{}`: {:?}", a.ty, p.name, pty)
            })?;
        }
        Ok(())
    }

    // ---- expressions

    fn expr(&mut self, e_id: ExprId) -> Res {
        let e = &self.f.exprs[e_id];
        let mut r = Ok(());
        let mut var = Variability::Uniform;
        e.for_each_child(|c| {
            if r.is_ok() {
                r = self.expr(c);
                var = var.join(self.f.exprs[c].var);
            }
        });
        r?;
        // A whole per-sequence-point array is only ever the array indexed.
        let per_seq_ok = match &e.kind {
            ExprKind::Index { index, .. } => !self.f.exprs[*index].ty.per_seq,
            _ => {
                let mut ok = true;
                e.for_each_child(|c| ok &= !self.f.exprs[c].ty.per_seq);
                ok
            }
        };
        self.check(per_seq_ok, Rule::PerSeqValue, e_id, || {
            "a whole per-sequence-point array used as an operand".into()
        })?;
        if let ExprKind::Local(l) = &e.kind {
            let local = self.local(*l, expr_node(e), self.f.exprs.span(e_id))?;
            var = local.var;
            self.check(e.ty == local.ty, Rule::LocalType, e_id, || {
                format!("reads `{}` of type {:?} as {:?}", local.name, local.ty, e.ty)
            })?;
        }
        self.check(e.var == var, Rule::ExprVariability, e_id, || {
            format!("marked {:?}, its operands make it {:?}", e.var, var)
        })?;
        self.expr_type(e_id)
    }

    fn expr_type(&self, e_id: ExprId) -> Res {
        let e = &self.f.exprs[e_id];
        let ty = &e.ty;
        match &e.kind {
            ExprKind::Local(_) => Ok(()),
            ExprKind::Const(c) => {
                let ok = ty.is_scalar()
                    && matches!(
                        (c, ty.elem),
                        (ConstValue::Float(_), Elem::Scalar(Scalar::Float))
                            | (ConstValue::Int(_), Elem::Scalar(Scalar::Int))
                            | (ConstValue::Bool(_), Elem::Scalar(Scalar::Bool))
                            | (ConstValue::Fixed(_), Elem::Scalar(Scalar::Fixed(_)))
                    );
                self.check(ok, Rule::ConstType, e_id, || format!("{c:?} of type {ty:?}"))
            }
            ExprKind::Index { base, index, site } => {
                self.site(*site, expr_node(e), self.f.exprs.span(e_id))?;
                let ok = (!self.f.exprs[*base].ty.dims.is_empty() || self.f.exprs[*base].ty.per_seq)
                    && self.f.exprs[*index].ty == Type::int()
                    && *ty == self.f.exprs[*base].ty.element();
                self.check(ok, Rule::IndexType, e_id, || {
                    format!(
                        "{:?}[{:?}] typed {:?}",
                        self.f.exprs[*base].ty, self.f.exprs[*index].ty, ty
                    )
                })
            }
            ExprKind::Unary { op, expr } => {
                let ok = match op {
                    UnaryOp::Neg => *ty == self.f.exprs[*expr].ty && ty.elem != Elem::Scalar(Scalar::Bool),
                    UnaryOp::Not => *ty == Type::bool() && self.f.exprs[*expr].ty == Type::bool(),
                };
                self.check(ok, Rule::UnaryType, e_id, || {
                    format!("{op:?} of {:?} typed {ty:?}", self.f.exprs[*expr].ty)
                })
            }
            ExprKind::Binary { op, lhs, rhs } => {
                let ok = binary_ok(*op, &self.f.exprs[*lhs].ty, &self.f.exprs[*rhs].ty, ty);
                self.check(ok, Rule::BinaryType, e_id, || {
                    format!(
                        "{:?} {op:?} {:?} typed {ty:?}",
                        self.f.exprs[*lhs].ty, self.f.exprs[*rhs].ty
                    )
                })
            }
            ExprKind::Convert(x) => match (ty.elem, self.f.exprs[*x].ty.elem) {
                (Elem::Scalar(t), Elem::Scalar(s)) => {
                    let ok = (t == s || (is_number(t) && is_number(s))) && ty.dims == self.f.exprs[*x].ty.dims;
                    self.check(ok, Rule::ConvertType, e_id, || {
                        format!("{:?} to {ty:?}", self.f.exprs[*x].ty)
                    })
                }
                (Elem::Interp, Elem::Scalar(Scalar::Float)) if ty.dims.is_empty() && !self.f.exprs[*x].ty.per_seq => {
                    match self.f.exprs[*x].ty.dims.len() {
                        0 => Ok(()),
                        1 => self.check(self.arm == Some(false), Rule::InterpFromList, e_id, || {
                            format!("{:?} made interpolation data outside a named arm", self.f.exprs[*x].ty)
                        }),
                        _ => self.fail(
                            Rule::ConvertType,
                            expr_node(e),
                            self.f.exprs.span(e_id),
                            format!("{:?} to {ty:?}", self.f.exprs[*x].ty),
                        ),
                    }
                }
                _ => self.fail(
                    Rule::ConvertType,
                    expr_node(e),
                    self.f.exprs.span(e_id),
                    format!("{:?} to {ty:?}", self.f.exprs[*x].ty),
                ),
            },
            ExprKind::Select { cond, then, otherwise } => {
                let ok = self.f.exprs[*cond].ty == Type::bool()
                    && self.f.exprs[*then].ty == *ty
                    && self.f.exprs[*otherwise].ty == *ty;
                self.check(ok, Rule::SelectType, e_id, || {
                    format!(
                        "{:?} ? {:?} : {:?} typed {ty:?}",
                        self.f.exprs[*cond].ty, self.f.exprs[*then].ty, self.f.exprs[*otherwise].ty
                    )
                })
            }
            ExprKind::Builtin { func, args } => {
                if matches!(
                    func,
                    Builtin::TransformPoint { .. } | Builtin::TransformVector { .. } | Builtin::TransformNormal { .. }
                ) {
                    self.check(self.f.uses_spaces, Rule::SpacesUsed, e_id, || {
                        format!("{func:?} in a function not marked uses_spaces")
                    })?;
                }
                self.check(
                    builtin_ok(&self.f.exprs, *func, args, ty),
                    Rule::BuiltinType,
                    e_id,
                    || {
                        let a: Vec<&Type> = args.iter().map(|a| &self.f.exprs[*a].ty).collect();
                        format!("{func:?} of {a:?} typed {ty:?}")
                    },
                )
            }
            ExprKind::List(items) => {
                let ok = !ty.per_seq
                    && ty.dims.first() == Some(&(items.len() as u32))
                    && items.iter().all(|i| self.f.exprs[*i].ty == ty.element());
                self.check(ok, Rule::ListType, e_id, || {
                    let a: Vec<&Type> = items.iter().map(|a| &self.f.exprs[*a].ty).collect();
                    format!("items {a:?} in a list typed {ty:?}")
                })
            }
            ExprKind::Splat(x) => {
                let ok = self.f.exprs[*x].ty.dims.is_empty()
                    && !self.f.exprs[*x].ty.per_seq
                    && self.f.exprs[*x].ty.elem == ty.elem
                    && !ty.dims.is_empty()
                    && !ty.per_seq;
                self.check(ok, Rule::SplatType, e_id, || {
                    format!("{:?} splat to {ty:?}", self.f.exprs[*x].ty)
                })
            }
            ExprKind::MatMul { lhs, rhs } => {
                let ok = is_float(&self.f.exprs[*lhs].ty)
                    && is_float(&self.f.exprs[*rhs].ty)
                    && match (
                        self.f.exprs[*lhs].ty.dims.as_slice(),
                        self.f.exprs[*rhs].ty.dims.as_slice(),
                    ) {
                        ([n, m], [m2]) => m == m2 && *ty == float_ty(vec![*n]),
                        ([n, m], [m2, k]) => m == m2 && *ty == float_ty(vec![*n, *k]),
                        _ => false,
                    };
                self.check(ok, Rule::MatMulType, e_id, || {
                    format!("{:?} * {:?} typed {ty:?}", self.f.exprs[*lhs].ty, self.f.exprs[*rhs].ty)
                })
            }
            ExprKind::SeqCount => self.check(*ty == Type::int(), Rule::QueryType, e_id, || format!("typed {ty:?}")),
            ExprKind::ClipFlag => self.check(*ty == Type::bool(), Rule::QueryType, e_id, || format!("typed {ty:?}")),
        }
    }
}

/// The checker's typing of `l op r` (see `check::lower`'s `binary` and `arith`).
fn binary_ok(op: BinOp, l: &Type, r: &Type, ty: &Type) -> bool {
    if l.per_seq || r.per_seq || ty.per_seq {
        return false;
    }
    let same_or_scalar = l.dims == r.dims || l.dims.is_empty() || r.dims.is_empty();
    let dims = if l.dims.is_empty() { &r.dims } else { &l.dims };
    match op {
        BinOp::And | BinOp::Or => *l == Type::bool() && *r == Type::bool() && *ty == Type::bool(),
        BinOp::Lt | BinOp::Le | BinOp::Gt | BinOp::Ge | BinOp::Eq | BinOp::Ne => {
            let ordered = !matches!(op, BinOp::Eq | BinOp::Ne);
            l.is_scalar()
                && *l == *r
                && *ty == Type::bool()
                && match l.elem {
                    Elem::Scalar(s) => !(ordered && s == Scalar::Bool),
                    Elem::Interp => false,
                }
        }
        BinOp::Add | BinOp::Sub | BinOp::Mul | BinOp::Div | BinOp::Rem => {
            if l.elem == Elem::Interp || r.elem == Elem::Interp {
                let side_ok = |t: &Type| t.elem == Elem::Interp || *t == Type::float();
                side_ok(l) && side_ok(r) && same_or_scalar && *ty == Type::array(Elem::Interp, dims.clone())
            } else {
                l.elem == r.elem
                    && matches!(l.elem, Elem::Scalar(s) if is_number(s))
                    && same_or_scalar
                    && *ty == Type::array(l.elem, dims.clone())
            }
        }
    }
}

/// The checker's typing of a built-in call (see `check::builtins`).
fn builtin_ok(x: &super::Exprs, func: Builtin, args: &[ExprId], ty: &Type) -> bool {
    use Builtin::*;
    let (fewest, most) = func.arities();
    if !(fewest..=most).contains(&args.len()) || !args.iter().all(|a| is_float(&x[*a].ty)) || ty.per_seq {
        return false;
    }
    let a0 = &x[args[0]].ty;
    let v3 = float_ty(vec![3]);
    match func {
        Faceforward | Reflect => args.iter().all(|a| x[*a].ty == v3) && *ty == v3,
        Refract => x[args[0]].ty == v3 && x[args[1]].ty == v3 && x[args[2]].ty == Type::float() && *ty == v3,
        Texture { .. } => args.iter().all(|a| x[*a].ty == Type::float()) && *ty == v3,
        Noise | CellNoise => {
            let shapes: Vec<&[u32]> = args.iter().map(|a| x[*a].ty.dims.as_slice()).collect();
            super::noise::noise_dims(&shapes).is_some() && *ty == Type::float()
        }
        Dot | Distance => a0.dims.len() == 1 && x[args[1]].ty == *a0 && *ty == Type::float(),
        Cross => *a0 == float_ty(vec![3]) && x[args[1]].ty == *a0 && *ty == *a0,
        Length => a0.dims.len() == 1 && *ty == Type::float(),
        Normalize => a0.dims.len() == 1 && *ty == *a0,
        TransformPoint { .. } => (a0.dims == [3] || a0.dims == [4]) && *ty == *a0,
        TransformVector { .. } | TransformNormal { .. } => a0.dims == [3] && *ty == *a0,
        _ => is_float(ty) && args.iter().all(|a| x[*a].ty == *ty),
    }
}
