//! The typed IR: what the checker produces and the JIT consumes.
//!
//! A [`Program`] holds every primitive and shared interpolator of a compilation as a
//! [`Function`]. Helper functions do not survive into the IR: the checker inlines each call
//! (a one-trip [`Stmt::Loop`] whose `return` is a `Break`), so recursion is rejected there.
//!
//! Rules that hold for a checked program. Codegen relies on them and asserts none: the
//! validator [`valid`] states each as a [`valid::Rule`] and checks it after the checker and
//! after every pass that rewrites a function (`forward`, `mid::unroll`) in test and
//! debug builds, so a pass that breaks one is an internal compiler error, not a miscompile:
//! - Every [`Expr`] of a function has an [`ExprId`] of its own, and the ids are exactly
//!   `0..Function::exprs` in pre-order ([`number`]): the key of the JIT's side tables, as a
//!   [`LoopId`] is a loop's (each names one `Loop` statement). An id names an expression of
//!   its own function only. The checker numbers every function, and so does every pass
//!   that adds, drops or copies expressions.
//! - Every [`Expr`] has a concrete [`Type`] and a [`Variability`]. An expression is varying
//!   iff one of its operands is. Operands of `Binary` have the same scalar element (the
//!   checker inserts `Convert`), and the same shape, except that one side may be a scalar
//!   that is broadcast over the other side's components.
//! - No uniform local is assigned under varying control flow; no primitive call, `bound` or
//!   `Return` of the setup kind occurs in the pixel part.
//! - `Elem::Interp` (interpolation_data) is symbolic: its component count comes from the
//!   [`crate::abi::VariantKey`] at specialisation time and from the enclosing
//!   `interpolation` arm (the arm for kind K sees only K's components; outside any arm, all
//!   per-sequence-point components).
//! - Each function is split into `setup` (uniform statements run once per primitive
//!   instance per tile) and `pixel` (run once per pixel group, varying values as vectors,
//!   uniform values as scalars); see [`split`].
//! - Indexing carries a [`SiteId`] of `Program::sites`: codegen clamps the index into range
//!   and records a runtime error at that site, so no program reads or writes outside its
//!   storage (an index [`range`] proves in range at every occurrence of its site needs
//!   neither). Locals, loop ids and callees are in range; `break`/`continue` leave an
//!   enclosing loop.
//! - A primitive call passes one argument per callee parameter, of its type, uniform, and
//!   X, Y, Z as the caller's own; `interpolator_return` and `interpolation` occur only where
//!   [`valid`] says.

pub mod eval;
pub mod forward;
pub mod number;
pub mod print;
pub mod range;
pub mod split;
pub mod valid;

use crate::diag::Span;
pub use crate::ops::{BinOp, UnaryOp};

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct FuncId(pub u32);
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct LocalId(pub u32);
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct LoopId(pub u32);
/// A place that can fail at run time (an index out of range, a loop out of fuel).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct SiteId(pub u32);
/// An expression of one function: the key of the analyses' side tables (see the module doc).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ExprId(pub u32);

impl ExprId {
    /// The id of an expression built outside a numbered function; [`number::renumber`]
    /// replaces it.
    pub const UNSET: ExprId = ExprId(u32::MAX);
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Variability {
    Uniform,
    Varying,
}

impl Variability {
    pub fn join(self, other: Variability) -> Variability {
        self.max(other)
    }
    pub fn is_varying(self) -> bool {
        self == Variability::Varying
    }
}

/// `fixed<bits,frac>`: a `bits`-bit two's complement integer `raw` standing for
/// `raw / 2^frac`, stored sign-extended in an i32 lane. A format with no integer bits
/// (`frac == bits`, e.g. the depth buffer's `fixed<32,32>`) is an unsigned fraction in
/// [0, 1). Invariants: 1 <= bits <= 32, frac <= bits.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct FixedFormat {
    pub bits: u8,
    pub frac: u8,
}

