//! A readable text dump of the syntax tree (`primflow check --emit ast`, snapshot tests).
//!
//! One node per line, children indented two spaces under their parent, each line ending in
//! `@line:col`, the 1-based position where the node starts in its file (a parameter's: its
//! name's, since the names of a group share its type). A node's line names
//! what it is and what it holds directly: item kind and name, a parameter's or declaration's
//! qualifiers and type as written, an operator's symbol, a literal's value, a name. A child
//! that fills a named slot of its parent (`cond`, `then`, `target`, `init`, ...) is prefixed
//! with the slot's name; children of the same kind (statements, arguments) are printed in
//! source order without one. Array sizes that are integer literals print in place
//! (`float m[4][4]`); any other size prints as `[_]` with a `dim:` child.
//!
//! Every `ast` node kind has a line here, so a tree the parser built always prints; the tree
//! is within [`crate::limits`]' depth limits after parsing, which bounds the recursion. The
//! output is deterministic (it can be kept as a golden file).

use std::fmt::Write;

use super::ast::*;
use crate::diag::{SourceMap, Span};

/// The tree of `module` (parsed from a file of `sources`) as indented text.
pub fn module_tree(module: &Module, sources: &SourceMap) -> String {
    let mut p = Printer {
        sources,
        out: String::new(),
        depth: 0,
    };
    for item in &module.items {
        p.item(item);
    }
    p.out
}

struct Printer<'s> {
    sources: &'s SourceMap,
    out: String,
    depth: usize,
}

impl Printer<'_> {
    /// One line: indentation, `slot: ` if any, `text`, the position of `span`.
    fn line(&mut self, slot: &str, text: &str, span: Span) {
        let (l, c) = self.sources.line_col(span.file, span.start);
        let slot = if slot.is_empty() {
            String::new()
        } else {
            format!("{slot}: ")
        };
        writeln!(self.out, "{:indent$}{slot}{text} @{l}:{c}", "", indent = 2 * self.depth)
            .expect("writing to a String");
    }

    /// Print the lines `f` prints one level deeper.
    fn nested(&mut self, f: impl FnOnce(&mut Self)) {
        self.depth += 1;
        f(self);
        self.depth -= 1;
    }

    fn item(&mut self, item: &Item) {
        let kind = match item.kind {
            ItemKind::Primitive => "primitive",
            ItemKind::Interpolator => "interpolator",
            ItemKind::Function => "function",
            ItemKind::Surface => "surface",
            ItemKind::Light => "light",
            ItemKind::Atmosphere => "atmosphere",
        };
        let mut text = kind.to_string();
        if item.kind == ItemKind::Function {
            let ret = item.ret.as_ref().map_or("void".to_string(), |t| type_text(&t.kind));
            text = format!("{text} {ret}");
        }
        if let Some(g) = &item.geometry {
            text = format!("{text} {}", g.name);
        }
        self.line("", &format!("{text} {}", item.name.name), item.span);
        self.nested(|p| {
            for param in &item.params {
                p.param(param);
            }
            p.block("body", &item.body);
        });
    }

    fn param(&mut self, param: &Param) {
        let text = format!(
            "param {}{} {}",
            quals_text(&param.quals),
            type_text(&param.ty.kind),
            declared(&param.name, &param.dims)
        );
        // At its name: the names of one group share the group's type, where its span starts.
        self.line("", &text, param.name.span);
        self.nested(|p| {
            p.dims(&param.dims);
            if let Some(d) = &param.default {
                p.expr("default", d);
            }
        });
    }

    /// `dim:` children for the sizes [`declared`] printed as `[_]`.
    fn dims(&mut self, dims: &[ArrayDim]) {
        for dim in dims {
            if let ArrayDim::Sized(e) = dim {
                if !matches!(e.kind, ExprKind::Int(_)) {
                    self.expr("dim", e);
                }
            }
        }
    }

    /// A block as one node (`slot: block`) with its statements under it.
    fn block(&mut self, slot: &str, block: &Block) {
        self.line(slot, "block", block.span);
        self.nested(|p| block.stmts.iter().for_each(|s| p.stmt("", s)));
    }

    fn stmt(&mut self, slot: &str, stmt: &Stmt) {
        let span = stmt.span;
        match &stmt.kind {
            StmtKind::Decl { quals, ty, vars } => {
                self.line(
                    slot,
                    &format!("decl {}{}", quals_text(quals), type_text(&ty.kind)),
                    span,
                );
                self.nested(|p| {
                    for var in vars {
                        p.line("", &format!("var {}", declared(&var.name, &var.dims)), var.span);
                        p.nested(|p| {
                            p.dims(&var.dims);
                            if let Some(init) = &var.init {
                                p.expr("init", init);
                            }
                        });
                    }
                });
            }
            StmtKind::Assign { target, op, value } => {
                let op = match op {
                    AssignOp::Set => "=",
                    AssignOp::Add => "+=",
                    AssignOp::Sub => "-=",
                    AssignOp::Mul => "*=",
                    AssignOp::Div => "/=",
                };
                self.line(slot, &format!("assign {op}"), span);
                self.nested(|p| {
                    p.expr("target", target);
                    p.expr("value", value);
                });
            }
            StmtKind::Expr(e) => {
                self.line(slot, "expr", span);
                self.nested(|p| p.expr("", e));
            }
            StmtKind::If { cond, then, otherwise } => {
                self.line(slot, "if", span);
                self.nested(|p| {
                    p.expr("cond", cond);
                    p.block("then", then);
                    if let Some(o) = otherwise {
                        p.block("else", o);
                    }
                });
            }
            StmtKind::For { init, cond, step, body } => {
                self.line(slot, "for", span);
                self.nested(|p| {
                    if let Some(s) = init {
                        p.stmt("init", s);
                    }
                    if let Some(e) = cond {
                        p.expr("cond", e);
                    }
                    if let Some(s) = step {
                        p.stmt("step", s);
                    }
                    p.block("body", body);
                });
            }
            StmtKind::While { cond, body } => {
                self.line(slot, "while", span);
                self.nested(|p| {
                    p.expr("cond", cond);
                    p.block("body", body);
                });
            }
            StmtKind::Break => self.line(slot, "break", span),
            StmtKind::Continue => self.line(slot, "continue", span),
            StmtKind::Return(e) => {
                self.line(slot, "return", span);
                self.nested(|p| e.iter().for_each(|e| p.expr("", e)));
            }
            StmtKind::Interpolation { arms } => {
                self.line(slot, "interpolation", span);
                self.nested(|p| {
                    for arm in arms {
                        let kind = match &arm.kind {
                            InterpArmKind::Named(name) => name.name.as_str(),
                            InterpArmKind::Default(_) => "default",
                        };
                        p.line("", &format!("arm {kind}"), arm.span);
                        p.nested(|p| arm.body.iter().for_each(|s| p.stmt("", s)));
                    }
                });
            }
            StmtKind::InterpolatorReturn(e) => {
                self.line(slot, "interpolator_return", span);
                self.nested(|p| e.iter().for_each(|e| p.expr("", e)));
            }
            StmtKind::Bound(args) => {
                self.line(slot, "bound", span);
                self.nested(|p| args.iter().for_each(|e| p.expr("", e)));
            }
            StmtKind::Illuminance { args, body } => {
                self.line(slot, "illuminance", span);
                self.nested(|p| {
                    args.iter().for_each(|e| p.expr("", e));
                    p.block("body", body);
                });
            }
            StmtKind::Block(b) => self.block(slot, b),
            StmtKind::Error => self.line(slot, "error (did not parse)", span),
        }
    }

    fn expr(&mut self, slot: &str, e: &Expr) {
        let text = match &e.kind {
            ExprKind::Int(v) => format!("int {v}"),
            ExprKind::Float(v) => format!("float {v:?}"),
            ExprKind::Bool(v) => format!("bool {v}"),
            ExprKind::Str(s) => format!("string {s:?}"),
            ExprKind::Name(id) => format!("name {}", id.name),
            ExprKind::Unary { op, .. } => format!("unary {}", op.symbol()),
            ExprKind::Binary { op, .. } => format!("binary {}", op.symbol()),
            ExprKind::Ternary { .. } => "ternary ?:".to_string(),
            ExprKind::Call { callee, .. } => format!("call {}", callee.name),
            ExprKind::Construct { ty, .. } => format!("construct {}", type_text(&ty.kind)),
            ExprKind::Index { .. } => "index".to_string(),
            ExprKind::Field { field, .. } => format!("field .{}", field.name),
            ExprKind::List(items) => format!("list of {}", items.len()),
            ExprKind::Error => "error (did not parse)".to_string(),
        };
        self.line(slot, &text, e.span);
        self.nested(|p| e.for_each_child(|c| p.expr("", c)));
    }
}

