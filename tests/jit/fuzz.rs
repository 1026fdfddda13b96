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
use primflow::fuzz::mutate::{literals as mutate, tokens, Kind};
use primflow::jit::{Jit, Tier};
use primflow::runtime::Renderer;
use proptest::prelude::*;

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
