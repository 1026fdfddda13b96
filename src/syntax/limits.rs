//! The depth limits of the AST ([`crate::limits`]), checked right after parsing and before
//! anything walks the tree recursively.
//!
//! [`enforce`] visits a module with an explicit work stack (so its own depth costs heap, not
//! stack), reports the first statement deeper than [`MAX_BLOCK_DEPTH`] (E0015) and the
//! first sub-expression deeper than [`MAX_EXPR_DEPTH`] (E0014) of each tree, and replaces
//! that node with an `Error` node, so every later pass sees a tree within the limits (an
//! `Error` node is skipped without further diagnostics). The nodes cut off are freed by the
//! iterative `Drop` of [`Expr`] and [`Stmt`] (`syntax::ast`), not recursively.
//!
//! After this point every expression is at most [`MAX_EXPR_DEPTH`] deep and every statement
//! at most [`MAX_BLOCK_DEPTH`] deep in its item.

use crate::diag::{Diagnostic, Diagnostics, FileId, Span};
use crate::limits::{MAX_BLOCK_DEPTH, MAX_EXPR_DEPTH, MAX_SOURCE_BYTES};
use crate::syntax::ast::*;

/// E0002 for a source longer than [`MAX_SOURCE_BYTES`]: located at the first byte past the
/// limit. `None` when the file fits.
pub fn source_too_large(file: FileId, text: &str) -> Option<Diagnostic> {
    if text.len() <= MAX_SOURCE_BYTES {
        return None;
    }
    let mut at = MAX_SOURCE_BYTES;
    while !text.is_char_boundary(at) {
        at -= 1;
    }
    Some(
        Diagnostic::error("E0002", format!("source file too large: {} bytes", text.len()))
            .primary(
                Span::new(file, at, at),
                format!("the limit is {MAX_SOURCE_BYTES} bytes; this is the first byte past it"),
            )
            .help("split the primitives over several files"),
    )
}

enum Work<'a> {
    /// A statement and its nesting depth in its item (1: directly in the item's body).
    Stmt(&'a mut Stmt, u32),
    /// An expression and its depth in its statement (1: a statement's own expression).
    Expr(&'a mut Expr, u32),
}

/// Check `module` against the AST depth limits, cutting over-deep subtrees off (see the
/// module comment). Diagnostics go to `diags`.
pub fn enforce(module: &mut Module, diags: &mut Diagnostics) {
    let mut work: Vec<Work> = Vec::new();
    for item in &mut module.items {
        for p in &mut item.params {
            push_dims(&mut p.dims, &mut work);
            if let Some(d) = &mut p.default {
                work.push(Work::Expr(d, 1));
            }
        }
        for s in &mut item.body.stmts {
            work.push(Work::Stmt(s, 1));
        }
        // One item at a time, in source order (the stack pops the last pushed first).
        work.reverse();
        walk(&mut work, diags);
    }
}

/// [`enforce`] for a lone expression (`syntax::parse_expr`).
pub fn enforce_expr(e: &mut Expr, diags: &mut Diagnostics) {
    walk(&mut vec![Work::Expr(e, 1)], diags);
}

fn push_dims<'a>(dims: &'a mut [ArrayDim], work: &mut Vec<Work<'a>>) {
    for d in dims {
        if let ArrayDim::Sized(e) = d {
            work.push(Work::Expr(e, 1));
        }
    }
}

/// Pops the work in source order (children are pushed last first). The sub-expressions of
/// one statement's expression come off the stack after it and before the next such
/// expression, so `reported` (reset at each) keeps to one E0014 per expression.
fn walk(work: &mut Vec<Work>, diags: &mut Diagnostics) {
    let mut reported = false;
    while let Some(w) = work.pop() {
        let pushed = work.len();
        match w {
            Work::Stmt(s, depth) if depth > MAX_BLOCK_DEPTH => {
                diags.push(
                    Diagnostic::error("E0015", "statements nested too deeply")
                        .primary(
                            s.span,
                            format!("this statement is nested {depth} deep; the limit is {MAX_BLOCK_DEPTH}"),
                        )
                        .help("move the inner part into a helper function"),
                );
                // Dropped iteratively (`Stmt`'s `Drop`).
                s.kind = StmtKind::Error;
            }
            Work::Stmt(s, depth) => push_stmt(s, depth, work),
            Work::Expr(e, depth) if depth > MAX_EXPR_DEPTH => {
                if std::mem::replace(&mut reported, true) {
                    e.kind = ExprKind::Error;
                    continue;
                }
                diags.push(
                    Diagnostic::error("E0014", "expression nested too deeply")
                        .primary(
                            e.span,
                            format!("this part is nested {depth} deep; the limit is {MAX_EXPR_DEPTH}"),
                        )
                        .help(
                            "a sum or product of many terms nests one level per term: split it over several variables",
                        ),
                );
                e.kind = ExprKind::Error;
            }
            Work::Expr(e, depth) => {
                reported &= depth > 1;
                e.for_each_child_mut(|c| work.push(Work::Expr(c, depth + 1)))
            }
        }
        work[pushed..].reverse();
    }
}

/// Push a statement's expressions (depth 1) and nested statements (`depth + 1`).
fn push_stmt<'a>(s: &'a mut Stmt, depth: u32, work: &mut Vec<Work<'a>>) {
    let inner = depth + 1;
    let block = |b: &'a mut Block, work: &mut Vec<Work<'a>>| {
        for s in &mut b.stmts {
            work.push(Work::Stmt(s, inner));
        }
    };
    match &mut s.kind {
        StmtKind::Decl { vars, .. } => {
            for v in vars {
                push_dims(&mut v.dims, work);
                if let Some(e) = &mut v.init {
                    work.push(Work::Expr(e, 1));
                }
            }
        }
        StmtKind::Assign { target, value, .. } => {
            work.push(Work::Expr(target, 1));
            work.push(Work::Expr(value, 1));
        }
        StmtKind::Expr(e) | StmtKind::Return(Some(e)) | StmtKind::InterpolatorReturn(Some(e)) => {
            work.push(Work::Expr(e, 1))
        }
        StmtKind::If { cond, then, otherwise } => {
            work.push(Work::Expr(cond, 1));
            block(then, work);
            if let Some(o) = otherwise {
                block(o, work);
            }
        }
        StmtKind::For { init, cond, step, body } => {
            if let Some(i) = init {
                work.push(Work::Stmt(i, inner));
            }
            if let Some(c) = cond {
                work.push(Work::Expr(c, 1));
            }
            if let Some(st) = step {
                work.push(Work::Stmt(st, inner));
            }
            block(body, work);
        }
        StmtKind::While { cond, body } => {
            work.push(Work::Expr(cond, 1));
            block(body, work);
        }
        StmtKind::Interpolation { arms } => {
            for arm in arms {
                for s in &mut arm.body {
                    work.push(Work::Stmt(s, inner));
                }
            }
        }
        StmtKind::Bound(args) => {
            for e in args {
                work.push(Work::Expr(e, 1));
            }
        }
        StmtKind::Illuminance { args, body } => {
            for e in args {
                work.push(Work::Expr(e, 1));
            }
            block(body, work);
        }
        StmtKind::Block(b) => block(b, work),
        StmtKind::Break
        | StmtKind::Continue
        | StmtKind::Return(None)
        | StmtKind::InterpolatorReturn(None)
        | StmtKind::Error => {}
    }
}
