//! Diagnostics at the edges of their input: a column past 65,535 (miette's renderer
//! panicked there), lines of any length (shown cut to a window around the label), a file
//! with thousands of errors (the first [`MAX_ERRORS`] kept, then `E0099`), and the line
//! index every location comes from.

use primflow::diag::{Diagnostic, Diagnostics, SourceMap, Span, LONG_LINE, MAX_ERRORS};

fn check_text(name: &str, text: &str) -> (Diagnostics, SourceMap) {
    let mut sources = SourceMap::new();
    let id = sources.add(name, text);
    let mut diags = Diagnostics::new();
    primflow::compile(&sources, &[id], &mut diags);
    (diags, sources)
}

/// Run the command line in-process: (exit code, stderr).
fn cli(args: &[&str]) -> (i32, String) {
    let (mut out, mut err) = (vec![], vec![]);
    let mut argv = vec!["primflow"];
    argv.extend_from_slice(args);
    let code = primflow::cli::run(argv, &mut out, &mut err);
    (code, String::from_utf8(err).unwrap())
}

fn temp_file(name: &str, text: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("primflow-diag-limits-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

fn longest_line(s: &str) -> usize {
    s.lines().map(|l| l.chars().count()).max().unwrap_or(0)
}

#[test]
fn an_error_past_column_65535_is_rendered_with_its_location() {
    let text = format!("{}@\n", " ".repeat(65536));
    let (diags, sources) = check_text("d.prim", &text);
    assert_eq!(diags.codes_at(&sources), vec!["E0001@1:65537"]);
    let out = diags.render(&sources);
    assert!(out.contains("(d.prim:1:65537)"), "{out}");
    assert!(out.contains("[d.prim:1:65537]"), "header names line and column:\n{out}");
    assert!(out.contains("not part of the language"), "{out}");
    // The line is shown cut: the label's window, not 65,536 spaces.
    assert!(out.contains('…'), "{out}");
    assert!(longest_line(&out) < 2 * LONG_LINE, "{out}");
    // The underline sits under the `@`.
    let lines: Vec<&str> = out.lines().collect();
    let src = lines.iter().position(|l| l.contains("│ …")).expect("source line");
    let at = lines[src].chars().position(|c| c == '@').unwrap();
    assert_eq!(lines[src + 1].chars().nth(at), Some('┬'), "{out}");
}

#[test]
fn check_of_a_file_with_a_huge_column_exits_1_instead_of_panicking() {
    let path = temp_file("d.prim", &format!("{}@\n", " ".repeat(70000)));
    let (code, err) = cli(&["check", path.to_str().unwrap()]);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("d.prim:1:70001"), "{err}");
    assert!(err.contains("error: 1 error(s); nothing compiled"), "{err}");
}

#[test]
fn a_scene_error_past_column_65535_is_rendered_with_its_location() {
    // A typo at the end of a long generated rast_param line.
    let numbers = " 0.5".repeat(20000);
    let scene = format!("image 8 8\nbegin screen_triangle\nrast_param screen_vertex{numbers} x\nend\n");
    let path = temp_file("long.scene", &scene);
    let out_png = path.with_extension("png");
    let (code, err) = cli(&["render", path.to_str().unwrap(), "-o", out_png.to_str().unwrap()]);
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains(&format!("long.scene:3:{}", 25 + numbers.len() + 1)),
        "{err}"
    );
    assert!(longest_line(&err) < 2 * LONG_LINE, "{err}");
    assert!(!out_png.exists());
}

#[test]
fn columns_on_a_long_line_count_characters_and_the_window_keeps_them_whole() {
    // Two-byte characters (in a comment) before the error: the column counts characters,
    // and the window's cut does not split one.
    let text = format!("// {}\n/*{}*/@\n", "x".repeat(10), "é".repeat(40000));
    let (diags, sources) = check_text("e.prim", &text);
    assert_eq!(diags.codes_at(&sources), vec!["E0001@2:40005"]);
    let out = diags.render(&sources);
    assert!(out.contains("[e.prim:2:40005]"), "{out}");
    assert!(out.contains("éé*/@"), "{out}");
}

