//! Every file in tests/check/ok/ (and the shipped prims/) checks without errors; the IR of
//! the seed 004 figures is kept as a snapshot.

use std::path::{Path, PathBuf};

use primflow::diag::{Diagnostics, SourceMap};
use primflow::ir;

fn prim_files(dir: &Path) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.expect("dir entry").path())
        .filter(|p| p.extension().is_some_and(|x| x == "prim"))
        .collect();
    files.sort();
    files
}

/// Compile files as one program; panics with the rendered diagnostics on any error.
fn compile(paths: &[PathBuf]) -> (ir::Program, Diagnostics, SourceMap) {
    let mut sources = SourceMap::new();
    let ids: Vec<_> = paths.iter().map(|p| sources.load(p).expect("readable")).collect();
    let mut diags = Diagnostics::new();
    let program = primflow::compile(&sources, &ids, &mut diags);
    match program {
        Some(p) => (p, diags, sources),
        None => panic!("{:?} failed to check:\n{}", paths, diags.render(&sources)),
    }
}

fn ok_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/check/ok")
}

#[test]
fn every_ok_file_checks_without_errors() {
    let files = prim_files(&ok_dir());
    assert!(files.len() >= 5, "expected the ok corpus, found {files:?}");
    for f in files {
        let (program, _, _) = compile(std::slice::from_ref(&f));
        assert!(!program.functions.is_empty(), "{}: no functions", f.display());
    }
}

#[test]
fn shipped_prims_check_as_one_program() {
    let files = prim_files(&Path::new(env!("CARGO_MANIFEST_DIR")).join("prims"));
    let (program, diags, _) = compile(&files);
    assert_eq!(diags.error_count(), 0);
    let tri = program.func(program.find("screen_triangle").expect("screen_triangle"));
    assert!(!tri.setup.is_empty() && !tri.pixel.is_empty());
}

#[test]
fn seed004_figures_ir_snapshot() {
    let (program, _, _) = compile(&[ok_dir().join("seed004_figures.prim")]);
    insta::assert_snapshot!("seed004_figures_ir", program.to_string());
}

/// The ```prim blocks of docs/language.md: each must check without errors (```prim,error
/// blocks are counter-examples and must not).
#[test]
fn language_reference_examples_check() {
    let doc = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/language.md"))
        .expect("docs/language.md");
    let mut blocks = vec![];
    let mut current: Option<(bool, String)> = None;
    for line in doc.lines() {
        match (&mut current, line.trim_start()) {
            (None, l) if l.starts_with("```prim") => current = Some((l.contains("error"), String::new())),
            (Some(_), "```") => blocks.push(current.take().expect("open block")),
            (Some((_, text)), _) => {
                text.push_str(line);
                text.push('\n');
            }
            (None, _) => {}
        }
    }
    assert!(
        blocks.len() >= 8,
        "expected the reference's examples, found {}",
        blocks.len()
    );
    for (i, (is_error, text)) in blocks.iter().enumerate() {
        let mut sources = SourceMap::new();
        let id = sources.add(format!("language.md block {i}"), text.clone());
        let mut diags = Diagnostics::new();
        let program = primflow::compile(&sources, &[id], &mut diags);
        if *is_error {
            assert!(program.is_none(), "block {i} should not check:\n{text}");
        } else {
            assert!(program.is_some(), "block {i} fails:\n{}", diags.render(&sources));
        }
    }
}
