//! The checker: name resolution, types and conversions, fixed-point formats and
//! uniform/varying inference, lowering the AST to the typed IR.
//!
//! [`check`] runs the passes in this order:
//! 1. **items** — every primitive, interpolator and helper of every module goes into one
//!    namespace (duplicates and redefined built-ins are errors);
//! 2. **signatures** — parameter types, roles (X/Y/Z, interpolation data, per sequence
//!    point, per primitive), spaces and constant defaults, so calls can be checked before
//!    the callee's body;
//! 3. **recursion** — the helper call graph; a cycle is reported once and never inlined;
//! 4. **bodies** — each helper is lowered once on its own (so an uncalled helper is still
//!    type-checked; skipped when an earlier inlining already lowered it cleanly, see
//!    [`check_helper`]), then each primitive and interpolator is lowered ([`lower`]), with
//!    helpers inlined; after this point every expression has its final type;
//! 5. **variability** — [`variability::analyze`] infers uniform/varying to a fixpoint and
//!    reports the variability errors; after this point every expression, loop and local
//!    has its final variability;
//! 6. **split** — [`ir::split::split_checked`] moves per-pixel statements of primitives
//!    into `pixel`; an interpolator's whole body is its pixel part; then
//!    [`ir::number::renumber`] gives each expression its id;
//! 7. **validate** (test and debug builds) — [`ir::valid::validate`] checks the rules code
//!    generation relies on; a broken one is an internal compiler error (E0900);
//! 8. **lints** — [`lint::program`] warns about primitives that check but do not do what
//!    they look like they do (W0003 to W0005), when the program has no error.
//!
//! Diagnostics are collected in a [`Sink`] that drops exact duplicates (a helper's type
//! error is found once standalone and again at every call site it is inlined at) and
//! sorted by position at the end.

mod builtins;
mod consts;
mod lint;
mod lower;
pub mod types;
mod variability;

use rustc_hash::{FxHashMap, FxHashSet};

use crate::diag::{Diagnostic, Diagnostics, Span};
use crate::ir::{self, ConstValue, FuncId, FuncKind, LocalKind, ParamRole, ParamSpace, Type, Variability};
use crate::syntax::ast;

use lower::{resolve_dims, resolve_type, var_of, FnLower, BUILTIN_NAMES};

/// Check every module as one program and lower it to IR (helpers inlined, functions split
/// into setup and pixel parts). Errors go to `diags`; the returned program is only
/// meaningful when there are none.
pub fn check(modules: &[&ast::Module], diags: &mut Diagnostics) -> ir::Program {
    let mut sink = Sink::default();
    let items = collect_items(modules, &mut sink);
    let (shaders, items): (Vec<&ast::Item>, Vec<&ast::Item>) = items.into_iter().partition(|i| i.kind.is_shader());
    let mut program = check_items(&items, false, &mut sink);
    if !shaders.is_empty() {
        program.shading_items = shaders
            .iter()
            .chain(items.iter().filter(|i| i.kind == ast::ItemKind::Function))
            .map(|i| (*i).clone())
            .collect();
    }
    // Shaders are compiled per frame, linked (`crate::link`); here each is linked against
    // every conventional plane and a light of each kind, to report its errors now.
    if !sink.items.iter().any(|d| d.is_error()) {
        let lights: Vec<&ast::Item> = shaders
            .iter()
            .copied()
            .filter(|s| s.kind == ast::ItemKind::Light)
            .collect();
        let helpers: Vec<&ast::Item> = items
            .iter()
            .copied()
            .filter(|i| i.kind == ast::ItemKind::Function)
            .collect();
        for &shader in &shaders {
            match crate::link::canonical(shader, &lights) {
                Ok(linked) => {
                    // What the deferred pass compiles: the helpers and the linked group
                    // (`check_linked`); the primitives were checked above.
                    let mut group: Vec<&ast::Item> = helpers.clone();
                    group.extend(linked.items.iter());
                    check_items(&group, true, &mut sink);
                }
                Err(e) => sink.push(
                    Diagnostic::error("E0900", format!("internal compiler error: {e}"))
                        .primary(shader.name.span, "here"),
                ),
            }
        }
    }
    finish(sink, diags);
    program
}