impl FixedFormat {
    pub fn is_unsigned(self) -> bool {
        self.frac == self.bits
    }
    pub fn int_bits(self) -> u8 {
        self.bits - self.frac
    }
    /// Smallest and largest raw values.
    pub fn raw_range(self) -> (i64, i64) {
        if self.is_unsigned() {
            (0, (1i64 << self.bits) - 1)
        } else {
            (-(1i64 << (self.bits - 1)), (1i64 << (self.bits - 1)) - 1)
        }
    }
    pub fn scale(self) -> f64 {
        (1u64 << self.frac) as f64
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Scalar {
    Float,
    Int,
    Bool,
    Fixed(FixedFormat),
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Elem {
    Scalar(Scalar),
    /// interpolation_data: as many float components as the context gives (see module doc).
    Interp,
}

/// A scalar or fixed-size array of one element kind. `point` is `float[4]` (homogeneous),
/// `vector`, `normal` and `color` are `float[3]`, `matrix` is `float[4][4]`.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct Type {
    pub elem: Elem,
    /// Fixed dimensions, outermost first; empty for a scalar.
    pub dims: Vec<u32>,
    /// The value has one more, outermost, dimension of run-time length: one element per
    /// sequence point (`point vertex[]`). Only parameters have it.
    pub per_seq: bool,
}

impl Type {
    pub fn scalar(s: Scalar) -> Type {
        Type {
            elem: Elem::Scalar(s),
            dims: vec![],
            per_seq: false,
        }
    }
    pub fn float() -> Type {
        Type::scalar(Scalar::Float)
    }
    pub fn int() -> Type {
        Type::scalar(Scalar::Int)
    }
    pub fn bool() -> Type {
        Type::scalar(Scalar::Bool)
    }
    pub fn array(elem: Elem, dims: Vec<u32>) -> Type {
        Type {
            elem,
            dims,
            per_seq: false,
        }
    }
    pub fn is_scalar(&self) -> bool {
        self.dims.is_empty() && !self.per_seq
    }
    /// Number of elements in the fixed dimensions (1 for a scalar).
    pub fn fixed_len(&self) -> u32 {
        self.dims.iter().product()
    }
    /// The type of `self[i]`.
    pub fn element(&self) -> Type {
        if self.per_seq {
            Type {
                elem: self.elem,
                dims: self.dims.clone(),
                per_seq: false,
            }
        } else {
            Type {
                elem: self.elem,
                dims: self.dims[1..].to_vec(),
                per_seq: false,
            }
        }
    }
}

/// A scalar constant.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ConstValue {
    Float(f32),
    Int(i32),
    Bool(bool),
    /// Raw bits of a fixed value of the expression's format.
    Fixed(i32),
}

/// How the runtime fills and transforms a parameter before the primitive runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ParamRole {
    /// Per-primitive value (`rast_param`), or a sized array of them.
    PerPrimitive,
    /// One value per sequence point (`point vertex[]`).
    PerSequencePoint,
    /// The pixel centre's x (varying, bound by the runtime).
    X,
    /// The pixel centre's y.
    Y,
    /// The depth-buffer value at the pixel (inout varying; larger is nearer).
    Z,
    /// The interpolation data bundle (`interpolation_data interp_data[]` or `[3]`): element i
    /// holds sequence point i's values of every per-sequence-point shading parameter.
    InterpData,
}

