//! Component access: `p.x`, `c.g`, and swizzles of several letters (`p.xyz`, `c.bgr`, `v.xx`).
//!
//! The letters `x y z w` name components 0 to 3 and `r g b` components 0 to 2 (colours have
//! three). Access applies to a 1-D array of at most 4 elements (point, vector, normal, colour,
//! `float[2]`...); it is desugared here, so no later stage knows it exists:
//! - one letter is a constant index, `p.x` = `p[0]`, an expression and an assignment target;
//! - several letters are a list of constant indices, `c.bgr` = `{c[2], c[1], c[0]}`, an
//!   expression only (E0403 as a target).
//!
//! Invariants: the indices are constants inside the array, so they never fail at run time (a
//! per-sequence-point array, whose length is known only at run time, has no components); a
//! swizzle of several letters repeats its base once per letter, as the list it stands for
//! would (a base with a non-constant index checks that index once per letter).
//! Errors, each with the span of the offending letter where there is one: E0217 a letter
//! that names no component, E0218 access on a value without components, E0219 a component
//! past the value's length, E0220 letters of both sets or more than four.

use crate::diag::{Diagnostic, Span};
use crate::ir::tree::{Tree, TreeKind};
use crate::ir::{ConstValue, Elem, Place, Scalar, SiteId, Stmt, Type};
use crate::syntax::ast;

use super::super::types::{self, type_name};
use super::{err, mk, FnLower};

/// The most letters a swizzle may have.
const MAX_LETTERS: usize = 4;

/// The component a letter names and whether it is a colour letter.
fn letter(c: char) -> Option<(u32, bool)> {
    match c {
        'x' => Some((0, false)),
        'y' => Some((1, false)),
        'z' => Some((2, false)),
        'w' => Some((3, false)),
        'r' => Some((0, true)),
        'g' => Some((1, true)),
        'b' => Some((2, true)),
        _ => None,
    }
}

/// The span of the `i`-th letter of `field` (identifiers are ASCII).
fn letter_span(field: &ast::Ident, i: usize) -> Span {
    let start = field.span.start as usize + i;
    Span::new(field.span.file, start, start + 1)
}

/// The component indices `field` names on a value of type `base`, or the error.
fn components(field: &ast::Ident, base: &Type) -> Result<Vec<u32>, Diagnostic> {
    let name = &field.name;
    if name.len() > MAX_LETTERS {
        return Err(err(
            "E0220",
            format!(
                "`.{name}` names {} components; a swizzle has at most {MAX_LETTERS}",
                name.len()
            ),
            field.span,
            "too many letters",
        ));
    }
    let mut out = vec![];
    let mut set = None;
    for (i, c) in name.chars().enumerate() {
        let Some((k, colour)) = letter(c) else {
            return Err(err(
                "E0217",
                format!("`{c}` is not a component name"),
                letter_span(field, i),
                "not a component",
            )
            .help("components are `x`, `y`, `z`, `w` or `r`, `g`, `b`"));
        };
        if *set.get_or_insert(colour) != colour {
            return Err(err(
                "E0220",
                format!("`.{name}` mixes `xyzw` and `rgb` letters"),
                letter_span(field, i),
                "from the other set",
            ));
        }
        out.push(k);
    }
    let len = match (&base.elem, base.dims.as_slice()) {
        (Elem::Scalar(_), &[n]) if !base.per_seq && n as usize <= MAX_LETTERS => n,
        _ => {
            return Err(err(
                "E0218",
                format!("a {} has no components", type_name(base)),
                field.span,
                format!("`.{name}` on a {}", type_name(base)),
            )
            .help("components belong to 1-D arrays of at most 4 elements: points, vectors, normals, colours"))
        }
    };
    for (i, &k) in out.iter().enumerate() {
        if k >= len {
            let c = &name[i..i + 1];
            return Err(err(
                "E0219",
                format!("component `{c}` is out of range for a {}", type_name(base)),
                letter_span(field, i),
                format!("a {} has {len} components", type_name(base)),
            ));
        }
    }
    Ok(out)
}

impl<'g, 'a> FnLower<'g, 'a> {
    /// `base.field` as a value.
    pub(super) fn field(
        &mut self,
        base: &ast::Expr,
        field: &ast::Ident,
        span: Span,
        pre: &mut Vec<Stmt<Tree>>,
    ) -> Option<Tree> {
        let b = self.expr(base, pre)?;
        let comps = self.components_or_report(field, &b.ty)?;
        let site = self.new_site(field.span);
        let elem_ty = b.ty.element();
        if let [k] = comps[..] {
            return Some(component(b, k, site, elem_ty, span));
        }
        let items: Vec<Tree> = comps
            .iter()
            .map(|&k| component(b.clone(), k, site, elem_ty.clone(), span))
            .collect();
        let ty = Type::array(b.ty.elem, vec![items.len() as u32]);
        Some(mk(TreeKind::List(items), ty, span))
    }

    /// `base.field` as an assignment target: one component of a place.
    pub(super) fn field_place(
        &mut self,
        e: &ast::Expr,
        base: &ast::Expr,
        field: &ast::Ident,
        pre: &mut Vec<Stmt<Tree>>,
    ) -> Option<(Place<Tree>, Type)> {
        let (mut place, ty) = self.place(base, pre)?;
        let comps = self.components_or_report(field, &ty)?;
        let [k] = comps[..] else {
            self.sink.push(
                err(
                    "E0403",
                    format!("cannot assign to `.{}`, a swizzle of several components", field.name),
                    field.span,
                    "several components",
                )
                .help("assign the components one by one"),
            );
            return None;
        };
        let site = self.new_site(field.span);
        let index = types::const_expr(ConstValue::Int(k as i32), Scalar::Int, field.span);
        place.indices.push((index, site));
        place.span = e.span;
        Some((place, ty.element()))
    }

    fn components_or_report(&mut self, field: &ast::Ident, base: &Type) -> Option<Vec<u32>> {
        match components(field, base) {
            Ok(c) => Some(c),
            Err(d) => {
                self.sink.push(d);
                None
            }
        }
    }
}

/// `base[k]` with a constant `k`.
fn component(base: Tree, k: u32, site: SiteId, ty: Type, span: Span) -> Tree {
    let index = types::const_expr(ConstValue::Int(k as i32), Scalar::Int, span);
    mk(
        TreeKind::Index {
            base: Box::new(base),
            index: Box::new(index),
            site,
        },
        ty,
        span,
    )
}
