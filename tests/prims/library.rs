//! The primitive library's own test cases (prims/tests/*.scene, `# expect:` lines) run by
//! `primflow test`, and the runner itself: a failing case names the line and what it saw,
//! and the command exits non-zero.

use std::path::PathBuf;

fn run_cli(args: &[&str]) -> (i32, String) {
    let mut out = vec![];
    let mut err = vec![];
    let mut argv = vec!["primflow"];
    argv.extend_from_slice(args);
    let code = primflow::cli::run(argv, &mut out, &mut err);
    let text = String::from_utf8_lossy(&out).to_string() + &String::from_utf8_lossy(&err);
    (code, text)
}

#[test]
fn library_cases_pass() {
    let (code, text) = run_cli(&["test", "--threads", "2"]);
    println!("{text}");
    assert_eq!(code, 0, "primflow test failed:\n{text}");
    let cases = text
        .lines()
        .filter(|l| l.starts_with("test ") && l.ends_with("checks)"))
        .count();
    let expected = std::fs::read_dir(primflow::testing::default_dir())
        .unwrap()
        .filter(|e| e.as_ref().unwrap().path().extension().is_some_and(|x| x == "scene"))
        .count();
    assert_eq!(cases, expected, "every case file ran and passed:\n{text}");
    assert!(expected >= 3);
}

