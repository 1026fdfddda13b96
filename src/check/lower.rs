//! Lowering one primitive or interpolator body from the AST to IR statements.
//!
//! [`FnLower`] resolves names through a stack of block scopes, types every expression
//! (inserting `Convert` where the type rules of [`super::types`] ask for it) and inlines helper
//! functions at their call sites. Lowering of an expression returns `None` after reporting an
//! error, and the enclosing statement is dropped, so one mistake gives one diagnostic.
//!
//! Expressions are built as owned trees ([`crate::ir::tree::Tree`]) and statements as
//! `Stmt<Tree>`; the checker then moves the body into the function's arena
//! ([`crate::ir::tree::intern_body`]). After this pass every IR expression has its final
//! type; variabilities are placeholders (uniform) that [`super::variability`] fills in. The
//! whole body is in `Function::setup`.
//!
//! This file holds [`FnLower`]'s state, nesting depth, locals and scopes; its methods for
//! statements are in [`stmt`], for calls (primitive calls and helper inlining) in [`call`],
//! for expressions in [`expr`], for component access (`p.x`, `c.rgb`) in [`swizzle`].
//!
//! Helper inlining: a call becomes pre-statements — the arguments assigned to fresh `Temp`
//! locals, then `Loop { cond: None, body: [helper body..., Break(L)] }` in which `return e`
//! is `result = e; break L` — and the call expression becomes `Local(result)`. The argument
//! assignments sit before the loop (not inside it, as a first draft of the design had
//! it) so that a varying `return` inside the helper, which makes the loop varying, does not
//! make the parameter copies "assigned under varying control flow".

use rustc_hash::FxHashMap;

use crate::diag::{Diagnostic, Span};
use crate::ir::tree::{Tree, TreeKind};
use crate::ir::{
    self, BinOp, ConstValue, Elem, FuncKind, Local, LocalId, LocalKind, LoopId, ParamRole, Scalar, SiteId, Stmt,
    StmtKind, Type, Variability,
};
use crate::limits::{MAX_CALL_DEPTH, MAX_NESTING};
use crate::syntax::ast;

use super::types::type_name;
use super::{consts, Globals, LocalInfo, Signature, Sink};

mod call;
mod expr;
mod stmt;
mod swizzle;

/// What an enclosing construct lets `break`/`continue` reach.
#[derive(Clone, Copy)]
enum LoopCtx {
    Loop(LoopId),
    /// An inlined helper's body: loops outside it are not reachable.
    Barrier,
}

struct InlineFrame {
    helper: usize,
    exit: LoopId,
    result: Option<LocalId>,
}

/// Lowers the bodies of one IR function (and of the helpers inlined into it).
pub struct FnLower<'g, 'a> {
    g: &'g Globals<'a>,
    pub sink: &'g mut Sink,
    sites: &'g mut Vec<Span>,
    pub kind: FuncKind,
    pub locals: Vec<Local>,
    pub infos: Vec<LocalInfo<'a>>,
    scopes: Vec<FxHashMap<String, LocalId>>,
    loops: Vec<LoopCtx>,
    inline: Vec<InlineFrame>,
    pub n_loops: u32,
    pub uses_spaces: bool,
    /// Inside an `interpolation` arm: `Some(is_default)`.
    arm: Option<bool>,
    in_interpolation: bool,
    /// Result types of an interpolator's `interpolator_return(e)`s.
    pub interp_returns: Vec<(Type, Span)>,
    /// This function's X, Y and Z parameters.
    xyz: [Option<LocalId>; 3],
    /// Helper calls inlined so far into this function.
    inlined: u32,
    /// The call written in the function itself that the current inlining started from.
    outermost_call: Span,
    /// Report running out of the inlining budget (off when a helper is checked on its own:
    /// only a call from a primitive or interpolator really inlines it).
    pub report_budget: bool,
    /// Helpers whose body was lowered here without a diagnostic the sink did not already
    /// hold and within the inlining budget (see [`super::check_helper`]).
    pub lowered_cleanly: Vec<usize>,
    /// Expression and statement levels (and two per inlined call) open now, counted
    /// through inlined helpers: the depth of this pass's own recursion, kept within
    /// [`MAX_NESTING`].
    nesting: u32,
    /// E0111 was reported for this function.
    nesting_reported: bool,
}

