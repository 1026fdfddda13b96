//! Parser tests: every construct parses to the expected AST shape, the paper's figures and the
//! library parse, and broken files report the expected codes at the expected places.

use primflow::diag::{Diagnostics, SourceMap};
use primflow::syntax::{self, ast::*};

fn parse(text: &str) -> (Module, Diagnostics, SourceMap) {
    let mut sources = SourceMap::new();
    let f = sources.add("test.prim", text);
    let mut diags = Diagnostics::new();
    let m = syntax::parse(f, sources.text(f), &mut diags);
    (m, diags, sources)
}

#[test]
fn every_construct_parses() {
    let text = std::fs::read_to_string("tests/parse/constructs.prim").unwrap();
    let (m, diags, sources) = parse(&text);
    assert!(!diags.has_errors(), "{}", diags.render(&sources));
    let kinds: Vec<_> = m.items.iter().map(|i| (i.kind, i.name.name.as_str())).collect();
    assert_eq!(
        kinds,
        vec![
            (ItemKind::Function, "lerp"),
            (ItemKind::Function, "nothing"),
            (ItemKind::Interpolator, "cylindrical_interpolation"),
            (ItemKind::Primitive, "everything"),
        ]
    );
    // RenderMan groups flatten: `float a, b; float t` is three params sharing types.
    let lerp = &m.items[0];
    assert_eq!(
        lerp.params.iter().map(|p| p.name.name.as_str()).collect::<Vec<_>>(),
        ["a", "b", "t"]
    );
    assert_eq!(lerp.ret.as_ref().map(|t| t.kind.clone()), Some(TypeKind::Float));
    assert!(m.items[1].ret.is_none());

    // Figure 10's parameter list, with its missing `;` between the first two groups.
    let interp = &m.items[2];
    let names: Vec<_> = interp
        .params
        .iter()
        .map(|p| (p.name.name.as_str(), p.ty.kind.clone()))
        .collect();
    assert_eq!(
        names,
        vec![
            ("cylinder_transform", TypeKind::Float),
            ("cylinder_start", TypeKind::Float),
            ("cylinder_end", TypeKind::Float),
            ("X", TypeKind::Fixed { bits: 32, frac: 4 }),
            ("Y", TypeKind::Fixed { bits: 32, frac: 4 }),
            ("Z", TypeKind::Fixed { bits: 32, frac: 32 }),
        ]
    );
    assert_eq!(interp.params[0].dims.len(), 2);
    assert!(matches!(&interp.params[0].default, Some(Expr { kind: ExprKind::List(rows), .. }) if rows.len() == 4));

    let prim = &m.items[3];
    let p = |n: &str| prim.params.iter().find(|p| p.name.name == n).unwrap();
    assert!(matches!(p("vertex").dims[..], [ArrayDim::Unsized(_)]));
    assert_eq!(p("vertex").ty.kind, TypeKind::Point);
    assert_eq!(p("interp_data").ty.kind, TypeKind::InterpolationData);
    assert_eq!(p("s").quals.variability.map(|v| v.0), Some(Variability::Uniform));
    assert!(matches!(
        p("s").default,
        Some(Expr {
            kind: ExprKind::Unary { op: UnaryOp::Neg, .. },
            ..
        })
    ));
    assert!(matches!(p("t").default, Some(Expr { kind: ExprKind::Float(x), .. }) if x == 0.5));
    assert_eq!(p("X").quals.variability.map(|v| v.0), Some(Variability::Varying));
    assert!(p("Z").quals.inout.is_some());
    assert!(p("Y").quals.inout.is_none());

    // Statement kinds in order.
    let kinds: Vec<&str> = prim
        .body
        .stmts
        .iter()
        .map(|s| match &s.kind {
            StmtKind::Decl { .. } => "decl",
            StmtKind::Assign { .. } => "assign",
            StmtKind::Expr(_) => "call",
            StmtKind::If { .. } => "if",
            StmtKind::For { .. } => "for",
            StmtKind::While { .. } => "while",
            StmtKind::Break => "break",
            StmtKind::Continue => "continue",
            StmtKind::Return(_) => "return",
            StmtKind::Interpolation { .. } => "interpolation",
            StmtKind::InterpolatorReturn(_) => "interpolator_return",
            StmtKind::Bound(_) => "bound",
            StmtKind::Illuminance { .. } => "illuminance",
            StmtKind::Block(_) => "block",
            StmtKind::Error => "error",
        })
        .collect();
    assert_eq!(
        kinds,
        [
            "decl",
            "decl",
            "decl",
            "bound",
            "for",
            "while",
            "for",
            "if",
            "if",
            "assign",
            "assign",
            "assign",
            "assign",
            "assign",
            "call",
            "decl",
            "interpolation",
            "block"
        ]
    );
    // The dangling else binds to the inner if.
    let StmtKind::If { then, otherwise, .. } = &prim.body.stmts[8].kind else {
        panic!()
    };
    assert!(otherwise.is_none());
    assert!(matches!(&then.stmts[0].kind, StmtKind::If { otherwise: Some(_), .. }));
    // `j--` is `j -= 1`.
    assert!(matches!(
        &prim.body.stmts[13].kind,
        StmtKind::Assign {
            op: AssignOp::Sub,
            value: Expr {
                kind: ExprKind::Int(1),
                ..
            },
            ..
        }
    ));
    let StmtKind::Interpolation { arms } = &prim.body.stmts[16].kind else {
        panic!()
    };
    let arm_names: Vec<String> = arms
        .iter()
        .map(|a| match &a.kind {
            InterpArmKind::Named(n) => n.name.clone(),
            InterpArmKind::Default(_) => "default".into(),
        })
        .collect();
    assert_eq!(arm_names, ["perspective_linear", "linear", "default"]);
    assert!(matches!(arms[2].body[0].kind, StmtKind::InterpolatorReturn(None)));
}