/// Check the helpers of `program`'s shading items with the items of a linked shader group
/// (`crate::link`) as one program: what the deferred pass compiles.
pub fn check_linked(program: &ir::Program, linked: &[ast::Item], diags: &mut Diagnostics) -> ir::Program {
    let mut sink = Sink::default();
    let mut items: Vec<&ast::Item> = program
        .shading_items
        .iter()
        .filter(|i| i.kind == ast::ItemKind::Function)
        .collect();
    items.extend(linked.iter());
    let program = check_items(&items, true, &mut sink);
    finish(sink, diags);
    program
}

fn finish(sink: Sink, diags: &mut Diagnostics) {
    let mut items = sink.items;
    items.sort_by_key(|d| d.primary_span().map(|s| (s.file, s.start)));
    for d in items {
        diags.push(d);
    }
}

/// Check `items` as one program (`linked`: a shader group's, which may read G-buffer planes).
fn check_items(items: &[&ast::Item], linked: bool, sink: &mut Sink) -> ir::Program {
    let mut g = signatures(items, sink);
    g.linked = linked;
    let g = find_recursion(g, sink);
    let roles: Vec<Vec<ParamRole>> = g
        .sigs
        .iter()
        .filter(|s| s.func.is_some())
        .map(|s| s.params.iter().map(|p| p.role).collect())
        .collect();

    let mut program = ir::Program::default();
    let mut lowered_cleanly = vec![false; g.sigs.len()];
    for (idx, sig) in g.sigs.iter().enumerate() {
        match sig.item.kind {
            ast::ItemKind::Function => check_helper(&g, idx, sink, &mut program.sites, &mut lowered_cleanly),
            ast::ItemKind::Primitive | ast::ItemKind::Interpolator => {
                let f = lower_function(&g, idx, &roles, sink, &mut program.sites, &mut lowered_cleanly);
                program.functions.push(f);
            }
            ast::ItemKind::Surface | ast::ItemKind::Light | ast::ItemKind::Atmosphere => {}
        }
    }
    (program.textures.names, program.textures.spans) = g.textures.take().into_iter().unzip();
    // After this point the program obeys every rule of `ir::valid` (checked in test and
    // debug builds; a broken rule is a bug of the checker, reported as one).
    if cfg!(debug_assertions) && !sink.items.iter().any(|d| d.is_error()) {
        if let Err(e) = ir::valid::validate(&program) {
            sink.push(Diagnostic::error("E0900", format!("internal compiler error: {e}")).primary(e.span, "here"));
        }
    }
    if !linked && sink.error_count() == 0 {
        lint::program(&program, sink);
    }
    program
}

/// A diagnostics collector that keeps the first of identical diagnostics (looked up in a
/// hash set: a linear search made reporting n errors cost n^2).
#[derive(Default)]
pub struct Sink {
    pub items: Vec<Diagnostic>,
    seen: std::collections::HashSet<Diagnostic>,
    errors: usize,
}

impl Sink {
    pub fn push(&mut self, d: Diagnostic) {
        if !self.seen.contains(&d) {
            self.errors += usize::from(d.is_error());
            self.seen.insert(d.clone());
            self.items.push(d);
        }
    }
    /// Errors kept so far.
    pub fn error_count(&self) -> usize {
        self.errors
    }
}

/// What the variability pass needs to know about a local beyond its IR form.
#[derive(Clone, Debug)]
pub struct LocalInfo<'a> {
    /// Declared (or fixed, for parameters) variability and where; `None`: inferred.
    pub declared: Option<(Variability, Span)>,
    /// How to name it in a message.
    pub what: LocalWhat<'a>,
    /// Parameters other than Z may not be assigned.
    pub read_only: bool,
}

/// What kind of local a message is about; [`LocalWhat::describe`] words it with the local's
/// name. Kept unformatted because only a variability error needs the words.
#[derive(Clone, Copy, Debug)]
pub enum LocalWhat<'a> {
    Variable,
    Param,
    /// A parameter of the helper named here, inlined.
    HelperParam(&'a str),
    /// The result of the helper named here, inlined.
    Result(&'a str),
}

impl LocalWhat<'_> {
    /// "variable `a`", "parameter `t` of helper `lerp`", ...: `name` is the local's name.
    pub fn describe(self, name: &str) -> String {
        match self {
            LocalWhat::Variable => format!("variable `{name}`"),
            LocalWhat::Param => format!("parameter `{name}`"),
            LocalWhat::HelperParam(helper) => format!("parameter `{name}` of helper `{helper}`"),
            LocalWhat::Result(helper) => format!("result of `{helper}`"),
        }
    }
}