/// Most helper calls inlined into one function.
pub const INLINE_BUDGET: u32 = 20_000;

fn err(code: &'static str, msg: impl Into<String>, span: Span, label: impl Into<String>) -> Diagnostic {
    Diagnostic::error(code, msg).primary(span, label)
}

/// E0215: a call to `what` (primitive or helper) `callee` with `given` arguments.
fn arity_error(what: &str, callee: &ast::Ident, sig: &Signature, given: usize, span: Span, label: &str) -> Diagnostic {
    err(
        "E0215",
        format!(
            "{what} `{}` takes {} arguments, found {given}",
            callee.name,
            sig.params.len()
        ),
        span,
        label,
    )
    .secondary(sig.item.name.span, "declared here")
}

fn mk(kind: TreeKind, ty: Type, span: Span) -> Tree {
    Tree::new(kind, ty, Variability::Uniform, span)
}

fn stmt(kind: StmtKind<Tree>, span: Span) -> Stmt<Tree> {
    Stmt { kind, span }
}

/// Built-in function names (they may not be redefined by items).
pub const BUILTIN_NAMES: &[&str] = &[
    "sqrt",
    "abs",
    "min",
    "max",
    "clamp",
    "floor",
    "ceil",
    "round",
    "sin",
    "cos",
    "tan",
    "asin",
    "acos",
    "atan",
    "pow",
    "exp",
    "log",
    "sign",
    "mix",
    "step",
    "smoothstep",
    "dot",
    "cross",
    "length",
    "normalize",
    "distance",
    "faceforward",
    "reflect",
    "refract",
    "noise",
    "cellnoise",
    "Dx",
    "Dy",
    "filterwidth",
    "texture",
    "transform",
    "vtransform",
    "ntransform",
    "len",
    "clipping",
    "bound",
    "PI",
];

/// Resolve a written type (without declarator dimensions).
pub fn resolve_type(t: &ast::TypeExpr, sink: &mut Sink) -> Option<Type> {
    use ast::TypeKind as K;
    let f3 = || Type::array(Elem::Scalar(Scalar::Float), vec![3]);
    Some(match &t.kind {
        K::Float => Type::float(),
        K::Int => Type::int(),
        K::Bool => Type::bool(),
        K::Fixed { bits, frac } => {
            if !(1..=32).contains(bits) || *frac < 0 || frac > bits {
                sink.push(
                    err(
                        "E0201",
                        format!("invalid fixed-point format fixed<{bits},{frac}>"),
                        t.span,
                        "not a valid format",
                    )
                    .help("fixed<B,F> needs 1 <= B <= 32 total bits and 0 <= F <= B fraction bits"),
                );
                return None;
            }
            Type::scalar(Scalar::Fixed(ir::FixedFormat {
                bits: *bits as u8,
                frac: *frac as u8,
            }))
        }
        K::Point => Type::array(Elem::Scalar(Scalar::Float), vec![4]),
        K::Vector | K::Normal | K::Color => f3(),
        K::Matrix => Type::array(Elem::Scalar(Scalar::Float), vec![4, 4]),
        K::InterpolationData => Type::scalar_interp(),
        K::String => {
            sink.push(
                err("E0214", "`string` values are not supported", t.span, "string type")
                    .help("a string may only appear as a space name literal in transform()"),
            );
            return None;
        }
        K::Void => {
            sink.push(err(
                "E0214",
                "`void` is only a helper function's return type",
                t.span,
                "void type",
            ));
            return None;
        }
    })
}

trait InterpType {
    fn scalar_interp() -> Type;
}
impl InterpType for Type {
    fn scalar_interp() -> Type {
        Type::array(Elem::Interp, vec![])
    }
}

