//! The abstract syntax tree: the program as written, with a [`Span`] on every node.
//!
//! Names are kept as written (resolution happens in `check`), types as written
//! (`point`, `fixed<32,16>`, `interpolator_data`), RenderMan parameter groups are flattened
//! into one [`Param`] per name (each keeps the group's qualifiers and type). `i++` and
//! `i += 1` are both [`StmtKind::Assign`]. Nodes that failed to parse are `Error` variants,
//! so later passes can skip them without inventing more errors.
//!
//! The larger parts of statements and items (conditions, assignment targets, declared
//! types, initialisers, callee names, bodies) are boxed: lalrpop moves its stack symbol,
//! as large as the largest node type, on every reduction, about four per token, and
//! keeping every node at most 104 bytes lets those moves be a few register copies instead
//! of a 224-byte `memcpy` (library parse -12% instructions).

use crate::diag::Span;
pub use crate::ops::{BinOp, UnaryOp};

#[derive(Clone, Debug, PartialEq)]
pub struct Ident {
    pub name: String,
    pub span: Span,
}

/// One source file: a list of top-level items.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Module {
    pub items: Vec<Item>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ItemKind {
    /// `primitive [GEOMETRY] NAME(PARAMS) { BODY }`
    Primitive,
    /// `interpolator NAME(PARAMS) { BODY }` — a shared interpolator (seed 004, 3.4).
    Interpolator,
    /// `TYPE NAME(PARAMS) { BODY }` or `void NAME(...)` — a helper function.
    Function,
    /// `surface NAME(PARAMS) { BODY }` — a surface shader: sets `Ci`, `Oi` from the
    /// shading globals (docs/shading.md). Shaders are not checked as functions of their
    /// own: `crate::link` links a frame's surface, lights and atmosphere into one primitive
    /// of the deferred pass and checks that.
    Surface,
    /// `light NAME(PARAMS) { BODY }` — a light shader: sets `L` and `Cl` for a surface point `Ps`.
    Light,
    /// `atmosphere NAME(PARAMS) { BODY }` — runs after the surface, changing `Ci`, `Oi`.
    Atmosphere,
}