/// A parameter of an item, resolved.
pub struct SigParam {
    pub name: String,
    pub ty: Type,
    pub role: ParamRole,
    pub space: ParamSpace,
    pub default: Option<Vec<ConstValue>>,
    pub declared: Option<(Variability, Span)>,
    pub inout: bool,
    pub span: Span,
}

pub struct Signature<'a> {
    pub item: &'a ast::Item,
    /// The IR function of a primitive or interpolator.
    pub func: Option<FuncId>,
    pub params: Vec<SigParam>,
    /// A helper's return type (`None`: void).
    pub ret: Option<Type>,
}

pub struct Globals<'a> {
    pub sigs: Vec<Signature<'a>>,
    pub by_name: FxHashMap<String, usize>,
    /// Helpers that are part of a call cycle.
    pub recursive: FxHashSet<usize>,
    /// A linked shader group's program: `__gbuffer` is callable.
    pub linked: bool,
    /// The texture file names `texture` calls have named so far, by slot, with the span
    /// of each first use.
    pub textures: std::cell::RefCell<Vec<(String, Span)>>,
}

fn collect_items<'a>(modules: &[&'a ast::Module], sink: &mut Sink) -> Vec<&'a ast::Item> {
    let mut seen: FxHashMap<&str, Span> = FxHashMap::default();
    let mut out = vec![];
    for &m in modules {
        for item in &m.items {
            let name = item.name.name.as_str();
            if BUILTIN_NAMES.contains(&name) {
                sink.push(
                    Diagnostic::error("E0103", format!("`{name}` is a built-in name and cannot be redefined"))
                        .primary(item.name.span, "redefined here"),
                );
                continue;
            }
            if let Some(prev) = seen.get(name) {
                sink.push(
                    Diagnostic::error("E0104", format!("`{name}` is defined twice"))
                        .primary(item.name.span, "defined again here")
                        .secondary(*prev, "first defined here")
                        .help("primitives, interpolators and helpers of all files share one namespace"),
                );
                continue;
            }
            seen.insert(name, item.name.span);
            out.push(item);
        }
    }
    out
}

fn signatures<'a>(items: &[&'a ast::Item], sink: &mut Sink) -> Globals<'a> {
    let mut sigs = vec![];
    let mut by_name = FxHashMap::default();
    let mut next_func = 0u32;
    for &item in items {
        let func = match item.kind {
            ast::ItemKind::Function => None,
            _ => {
                next_func += 1;
                Some(FuncId(next_func - 1))
            }
        };
        let mut params: Vec<SigParam> = vec![];
        let mut names: FxHashMap<&str, Span> = FxHashMap::default();
        for p in &item.params {
            if let Some(prev) = names.get(p.name.name.as_str()) {
                sink.push(
                    Diagnostic::error("E0106", format!("parameter `{}` is declared twice", p.name.name))
                        .primary(p.name.span, "declared again here")
                        .secondary(*prev, "first declared here"),
                );
            }
            names.insert(&p.name.name, p.name.span);
            params.push(sig_param(item, p, sink));
        }
        let ret = item.ret.as_ref().and_then(|t| resolve_type(t, sink));
        by_name.insert(item.name.name.clone(), sigs.len());
        sigs.push(Signature {
            item,
            func,
            params,
            ret,
        });
    }
    Globals {
        sigs,
        by_name,
        recursive: FxHashSet::default(),
        linked: false,
        textures: Default::default(),
    }
}