/// Which space the runtime transforms a parameter's value into.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ParamSpace {
    /// Not transformed (plain floats, ints, colours, float arrays).
    None,
    /// `point`: to homogeneous device coordinates (x, y in pixels and z in depth units after
    /// dividing by w).
    Point,
    /// `vector`: to lighting coordinates (no translation).
    Vector,
    /// `normal`: to lighting coordinates by the inverse transpose, renormalised.
    Normal,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Param {
    pub local: LocalId,
    pub name: String,
    pub role: ParamRole,
    pub space: ParamSpace,
    /// Default value, flattened components (from `float a = 0` or a `{...}` literal).
    pub default: Option<Vec<ConstValue>>,
    pub span: Span,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LocalKind {
    /// The i-th parameter.
    Param(u32),
    /// A declared variable.
    Var,
    /// A compiler temporary (an inlined helper's result or parameter).
    Temp,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Local {
    pub name: String,
    pub ty: Type,
    pub var: Variability,
    pub kind: LocalKind,
    pub span: Span,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FuncKind {
    Primitive,
    Interpolator,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Function {
    pub name: String,
    pub kind: FuncKind,
    /// The function's name where it is declared (what a diagnostic about the whole
    /// function underlines).
    pub span: Span,
    pub params: Vec<Param>,
    /// Every variable; parameter i is `LocalId(i)`.
    pub locals: Vec<Local>,
    /// Uniform statements, run once per instance (and per tile it touches).
    pub setup: Vec<Stmt>,
    /// Statements run for every pixel group of the pass rectangle, after `setup`. Empty if
    /// the function has no varying code.
    pub pixel: Vec<Stmt>,
    /// Number of `LoopId`s used (ids are 0..loops).
    pub loops: u32,
    /// Number of expressions: their ids are 0..exprs (see [`number`]).
    pub exprs: u32,
    /// The function uses `transform(...)` between named spaces, so its arguments carry the
    /// space matrices.
    pub uses_spaces: bool,
}

impl Function {
    pub fn local(&self, id: LocalId) -> &Local {
        &self.locals[id.0 as usize]
    }
    pub fn param_by_role(&self, role: ParamRole) -> Option<&Param> {
        self.params.iter().find(|p| p.role == role)
    }
}

/// A checked compilation: every primitive and interpolator from every source file.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Program {
    pub functions: Vec<Function>,
    /// Span of each run-time failure site.
    pub sites: Vec<Span>,
}

impl Program {
    pub fn func(&self, id: FuncId) -> &Function {
        &self.functions[id.0 as usize]
    }
    pub fn find(&self, name: &str) -> Option<FuncId> {
        self.functions
            .iter()
            .position(|f| f.name == name)
            .map(|i| FuncId(i as u32))
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct Expr {
    pub kind: ExprKind,
    pub ty: Type,
    pub var: Variability,
    pub span: Span,
    pub id: ExprId,
}

impl Expr {
    /// An expression not numbered yet ([`ExprId::UNSET`]).
    pub fn new(kind: ExprKind, ty: Type, var: Variability, span: Span) -> Expr {
        Expr {
            kind,
            ty,
            var,
            span,
            id: ExprId::UNSET,
        }
    }

    /// Call `f` on each direct sub-expression, in evaluation order. The one place that
    /// knows the shape of every `ExprKind`; walks that treat all children alike recurse
    /// through it.
    pub fn for_each_child<'e>(&'e self, mut f: impl FnMut(&'e Expr)) {
        match &self.kind {
            ExprKind::Const(_) | ExprKind::Local(_) | ExprKind::SeqCount | ExprKind::ClipFlag => {}
            ExprKind::Index { base, index, .. } => {
                f(base);
                f(index);
            }
            ExprKind::Unary { expr, .. } | ExprKind::Convert(expr) | ExprKind::Splat(expr) => f(expr),
            ExprKind::Binary { lhs, rhs, .. } | ExprKind::MatMul { lhs, rhs } => {
                f(lhs);
                f(rhs);
            }
            ExprKind::Select { cond, then, otherwise } => {
                f(cond);
                f(then);
                f(otherwise);
            }
            ExprKind::Builtin { args, .. } | ExprKind::List(args) => args.iter().for_each(f),
        }
    }

    /// [`Expr::for_each_child`] for rewriting.
    pub fn for_each_child_mut(&mut self, mut f: impl FnMut(&mut Expr)) {
        match &mut self.kind {
            ExprKind::Const(_) | ExprKind::Local(_) | ExprKind::SeqCount | ExprKind::ClipFlag => {}
            ExprKind::Index { base, index, .. } => {
                f(base);
                f(index);
            }
            ExprKind::Unary { expr, .. } | ExprKind::Convert(expr) | ExprKind::Splat(expr) => f(expr),
            ExprKind::Binary { lhs, rhs, .. } | ExprKind::MatMul { lhs, rhs } => {
                f(lhs);
                f(rhs);
            }
            ExprKind::Select { cond, then, otherwise } => {
                f(cond);
                f(then);
                f(otherwise);
            }
            ExprKind::Builtin { args, .. } | ExprKind::List(args) => args.iter_mut().for_each(f),
        }
    }

    /// Call `f` on every local `self` reads, anywhere inside it (once per occurrence).
    pub fn for_each_local(&self, f: &mut dyn FnMut(LocalId)) {
        if let ExprKind::Local(l) = self.kind {
            f(l);
        }
        self.for_each_child(|c| c.for_each_local(f));
    }

    /// Whether `self` reads a local for which `pred` holds.
    pub fn reads_any(&self, pred: &dyn Fn(LocalId) -> bool) -> bool {
        let mut found = false;
        self.for_each_local(&mut |l| found |= pred(l));
        found
    }
}

/// Call `f` on every statement in `stmts`, nested ones too (through `if` sides, loop
/// bodies and steps, interpolation arms), each before the statements inside it. The one
/// place that knows which statements hold others.
pub fn for_each_stmt<'s>(stmts: &'s [Stmt], f: &mut dyn FnMut(&'s Stmt)) {
    for s in stmts {
        f(s);
        match &s.kind {
            StmtKind::If { then, otherwise, .. } => {
                for_each_stmt(then, f);
                for_each_stmt(otherwise, f);
            }
            StmtKind::Loop { body, step, .. } => {
                for_each_stmt(body, f);
                for_each_stmt(step, f);
            }
            StmtKind::Interpolation { arms } => arms.iter().for_each(|a| for_each_stmt(&a.body, f)),
            _ => {}
        }
    }
}

/// [`for_each_stmt`] for rewriting.
pub fn for_each_stmt_mut(stmts: &mut [Stmt], f: &mut dyn FnMut(&mut Stmt)) {
    for s in stmts {
        f(s);
        match &mut s.kind {
            StmtKind::If { then, otherwise, .. } => {
                for_each_stmt_mut(then, f);
                for_each_stmt_mut(otherwise, f);
            }
            StmtKind::Loop { body, step, .. } => {
                for_each_stmt_mut(body, f);
                for_each_stmt_mut(step, f);
            }
            StmtKind::Interpolation { arms } => arms.iter_mut().for_each(|a| for_each_stmt_mut(&mut a.body, f)),
            _ => {}
        }
    }
}

impl Stmt {
    /// Call `f` on each expression `self` holds itself (not those of the statements inside
    /// it): a place's indices, then the assigned value; a condition; the arguments of
    /// `bound` and of a call; an interpolator's value.
    pub fn for_each_expr<'s>(&'s self, mut f: impl FnMut(&'s Expr)) {
        match &self.kind {
            StmtKind::Assign { place, value } => {
                place.indices.iter().for_each(|(i, _)| f(i));
                f(value);
            }
            StmtKind::If { cond, .. } => f(cond),
            StmtKind::Loop { cond, .. } => cond.iter().for_each(f),
            StmtKind::InterpolatorReturn(e) => e.iter().for_each(f),
            StmtKind::Bound(es) => es.iter().for_each(f),
            StmtKind::CallPrimitive { args, .. } => args.iter().for_each(f),
            StmtKind::Break(_) | StmtKind::Continue(_) | StmtKind::Return | StmtKind::Interpolation { .. } => {}
        }
    }

    /// [`Stmt::for_each_expr`] for rewriting.
    pub fn for_each_expr_mut(&mut self, mut f: impl FnMut(&mut Expr)) {
        match &mut self.kind {
            StmtKind::Assign { place, value } => {
                place.indices.iter_mut().for_each(|(i, _)| f(i));
                f(value);
            }
            StmtKind::If { cond, .. } => f(cond),
            StmtKind::Loop { cond, .. } => cond.iter_mut().for_each(f),
            StmtKind::InterpolatorReturn(e) => e.iter_mut().for_each(f),
            StmtKind::Bound(es) => es.iter_mut().for_each(f),
            StmtKind::CallPrimitive { args, .. } => args.iter_mut().for_each(f),
            StmtKind::Break(_) | StmtKind::Continue(_) | StmtKind::Return | StmtKind::Interpolation { .. } => {}
        }
    }
}

/// Call `f` on every assignment in `stmts`, nested ones too, with its place and value; the
/// walks that collect assigned locals go through it.
pub fn for_each_assign(stmts: &[Stmt], f: &mut dyn FnMut(&Place, &Expr)) {
    for_each_stmt(stmts, &mut |s| {
        if let StmtKind::Assign { place, value } = &s.kind {
            f(place, value);
        }
    });
}

/// Built-in functions. Unless stated, they work component-wise on floats.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Builtin {
    Sqrt,
    Abs,
    Min,
    Max,
    Clamp,
    Floor,
    Ceil,
    Round,
    Sin,
    Cos,
    Tan,
    Asin,
    Acos,
    /// `atan(x)`
    Atan,
    /// `atan(y, x)`
    Atan2,
    Pow,
    Exp,
    Log,
    Sign,
    /// `mix(a, b, t)` = a + (b - a) * t
    Mix,
    /// `step(edge, x)`
    Step,
    Smoothstep,
    /// `dot(a, b)` of two equal-length float arrays -> float
    Dot,
    /// `cross(a, b)` of float[3] -> float[3]
    Cross,
    /// `length(v)` -> float
    Length,
    Normalize,
    /// `distance(a, b)` -> float
    Distance,
    /// `transform(from, to, p)`: point between named spaces (homogeneous float[4], or float[3]
    /// taken with w = 1).
    TransformPoint {
        from: Space,
        to: Space,
    },
    /// `vtransform(from, to, v)`: direction (no translation).
    TransformVector {
        from: Space,
        to: Space,
    },
    /// `ntransform(from, to, n)`: normal (inverse transpose), not renormalised.
    TransformNormal {
        from: Space,
        to: Space,
    },
}

/// Named coordinate spaces for `transform`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Space {
    Object,
    World,
    Lighting,
    Device,
}

#[derive(Clone, Debug, PartialEq)]
pub enum ExprKind {
    /// A scalar constant of the expression's scalar type.
    Const(ConstValue),
    /// A whole variable or parameter.
    Local(LocalId),
    /// `base[index]`; `index` is Int. Out-of-range indices are clamped and reported at `site`.
    Index {
        base: Box<Expr>,
        index: Box<Expr>,
        site: SiteId,
    },
    Unary {
        op: UnaryOp,
        expr: Box<Expr>,
    },
    Binary {
        op: BinOp,
        lhs: Box<Expr>,
        rhs: Box<Expr>,
    },
    /// Element conversion to this expression's scalar type, shape unchanged. Float to int
    /// truncates toward zero and saturates; to fixed rounds to nearest and saturates;
    /// fixed to float is exact up to f32 rounding.
    Convert(Box<Expr>),
    /// `cond ? then : otherwise`; `cond` is a scalar Bool.
    Select {
        cond: Box<Expr>,
        then: Box<Expr>,
        otherwise: Box<Expr>,
    },
    Builtin {
        func: Builtin,
        args: Vec<Expr>,
    },
    /// Aggregate literal: each element has the type of `self.ty.element()`.
    List(Vec<Expr>),
    /// A scalar of this expression's element kind (or one interpolation_data element)
    /// repeated into every element of its fixed-size array type: what a declaration
    /// without an initialiser (zero) and a scalar assigned to an array become. One node
    /// whatever the array's size (`point known[1280];` was 6 400 as a `List`, walked and
    /// copied by every pass).
    Splat(Box<Expr>),
    /// Matrix product: `[n][m] * [m]` -> `[n]`, `[n][m] * [m][k]` -> `[n][k]` (floats).
    MatMul {
        lhs: Box<Expr>,
        rhs: Box<Expr>,
    },
    /// Run-time number of sequence points (`len(a)` of a per-sequence-point parameter).
    SeqCount,
    /// `clipping()`: uniform bool, whether the primitive may cross the near plane. A
    /// constant of the variant key (`!VariantKey::trivial_accept`), folded by the JIT, so an
    /// `if (clipping())` compiles only the branch the key selects.
    ClipFlag,
}

/// An assignable place: a local and zero or more indices into it.
#[derive(Clone, Debug, PartialEq)]
pub struct Place {
    pub local: LocalId,
    pub indices: Vec<(Expr, SiteId)>,
    pub span: Span,
}

#[derive(Clone, Debug, PartialEq)]
pub enum ArmKind {
    /// `linear:`, `perspective_linear:`, or another per-sequence-point kind.
    Named(String),
    Default,
}

#[derive(Clone, Debug, PartialEq)]
pub struct InterpArm {
    pub kind: ArmKind,
    pub body: Vec<Stmt>,
    pub span: Span,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Stmt {
    pub kind: StmtKind,
    pub span: Span,
}

#[derive(Clone, Debug, PartialEq)]
pub enum StmtKind {
    /// Declarations become assignments (a declaration without an initialiser assigns zero).
    /// Compound assignment is desugared (`a += b` is `a = a + b`).
    Assign {
        place: Place,
        value: Expr,
    },
    /// A varying `cond` executes both sides under masks.
    If {
        cond: Expr,
        then: Vec<Stmt>,
        otherwise: Vec<Stmt>,
    },
    /// `loop { if let Some(c) = cond { if !c break }; body; step }`. `continue` goes to
    /// `step`. `varying` is set when the condition is varying or a break/continue/return
    /// of this loop sits under varying control flow: the loop then runs until no lane is
    /// active. Every iteration spends fuel; out of fuel is a run-time error at `site`.
    Loop {
        id: LoopId,
        cond: Option<Expr>,
        body: Vec<Stmt>,
        step: Vec<Stmt>,
        varying: bool,
        site: SiteId,
    },
    Break(LoopId),
    Continue(LoopId),
    /// In setup: the primitive ends. In the pixel part: the active lanes retire (write
    /// nothing more).
    Return,
    Interpolation {
        arms: Vec<InterpArm>,
    },
    /// Store into the shading parameters of the enclosing arm's kind (or, in an
    /// interpolator, set its result and end it). `None`: run the shared interpolators and
    /// constants bound to the parameters of kinds this construct has no arm for.
    InterpolatorReturn(Option<Expr>),
    /// `bound(xmin, ymin, xmax, ymax)`, all uniform floats.
    Bound(Box<[Expr; 4]>),
    /// Render another primitive now: one argument per callee parameter (defaults filled in),
    /// the callee's X, Y, Z receiving this function's own X, Y, Z locals.
    CallPrimitive {
        callee: FuncId,
        args: Vec<Expr>,
    },
}