#[test]
fn precedence_and_spans() {
    let mut sources = SourceMap::new();
    let text = "a + b * c[1] < -d ? e : f || g && !h";
    let f = sources.add("e", text);
    let mut diags = Diagnostics::new();
    let e = syntax::parse_expr(f, text, &mut diags).unwrap();
    let ExprKind::Ternary { cond, then, otherwise } = &e.kind else {
        panic!("{e:?}")
    };
    let ExprKind::Binary { op: BinOp::Lt, lhs, .. } = &cond.kind else {
        panic!()
    };
    let ExprKind::Binary {
        op: BinOp::Add, rhs, ..
    } = &lhs.kind
    else {
        panic!()
    };
    assert!(matches!(&rhs.kind, ExprKind::Binary { op: BinOp::Mul, .. }));
    assert_eq!(&text[rhs.span.start as usize..rhs.span.end as usize], "b * c[1]");
    assert!(matches!(then.kind, ExprKind::Name(_)));
    let ExprKind::Binary { op: BinOp::Or, rhs, .. } = &otherwise.kind else {
        panic!()
    };
    assert!(matches!(&rhs.kind, ExprKind::Binary { op: BinOp::And, .. }));
    assert_eq!((e.span.start, e.span.end), (0, text.len() as u32));
}

/// Every .prim file shipped with the project parses without errors.
#[test]
fn library_and_test_inputs_parse() {
    let mut count = 0;
    for dir in ["prims", "tests/parse", "tests/check/ok"] {
        let Ok(entries) = std::fs::read_dir(dir) else { continue };
        for entry in entries {
            let path = entry.unwrap().path();
            if path.extension().is_some_and(|e| e == "prim") {
                let text = std::fs::read_to_string(&path).unwrap();
                let (_, diags, sources) = parse(&text);
                assert!(!diags.has_errors(), "{}: {}", path.display(), diags.render(&sources));
                count += 1;
            }
        }
    }
    assert!(count >= 8, "found only {count} files");
}

/// Broken files: several errors per file (recovery), each code at its line:col.
#[test]
fn syntax_errors_recover_and_point_at_the_right_place() {
    let cases: &[(&str, &[&str])] = &[
        // Missing `;` after a statement (reported where it is missing, at the end of line
        // 2), then a bad token: both reported.
        (
            "primitive p() {\n  float a = 1\n  a = 2;\n  b = ) ;\n}\n",
            &["E0011@2:14", "E0011@4:7"],
        ),
        // On the same line the unexpected token is the place.
        ("primitive p() {\n  float a = 1 a = 2;\n}\n", &["E0011@2:15"]),
        // A comment between the statement and the next line's token: still the end of `1`.
        (
            "primitive p() {\n  float a = 1 // one\n  /* two */ a = 2;\n}\n",
            &["E0011@2:14"],
        ),
        // Lexical garbage is reported and skipped; parsing goes on.
        (
            "primitive p() {\n  float a = 1 @ 2;\n  a = 3 $;\n}\n",
            &["E0001@2:15", "E0001@3:9", "E0011@2:17"],
        ),
        // Unterminated item.
        ("primitive p() {\n  float a = 1;\n", &["E0012@2:15"]),
        // Lexical garbage where the parse runs out of input: still reported.
        (
            "primitive p() {\n  float a = 1;\n @ $",
            &["E0001@3:2", "E0001@3:4", "E0012@2:15"],
        ),
        // Statement before the first interpolation label.
        (
            "primitive p() {\n  interpolation {\n    a = 1;\n    linear: interpolator_return(1);\n  }\n}\n",
            &["E0010@3:5"],
        ),
        // An error in one item does not hide the next item's error.
        (
            "primitive p() { a = ; }\nprimitive q() { b = = 1; }\n",
            &["E0011@1:21", "E0011@2:21"],
        ),
        // Huge integer literal.
        ("primitive p() { int a = 99999999999999999999999; }\n", &["E0002@1:25"]),
        ("primitive p() { /* never closed\n }\n", &["E0003@1:17", "E0012@1:16"]),
    ];
    for (text, expected) in cases {
        let (_, diags, sources) = parse(text);
        let mut got = diags.codes_at(&sources);
        got.sort();
        let mut want: Vec<String> = expected.iter().map(|s| s.to_string()).collect();
        want.sort();
        assert_eq!(got, want, "for:\n{text}\n{}", diags.render(&sources));
    }
}

