//! Small constructors the grammar's actions use, kept out of the .lalrpop file so they are
//! ordinary, type-checked, testable Rust.

use crate::diag::{Diagnostic, FileId, Span};
use crate::syntax::ast::*;

pub fn stmt(file: FileId, l: usize, r: usize, kind: StmtKind) -> Stmt {
    Stmt {
        kind,
        span: Span::new(file, l, r),
    }
}

pub fn expr(file: FileId, l: usize, r: usize, kind: ExprKind) -> Expr {
    Expr {
        kind,
        span: Span::new(file, l, r),
    }
}

pub fn binary(file: FileId, l: usize, r: usize, op: BinOp, lhs: Expr, rhs: Expr) -> Expr {
    expr(
        file,
        l,
        r,
        ExprKind::Binary {
            op,
            lhs: Box::new(lhs),
            rhs: Box::new(rhs),
        },
    )
}

pub fn int_lit(file: FileId, l: usize, r: usize, value: i64) -> Expr {
    expr(file, l, r, ExprKind::Int(value))
}

/// The body of an `if`/`while`/`for`: a block as written, or a single statement wrapped.
pub fn as_block(mut s: Stmt) -> Block {
    match &mut s.kind {
        StmtKind::Block(b) => std::mem::replace(
            b,
            Block {
                stmts: vec![],
                span: b.span,
            },
        ),
        _ => {
            let span = s.span;
            Block { stmts: vec![s], span }
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum QualWord {
    Uniform,
    Varying,
    Inout,
}

/// Qualifier words in any order; a later `uniform`/`varying` overrides an earlier one (the
/// checker sees only the result; contradictory pairs are rare enough not to warrant a code).
pub fn qualifiers(words: Vec<(QualWord, Span)>) -> Qualifiers {
    let mut q = Qualifiers::default();
    for (w, span) in words {
        match w {
            QualWord::Uniform => q.variability = Some((Variability::Uniform, span)),
            QualWord::Varying => q.variability = Some((Variability::Varying, span)),
            QualWord::Inout => q.inout = Some(span),
        }
    }
    q
}

/// One name of a parameter list; `head` is set where a new group (qualifiers + type) starts.
pub struct ParamEntry {
    pub head: Option<(Qualifiers, TypeExpr)>,
    pub decl: DeclVar,
}

/// Give every name its group's qualifiers and type.
pub fn flatten_params(entries: Vec<ParamEntry>) -> Vec<Param> {
    let mut out = Vec::with_capacity(entries.len());
    let mut current: Option<(Qualifiers, TypeExpr)> = None;
    for e in entries {
        if e.head.is_some() {
            current = e.head;
        }
        // The grammar starts every list with a group head, so `current` is always set.
        let Some((quals, ty)) = current.clone() else { continue };
        let span = ty.span.to(e.decl.span);
        out.push(Param {
            quals,
            ty,
            name: e.decl.name,
            dims: e.decl.dims,
            default: e.decl.init.map(|init| *init),
            span,
        });
    }
    out
}

pub enum InterpItem {
    Label(InterpArmKind, Span),
    Stmt(Stmt),
}

/// Group the flat labels and statements of an `interpolation { ... }` into arms.
/// Statements before the first label are reported (E0010) and dropped.
pub fn group_arms(_file: FileId, items: Vec<InterpItem>, extra: &mut Vec<Diagnostic>) -> Vec<InterpArm> {
    let mut arms: Vec<InterpArm> = Vec::new();
    for item in items {
        match item {
            InterpItem::Label(kind, span) => arms.push(InterpArm {
                kind,
                body: vec![],
                span,
            }),
            InterpItem::Stmt(s) => match arms.last_mut() {
                Some(arm) => {
                    arm.span = arm.span.to(s.span);
                    arm.body.push(s);
                }
                None => extra.push(
                    Diagnostic::error("E0010", "statement before the first interpolation kind label")
                        .primary(s.span, "this statement belongs to no interpolation kind")
                        .help("start the arm with a kind label such as `linear:` or `default:`"),
                ),
            },
        }
    }
    arms
}

/// An item introduced by a name (`surface`, `light`, `atmosphere`); any other name there
/// is E0016 and the item is dropped.
pub fn shader_item(
    kw: Ident,
    name: Ident,
    params: Vec<Param>,
    body: Block,
    span: Span,
    extra: &mut Vec<Diagnostic>,
) -> Option<Item> {
    let kind = match kw.name.as_str() {
        "surface" => ItemKind::Surface,
        "light" => ItemKind::Light,
        "atmosphere" => ItemKind::Atmosphere,
        other => {
            extra.push(
                Diagnostic::error("E0016", format!("`{other}` does not start an item")).primary(
                    kw.span,
                    "expected a type, `primitive`, `interpolator`, `surface`, `light` or `atmosphere`",
                ),
            );
            return None;
        }
    };
    Some(Item {
        kind,
        ret: None,
        geometry: None,
        name,
        params,
        body: Box::new(body),
        span,
    })
}