#[test]
fn labels_outside_the_window_are_listed_by_location() {
    let mut sources = SourceMap::new();
    let text = format!("{}b{}\n", "a".repeat(5000), "a".repeat(5000));
    let file = sources.add("w.prim", text);
    let d = Diagnostic::error("E0101", "something")
        .primary(Span::new(file, 5000, 5001), "here")
        .secondary(Span::new(file, 10, 11), "because of this");
    let out = d.render(&sources);
    assert!(out.contains("[w.prim:1:5001]"), "{out}");
    assert!(out.contains("see w.prim:1:11: because of this"), "{out}");
    assert!(longest_line(&out) < 2 * LONG_LINE, "{out}");
}

#[test]
fn a_short_line_deep_in_a_file_is_shown_with_its_neighbours() {
    let mut text: String = (1..=5000).map(|i| format!("// line {i}\n")).collect();
    text.push_str("@\n// after\n");
    let (diags, sources) = check_text("deep.prim", &text);
    let out = diags.render(&sources);
    assert!(out.contains("[deep.prim:5001:1]"), "{out}");
    assert!(out.contains(" 5000 │ // line 5000"), "{out}");
    assert!(out.contains(" 5001 │ @"), "{out}");
    assert!(out.contains(" 5002 │ // after"), "{out}");
}

#[test]
fn errors_past_the_limit_are_counted_behind_one_e0099() {
    let text = "@\n".repeat(MAX_ERRORS + 500);
    let (diags, sources) = check_text("many.prim", &text);
    let codes = diags.codes_at(&sources);
    assert_eq!(codes.len(), MAX_ERRORS + 1);
    assert!(codes[..MAX_ERRORS].iter().all(|c| c.starts_with("E0001@")));
    assert_eq!(codes[MAX_ERRORS], format!("E0099@{}:1", MAX_ERRORS + 1));
    assert_eq!(diags.error_count(), MAX_ERRORS + 500);
    assert!(diags.has_errors());

    let path = temp_file("many.prim", &text);
    let (code, err) = cli(&["check", path.to_str().unwrap()]);
    assert_eq!(code, 1);
    assert!(err.contains("E0099"), "{err}");
    assert!(err.contains("too many errors"), "{err}");
    assert!(
        err.contains(&format!("error: {} error(s); nothing compiled", MAX_ERRORS + 500)),
        "{err}"
    );
}

#[test]
fn extend_keeps_the_limit_and_the_count() {
    let mut sources = SourceMap::new();
    let file = sources.add("x", "x".repeat(10));
    let mut a = Diagnostics::new();
    let mut b = Diagnostics::new();
    for i in 0..700 {
        a.push(Diagnostic::error("E0101", format!("a{i}")).primary(Span::new(file, 1, 2), ""));
        b.push(Diagnostic::error("E0101", format!("b{i}")).primary(Span::new(file, 1, 2), ""));
        b.push(Diagnostic::warning("W0002", "w").primary(Span::new(file, 1, 2), ""));
    }
    a.extend(b);
    assert_eq!(a.error_count(), 1400);
    assert_eq!(a.items.iter().filter(|d| d.is_error()).count(), MAX_ERRORS + 1);
    assert_eq!(a.items.iter().filter(|d| d.code == "E0099").count(), 1);
    // Warnings are not limited.
    assert_eq!(a.items.iter().filter(|d| !d.is_error()).count(), 700);
}

#[test]
fn line_col_agrees_with_a_scan_of_the_text() {
    let text = "ab\r\n\néé x\n\nlast line without break";
    let mut sources = SourceMap::new();
    let file = sources.add("t", text);
    for offset in 0..=text.len() + 3 {
        let o = offset.min(text.len());
        let mut o2 = o;
        while !text.is_char_boundary(o2) {
            o2 -= 1;
        }
        let before = &text[..o2];
        let line = before.matches('\n').count() + 1;
        let col = before.rsplit('\n').next().unwrap().chars().count() + 1;
        assert_eq!(sources.line_col(file, offset as u32), (line, col), "offset {offset}");
    }
}