/// `uniform `, `inout varying `, or nothing: the qualifiers written, each with its space.
fn quals_text(q: &Qualifiers) -> String {
    let mut s = String::new();
    if q.inout.is_some() {
        s.push_str("inout ");
    }
    match q.variability {
        Some((Variability::Uniform, _)) => s.push_str("uniform "),
        Some((Variability::Varying, _)) => s.push_str("varying "),
        None => {}
    }
    s
}

/// A type as the source writes it (the alias `interpolator_data` prints as `interpolation_data`).
fn type_text(t: &TypeKind) -> String {
    match t {
        TypeKind::Float => "float".into(),
        TypeKind::Int => "int".into(),
        TypeKind::Bool => "bool".into(),
        TypeKind::Fixed { bits, frac } => format!("fixed<{bits},{frac}>"),
        TypeKind::Point => "point".into(),
        TypeKind::Vector => "vector".into(),
        TypeKind::Normal => "normal".into(),
        TypeKind::Color => "color".into(),
        TypeKind::Matrix => "matrix".into(),
        TypeKind::InterpolationData => "interpolation_data".into(),
        TypeKind::String => "string".into(),
        TypeKind::Void => "void".into(),
    }
}

/// `name[3][]`: the array sizes that are integer literals, `[]` for unsized, `[_]` for others.
fn declared(name: &Ident, dims: &[ArrayDim]) -> String {
    let mut s = name.name.clone();
    for dim in dims {
        match dim {
            ArrayDim::Sized(Expr {
                kind: ExprKind::Int(n), ..
            }) => write!(s, "[{n}]").expect("writing to a String"),
            ArrayDim::Sized(_) => s.push_str("[_]"),
            ArrayDim::Unsized(_) => s.push_str("[]"),
        }
    }
    s
}