#[test]
fn rendered_diagnostic_has_location_and_underline() {
    let (_, diags, sources) = parse("primitive p() {\n  float a = 1;\n  b = ) ;\n}\n");
    let out = diags.render(&sources);
    assert!(out.contains("E0011"), "{out}");
    assert!(out.contains("test.prim:3:7"), "{out}");
    assert!(out.contains("expected"), "{out}");
    assert!(out.contains("──"), "no underline in {out}");
}

/// A statement whose `;` is missing, the next one on the following line: the error is at
/// the end of the statement, with the next line's token as the unexpected one and a help.
#[test]
fn missing_semicolon_points_at_the_end_of_the_line_before() {
    let text = "primitive p(varying float X, Y) {\n    color a = color(1, 2, 3)\n    float b = 2;\n}\n";
    let (_, diags, sources) = parse(text);
    assert_eq!(diags.codes_at(&sources), ["E0011@2:29"]);
    let d = &diags.items[0];
    assert_eq!(d.message, "expected `;`, found `float`");
    assert_eq!(
        d.help.as_deref(),
        Some("a statement must end with `;`: add one at the end of the line")
    );
    assert_eq!(
        diags.render(&sources).lines().take(10).collect::<Vec<_>>(),
        [
            "E0011",
            "",
            "  × expected `;`, found `float` (test.prim:2:29)",
            "   ╭─[test.prim:2:29]",
            " 1 │ primitive p(varying float X, Y) {",
            " 2 │     color a = color(1, 2, 3)",
            "   ·                             ▲",
            "   ·                             ╰── expected `;` here",
            " 3 │     float b = 2;",
            "   ·     ──┬──",
        ]
    );
}

/// `(1, 2, 3)` is not a value: the error is at the first `,` and says how to write a list.
#[test]
fn a_parenthesised_list_gets_a_help() {
    let (_, diags, sources) = parse("primitive p() {\n    float a = (1, 2, 3)\n    float b = 2;\n}\n");
    assert_eq!(diags.codes_at(&sources), ["E0011@2:17"]);
    assert_eq!(
        diags.items[0].help.as_deref(),
        Some("parentheses hold one expression; several values are a list `{1, 2, 3}` or a constructor such as `color(1, 2, 3)`")
    );
}

mod fuzz {
    use super::*;
    use proptest::prelude::*;

    fn mutate(text: &str, edits: &[(usize, u8, u8)]) -> String {
        let mut bytes = text.as_bytes().to_vec();
        for &(at, kind, byte) in edits {
            if bytes.is_empty() {
                break;
            }
            let at = at % bytes.len();
            match kind % 3 {
                0 => {
                    bytes.remove(at);
                }
                1 => {
                    let table = b"{}()[];,=<>+-*/!?:\"x1. \n#@";
                    bytes.insert(at, table[byte as usize % table.len()])
                }
                _ => bytes[at] = byte,
            }
        }
        String::from_utf8_lossy(&bytes).into_owned()
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(300))]
        /// Mutated sources never panic the lexer or parser, and every diagnostic has a span
        /// inside the file.
        #[test]
        fn mutated_sources_never_panic(edits in proptest::collection::vec((0usize..100_000, 0u8..3, any::<u8>()), 1..12)) {
            let base = std::fs::read_to_string("prims/screen_triangle.prim").unwrap();
            let text = mutate(&base, &edits);
            let (_, diags, sources) = parse(&text);
            for d in &diags.items {
                if let Some(s) = d.primary_span() {
                    prop_assert!(s.end as usize <= text.len());
                }
            }
            let _ = diags.render(&sources);
        }
    }
}

#[test]
fn shader_items_and_illuminance_parse_and_their_keywords_stay_names_elsewhere() {
    let src = "surface s(float k = 1) { illuminance(P, N, 1.5) { Ci += k * Cl; } }
light l() { L = Ps; Cl = 1; }
atmosphere a() { Ci = Ci; }
primitive p(float light, surface; varying float X, Y; inout varying float Z) { float atmosphere = light + surface; }";
    let mut diags = primflow::diag::Diagnostics::new();
    let m = primflow::syntax::parse(0, src, &mut diags);
    assert!(!diags.has_errors(), "{diags:?}");
    let kinds: Vec<ItemKind> = m.items.iter().map(|i| i.kind).collect();
    assert_eq!(
        kinds,
        [
            ItemKind::Surface,
            ItemKind::Light,
            ItemKind::Atmosphere,
            ItemKind::Primitive
        ]
    );
    match &m.items[0].body.stmts[0].kind {
        StmtKind::Illuminance { args, body } => {
            assert_eq!(args.len(), 3);
            assert_eq!(body.stmts.len(), 1);
        }
        other => panic!("expected illuminance, found {other:?}"),
    }
}
