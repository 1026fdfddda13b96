//! `syntax::print::module_tree` (`primflow check --emit ast`): a small file's tree as an insta
//! snapshot, every node kind of the grammar printed from the construct file, the library and
//! a small file of the rest, and `Error` nodes where a statement did not parse.

use std::collections::BTreeSet;

use primflow::diag::{Diagnostics, SourceMap};
use primflow::syntax;

use crate::support;

/// The tree of `text` and its syntax diagnostics.
fn tree(name: &str, text: &str) -> (String, Diagnostics) {
    let mut sources = SourceMap::new();
    let file = sources.add(name, text);
    let mut diags = Diagnostics::new();
    let module = syntax::parse(file, sources.text(file), &mut diags);
    (syntax::print::module_tree(&module, &sources), diags)
}

/// What the library and tests/parse/constructs.prim leave out: a shader with `illuminance`,
/// an array size that is not a literal.
const SMALL: &str = r#"float scale(float v; uniform int n) { return v * n; }

surface tint(color base = color(1, 0.5, 0)) {
    Ci = base;
    illuminance(P) { Ci += Cl * 0.5; }
}

primitive dot(float center[2]; varying float X, Y; inout varying fixed<32,32> Z)
{
    float w[2 + 1] = {1, 2, 3};
    while (w[0] < 2) { w[0] += 1; }
    if (abs(X - center[0]) > scale(1.0, 2)) return;
    Z = fixed<32,32>(0.5);
}
"#;

#[test]
fn small_file_tree() {
    let (text, diags) = tree("small.prim", SMALL);
    assert!(diags.items.is_empty(), "{diags:?}");
    insta::assert_snapshot!("ast_tree_small", text);
}

/// The node kind of a line: its first word after the indentation and a `slot: ` prefix.
fn kind(line: &str) -> &str {
    let line = line.trim_start();
    let line = match line.split_once(": ") {
        Some((slot, rest)) if !slot.contains(' ') => rest,
        _ => line,
    };
    line.split_whitespace().next().unwrap_or("")
}

#[test]
fn every_node_kind_prints_with_its_position() {
    let mut files = support::read_dir("prims", "prim");
    files.push((
        "tests/parse/constructs.prim".into(),
        std::fs::read_to_string("tests/parse/constructs.prim").unwrap(),
    ));
    files.push(("small.prim".into(), SMALL.into()));
    let mut kinds = BTreeSet::new();
    let mut texts = vec![];
    for (name, text) in &files {
        let (printed, diags) = tree(name, text);
        assert!(!diags.has_errors(), "{name}: {diags:?}");
        for line in printed.lines() {
            let (_, at) = line
                .rsplit_once(" @")
                .unwrap_or_else(|| panic!("{name}: no position on {line:?}"));
            let (l, c) = at.split_once(':').unwrap_or_else(|| panic!("{name}: {line:?}"));
            assert!(
                l.parse::<usize>().is_ok() && c.parse::<usize>().is_ok(),
                "{name}: {line:?}"
            );
            kinds.insert(kind(line).to_string());
        }
        texts.push(printed);
    }
    let all = [
        "primitive",
        "interpolator",
        "function",
        "surface",
        "light",
        "atmosphere",
        "param",
        "block",
        "decl",
        "var",
        "assign",
        "expr",
        "if",
        "for",
        "while",
        "break",
        "continue",
        "return",
        "interpolation",
        "arm",
        "interpolator_return",
        "bound",
        "illuminance",
        "int",
        "float",
        "bool",
        "string",
        "name",
        "unary",
        "binary",
        "ternary",
        "call",
        "construct",
        "index",
        "field",
        "list",
    ];
    let missing: Vec<_> = all.iter().filter(|k| !kinds.contains(**k)).collect();
    assert!(missing.is_empty(), "never printed: {missing:?}");
    let unknown: Vec<_> = kinds.iter().filter(|k| !all.contains(&k.as_str())).collect();
    assert!(unknown.is_empty(), "not in the list: {unknown:?}");

    // A few lines of the library and the construct file, exactly.
    let library = texts.join("");
    for line in [
        "primitive screen_triangle @21:1",
        "  param float screen_vertex[3][4] @22:11",
        "  param inout varying fixed<32,32> Z @25:32",
        "primitive facet polygon @12:1",
        "  param point vertex[] @12:31",
    ] {
        assert!(library.lines().any(|l| l == line), "no line {line:?}");
    }
    let constructs = &texts[texts.len() - 2];
    for line in [
        "function float lerp @2:1",
        "  param float b @2:21",
        "  param uniform float t @19:83",
        "    default: float 0.5 @19:87",
        "          else: block @29:47",
        "    assign -= @38:21",
        "      target: name j @38:21",
    ] {
        assert!(
            constructs.lines().any(|l| l == line),
            "no line {line:?} in\n{constructs}"
        );
    }
}

#[test]
fn statements_that_did_not_parse_print_as_error_nodes() {
    let (text, diags) = tree(
        "broken.prim",
        "primitive p(varying float X, Y) {\n    float a = ;\n    a = 1;\n}\n",
    );
    assert!(diags.has_errors());
    assert_eq!(
        text,
        "primitive p @1:1\n  param varying float X @1:27\n  param varying float Y @1:30\n  body: block @1:33\n    error (did not parse) @2:5\n    assign = @3:5\n      target: name a @3:5\n      value: int 1 @3:9\n"
    );
}