fn sig_param(item: &ast::Item, p: &ast::Param, sink: &mut Sink) -> SigParam {
    let helper = item.kind == ast::ItemKind::Function;
    let name = p.name.name.as_str();
    let base = resolve_type(&p.ty, sink).unwrap_or_else(Type::float);
    // An unsized first dimension makes a per-sequence-point parameter (primitives only).
    let (per_seq, sized) = match p.dims.first() {
        Some(ast::ArrayDim::Unsized(sp)) => {
            if item.kind != ast::ItemKind::Primitive {
                let what = if helper { "a helper" } else { "an interpolator" };
                sink.push(
                    Diagnostic::error("E0505", format!("unsized array parameter `{name}` in {what}"))
                        .primary(*sp, "unsized")
                        .help("only primitives have per-sequence-point parameters"),
                );
            }
            (true, &p.dims[1..])
        }
        _ => (false, &p.dims[..]),
    };
    let dims = resolve_dims(sized, &base, sink).unwrap_or_else(|| base.dims.clone());
    let ty = Type {
        elem: base.elem,
        dims,
        per_seq,
    };
    let pixel = !helper && matches!(name, "X" | "Y" | "Z");
    let role = if pixel {
        match name {
            "X" => ParamRole::X,
            "Y" => ParamRole::Y,
            _ => ParamRole::Z,
        }
    } else if ty.elem == ir::Elem::Interp && !helper {
        ParamRole::InterpData
    } else if per_seq {
        ParamRole::PerSequencePoint
    } else {
        ParamRole::PerPrimitive
    };
    let space = match p.ty.kind {
        ast::TypeKind::Point => ParamSpace::Point,
        ast::TypeKind::Vector => ParamSpace::Vector,
        ast::TypeKind::Normal => ParamSpace::Normal,
        _ => ParamSpace::None,
    };
    let quals = &p.quals;
    let declared = if helper {
        quals.variability.map(|(v, sp)| (var_of(v), sp))
    } else if pixel {
        Some((Variability::Varying, p.name.span))
    } else {
        Some((Variability::Uniform, p.span))
    };
    if !helper {
        check_param_quals(item, p, role, &ty, sink);
    }
    let mut default = None;
    if let Some(d) = &p.default {
        if matches!(role, ParamRole::X | ParamRole::Y | ParamRole::Z | ParamRole::InterpData) || p.quals.inout.is_some()
        {
            sink.push(
                Diagnostic::error("E0507", format!("parameter `{name}` cannot have a default"))
                    .primary(d.span, "default given here")
                    .help("X, Y, Z, interpolation data and inout parameters are bound by the runtime or the caller"),
            );
        } else {
            let elem_ty = Type {
                per_seq: false,
                ..ty.clone()
            };
            match consts::eval(d) {
                Ok(c) => match consts::flatten_to(&c, &elem_ty) {
                    Ok(v) => default = Some(v),
                    Err(msg) => sink.push(
                        Diagnostic::error("E0209", format!("default of `{name}` does not fit its type: {msg}"))
                            .primary(d.span, format!("for {}", types::type_name(&elem_ty))),
                    ),
                },
                Err((sp, why)) => sink.push(
                    Diagnostic::error("E0209", format!("default of `{name}` must be a constant"))
                        .primary(sp, why)
                        .help("defaults are literals, PI, `{...}` lists and arithmetic on them"),
                ),
            }
        }
    }
    SigParam {
        name: name.to_string(),
        ty,
        role,
        space,
        default,
        declared,
        inout: quals.inout.is_some(),
        span: p.name.span,
    }
}

fn check_param_quals(item: &ast::Item, p: &ast::Param, role: ParamRole, ty: &Type, sink: &mut Sink) {
    let name = p.name.name.as_str();
    let q = &p.quals;
    let scalar = if ty.dims.is_empty() && !ty.per_seq {
        types::scalar_of(ty)
    } else {
        None
    };
    match role {
        ParamRole::X | ParamRole::Y | ParamRole::Z => {
            if let Some((ast::Variability::Uniform, sp)) = q.variability {
                sink.push(
                    Diagnostic::error("E0501", format!("`{name}` must be varying"))
                        .primary(sp, "declared uniform here")
                        .help("X, Y and Z are the pixel's position and depth: they vary per pixel"),
                );
            }
            let ok_type = match (role, scalar) {
                (ParamRole::Z, Some(s)) => matches!(s, ir::Scalar::Float | ir::Scalar::Fixed(_)),
                (_, Some(s)) => matches!(s, ir::Scalar::Float | ir::Scalar::Int | ir::Scalar::Fixed(_)),
                _ => false,
            };
            if !ok_type {
                let want = if role == ParamRole::Z {
                    "float or fixed"
                } else {
                    "float, int or fixed"
                };
                sink.push(
                    Diagnostic::error("E0502", format!("`{name}` must be a {want} scalar"))
                        .primary(p.ty.span, format!("this is {}", types::type_name(ty))),
                );
            }
            if role == ParamRole::Z {
                if q.inout.is_none() {
                    sink.push(
                        Diagnostic::warning("W0001", "`Z` should be declared `inout varying`")
                            .primary(p.name.span, "taken as inout")
                            .help("the primitive reads and writes the depth buffer through Z"),
                    );
                }
            } else if let Some(sp) = q.inout {
                sink.push(
                    Diagnostic::error("E0504", format!("`inout` on parameter `{name}`"))
                        .primary(sp, "only Z may be inout"),
                );
            }
        }
        _ => {
            if let Some((ast::Variability::Varying, sp)) = q.variability {
                sink.push(
                    Diagnostic::error("E0503", format!("parameter `{name}` cannot be varying"))
                        .primary(sp, "declared varying here")
                        .help("per-primitive data has one value for the whole primitive; only X, Y and Z vary"),
                );
            }
            if let Some(sp) = q.inout {
                sink.push(
                    Diagnostic::error("E0504", format!("`inout` on parameter `{name}`"))
                        .primary(sp, "only Z may be inout"),
                );
            }
            if role == ParamRole::InterpData && item.kind == ast::ItemKind::Interpolator {
                sink.push(
                    Diagnostic::error("E0506", "interpolation data parameter in a shared interpolator")
                        .primary(p.span, "not available to interpolators")
                        .help("a shared interpolator sees only per-primitive parameters and X, Y, Z"),
                );
            }
        }
    }
}