impl ItemKind {
    pub fn is_shader(self) -> bool {
        matches!(self, ItemKind::Surface | ItemKind::Light | ItemKind::Atmosphere)
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct Item {
    pub kind: ItemKind,
    /// Return type of a helper function (`None` for `void`, primitives and interpolators).
    pub ret: Option<Box<TypeExpr>>,
    /// A primitive's geometry type as written (`primitive facet polygon(...)`): the name
    /// the checker resolves to an [`crate::ir::Geometry`]; `None` when not written.
    pub geometry: Option<Ident>,
    pub name: Ident,
    pub params: Vec<Param>,
    pub body: Box<Block>,
    pub span: Span,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Variability {
    Uniform,
    Varying,
}

#[derive(Clone, Debug, PartialEq, Default)]
pub struct Qualifiers {
    /// `uniform` or `varying` if written.
    pub variability: Option<(Variability, Span)>,
    /// `inout` if written.
    pub inout: Option<Span>,
}

/// One parameter name with its group's qualifiers and type:
/// `varying fixed<32,16> X, Y;` gives two `Param`s.
#[derive(Clone, Debug, PartialEq)]
pub struct Param {
    pub quals: Qualifiers,
    pub ty: TypeExpr,
    pub name: Ident,
    /// Array dimensions after the name, outermost first: `float m[4][4]`, `point vertex[]`.
    pub dims: Vec<ArrayDim>,
    pub default: Option<Expr>,
    pub span: Span,
}

#[derive(Clone, Debug, PartialEq)]
pub enum ArrayDim {
    /// `[expr]` — must be a constant integer expression.
    Sized(Expr),
    /// `[]` — one element per sequence point (parameters only).
    Unsized(Span),
}

#[derive(Clone, Debug, PartialEq)]
pub struct TypeExpr {
    pub kind: TypeKind,
    pub span: Span,
}

#[derive(Clone, Debug, PartialEq)]
pub enum TypeKind {
    Float,
    Int,
    Bool,
    /// `fixed<B,F>` as written; the checker validates the numbers.
    Fixed {
        bits: i64,
        frac: i64,
    },
    /// `point` (also `Point`, as in figure 6): homogeneous, 4 components.
    Point,
    Vector,
    Normal,
    Color,
    Matrix,
    /// `interpolation_data` or its alias `interpolator_data`.
    InterpolationData,
    /// `string` (only for parameters naming spaces; rarely used).
    String,
    /// `void` (helper functions only).
    Void,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Block {
    pub stmts: Vec<Stmt>,
    pub span: Span,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Stmt {
    pub kind: StmtKind,
    pub span: Span,
}

#[derive(Clone, Debug, PartialEq)]
pub struct DeclVar {
    pub name: Ident,
    pub dims: Vec<ArrayDim>,
    pub init: Option<Box<Expr>>,
    pub span: Span,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AssignOp {
    /// `=`
    Set,
    /// `+=` (and `++`)
    Add,
    /// `-=` (and `--`)
    Sub,
    /// `*=`
    Mul,
    /// `/=`
    Div,
}

#[derive(Clone, Debug, PartialEq)]
pub enum InterpArmKind {
    /// `linear:`, `perspective_linear:` or any other kind name.
    Named(Ident),
    /// `default:`
    Default(Span),
}

#[derive(Clone, Debug, PartialEq)]
pub struct InterpArm {
    pub kind: InterpArmKind,
    pub body: Vec<Stmt>,
    pub span: Span,
}

#[derive(Clone, Debug, PartialEq)]
pub enum StmtKind {
    /// `[uniform|varying] TYPE a = 1, b[3] = {..};`
    Decl {
        quals: Qualifiers,
        ty: Box<TypeExpr>,
        vars: Vec<DeclVar>,
    },
    /// `place op value;` — `place` is a name, possibly indexed.
    Assign {
        target: Box<Expr>,
        op: AssignOp,
        value: Expr,
    },
    /// An expression statement (a call).
    Expr(Expr),
    If {
        cond: Box<Expr>,
        then: Block,
        otherwise: Option<Block>,
    },
    /// `for (init; cond; step) body` — each header part optional.
    For {
        init: Option<Box<Stmt>>,
        cond: Option<Box<Expr>>,
        step: Option<Box<Stmt>>,
        body: Block,
    },
    While {
        cond: Box<Expr>,
        body: Block,
    },
    Break,
    Continue,
    /// `return;` or, in a helper function, `return e;`.
    Return(Option<Expr>),
    /// `interpolation { KIND: ... default: ... }`
    Interpolation {
        arms: Vec<InterpArm>,
    },
    /// `interpolator_return(e);` or `interpolator_return;`
    InterpolatorReturn(Option<Expr>),
    /// `bound(xmin, ymin, xmax, ymax);` — arity checked by the checker.
    Bound(Vec<Expr>),
    /// `illuminance(P [, axis, angle]) { ... }` — in a surface shader: the body once per
    /// light of the frame (unrolled by `crate::link`), with `L` and `Cl` set.
    Illuminance {
        args: Vec<Expr>,
        body: Block,
    },
    Block(Block),
    /// A statement that did not parse; its error was already reported.
    Error,
}

impl Stmt {
    /// Call `on_stmt` on each direct sub-statement and `on_expr` on each direct expression
    /// (array sizes, initialisers, conditions, targets, values, arguments), in source order:
    /// the one place that knows the shape of every `StmtKind`, for walks that treat all
    /// children alike.
    pub fn for_each_child<'s>(&'s self, mut on_stmt: impl FnMut(&'s Stmt), mut on_expr: impl FnMut(&'s Expr)) {
        match &self.kind {
            StmtKind::Decl { vars, .. } => {
                for var in vars {
                    for dim in &var.dims {
                        if let ArrayDim::Sized(e) = dim {
                            on_expr(e);
                        }
                    }
                    if let Some(init) = &var.init {
                        on_expr(init);
                    }
                }
            }
            StmtKind::Assign { target, value, .. } => {
                on_expr(target);
                on_expr(value);
            }
            StmtKind::Expr(e) => on_expr(e),
            StmtKind::If { cond, then, otherwise } => {
                on_expr(cond);
                then.stmts.iter().for_each(&mut on_stmt);
                otherwise.iter().flat_map(|b| &b.stmts).for_each(on_stmt);
            }
            StmtKind::For { init, cond, step, body } => {
                init.iter().for_each(|s| on_stmt(s));
                cond.iter().for_each(|e| on_expr(e));
                step.iter().for_each(|s| on_stmt(s));
                body.stmts.iter().for_each(on_stmt);
            }
            StmtKind::While { cond, body } => {
                on_expr(cond);
                body.stmts.iter().for_each(on_stmt);
            }
            StmtKind::Return(e) | StmtKind::InterpolatorReturn(e) => e.iter().for_each(on_expr),
            StmtKind::Interpolation { arms } => arms.iter().flat_map(|a| &a.body).for_each(on_stmt),
            StmtKind::Bound(args) => args.iter().for_each(on_expr),
            StmtKind::Illuminance { args, body } => {
                args.iter().for_each(&mut on_expr);
                body.stmts.iter().for_each(on_stmt);
            }
            StmtKind::Block(b) => b.stmts.iter().for_each(on_stmt),
            StmtKind::Break | StmtKind::Continue | StmtKind::Error => {}
        }
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct Expr {
    pub kind: ExprKind,
    pub span: Span,
}

impl Expr {
    /// Call `f` on each direct sub-expression, in source order: the one place that knows
    /// the shape of every `ExprKind`, for walks that treat all children alike.
    pub fn for_each_child<'e>(&'e self, mut f: impl FnMut(&'e Expr)) {
        match &self.kind {
            ExprKind::Unary { expr, .. } => f(expr),
            ExprKind::Binary { lhs, rhs, .. } => {
                f(lhs);
                f(rhs);
            }
            ExprKind::Ternary { cond, then, otherwise } => {
                f(cond);
                f(then);
                f(otherwise);
            }
            ExprKind::Call { args, .. } | ExprKind::Construct { args, .. } | ExprKind::List(args) => {
                args.iter().for_each(f)
            }
            ExprKind::Index { base, index } => {
                f(base);
                f(index);
            }
            ExprKind::Field { base, .. } => f(base),
            ExprKind::Int(_)
            | ExprKind::Float(_)
            | ExprKind::Bool(_)
            | ExprKind::Str(_)
            | ExprKind::Name(_)
            | ExprKind::Error => {}
        }
    }
}

impl Expr {
    /// [`Expr::for_each_child`] with mutable access (the depth limits cut subtrees off).
    pub fn for_each_child_mut<'e>(&'e mut self, mut f: impl FnMut(&'e mut Expr)) {
        match &mut self.kind {
            ExprKind::Unary { expr, .. } => f(expr),
            ExprKind::Binary { lhs, rhs, .. } => {
                f(lhs);
                f(rhs);
            }
            ExprKind::Ternary { cond, then, otherwise } => {
                f(cond);
                f(then);
                f(otherwise);
            }
            ExprKind::Call { args, .. } | ExprKind::Construct { args, .. } | ExprKind::List(args) => {
                args.iter_mut().for_each(f)
            }
            ExprKind::Index { base, index } => {
                f(base);
                f(index);
            }
            ExprKind::Field { base, .. } => f(base),
            ExprKind::Int(_)
            | ExprKind::Float(_)
            | ExprKind::Bool(_)
            | ExprKind::Str(_)
            | ExprKind::Name(_)
            | ExprKind::Error => {}
        }
    }

    /// Move this node's sub-expressions to `out`, leaving it an `Error` leaf.
    fn take_children(&mut self, out: &mut Vec<Expr>) {
        match &mut self.kind {
            ExprKind::Int(_)
            | ExprKind::Float(_)
            | ExprKind::Bool(_)
            | ExprKind::Str(_)
            | ExprKind::Name(_)
            | ExprKind::Error => return,
            _ => {}
        }
        match std::mem::replace(&mut self.kind, ExprKind::Error) {
            ExprKind::Unary { expr, .. } => out.push(*expr),
            ExprKind::Binary { lhs, rhs, .. } => out.extend([*lhs, *rhs]),
            ExprKind::Ternary { cond, then, otherwise } => out.extend([*cond, *then, *otherwise]),
            ExprKind::Call { args, .. } | ExprKind::Construct { args, .. } | ExprKind::List(args) => out.extend(args),
            ExprKind::Index { base, index } => out.extend([*base, *index]),
            ExprKind::Field { base, .. } => out.push(*base),
            _ => {}
        }
    }
}

/// Freed without recursion: the parser drops whole trees when it recovers from a syntax
/// error, before the depth limits are checked, and a sum of 100,000 terms is a chain of
/// 100,000 boxes (the derived drop takes a frame per box).
impl Drop for Expr {
    fn drop(&mut self) {
        let mut pending = Vec::new();
        self.take_children(&mut pending);
        while let Some(mut e) = pending.pop() {
            // `e` goes as a leaf: its own drop finds nothing to take.
            e.take_children(&mut pending);
        }
    }
}

impl Stmt {
    /// Move the statements nested in this one to `out` (its expressions stay; they free
    /// themselves without recursion).
    fn take_nested(&mut self, out: &mut Vec<Stmt>) {
        match &mut self.kind {
            StmtKind::If { then, otherwise, .. } => {
                out.append(&mut then.stmts);
                if let Some(o) = otherwise {
                    out.append(&mut o.stmts);
                }
            }
            StmtKind::For { body, .. } | StmtKind::While { body, .. } | StmtKind::Block(body) => {
                out.append(&mut body.stmts)
            }
            StmtKind::Interpolation { arms } => arms.iter_mut().for_each(|a| out.append(&mut a.body)),
            // `for` headers hold simple statements only.
            _ => {}
        }
    }
}

/// Freed without recursion, as [`Expr`]: 100,000 nested blocks parse into a chain.
impl Drop for Stmt {
    fn drop(&mut self) {
        let mut pending = Vec::new();
        self.take_nested(&mut pending);
        while let Some(mut s) = pending.pop() {
            s.take_nested(&mut pending);
        }
    }
}

#[derive(Clone, Debug, PartialEq)]
pub enum ExprKind {
    Int(i64),
    Float(f64),
    Bool(bool),
    Str(String),
    Name(Ident),
    Unary {
        op: UnaryOp,
        expr: Box<Expr>,
    },
    Binary {
        op: BinOp,
        lhs: Box<Expr>,
        rhs: Box<Expr>,
    },
    /// `c ? a : b`
    Ternary {
        cond: Box<Expr>,
        then: Box<Expr>,
        otherwise: Box<Expr>,
    },
    /// `name(args)`: helper, built-in, or primitive call.
    Call {
        callee: Box<Ident>,
        args: Vec<Expr>,
    },
    /// `point(x, y, z, w)`, `color(r, g, b)`, `float(i)`, `fixed<32,16>(x)`: a type used as a
    /// constructor or conversion.
    Construct {
        ty: Box<TypeExpr>,
        args: Vec<Expr>,
    },
    Index {
        base: Box<Expr>,
        index: Box<Expr>,
    },
    /// `p.x`, `c.rgb`: component access (a swizzle), the letters as written in `field`.
    Field {
        base: Box<Expr>,
        field: Box<Ident>,
    },
    /// `{a, b, c}` — array, matrix or aggregate literal.
    List(Vec<Expr>),
    /// An expression that did not parse; its error was already reported.
    Error,
}