/// Evaluate declarator dimensions (`[4][4]`): constant positive ints, at most 65536
/// components in all (including the base type's own).
pub fn resolve_dims(dims: &[ast::ArrayDim], base: &Type, sink: &mut Sink) -> Option<Vec<u32>> {
    let mut out = vec![];
    let mut total: u64 = base.fixed_len() as u64;
    for d in dims {
        match d {
            ast::ArrayDim::Sized(e) => match consts::eval(e) {
                Ok(consts::ConstTree::Int(n)) if n > 0 => {
                    total = total.saturating_mul(n as u64);
                    if total > 65536 {
                        sink.push(
                            err("E0208", "array too large", e.span, "more than 65536 components in all")
                                .help("an array may hold at most 65536 components"),
                        );
                        return None;
                    }
                    out.push(n as u32);
                }
                Ok(_) => {
                    sink.push(err(
                        "E0208",
                        "array dimension must be a positive integer constant",
                        e.span,
                        "not a positive int",
                    ));
                    return None;
                }
                Err((span, why)) => {
                    sink.push(err("E0208", "array dimension must be a constant", span, why));
                    return None;
                }
            },
            ast::ArrayDim::Unsized(span) => {
                sink.push(
                    err(
                        "E0505",
                        "unsized array `[]` here",
                        *span,
                        "only a primitive's parameter may be unsized",
                    )
                    .help("unsized arrays are per-sequence-point parameters of primitives"),
                );
                return None;
            }
        }
    }
    out.extend(base.dims.iter().copied());
    Some(out)
}

impl<'g, 'a> FnLower<'g, 'a> {
    pub fn new(g: &'g Globals<'a>, sink: &'g mut Sink, sites: &'g mut Vec<Span>, kind: FuncKind) -> Self {
        FnLower {
            g,
            sink,
            sites,
            kind,
            locals: vec![],
            infos: vec![],
            scopes: vec![FxHashMap::default()],
            loops: vec![],
            inline: vec![],
            n_loops: 0,
            uses_spaces: false,
            arm: None,
            in_interpolation: false,
            interp_returns: vec![],
            xyz: [None; 3],
            inlined: 0,
            outermost_call: Span::default(),
            report_budget: true,
            lowered_cleanly: vec![],
            nesting: 0,
            nesting_reported: false,
        }
    }

    // ---- depth ------------------------------------------------------------------------

    /// Open `levels` levels of nesting for the construct at `span`; false (after E0111,
    /// once per function) when that goes past [`MAX_NESTING`]: the caller then lowers
    /// nothing below it and does not call [`Self::leave`].
    fn enter(&mut self, levels: u32, span: Span) -> bool {
        if self.nesting + levels > MAX_NESTING {
            if !self.nesting_reported && self.report_budget {
                self.nesting_reported = true;
                self.sink.push(
                    err(
                        "E0111",
                        format!("nested too deeply after inlining helpers (more than {MAX_NESTING} levels)"),
                        span,
                        "this is past the limit",
                    )
                    .secondary(self.outermost_call, "in the helpers inlined for this call")
                    .help("expressions, statements and helper calls nest through every helper a call inlines"),
                );
            }
            return false;
        }
        self.nesting += levels;
        true
    }

    fn leave(&mut self, levels: u32) {
        self.nesting -= levels;
    }

    // ---- locals, scopes, ids ----------------------------------------------------------

    pub fn new_local(&mut self, name: &str, ty: Type, kind: LocalKind, span: Span, info: LocalInfo<'a>) -> LocalId {
        let id = LocalId(self.locals.len() as u32);
        self.locals.push(Local {
            name: name.to_string(),
            ty,
            var: Variability::Uniform,
            kind,
            span,
        });
        self.infos.push(info);
        id
    }

    /// Bind `name` in the innermost scope; a second declaration in the same scope is an
    /// error (shadowing in an inner block is fine).
    /// Bind a parameter (duplicates were reported with the signature).
    pub fn declare_param(&mut self, name: &str, id: LocalId) {
        self.scopes
            .last_mut()
            .expect("scope stack never empty")
            .insert(name.to_string(), id);
    }

    pub fn declare(&mut self, name: &ast::Ident, id: LocalId) {
        let scope = self.scopes.last_mut().expect("scope stack never empty");
        if let Some(&prev) = scope.get(&name.name) {
            let prev_span = self.locals[prev.0 as usize].span;
            self.sink.push(
                err(
                    "E0105",
                    format!("`{}` is declared twice in the same block", name.name),
                    name.span,
                    "declared again here",
                )
                .secondary(prev_span, "first declared here"),
            );
        }
        scope.insert(name.name.clone(), id);
    }

