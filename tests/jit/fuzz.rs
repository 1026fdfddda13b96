//! Mutated built-in primitives that still check never make the JIT or the renderer panic
//! (nor the JIT report a panic it caught as an internal compiler error):
//! a library primitive with some of its number literals replaced (by 0, -1, array-edge
//! values, 65536, 3.4e38, 1e-30, ...) or comparison and arithmetic operators swapped
//! compiles at both tiers and renders every example scene (small), or reports errors. Such
//! mutants reach what hand-written tests rarely do: huge and negative array sizes and
//! indices, loops that never end or never run, NaN and infinite coordinates; the first one
//! run (`float fa[65535]` in screen_triangle) panicked Cranelift's SSA builder
//! (`tests/jit/large_locals.rs` keeps that case).

use crate::support;

use std::sync::Arc;

use primflow::diag::{Diagnostics, SourceMap};
use primflow::jit::{Jit, Tier};
use primflow::runtime::Renderer;
use proptest::prelude::*;

const INTS: &[&str] = &[
    "0",
    "1",
    "-1",
    "2",
    "3",
    "4",
    "15",
    "16",
    "17",
    "127",
    "128",
    "129",
    "1279",
    "1280",
    "65536",
    "2147483647",
];
const FLOATS: &[&str] = &["0.0", "-0.0", "1e-30", "1e30", "3.4e38", "-1.0", "0.5", "1.0e-45"];
const SWAPS: &[(&str, &str)] = &[
    ("+", "-"),
    ("-", "+"),
    ("*", "/"),
    ("/", "*"),
    ("<", "<="),
    ("<=", "<"),
    (">", ">="),
    (">=", ">"),
    ("&&", "||"),
    ("||", "&&"),
    ("==", "!="),
];

/// What a mutable token is.
#[derive(Clone, Copy, PartialEq)]
enum Kind {
    Int,
    Float,
    Operator,
}

/// The number literals and operators of `src` outside `//` comments: (start, end, kind).
fn tokens(src: &str) -> Vec<(usize, usize, Kind)> {
    let b = src.as_bytes();
    let ident = |c: u8| c.is_ascii_alphanumeric() || c == b'_';
    let mut out = vec![];
    let mut i = 0;
    while i < b.len() {
        if b[i..].starts_with(b"//") {
            while i < b.len() && b[i] != b'\n' {
                i += 1;
            }
        } else if b[i].is_ascii_digit() && (i == 0 || !ident(b[i - 1])) {
            let start = i;
            while i < b.len() && (b[i].is_ascii_digit() || b[i] == b'.' || b[i] == b'e') {
                i += 1;
            }
            let float = src[start..i].contains(['.', 'e']);
            out.push((start, i, if float { Kind::Float } else { Kind::Int }));
        } else if let Some((op, _)) = SWAPS
            .iter()
            .filter(|(op, _)| b[i..].starts_with(op.as_bytes()))
            .max_by_key(|(op, _)| op.len())
        {
            // Not part of a longer operator (`+=`, `->`, `<<`).
            let end = i + op.len();
            let next = b.get(end).copied().unwrap_or(b' ');
            if !b"=<>&|".contains(&next) {
                out.push((i, end, Kind::Operator));
            }
            i = end;
        } else {
            i += 1;
        }
    }
    out
}

/// `src` with the tokens picked by `edits` (token index, replacement index) replaced.
fn mutate(src: &str, edits: &[(usize, usize)]) -> String {
    let toks = tokens(src);
    let mut picked: Vec<(usize, usize, String)> = edits
        .iter()
        .map(|&(t, r)| {
            let (start, end, kind) = toks[t % toks.len()];
            let new = match kind {
                Kind::Int => INTS[r % INTS.len()].to_string(),
                Kind::Float => FLOATS[r % FLOATS.len()].to_string(),
                Kind::Operator => {
                    let old = &src[start..end];
                    SWAPS
                        .iter()
                        .find(|(a, _)| *a == old)
                        .map_or(old, |(_, b)| b)
                        .to_string()
                }
            };
            (start, end, new)
        })
        .collect();
    picked.sort_by_key(|p| std::cmp::Reverse(p.0));
    picked.dedup_by_key(|p| p.0);
    let mut out = src.to_string();
    for (start, end, new) in picked {
        out.replace_range(start..end, &new);
    }
    out
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]
    #[test]
    fn mutated_library_primitives_compile_and_render_or_report_errors(
        prim in 0usize..64,
        edits in prop::collection::vec((0usize..100_000, 0usize..1000), 1..4),
    ) {
        let prims = support::read_dir("prims", "prim");
        let scenes = support::read_dir("examples", "scene");
        let which = prim % prims.len();
        let mut sources = SourceMap::new();
        let files: Vec<_> = prims
            .iter()
            .enumerate()
            .map(|(i, (name, text))| {
                let text = if i == which { mutate(text, &edits) } else { text.clone() };
                sources.add(name.clone(), text)
            })
            .collect();
        let mut diags = Diagnostics::new();
        let Some(program) = primflow::compile(&sources, &files, &mut diags) else {
            prop_assert!(diags.has_errors());
            return Ok(());
        };
        let program = Arc::new(program);
        for (name, text) in &scenes {
            let mut sources = sources.clone();
            let file = sources.add(name.clone(), text.clone());
            let mut r = Renderer::new(program.clone());
            let mut diags = Diagnostics::new();
            primflow::scene::load_into(&sources, file, &mut r, &mut diags);
            if diags.has_errors() {
                continue;
            }
            r.set_image_size(40, 30).expect("image size");
            for tier in [Tier::Fast, Tier::Optimised] {
                let mut jit = Jit::at_tier(program.clone(), tier).expect("host ISA");
                let out = r.render(&mut jit);
                // Whatever it drew, every diagnostic renders (spans inside their files), and
                // none is a panic caught in the JIT (`Jit::compile_batch_caught`).
                let _ = out.diags.render(&sources);
                for d in &out.diags.items {
                    prop_assert!(!d.message.contains("internal compiler error"), "{} {tier:?}: {}", name, d.message);
                }
            }
        }
    }
}

#[test]
fn the_mutator_finds_and_replaces_literals_and_operators() {
    let src = "float a[3] = {1.5, 2, x - 1}; // 7 + 8\nif (a <= b && c) d += 4;";
    let kinds: Vec<(&str, bool)> = tokens(src)
        .iter()
        .map(|&(s, e, k)| (&src[s..e], k == Kind::Operator))
        .collect();
    assert_eq!(
        kinds,
        [
            ("3", false),
            ("1.5", false),
            ("2", false),
            ("-", true),
            ("1", false),
            ("<=", true),
            ("&&", true),
            ("4", false)
        ]
    );
    // Token 0 (`3`) to INTS[14] (`65536`), token 3 (`-`) swapped.
    assert_eq!(
        mutate(src, &[(0, 14), (3, 0)]),
        "float a[65536] = {1.5, 2, x + 1}; // 7 + 8\nif (a <= b && c) d += 4;"
    );
}
