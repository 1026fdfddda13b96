//! Malformed programs never make the checker panic: the ok corpus with random edits (token
//! swaps, deletions, insertions) either checks or gives at least one error diagnostic.

use std::path::Path;

use primflow::diag::{Diagnostics, SourceMap};
use proptest::prelude::*;

fn corpus() -> Vec<String> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/check/ok");
    let mut files: Vec<_> = std::fs::read_dir(dir)
        .expect("ok corpus")
        .map(|e| e.expect("entry").path())
        .filter(|p| p.extension().is_some_and(|x| x == "prim"))
        .collect();
    files.sort();
    files
        .iter()
        .map(|p| std::fs::read_to_string(p).expect("readable"))
        .collect()
}

fn edit(text: &str, edits: &[(usize, usize, usize)]) -> String {
    primflow::fuzz::mutate::splice(text, primflow::fuzz::mutate::PRIM_TOKENS, edits)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 160, ..ProptestConfig::default() })]
    #[test]
    fn edited_programs_check_or_report_errors(
        file in 0usize..64,
        edits in prop::collection::vec((0usize..20_000, 0usize..24, 0usize..1000), 1..5),
    ) {
        let corpus = corpus();
        let text = edit(&corpus[file % corpus.len()], &edits);
        let mut sources = SourceMap::new();
        let id = sources.add("fuzz.prim", text);
        let mut diags = Diagnostics::new();
        let program = primflow::compile(&sources, &[id], &mut diags);
        prop_assert_eq!(program.is_none(), diags.has_errors());
        // Rendering every diagnostic must work too (spans inside the file).
        let rendered = diags.render(&sources);
        prop_assert_eq!(rendered.is_empty(), diags.items.is_empty());
        // The checker also copes with what the parser recovered (`Error` nodes included).
        let mut parse_diags = Diagnostics::new();
        let module = primflow::syntax::parse(id, sources.text(id), &mut parse_diags);
        let mut check_diags = Diagnostics::new();
        let _ = primflow::check::check(&[&module], &mut check_diags);
        let _ = check_diags.render(&sources);
        // Whatever the checker accepts obeys the IR validator's rules (`ir::valid`).
        let ice = diags.items.iter().chain(&check_diags.items).find(|d| d.code == "E0900");
        prop_assert!(ice.is_none(), "{:?}", ice);
    }
}