/// The geometry type primitive `item` declares (`Surface` when none), checked against its
/// parameters: the runtime clips and splits a `facet`, `line` or `point` primitive's `point vertex[]`
/// and carries only interpolation data along, so those are its only per-sequence-point
/// parameters (E0509). An unknown name is E0508.
fn declared_geometry(item: &ast::Item, f: &ir::Function, sink: &mut Sink) -> ir::Geometry {
    let Some(name) = &item.geometry else {
        return ir::Geometry::Surface;
    };
    let Some(&(_, geometry)) = ir::Geometry::NAMES.iter().find(|(n, _)| *n == name.name) else {
        let mut d = Diagnostic::error("E0508", format!("unknown geometry type `{}`", name.name))
            .primary(name.span, "not a geometry type");
        d = match crate::diag::did_you_mean(&name.name, ir::Geometry::NAMES.iter().map(|(n, _)| *n)) {
            Some(hint) => d.help(hint),
            None => d.help("the geometry types are `facet`, `line` and `point`; a primitive may have none"),
        };
        sink.push(d);
        return ir::Geometry::Surface;
    };
    let kind = geometry.name();
    let vertex = f.params.iter().find(|p| p.name == "vertex");
    let vertex_ok = vertex.is_some_and(|p| {
        let ty = &f.local(p.local).ty;
        p.space == ParamSpace::Point && ty.per_seq && ty.dims.len() == 1
    });
    if !vertex_ok {
        let at = vertex.map_or(item.name.span, |p| p.span);
        sink.push(
            Diagnostic::error(
                "E0509",
                format!("a `{kind}` primitive takes its points in `point vertex[]`"),
            )
            .primary(
                at,
                if vertex.is_some() {
                    "not `point vertex[]`"
                } else {
                    "no `vertex` parameter"
                },
            )
            .help("the runtime clips and splits the points of `vertex[]`, one per sequence point"),
        );
        return geometry;
    }
    for p in &f.params {
        if p.name != "vertex" && f.local(p.local).ty.per_seq && p.role != ParamRole::InterpData {
            sink.push(
                Diagnostic::error(
                    "E0509",
                    format!("per-sequence-point parameter `{}` in a `{kind}` primitive", p.name),
                )
                .primary(p.span, "neither `vertex` nor interpolation data")
                .help("clipping makes new sequence points and carries only interpolation data to them"),
            );
        }
    }
    geometry
}

/// Report each cycle of helper calls once and mark its helpers as not inlinable.
fn find_recursion<'a>(mut g: Globals<'a>, sink: &mut Sink) -> Globals<'a> {
    let n = g.sigs.len();
    let mut edges: Vec<Vec<(usize, Span)>> = vec![vec![]; n];
    for (i, sig) in g.sigs.iter().enumerate() {
        if sig.item.kind != ast::ItemKind::Function {
            continue;
        }
        let mut calls = vec![];
        for s in &sig.item.body.stmts {
            stmt_calls(s, &mut calls);
        }
        for (name, span) in calls {
            if let Some(&j) = g.by_name.get(&name) {
                if g.sigs[j].item.kind == ast::ItemKind::Function {
                    edges[i].push((j, span));
                }
            }
        }
    }
    // Depth-first search; a back edge closes a cycle.
    let mut dfs = CycleSearch {
        g: &g,
        edges: &edges,
        state: vec![0u8; n],
        stack: vec![],
        recursive: FxHashSet::default(),
        reported: FxHashSet::default(),
    };
    for v in 0..n {
        if dfs.state[v] == 0 && g.sigs[v].item.kind == ast::ItemKind::Function {
            dfs.stack.push((v, g.sigs[v].item.name.span));
            dfs.visit(v, sink);
            dfs.stack.pop();
        }
    }
    let rec = dfs.recursive;
    g.recursive = rec;
    g
}

