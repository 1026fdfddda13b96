//! The typed IR: what the checker produces and the JIT consumes.
//!
//! A [`Program`] holds every primitive and shared interpolator of a compilation as a
//! [`Function`]. Helper functions do not survive into the IR: the checker inlines each call
//! (a one-trip [`StmtKind::Loop`] whose `return` is a `Break`), so recursion is rejected
//! there.
//!
//! Rules that hold for a checked program. Codegen relies on them and asserts none: the
//! validator [`valid`] states each as a [`valid::Rule`] and checks it after the checker and
//! after every pass that rewrites a function (`forward`, `mid::unroll`) in test and
//! debug builds, so a pass that breaks one is an internal compiler error, not a miscompile:
//! - A function's statements and expressions live in its two arenas ([`arena`]):
//!   [`Function::stmts`] holds [`StmtKind`] nodes addressed by [`StmtId`],
//!   [`Function::exprs`] holds [`Expr`] nodes (kind, type, variability) addressed by
//!   [`ExprId`]; spans are in each arena's side table. A statement holds the ids of its
//!   expressions and, for the statements inside it, [`Block`]s of statement ids; an
//!   expression holds its operands' ids. `Function::setup` and `Function::pixel` are blocks.
//!   Both arenas store trees: each statement is in exactly one block, each expression node
//!   the operand of exactly one node or the expression of exactly one statement, so a pass
//!   may rewrite nodes in place. In each arena the ids are exactly `0..len` in pre-order and
//!   every node is reachable ([`number`]): the key of every analysis' side table, as a
//!   [`LoopId`] is a loop's (each names one `Loop` statement). An id names a node of its
//!   own function only. The checker builds a body as owned trees ([`tree`]) and moves it
//!   into the arenas in that order; every pass that adds, drops, moves or copies
//!   statements or expressions renumbers its result.
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

pub mod arena;
pub mod eval;
pub mod forward;
pub mod noise;
pub mod number;
pub mod print;
pub mod range;
pub mod split;
pub mod tree;
pub mod valid;

use std::fmt;

use crate::diag::Span;
pub use crate::ops::{BinOp, UnaryOp};
pub use arena::{Exprs, Stmts};

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct FuncId(pub u32);
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct LocalId(pub u32);
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct LoopId(pub u32);
/// A place that can fail at run time (an index out of range, a loop out of fuel).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct SiteId(pub u32);
/// An expression of one function: its index in the function's arena ([`Function::exprs`]),
/// and the key of the analyses' side tables (see the module doc).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ExprId(pub u32);
/// A statement of one function: its index in the function's statement arena
/// ([`Function::stmts`]), and the key of side tables about statements.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct StmtId(pub u32);
/// Statements run in order: ids of nodes of the function's statement arena. The setup and
/// pixel parts and every nested body (an `if` side, a loop's body and step, an
/// interpolation arm) are blocks.
pub type Block = Vec<StmtId>;

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

/// What a primitive's sequence points are, as it declares after `primitive` (docs/language.md
/// section 2): it decides what the runtime's geometry stage does with them before the kernel
/// runs (docs/pipeline.md, "Geometry types"). Interpolators are `Surface`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Geometry {
    /// Nothing declared: points are transformed and passed as given; the primitive decides
    /// coverage alone (sphere, NURB surface, a user's own shapes).
    Surface,
    /// `primitive facet`: `point vertex[]` holds a planar polygon's corners: clip codes,
    /// clipping, face culling and a fan of instances.
    Facet,
    /// `primitive line`: `point vertex[]` holds a polyline: each segment clipped alone and
    /// drawn as one instance with its neighbours (docs/pipeline.md, "Lines").
    Line,
    /// `primitive point`: `point vertex[]` holds separate points: each one outside the view
    /// dropped, the others drawn as one instance each (docs/pipeline.md, "Points").
    Point,
}

