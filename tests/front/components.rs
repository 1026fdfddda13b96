//! Component access as the front end sees it: `.` lexes as its own token only where it is
//! not part of a number, `p.x` parses as a field of `p`, and swizzles have the types their
//! letters give (a wrong one shows as a conversion error).

use primflow::diag::{Diagnostics, SourceMap};
use primflow::syntax::ast::{Expr, ExprKind};
use primflow::syntax::lexer::{lex, Tok};
use primflow::syntax::parse_expr;

fn tokens(text: &str) -> Vec<Tok> {
    let mut sources = SourceMap::new();
    let f = sources.add("t.prim", text);
    let mut diags = Diagnostics::new();
    let out: Vec<Tok> = lex(f, text, &mut diags).map(|(_, t, _)| t).collect();
    assert!(!diags.has_errors(), "{text}: {}", diags.render(&sources));
    out
}

#[test]
fn numbers_keep_their_dots_and_fields_get_one() {
    use Tok::*;
    assert_eq!(
        tokens("1.5 .5 1. 1.e2 2.5f"),
        [
            FloatLit(1.5),
            FloatLit(0.5),
            FloatLit(1.0),
            FloatLit(100.0),
            FloatLit(2.5)
        ]
    );
    assert_eq!(tokens("p.x"), [Ident("p".into()), Dot, Ident("x".into())]);
    assert_eq!(
        tokens("a[0].yz+.5"),
        [
            Ident("a".into()),
            LBracket,
            IntLit(0),
            RBracket,
            Dot,
            Ident("yz".into()),
            Plus,
            FloatLit(0.5)
        ]
    );
}

fn expr(text: &str) -> Expr {
    let mut sources = SourceMap::new();
    let f = sources.add("t.prim", text);
    let mut diags = Diagnostics::new();
    let e = parse_expr(f, text, &mut diags);
    e.unwrap_or_else(|| panic!("{text}: {}", diags.render(&sources)))
}

#[test]
fn fields_bind_like_indexing() {
    // `-p.x * 2` is `(-(p.x)) * 2`; `f(v).y` and `a[i].x.y` are fields of the postfix
    // expression before them.
    let e = expr("-p.x * 2");
    let ExprKind::Binary { lhs, .. } = &e.kind else {
        panic!("a product")
    };
    let ExprKind::Unary { expr: inner, .. } = &lhs.kind else {
        panic!("a negation")
    };
    let ExprKind::Field { base, field } = &inner.kind else {
        panic!("a field")
    };
    assert_eq!(field.name, "x");
    assert!(matches!(&base.kind, ExprKind::Name(n) if n.name == "p"));
    assert!(
        matches!(expr("f(v).y").kind, ExprKind::Field { ref base, .. } if matches!(base.kind, ExprKind::Call { .. }))
    );
    let e = expr("a[i].x.y");
    let ExprKind::Field { base, field } = &e.kind else {
        panic!("a field")
    };
    assert_eq!(field.name, "y");
    assert!(matches!(&base.kind, ExprKind::Field { base, .. } if matches!(base.kind, ExprKind::Index { .. })));
}

/// The codes `body`, inside a primitive that draws (a bound and a depth write on line 2, so
/// no W0003 or W0004), reports.
fn codes(body: &str) -> Vec<String> {
    let text = format!(
        "primitive p(point q; color c; vector v; varying float X, Y; inout varying float Z)\n{{ bound(0, 0, 1, 1); Z = 0.5;\n{body}\n}}\n"
    );
    let mut sources = SourceMap::new();
    let f = sources.add("t.prim", text);
    let mut diags = Diagnostics::new();
    primflow::compile(&sources, &[f], &mut diags);
    diags
        .codes_at(&sources)
        .into_iter()
        .map(|c| c[..5].to_string())
        .collect()
}

#[test]
fn swizzles_have_the_types_of_their_letters() {
    let ok = [
        "float a = q.x + q.w + c.r + c.b + v.z;",
        "float a[3] = q.xyz;",
        "vector a = c.bgr;",
        "float a[4] = v.xxyy;",
        "float a[2] = q.wx;",
        "point a = q; a.y = X; a.w *= 2; a.x++;",
        "color a = c; a.g += 0.5;",
        "float a = normalize(v).y + cross(v, v).z + (q + q).w;",
        "float a = transform(\"object\", \"world\", q).x;",
        "float a[3] = {1, 2, 3}; a.z = a.y;",
    ];
    for body in ok {
        assert_eq!(codes(body), Vec::<String>::new(), "{body}");
    }
    let wrong = [
        ("float a[2] = q.xyz;", "E0205"),
        ("float a = q.xy;", "E0205"),
        ("float a = q.x.y;", "E0218"),
        ("float a = X.x;", "E0218"),
        ("float a = q.xyzw1;", "E0220"),
        ("float a = q.x1;", "E0217"),
        ("float a = c.a;", "E0217"),
        ("q.x = 1;", "E0402"),
        ("point a = q; a.xy = 1;", "E0403"),
    ];
    for (body, code) in wrong {
        assert_eq!(codes(body), [code], "{body}");
    }
}