/// State of the depth-first search for helper call cycles.
struct CycleSearch<'g, 'a> {
    g: &'g Globals<'a>,
    /// Helper calls: callee and call span, per caller.
    edges: &'g [Vec<(usize, Span)>],
    /// 0 not visited, 1 on the stack, 2 done.
    state: Vec<u8>,
    /// The current call chain: each helper with the span of the call that reached it.
    stack: Vec<(usize, Span)>,
    recursive: FxHashSet<usize>,
    /// Cycles already reported, as sorted helper sets.
    reported: FxHashSet<Vec<usize>>,
}

impl CycleSearch<'_, '_> {
    /// Visit everything reachable from `v` (on top of `self.stack`), depth first. Iterative:
    /// a chain of helpers calling each other is as long as the file allows, and each one
    /// is a level of this search. `next[k]`: the edge of `self.stack[k]` to look at next.
    fn visit(&mut self, v: usize, sink: &mut Sink) {
        let base = self.stack.len() - 1;
        self.state[v] = 1;
        let mut next: Vec<usize> = vec![0];
        while let Some(&(u, _)) = self.stack.get(base + next.len() - 1) {
            let k = next.len() - 1;
            let Some(&(w, span)) = self.edges[u].get(next[k]) else {
                self.state[u] = 2;
                next.pop();
                if next.is_empty() {
                    break;
                }
                self.stack.pop();
                continue;
            };
            next[k] += 1;
            if self.state[w] == 1 {
                self.report(w, u, span, sink);
            } else if self.state[w] == 0 {
                self.state[w] = 1;
                self.stack.push((w, span));
                next.push(0);
            }
        }
    }

    /// The call at `span` from `v` back to `w` (on the stack) closes the cycle w -> ... -> v -> w.
    fn report(&mut self, w: usize, v: usize, span: Span, sink: &mut Sink) {
        let g = self.g;
        let start = self.stack.iter().position(|&(x, _)| x == w).unwrap_or(self.stack.len());
        let cycle: Vec<(usize, Span)> = self.stack[start..].to_vec();
        let mut key: Vec<usize> = cycle.iter().map(|c| c.0).chain([v]).collect();
        key.sort_unstable();
        key.dedup();
        self.recursive.extend(key.iter().copied());
        if cycle.is_empty() || !self.reported.insert(key) {
            return;
        }
        let names: Vec<&str> = cycle.iter().map(|c| g.sigs[c.0].item.name.name.as_str()).collect();
        let chain = format!("{} -> {}", names.join(" -> "), names[0]);
        let mut d = Diagnostic::error("E0107", format!("recursive helper calls: {chain}"))
            .primary(
                span,
                format!("`{}` calls `{}` here", g.sigs[v].item.name.name, names[0]),
            )
            .help("helpers are inlined at each call, so they cannot be recursive");
        // The other calls of the cycle: stack entry k was called from entry k-1.
        for k in start + 1..self.stack.len() {
            let (callee, sp) = self.stack[k];
            let caller = self.stack[k - 1].0;
            d = d.secondary(
                sp,
                format!(
                    "`{}` calls `{}` here",
                    g.sigs[caller].item.name.name, g.sigs[callee].item.name.name
                ),
            );
        }
        sink.push(d);
    }
}