impl Geometry {
    /// The declaration's names, as written after `primitive`.
    pub const NAMES: [(&'static str, Geometry); 3] = [
        ("facet", Geometry::Facet),
        ("line", Geometry::Line),
        ("point", Geometry::Point),
    ];

    pub fn name(self) -> &'static str {
        match self {
            Geometry::Surface => "surface",
            Geometry::Facet => "facet",
            Geometry::Line => "line",
            Geometry::Point => "point",
        }
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct Function {
    pub name: String,
    pub kind: FuncKind,
    pub geometry: Geometry,
    /// The function's name where it is declared (what a diagnostic about the whole
    /// function underlines).
    pub span: Span,
    pub params: Vec<Param>,
    /// Every variable; parameter i is `LocalId(i)`.
    pub locals: Vec<Local>,
    /// Uniform statements, run once per instance (and per tile it touches).
    pub setup: Block,
    /// Statements run for every pixel group of the pass rectangle, after `setup`. Empty if
    /// the function has no varying code.
    pub pixel: Block,
    /// Number of `LoopId`s used (ids are 0..loops).
    pub loops: u32,
    /// Every statement of `setup` and `pixel`, nested ones too, indexed by [`StmtId`] (see
    /// [`number`]).
    pub stmts: Stmts,
    /// Every expression of those statements, indexed by [`ExprId`] (see [`number`]).
    pub exprs: Exprs,
    /// The function uses `transform(...)` between named spaces, so its arguments carry the
    /// space matrices.
    pub uses_spaces: bool,
}

impl Function {
    /// Whether it has per-pixel code and no `bound` on any path: that code then runs over
    /// the whole viewport for every instance (W0004 at check time, W0803 when drawn).
    pub fn runs_unbounded(&self) -> bool {
        !self.pixel.is_empty() && !self.stmts.iter().any(|(_, s)| matches!(s, StmtKind::Bound(_)))
    }
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
    /// The surface, light and atmosphere shaders of the sources, and their helper functions,
    /// as written: a frame links the ones it uses into a program of its own
    /// (`crate::link`). Empty when the sources define no shader.
    pub shading_items: Vec<crate::syntax::ast::Item>,
    /// The image textures its `texture` calls name.
    pub textures: Textures,
}

/// The image textures of a program, by slot ([`Builtin::Texture`]).
#[derive(Clone, Debug, Default)]
pub struct Textures {
    /// The file names as written, each once, and where each is first named.
    pub names: Vec<String>,
    pub spans: Vec<crate::diag::Span>,
    /// Once loaded (`runtime::shading::language`, before anything renders): the set and each
    /// slot's texture in it. Kernels and the evaluator read black without it.
    pub loaded: Option<(std::sync::Arc<crate::runtime::texture::TextureSet>, Vec<u32>)>,
}

impl PartialEq for Textures {
    fn eq(&self, other: &Textures) -> bool {
        let same_set = match (&self.loaded, &other.loaded) {
            (None, None) => true,
            (Some((a, ia)), Some((b, ib))) => std::sync::Arc::ptr_eq(a, b) && ia == ib,
            _ => false,
        };
        self.names == other.names && self.spans == other.spans && same_set
    }
}

impl Textures {
    /// The set and the texture id of `slot`, when loaded.
    pub fn lookup(&self, slot: u32) -> Option<(&crate::runtime::texture::TextureSet, u32)> {
        let (set, ids) = self.loaded.as_ref()?;
        Some((set, *ids.get(slot as usize)?))
    }
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

    /// The interpolation kinds the functions' `interpolation` arms name (`linear:`,
    /// `implicit:`...), sorted, each once.
    pub fn arm_kinds(&self) -> Vec<String> {
        let mut kinds = std::collections::BTreeSet::new();
        for f in &self.functions {
            for block in [&f.setup, &f.pixel] {
                for_each_stmt(&f.stmts, block, &mut |_, s| {
                    if let StmtKind::Interpolation { arms } = s {
                        kinds.extend(arms.iter().filter_map(|a| match &a.kind {
                            ArmKind::Named(k) => Some(k.clone()),
                            ArmKind::Default => None,
                        }));
                    }
                });
            }
        }
        kinds.into_iter().collect()
    }
}

/// An expression node of a function's arena ([`Function::exprs`]): its operands are the
/// [`ExprId`]s of other nodes of the same arena; its span is in the arena's side table.
#[derive(Clone, Debug, PartialEq)]
pub struct Expr {
    pub kind: ExprKind,
    pub ty: Type,
    pub var: Variability,
}

impl Expr {
    pub fn new(kind: ExprKind, ty: Type, var: Variability) -> Expr {
        Expr { kind, ty, var }
    }

    /// The `k`-th direct operand, in evaluation order (`None` past the last). The one place
    /// that knows the shape of every `ExprKind` (with [`Expr::for_each_child_mut`]); walks
    /// that treat all operands alike go through it.
    pub fn child(&self, k: usize) -> Option<ExprId> {
        match &self.kind {
            ExprKind::Const(_) | ExprKind::Local(_) | ExprKind::SeqCount | ExprKind::ClipFlag => None,
            ExprKind::Index { base: a, index: b, .. }
            | ExprKind::Binary { lhs: a, rhs: b, .. }
            | ExprKind::MatMul { lhs: a, rhs: b } => [*a, *b].get(k).copied(),
            ExprKind::Unary { expr, .. } | ExprKind::Convert(expr) | ExprKind::Splat(expr) => (k == 0).then_some(*expr),
            ExprKind::Select { cond, then, otherwise } => [*cond, *then, *otherwise].get(k).copied(),
            ExprKind::Builtin { args, .. } | ExprKind::List(args) => args.get(k).copied(),
        }
    }

    /// Call `f` on each direct operand, in evaluation order.
    pub fn for_each_child(&self, mut f: impl FnMut(ExprId)) {
        let mut k = 0;
        while let Some(c) = self.child(k) {
            f(c);
            k += 1;
        }
    }

    /// [`Expr::for_each_child`] for rewriting the operand ids.
    pub fn for_each_child_mut(&mut self, mut f: impl FnMut(&mut ExprId)) {
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
}

/// Call `f` on every statement of `block`, nested ones too (through `if` sides, loop
/// bodies and steps, interpolation arms), each before the statements inside it, with its
/// id and node.
pub fn for_each_stmt<'s>(stmts: &'s Stmts, block: &[StmtId], f: &mut dyn FnMut(StmtId, &'s StmtKind)) {
    for &id in block {
        let s = &stmts[id];
        f(id, s);
        s.for_each_block(|b| for_each_stmt(stmts, b, f));
    }
}

/// Whether loop `id` with `body` can start a second trip: not when the body ends with a
/// `break` of the loop itself and holds no `continue` of it, since then no trip reaches
/// the step (an inlined helper's body is such a loop, so that its `return`s can leave it).
/// Only a loop that can repeat spends fuel: kernels and the evaluator both ask here.
pub fn loop_repeats(stmts: &Stmts, id: LoopId, body: &[StmtId]) -> bool {
    if !matches!(body.last().map(|&s| &stmts[s]), Some(StmtKind::Break(l)) if *l == id) {
        return true;
    }
    let mut continues = false;
    for_each_stmt(stmts, body, &mut |_, s| {
        continues |= matches!(s, StmtKind::Continue(l) if *l == id)
    });
    continues
}

/// Call `f` on every assignment of `block`, nested ones too, with its place and value; the
/// walks that collect assigned locals go through it.
pub fn for_each_assign(stmts: &Stmts, block: &[StmtId], f: &mut dyn FnMut(&Place, ExprId)) {
    for_each_stmt(stmts, block, &mut |_, s| {
        if let StmtKind::Assign { place, value } = s {
            f(place, *value);
        }
    });
}

impl<E: Form> StmtKind<E> {
    /// Call `f` on each expression `self` holds itself (not those of the statements inside
    /// it): a place's indices, then the assigned value; a condition; the arguments of
    /// `bound` and of a call; an interpolator's value.
    pub fn for_each_expr<'s>(&'s self, mut f: impl FnMut(&'s E)) {
        match self {
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

    /// [`StmtKind::for_each_expr`] for rewriting.
    pub fn for_each_expr_mut(&mut self, mut f: impl FnMut(&mut E)) {
        match self {
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

    /// Call `f` on each block `self` holds, in execution order: `then` and `otherwise`; a
    /// loop's body and step; each interpolation arm's body. The one place that knows which
    /// statements hold others; walks that treat all blocks alike go through it.
    pub fn for_each_block<'s>(&'s self, mut f: impl FnMut(&'s E::Block)) {
        match self {
            StmtKind::If { then, otherwise, .. } => {
                f(then);
                f(otherwise);
            }
            StmtKind::Loop { body, step, .. } => {
                f(body);
                f(step);
            }
            StmtKind::Interpolation { arms } => arms.iter().for_each(|a| f(&a.body)),
            _ => {}
        }
    }

    /// [`StmtKind::for_each_block`] for rewriting.
    pub fn for_each_block_mut(&mut self, mut f: impl FnMut(&mut E::Block)) {
        match self {
            StmtKind::If { then, otherwise, .. } => {
                f(then);
                f(otherwise);
            }
            StmtKind::Loop { body, step, .. } => {
                f(body);
                f(step);
            }
            StmtKind::Interpolation { arms } => arms.iter_mut().for_each(|a| f(&mut a.body)),
            _ => {}
        }
    }

    /// The name of the kind, as the validator and diagnostics name a statement.
    pub fn name(&self) -> &'static str {
        match self {
            StmtKind::Assign { .. } => "Assign",
            StmtKind::If { .. } => "If",
            StmtKind::Loop { .. } => "Loop",
            StmtKind::Break(_) => "Break",
            StmtKind::Continue(_) => "Continue",
            StmtKind::Return => "Return",
            StmtKind::Interpolation { .. } => "Interpolation",
            StmtKind::InterpolatorReturn(_) => "InterpolatorReturn",
            StmtKind::Bound(_) => "Bound",
            StmtKind::CallPrimitive { .. } => "CallPrimitive",
        }
    }
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
    /// `faceforward(N, I)` or `faceforward(N, I, Nref)` of float[3] -> float[3]: `N` where
    /// `dot(Nref, I) < 0`, else `-N` (`Nref` is `N` in the two-argument form).
    Faceforward,
    /// `reflect(I, N)` of float[3] -> float[3]: `I - 2 dot(N, I) N`.
    Reflect,
    /// `refract(I, N, eta)` of float[3], float[3], float -> float[3]; zero on total
    /// internal reflection.
    Refract,
    /// `noise(x)`, `noise(x, y)`, `noise(p)`, `noise(p, t)` -> float in [0, 1]: gradient
    /// noise of the arguments' components (a float[4] point contributes x, y, z), see
    /// [`noise`].
    Noise,
    /// `cellnoise(...)`, the same arguments as `Noise` -> float in [0, 1), constant on
    /// integer cells.
    CellNoise,
    /// `__gbuffer(plane, X, Y)` -> float: G-buffer plane `plane` (a constant) at the pixel
    /// `(X, Y)`, which must be the function's own pixel centre (only linked shader groups
    /// call it, `crate::link`, with their `X` and `Y`). A plane past `ctx.num_planes` reads
    /// 0. Taking `X` and `Y` makes the value varying and keeps it in the pixel part.
    GBuffer,
    /// `Dx(v)`, `Dy(v)`: per component, the change of `v` from one pixel to the next along
    /// screen x (y) within the 2x2 quad of pixels a shading group holds (lanes 0, 1 the
    /// quad's upper row, 2, 3 its lower one): the difference across the lane's own row
    /// (column) when both of its pixels execute, else across the other row (column) when
    /// both of those do, else 0. A uniform `v` gives 0. Only shaders call them
    /// (`crate::link` runs such groups on quads).
    Dx,
    Dy,
    /// `filterwidth(v)` = `sqrt(Dx(v)^2 + Dy(v)^2)` per component.
    FilterWidth,
    /// `texture("file", s, t)` -> float[3]: image texture `slot` of [`Program::textures`]
    /// filtered at `(s, t)` with wrap mode `wrap` (`runtime::texture::Wrap` as a number);
    /// the operands are `s, t, Dx(s), Dx(t), Dy(s), Dy(t)`. Only shaders call it.
    Texture {
        slot: u32,
        wrap: u32,
    },
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

impl Builtin {
    /// The fewest and most arguments a call has (`faceforward` and the noises vary).
    pub fn arities(self) -> (usize, usize) {
        use Builtin::*;
        match self {
            Min | Max | Pow | Step | Atan2 | Dot | Cross | Distance | Reflect => (2, 2),
            Clamp | Mix | Smoothstep | Refract | GBuffer => (3, 3),
            Texture { .. } => (6, 6),
            Faceforward => (2, 3),
            Noise | CellNoise => (1, 2),
            _ => (1, 1),
        }
    }
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
        base: ExprId,
        index: ExprId,
        site: SiteId,
    },
    Unary {
        op: UnaryOp,
        expr: ExprId,
    },
    Binary {
        op: BinOp,
        lhs: ExprId,
        rhs: ExprId,
    },
    /// Element conversion to this expression's scalar type, shape unchanged. Float to int
    /// truncates toward zero and saturates; to fixed rounds to nearest and saturates;
    /// fixed to float is exact up to f32 rounding.
    Convert(ExprId),
    /// `cond ? then : otherwise`; `cond` is a scalar Bool.
    Select {
        cond: ExprId,
        then: ExprId,
        otherwise: ExprId,
    },
    Builtin {
        func: Builtin,
        args: Vec<ExprId>,
    },
    /// Aggregate literal: each element has the type of `self.ty.element()`.
    List(Vec<ExprId>),
    /// A scalar of this expression's element kind (or one interpolation_data element)
    /// repeated into every element of its fixed-size array type: what a declaration
    /// without an initialiser (zero) and a scalar assigned to an array become. One node
    /// whatever the array's size (`point known[1280];` was 6 400 as a `List`, walked and
    /// copied by every pass).
    Splat(ExprId),
    /// Matrix product: `[n][m] * [m]` -> `[n]`, `[n][m] * [m][k]` -> `[n][k]` (floats).
    MatMul {
        lhs: ExprId,
        rhs: ExprId,
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
pub struct Place<E = ExprId> {
    pub local: LocalId,
    pub indices: Vec<(E, SiteId)>,
    pub span: Span,
}

#[derive(Clone, Debug, PartialEq)]
pub enum ArmKind {
    /// `linear:`, `perspective_linear:`, or another per-sequence-point kind.
    Named(String),
    Default,
}

#[derive(Clone, Debug, PartialEq)]
pub struct InterpArm<E: Form = ExprId> {
    pub kind: ArmKind,
    pub body: E::Block,
    pub span: Span,
}

/// How a statement holds its expressions (`E`) and, following from it, the statements
/// inside it: the IR's statements hold [`ExprId`]s and [`Block`]s of ids of the same
/// arenas; the checker's owned statements ([`tree`]) hold their trees and statements inline.
pub trait Form: Clone + fmt::Debug + PartialEq {
    type Block: Clone + fmt::Debug + PartialEq;
}

impl Form for ExprId {
    type Block = Block;
}

/// A statement with its span, owned: how the checker builds a body ([`tree`]) before
/// [`tree::intern_body`] moves it into the function's arenas. In the IR a statement is a
/// [`StmtKind`] node of [`Function::stmts`], its span in the arena's side table.
#[derive(Clone, Debug, PartialEq)]
pub struct Stmt<E: Form> {
    pub kind: StmtKind<E>,
    pub span: Span,
}

#[derive(Clone, Debug, PartialEq)]
pub enum StmtKind<E: Form = ExprId> {
    /// Declarations become assignments (a declaration without an initialiser assigns zero).
    /// Compound assignment is desugared (`a += b` is `a = a + b`).
    Assign {
        place: Place<E>,
        value: E,
    },
    /// A varying `cond` executes both sides under masks.
    If {
        cond: E,
        then: E::Block,
        otherwise: E::Block,
    },
    /// `loop { if let Some(c) = cond { if !c break }; body; step }`. `continue` goes to
    /// `step`. `varying` is set when the condition is varying or a break/continue/return
    /// of this loop sits under varying control flow: the loop then runs until no lane is
    /// active. Every iteration spends fuel; out of fuel is a run-time error at `site`.
    Loop {
        id: LoopId,
        cond: Option<E>,
        body: E::Block,
        step: E::Block,
        varying: bool,
        site: SiteId,
    },
    Break(LoopId),
    Continue(LoopId),
    /// In setup: the primitive ends. In the pixel part: the active lanes retire (write
    /// nothing more).
    Return,
    Interpolation {
        arms: Vec<InterpArm<E>>,
    },
    /// Store into the shading parameters of the enclosing arm's kind (or, in an
    /// interpolator, set its result and end it). `None`: run the shared interpolators and
    /// constants bound to the parameters of kinds this construct has no arm for.
    InterpolatorReturn(Option<E>),
    /// `bound(xmin, ymin, xmax, ymax)`, all uniform floats.
    Bound([E; 4]),
    /// Render another primitive now: one argument per callee parameter (defaults filled in),
    /// the callee's X, Y, Z receiving this function's own X, Y, Z locals.
    CallPrimitive {
        callee: FuncId,
        args: Vec<E>,
        /// Where a call skipped for depth (`abi::MAX_CALL_DEPTH`) is counted and reported.
        site: SiteId,
    },
}
