//! One small broken file per diagnostic code in tests/check/errors/. Each file's first line
//! says what it must produce (`// expect: E0301@4:9 E0302@7:5`, `code@line:col` of the
//! primary span); the test compares that with the checker's diagnostics, then keeps every
//! rendered diagnostic as an insta snapshot.

use std::path::{Path, PathBuf};

use primflow::diag::{Diagnostics, SourceMap};

fn error_files() -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/check/errors");
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .expect("tests/check/errors")
        .map(|e| e.expect("dir entry").path())
        .filter(|p| p.extension().is_some_and(|x| x == "prim"))
        .collect();
    files.sort();
    files
}

fn expected(text: &str) -> Vec<String> {
    let first = text.lines().next().unwrap_or_default();
    let list = first
        .strip_prefix("// expect:")
        .unwrap_or_else(|| panic!("first line must be `// expect: ...`, found {first:?}"));
    list.split_whitespace().map(str::to_string).collect()
}

fn check_file(path: &Path) -> (Diagnostics, SourceMap) {
    let mut sources = SourceMap::new();
    let text = std::fs::read_to_string(path).expect("readable");
    let name = path.file_name().expect("file name").to_string_lossy().to_string();
    let id = sources.add(name, text);
    let mut diags = Diagnostics::new();
    primflow::compile(&sources, &[id], &mut diags);
    (diags, sources)
}

#[test]
fn every_error_file_reports_exactly_its_expected_codes() {
    let files = error_files();
    let mut failures = vec![];
    for f in &files {
        let (diags, sources) = check_file(f);
        let text = std::fs::read_to_string(f).expect("readable");
        let want = expected(&text);
        let got = diags.codes_at(&sources);
        if got != want {
            failures.push(format!(
                "{}: expected {want:?}, got {got:?}\n{}",
                f.display(),
                diags.render(&sources)
            ));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n\n"));
}

#[test]
fn every_code_has_a_file_and_is_documented() {
    let files = error_files();
    let docs = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/language.md"))
        .expect("docs/language.md");
    for f in &files {
        let stem = f.file_stem().expect("stem").to_string_lossy().to_string();
        let code = stem.split('_').next().expect("code prefix");
        let text = std::fs::read_to_string(f).expect("readable");
        assert!(
            expected(&text).iter().any(|e| e.starts_with(code)),
            "{stem}: the file is named for {code} but does not expect it"
        );
        assert!(
            docs.contains(&format!("`{code}`")),
            "{code} is not listed in docs/language.md"
        );
    }
    assert!(files.len() >= 45, "one file per code: found {}", files.len());
}

#[test]
fn rendered_diagnostics_snapshot() {
    let mut all = String::new();
    for f in error_files() {
        let (diags, sources) = check_file(&f);
        all.push_str(&format!("==== {}\n", f.file_name().expect("name").to_string_lossy()));
        all.push_str(&diags.render(&sources));
        all.push('\n');
    }
    insta::assert_snapshot!("check_errors_rendered", all);
}