fn stmt_calls(s: &ast::Stmt, out: &mut Vec<(String, Span)>) {
    use ast::StmtKind as K;
    let block = |b: &ast::Block, out: &mut Vec<(String, Span)>| b.stmts.iter().for_each(|s| stmt_calls(s, out));
    match &s.kind {
        K::Decl { vars, .. } => vars
            .iter()
            .filter_map(|v| v.init.as_ref())
            .for_each(|e| expr_calls(e, out)),
        K::Assign { target, value, .. } => {
            expr_calls(target, out);
            expr_calls(value, out);
        }
        K::Expr(e) => expr_calls(e, out),
        K::If { cond, then, otherwise } => {
            expr_calls(cond, out);
            block(then, out);
            if let Some(o) = otherwise {
                block(o, out);
            }
        }
        K::Illuminance { args, body } => {
            args.iter().for_each(|e| expr_calls(e, out));
            block(body, out);
        }
        K::For { init, cond, step, body } => {
            if let Some(i) = init {
                stmt_calls(i, out);
            }
            if let Some(c) = cond {
                expr_calls(c, out);
            }
            if let Some(st) = step {
                stmt_calls(st, out);
            }
            block(body, out);
        }
        K::While { cond, body } => {
            expr_calls(cond, out);
            block(body, out);
        }
        K::Return(Some(e)) | K::InterpolatorReturn(Some(e)) => expr_calls(e, out),
        K::Interpolation { arms } => arms.iter().flat_map(|a| &a.body).for_each(|s| stmt_calls(s, out)),
        K::Bound(args) => args.iter().for_each(|e| expr_calls(e, out)),
        K::Block(b) => block(b, out),
        K::Break | K::Continue | K::Return(None) | K::InterpolatorReturn(None) | K::Error => {}
    }
}

fn expr_calls(e: &ast::Expr, out: &mut Vec<(String, Span)>) {
    if let ast::ExprKind::Call { callee, .. } = &e.kind {
        out.push((callee.name.clone(), e.span));
    }
    e.for_each_child(|c| expr_calls(c, out));
}

/// Type-check a helper on its own (its parameters as temporaries) and check that a helper
/// with a value cannot fall off its end. The IR made here is thrown away: helpers only
/// exist inlined.
///
/// Lowering a helper's body reports the same diagnostics wherever it is inlined (its
/// parameters are typed by the signature, and what depends on the enclosing function is
/// decided by being in a helper), except when the inlining budget runs out. So when an
/// earlier inlining (`lowered_cleanly[idx]`) lowered the body within the budget and pushed
/// nothing the sink did not already hold, lowering it again here could only push
/// duplicates, which the sink drops: it is skipped.
fn check_helper(g: &Globals, idx: usize, sink: &mut Sink, sites: &mut Vec<Span>, lowered_cleanly: &mut [bool]) {
    let sig = &g.sigs[idx];
    if sig.ret.is_some() && !block_returns(&sig.item.body.stmts) {
        sink.push(
            Diagnostic::error(
                "E0405",
                format!(
                    "helper `{}` can reach its end without returning a value",
                    sig.item.name.name
                ),
            )
            .primary(sig.item.name.span, "declared with a return type")
            .secondary(
                Span {
                    start: sig.item.body.span.end.saturating_sub(1),
                    ..sig.item.body.span
                },
                "the end is reachable here",
            ),
        );
    }
    if g.recursive.contains(&idx) || lowered_cleanly[idx] {
        return;
    }
    let mut scratch_sites = std::mem::take(sites);
    let n_sites = scratch_sites.len();
    {
        let mut fl = FnLower::new(g, sink, &mut scratch_sites, FuncKind::Primitive);
        fl.report_budget = false;
        let mut params = vec![];
        for p in &sig.params {
            params.push(fl.new_local(
                &p.name,
                p.ty.clone(),
                LocalKind::Temp,
                p.span,
                LocalInfo {
                    declared: p.declared,
                    what: LocalWhat::Param,
                    read_only: false,
                },
            ));
        }
        let mut pre = vec![];
        fl.inline_body(idx, &params, sig.item.span, &mut pre);
        for &h in &fl.lowered_cleanly {
            lowered_cleanly[h] = true;
        }
    }
    // The standalone IR is discarded, so are its sites.
    scratch_sites.truncate(n_sites);
    *sites = scratch_sites;
}

fn block_returns(stmts: &[ast::Stmt]) -> bool {
    stmts.iter().any(stmt_returns)
}

fn stmt_returns(s: &ast::Stmt) -> bool {
    match &s.kind {
        ast::StmtKind::Return(_) => true,
        ast::StmtKind::If {
            then,
            otherwise: Some(o),
            ..
        } => block_returns(&then.stmts) && block_returns(&o.stmts),
        ast::StmtKind::Block(b) => block_returns(&b.stmts),
        // A statement that did not parse: assume it returned rather than pile on errors.
        ast::StmtKind::Error => true,
        _ => false,
    }
}