    pub fn set_xyz(&mut self, role: ParamRole, id: LocalId) {
        match role {
            ParamRole::X => self.xyz[0] = Some(id),
            ParamRole::Y => self.xyz[1] = Some(id),
            ParamRole::Z => self.xyz[2] = Some(id),
            _ => {}
        }
    }

    fn lookup(&self, name: &str) -> Option<LocalId> {
        self.scopes.iter().rev().find_map(|s| s.get(name).copied())
    }

    /// The names a value may be read from here (for "did you mean"): the locals and
    /// parameters in scope (an inlined helper's scopes are only its own) and `PI`.
    fn visible_values(&self) -> impl Iterator<Item = &str> {
        self.scopes
            .iter()
            .flat_map(|s| s.keys().map(String::as_str))
            .chain(["PI"])
    }

    /// The names a call may name (for "did you mean"): the built-in functions, the helpers
    /// and the primitives.
    fn visible_functions(&self) -> impl Iterator<Item = &str> {
        let items = self.g.sigs.iter().filter_map(|s| {
            matches!(s.item.kind, ast::ItemKind::Function | ast::ItemKind::Primitive)
                .then_some(s.item.name.name.as_str())
        });
        BUILTIN_NAMES.iter().copied().filter(|&n| n != "PI").chain(items)
    }

    fn new_site(&mut self, span: Span) -> SiteId {
        self.sites.push(span);
        SiteId((self.sites.len() - 1) as u32)
    }

    fn new_loop(&mut self) -> LoopId {
        self.n_loops += 1;
        LoopId(self.n_loops - 1)
    }

    fn in_helper(&self) -> bool {
        !self.inline.is_empty()
    }

    fn local_expr(&self, id: LocalId, span: Span) -> Tree {
        mk(TreeKind::Local(id), self.locals[id.0 as usize].ty.clone(), span)
    }
}

pub fn var_of(v: ast::Variability) -> Variability {
    match v {
        ast::Variability::Uniform => Variability::Uniform,
        ast::Variability::Varying => Variability::Varying,
    }
}

/// `float and point`: the operand types of a binary operation, for its error messages
/// (formatted only when there is an error: this is the hot path of lowering).
fn shapes(l: &Tree, r: &Tree) -> String {
    format!("{} and {}", type_name(&l.ty), type_name(&r.ty))
}

fn bin(op: BinOp, l: Tree, r: Tree, ty: Type, span: Span) -> Tree {
    mk(
        TreeKind::Binary {
            op,
            lhs: Box::new(l),
            rhs: Box::new(r),
        },
        ty,
        span,
    )
}

fn negate_const(c: ConstValue, s: Scalar) -> Option<ConstValue> {
    match (c, s) {
        (ConstValue::Float(v), _) => Some(ConstValue::Float(-v)),
        (ConstValue::Int(v), _) => Some(ConstValue::Int(v.wrapping_neg())),
        (ConstValue::Fixed(raw), Scalar::Fixed(f)) if !f.is_unsigned() => Some(ConstValue::Fixed(raw.wrapping_neg())),
        _ => None,
    }
}

/// A float scalar seen as interpolation data: the same value for every component.
fn to_interp(v: Tree) -> Tree {
    let span = v.span;
    mk(TreeKind::Convert(Box::new(v)), Type::array(Elem::Interp, vec![]), span)
}

/// A scalar (or interpolation_data element) repeated over an array of the given
/// dimensions: one [`TreeKind::Splat`] node, not a tree of lists.
fn broadcast(v: Tree, dims: &[u32]) -> Tree {
    if dims.is_empty() {
        return v;
    }
    let span = v.span;
    let ty = Type::array(v.ty.elem, dims.to_vec());
    mk(TreeKind::Splat(Box::new(v)), ty, span)
}

/// Does the name `name` occur anywhere in `e` (in nested calls' arguments too)?
fn mentions(e: &ast::Expr, name: &str) -> bool {
    if let ast::ExprKind::Name(id) = &e.kind {
        return id.name == name;
    }
    let mut found = false;
    e.for_each_child(|c| found = found || mentions(c, name));
    found
}