fn temp_case(name: &str, text: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("primflow-test-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(format!("{name}.scene"));
    std::fs::write(&path, text).unwrap();
    path
}

const QUAD: &str =
    "image 16 16\nbegin polygon\nvertex 2 2 0.5\nvertex 10 2 0.5\nvertex 10 6 0.5\nvertex 2 6 0.5\nend\n";

#[test]
fn failing_expectations_are_reported_with_line_and_value() {
    let text = format!(
        "{QUAD}# expect: coverage 32\n# expect: coverage 33\n# expect: depth 3 3 0.25\n# expect: empty 3 3\n# expect: writes-at-most 1\n"
    );
    let path = temp_case("failing", &text);
    let (code, out) = run_cli(&["test", path.to_str().unwrap()]);
    assert_eq!(code, 1, "{out}");
    assert!(out.contains("FAILED"), "{out}");
    assert!(
        out.contains("failing.scene:9: 32 pixels covered, expected 33 ± 0"),
        "{out}"
    );
    assert!(
        out.contains("failing.scene:10: depth at (3, 3) is 0.5, expected 0.25"),
        "{out}"
    );
    assert!(out.contains("failing.scene:11: pixel (3, 3) is covered"), "{out}");
    assert!(
        !out.contains("failing.scene:8:") && !out.contains("failing.scene:12:"),
        "passing lines reported: {out}"
    );
    assert!(out.contains("test result: FAILED. 0 passed; 1 failed"), "{out}");
}

#[test]
fn unexpected_and_announced_diagnostics() {
    // A primitive with no vertex given: W0701 (zero-filled) unless the case announces it.
    let scene = "image 8 8\nbegin polygon\nend\n";
    let quiet = temp_case("unannounced", &format!("{scene}# expect: coverage 0\n"));
    let (code, out) = run_cli(&["test", quiet.to_str().unwrap()]);
    assert_eq!(code, 1, "{out}");
    // Named by file, line and column.
    assert!(out.contains("unexpected diagnostic "), "{out}");
    assert!(out.contains("unannounced.scene:3:1: W0701"), "{out}");
    let announced = temp_case(
        "announced",
        &format!("{scene}# expect: coverage 0\n# expect: diag W0701\n"),
    );
    let (code, out) = run_cli(&["test", announced.to_str().unwrap()]);
    assert_eq!(code, 0, "{out}");
    // A scene error with an announced code: the case passes without a frame.
    let broken = temp_case("broken", "image 8 8\nbegin no_such_prim\nend\n# expect: diag E0701\n");
    let (code, out) = run_cli(&["test", broken.to_str().unwrap()]);
    assert_eq!(code, 0, "{out}");
}

#[test]
fn malformed_cases_and_missing_paths_fail() {
    // A misspelt line fails the case, and the lines after it are still checked.
    let bad = temp_case(
        "malformed",
        &format!("{QUAD}# expect: coverage lots\n# expect: covrage 32\n# expect: coverage 33\n# expect: covered 3 3\n"),
    );
    let (code, out) = run_cli(&["test", bad.to_str().unwrap()]);
    assert_eq!(code, 1);
    assert!(
        out.contains("malformed.scene:8: `lots` is not a valid pixel count"),
        "{out}"
    );
    assert!(
        out.contains("malformed.scene:9: unknown expectation `covrage`"),
        "{out}"
    );
    assert!(
        out.contains("malformed.scene:10: 32 pixels covered, expected 33"),
        "{out}"
    );
    assert!(!out.contains("malformed.scene:11"), "{out}");
    let (code, out) = run_cli(&["test", "/nonexistent/primflow/cases"]);
    assert_eq!(code, 1);
    assert!(out.contains("no such file or directory"), "{out}");
}

#[test]
fn golden_images_compare_within_tolerance_and_bless_creates_them() {
    let path = temp_case("golden", &format!("{QUAD}# expect: golden quad.png tol=0\n"));
    let golden = path.with_file_name("quad.png");
    let _ = std::fs::remove_file(&golden);
    let (code, out) = run_cli(&["test", path.to_str().unwrap()]);
    assert_eq!(code, 1);
    assert!(out.contains("does not exist (run `primflow test --bless`"), "{out}");
    let (code, out) = run_cli(&["test", "--bless", path.to_str().unwrap()]);
    assert_eq!(code, 0, "{out}");
    let (code, out) = run_cli(&["test", path.to_str().unwrap()]);
    assert_eq!(code, 0, "{out}");
    // Change the golden: one pixel off by 40 fails at tol=0, passes with bad=1.
    let mut img = image::open(&golden).unwrap().to_rgb8();
    img.get_pixel_mut(0, 0).0 = [40, 0, 0];
    img.save(&golden).unwrap();
    let (code, out) = run_cli(&["test", path.to_str().unwrap()]);
    assert_eq!(code, 1);
    assert!(out.contains("1 pixel(s) differ"), "{out}");
    std::fs::write(&path, format!("{QUAD}# expect: golden quad.png tol=0 bad=1\n")).unwrap();
    let (code, out) = run_cli(&["test", path.to_str().unwrap()]);
    assert_eq!(code, 0, "{out}");
}

#[test]
fn bless_writes_no_golden_while_another_check_fails() {
    let path = temp_case(
        "bless_refused",
        &format!("{QUAD}# expect: coverage 31\n# expect: golden refused.png\n"),
    );
    let golden = path.with_file_name("refused.png");
    let _ = std::fs::remove_file(&golden);
    let (code, out) = run_cli(&["test", "--bless", path.to_str().unwrap()]);
    assert_eq!(code, 1, "{out}");
    assert!(out.contains("bless_refused.scene:9: golden image"), "{out}");
    assert!(
        out.contains("not blessed: 1 other check(s) of this case failed"),
        "{out}"
    );
    assert!(!golden.exists());
    // Fixed, the same command writes it.
    std::fs::write(
        &path,
        format!("{QUAD}# expect: coverage 32\n# expect: golden refused.png\n"),
    )
    .unwrap();
    let (code, out) = run_cli(&["test", "--bless", path.to_str().unwrap()]);
    assert_eq!(code, 0, "{out}");
    assert!(golden.exists());
}

/// `tol=0` on decimals that have no exact f32 or depth step: compared as stored, so they
/// pass; a value one step off still fails.
#[test]
fn zero_tolerance_compares_decimals_as_the_frame_stores_them() {
    let scene = "image 16 16\nmaterial_interp Cs constant\nbegin polygon\nmaterial Cs 0.1 0.2 0.3\n\
                 vertex 2 2 0.3\nvertex 10 2 0.3\nvertex 10 6 0.3\nvertex 2 6 0.3\nend\n";
    let exact = temp_case(
        "decimals",
        &format!("{scene}# expect: depth 3 3 0.3 tol=0\n# expect: param Cs 3 3 0.1 0.2 0.3 tol=0\n"),
    );
    let (code, out) = run_cli(&["test", exact.to_str().unwrap()]);
    assert_eq!(code, 0, "{out}");
    let off = temp_case(
        "decimals_off",
        &format!("{scene}# expect: depth 3 3 0.30000003 tol=0\n# expect: param Cs 3 3 0.1 0.2 0.30000003 tol=0\n"),
    );
    let (code, out) = run_cli(&["test", off.to_str().unwrap()]);
    assert_eq!(code, 1, "{out}");
    assert!(out.contains("decimals_off.scene:10: depth at (3, 3)"), "{out}");
    assert!(out.contains("(stored as "), "{out}");
    assert!(out.contains("decimals_off.scene:11: `Cs` at (3, 3)"), "{out}");
}

/// `primflow test --prims DIR` with no paths also runs the cases kept in DIR.
#[test]
fn cases_beside_a_prims_directory_are_found() {
    let dir = std::env::temp_dir().join(format!("primflow-test-{}-beside", std::process::id()));
    std::fs::create_dir_all(dir.join("tests")).unwrap();
    std::fs::write(
        dir.join("square.prim"),
        "primitive square(float lo, hi; varying float X, Y; inout varying fixed<32,32> Z)\n\
         {\n    bound(lo, lo, hi, hi);\n    if (X < lo || X > hi || Y < lo || Y > hi) return;\n    Z = 0.5;\n}\n",
    )
    .unwrap();
    std::fs::write(
        dir.join("tests/square.scene"),
        "image 8 8\nbegin square\nrast_param lo 2\nrast_param hi 4\nend\n# expect: coverage 4\n",
    )
    .unwrap();
    let (code, out) = run_cli(&["test", "--threads", "1", "--prims", dir.to_str().unwrap()]);
    assert_eq!(code, 0, "{out}");
    assert!(out.contains("tests/square.scene ... ok (1 checks)"), "{out}");
    assert!(out.contains("polygon"), "the library's cases ran too: {out}");
}