fn lower_function(
    g: &Globals,
    idx: usize,
    roles: &[Vec<ParamRole>],
    sink: &mut Sink,
    sites: &mut Vec<Span>,
    lowered_cleanly: &mut [bool],
) -> ir::Function {
    let sig = &g.sigs[idx];
    let kind = match sig.item.kind {
        ast::ItemKind::Interpolator => FuncKind::Interpolator,
        _ => FuncKind::Primitive,
    };
    let mut fl = FnLower::new(g, sink, sites, kind);
    let mut params = vec![];
    for (i, p) in sig.params.iter().enumerate() {
        let id = fl.new_local(
            &p.name,
            p.ty.clone(),
            LocalKind::Param(i as u32),
            p.span,
            LocalInfo {
                declared: p.declared,
                what: LocalWhat::Param,
                read_only: p.role != ParamRole::Z,
            },
        );
        fl.declare_param(&p.name, id);
        fl.set_xyz(p.role, id);
        params.push(ir::Param {
            local: id,
            name: p.name.clone(),
            role: p.role,
            space: p.space,
            default: p.default.clone(),
            span: p.span,
        });
    }
    let mut body = vec![];
    fl.stmts_in_scope(&sig.item.body.stmts, &mut body);
    if kind == FuncKind::Interpolator {
        match fl.interp_returns.first() {
            None => fl.sink.push(
                Diagnostic::error(
                    "E0413",
                    format!("interpolator `{}` never gives a value", sig.item.name.name),
                )
                .primary(sig.item.name.span, "no `interpolator_return(e)` in its body")
                .help("end it with `interpolator_return(value);`"),
            ),
            Some((first, first_span)) => {
                let (first, first_span) = (first.clone(), *first_span);
                let other = fl.interp_returns.iter().find(|(t, _)| *t != first).cloned();
                if let Some((t, sp)) = other {
                    fl.sink.push(
                        Diagnostic::error("E0413", "an interpolator's results must all have one type")
                            .primary(sp, format!("this is {}", types::type_name(&t)))
                            .secondary(first_span, format!("this is {}", types::type_name(&first))),
                    );
                }
            }
        }
    }
    for &h in &fl.lowered_cleanly {
        lowered_cleanly[h] = true;
    }
    let (locals, infos, n_loops, uses_spaces) = (fl.locals, fl.infos, fl.n_loops, fl.uses_spaces);
    let body = ir::tree::intern_body(body, vec![]);
    let mut f = ir::Function {
        name: sig.item.name.name.clone(),
        kind,
        geometry: ir::Geometry::Surface,
        span: sig.item.name.span,
        params,
        locals,
        setup: body.setup,
        pixel: body.pixel,
        loops: n_loops,
        stmts: body.stmts,
        exprs: body.exprs,
        uses_spaces,
    };
    f.geometry = declared_geometry(sig.item, &f, sink);
    let errors_before = sink.error_count();
    variability::analyze(&mut f, &infos, roles, sink);
    check_local_bytes(&f, sink);
    let variability_errors = sink.error_count() > errors_before;
    match kind {
        FuncKind::Primitive => {
            let mut d = Diagnostics::new();
            ir::split::split_checked(&mut f, &mut d);
            // A call or bound the variability pass already rejected would be reported twice.
            if !variability_errors {
                for x in d.items {
                    sink.push(x);
                }
            }
        }
        FuncKind::Interpolator => f.pixel = std::mem::take(&mut f.setup),
    }
    ir::number::renumber(&mut f);
    f
}

/// E0216 at the first local (in declaration order) whose bytes bring `f`'s total past
/// [`crate::limits::MAX_LOCAL_BYTES`]. Parameters live in the argument block, not the frame.
fn check_local_bytes(f: &ir::Function, sink: &mut Sink) {
    use crate::limits::MAX_LOCAL_BYTES;
    let mut total: u64 = 0;
    for l in &f.locals {
        if matches!(l.kind, LocalKind::Param(_)) {
            continue;
        }
        let per_comp = if l.var.is_varying() { 16 } else { 4 };
        total += u64::from(l.ty.fixed_len().max(1)) * per_comp;
        if total > MAX_LOCAL_BYTES {
            sink.push(
                Diagnostic::error(
                    "E0216",
                    format!("`{}`'s local variables take more than {} MiB", f.name, MAX_LOCAL_BYTES >> 20),
                )
                .primary(l.span, format!("`{}` brings them to {} bytes", l.name, total))
                .help("a varying component takes 16 bytes, a uniform one 4; local arrays live on the render thread's stack"),
            );
            return;
        }
    }
}
