//! `primflow test`: test cases that travel with the primitives.
//!
//! A test case is an ordinary scene file (it still renders with `primflow render`) with
//! expectation lines in comments. The runner renders the scene through the whole stack
//! (scene reader, registry, JIT, tiled renderer) and checks every expectation against the
//! frame, reporting each failed one with its line and the value it saw:
//!
//! ```text
//! # expect: covered 10 12              pixel (10, 12) was written
//! # expect: empty 0 0                  pixel (0, 0) was not written
//! # expect: depth 10 12 0.5 tol=1e-6   depth (device z, larger is nearer) at a pixel
//! # expect: param N 10 12 0 0 1 tol=1e-4
//! #                                    a shading parameter's components at a pixel
//! # expect: coverage 1234 tol=0        number of written pixels
//! # expect: coverage-in 0 0 8 8 64     written pixels in the rectangle x0 <= x < x1, y0 <= y < y1
//! # expect: writes-at-most 1           no pixel's depth written more than once (a shared
//! #                                    edge or a tessellated mesh must not overdraw)
//! # expect: writes-exactly 1 0 0 8 8   every pixel of the rectangle written exactly once
//! # expect: golden sphere.png tol=2 bad=0
//! #                                    the RGB image against a PNG next to the scene: at most
//! #                                    `bad` pixels with a channel differing by more than `tol`
//! # expect: diag W0801                 this diagnostic code is reported (an error code makes
//! #                                    the case expect a failed render)
//! ```
//!
//! Invariants: a case passes only if every expectation holds AND the run reported no
//! diagnostic the case did not announce with `diag` (so a new warning fails the library's
//! tests instead of scrolling past). Every failure is reported as `file:line: why`, a
//! malformed expectation line among them; the other lines are still checked. Nothing here
//! panics on bad input. `depth` and `param` values are compared as a scene gives them and
//! the frame stores them (the nearest f32, then for depth the nearest 2^-32 step), so
//! `tol=0` means "exactly the stored value nearest the decimal written". `--bless` writes a missing golden image only when
//! every other check of its case passed. Write counting is switched on only for cases that
//! ask about write counts. Cases run one after the other, each on a fresh JIT; a directory
//! is searched recursively for `*.scene` files holding at least one `expect:` line, in
//! sorted order.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use crate::diag::{Diagnostics, SourceMap};
use crate::jit::Jit;
use crate::runtime::{Frame, Registry, Renderer};

/// One checkable statement about a rendered frame.
#[derive(Clone, Debug, PartialEq)]
pub enum Check {
    Covered {
        x: u32,
        y: u32,
    },
    Empty {
        x: u32,
        y: u32,
    },
    Depth {
        x: u32,
        y: u32,
        value: f64,
        tol: f64,
    },
    Param {
        name: String,
        x: u32,
        y: u32,
        values: Vec<f64>,
        tol: f64,
    },
    Coverage {
        count: u64,
        tol: u64,
    },
    CoverageIn {
        rect: [u32; 4],
        count: u64,
    },
    WritesAtMost {
        max: u32,
    },
    WritesExactly {
        count: u32,
        rect: [u32; 4],
    },
    Golden {
        file: PathBuf,
        tol: u8,
        bad: u64,
    },
    Diag {
        code: String,
    },
}

/// An expectation and the 1-based line it was written on.
#[derive(Clone, Debug, PartialEq)]
pub struct Expectation {
    pub line: usize,
    pub check: Check,
}

/// The outcome of one case.
#[derive(Clone, Debug, PartialEq)]
pub struct CaseResult {
    pub path: PathBuf,
    /// Number of expectations checked.
    pub checked: usize,
    /// Why the case failed, one reason per failed expectation (empty: passed).
    pub failures: Vec<String>,
}

impl CaseResult {
    pub fn passed(&self) -> bool {
        self.failures.is_empty()
    }
}

/// How to run cases.
#[derive(Clone, Debug, Default)]
pub struct TestOptions {
    /// Extra primitive directories (besides the built-in library and the scene's `prims`).
    pub prim_dirs: Vec<PathBuf>,
    /// Worker threads (0: one per core).
    pub threads: usize,
    /// Write golden images that are missing instead of failing.
    pub bless: bool,
}

/// The default place of the library's own cases: `prims/tests` of the crate.
pub fn default_dir() -> PathBuf {
    Registry::source_dir().join("tests")
}

/// The case files under `paths` (files as given, directories searched recursively), sorted
/// within each directory. A path that does not exist is reported in the error list.
pub fn collect_cases(paths: &[PathBuf]) -> (Vec<PathBuf>, Vec<String>) {
    let mut cases = vec![];
    let mut errors = vec![];
    for p in paths {
        if p.is_dir() {
            walk(p, &mut cases, &mut errors);
        } else if p.is_file() {
            cases.push(p.clone());
        } else {
            errors.push(format!("`{}`: no such file or directory", p.display()));
        }
    }
    (cases, errors)
}

fn walk(dir: &Path, cases: &mut Vec<PathBuf>, errors: &mut Vec<String>) {
    let entries = match std::fs::read_dir(dir) {
        Ok(e) => e,
        Err(e) => {
            errors.push(format!("`{}`: {e}", dir.display()));
            return;
        }
    };
    let mut paths: Vec<PathBuf> = entries.filter_map(|e| e.ok().map(|e| e.path())).collect();
    paths.sort();
    for p in paths {
        if p.is_dir() {
            walk(&p, cases, errors);
        } else if p.extension().is_some_and(|e| e == "scene")
            && std::fs::read_to_string(&p).is_ok_and(|t| t.lines().any(|l| expect_text(l).is_some()))
        {
            cases.push(p);
        }
    }
}

/// The text after `expect:` if `line` is an expectation comment.
fn expect_text(line: &str) -> Option<&str> {
    let rest = line.trim_start().strip_prefix('#')?.trim_start();
    rest.strip_prefix("expect:").map(str::trim)
}

/// Parse every expectation line of a scene's text. Errors are (1-based line, message).
pub fn parse_expectations(text: &str, base: &Path) -> (Vec<Expectation>, Vec<(usize, String)>) {
    let mut out = vec![];
    let mut errors = vec![];
    for (i, line) in text.lines().enumerate() {
        let Some(body) = expect_text(line) else { continue };
        match parse_check(body, base) {
            Ok(check) => out.push(Expectation { line: i + 1, check }),
            Err(e) => errors.push((i + 1, e)),
        }
    }
    (out, errors)
}

/// Positional words and `key=value` options of one expectation.
struct Words<'a> {
    positional: Vec<&'a str>,
    options: Vec<(&'a str, &'a str)>,
}

impl<'a> Words<'a> {
    fn new(body: &'a str) -> Words<'a> {
        let mut positional = vec![];
        let mut options = vec![];
        for w in body.split_whitespace() {
            match w.split_once('=') {
                Some((k, v)) => options.push((k, v)),
                None => positional.push(w),
            }
        }
        Words { positional, options }
    }
    fn option<T: std::str::FromStr>(&self, key: &str, default: T) -> Result<T, String> {
        match self.options.iter().find(|(k, _)| *k == key) {
            Some((_, v)) => v.parse().map_err(|_| format!("`{key}={v}` is not a valid value")),
            None => Ok(default),
        }
    }
    fn unknown_option(&self, known: &[&str]) -> Result<(), String> {
        match self.options.iter().find(|(k, _)| !known.contains(k)) {
            Some((k, _)) => Err(format!("unknown option `{k}=`")),
            None => Ok(()),
        }
    }
}

fn num<T: std::str::FromStr>(w: &str, what: &str) -> Result<T, String> {
    w.parse().map_err(|_| format!("`{w}` is not a valid {what}"))
}

fn arity(words: &[&str], n: usize, usage: &str) -> Result<(), String> {
    if words.len() == n {
        Ok(())
    } else {
        Err(format!("expected `{usage}`"))
    }
}

fn rect(w: &[&str]) -> Result<[u32; 4], String> {
    let r = [
        num(w[0], "pixel coordinate")?,
        num(w[1], "pixel coordinate")?,
        num(w[2], "pixel coordinate")?,
        num(w[3], "pixel coordinate")?,
    ];
    if r[0] > r[2] || r[1] > r[3] {
        return Err("the rectangle's corners are out of order (x0 y0 x1 y1)".into());
    }
    Ok(r)
}

fn parse_check(body: &str, base: &Path) -> Result<Check, String> {
    let words = Words::new(body);
    let Some((&kind, w)) = words.positional.split_first() else {
        return Err("empty expectation".into());
    };
    let check = match kind {
        "covered" | "empty" => {
            arity(w, 2, &format!("{kind} X Y"))?;
            words.unknown_option(&[])?;
            let (x, y) = (num(w[0], "pixel coordinate")?, num(w[1], "pixel coordinate")?);
            if kind == "covered" {
                Check::Covered { x, y }
            } else {
                Check::Empty { x, y }
            }
        }
        "depth" => {
            arity(w, 3, "depth X Y VALUE [tol=T]")?;
            words.unknown_option(&["tol"])?;
            Check::Depth {
                x: num(w[0], "pixel coordinate")?,
                y: num(w[1], "pixel coordinate")?,
                value: num(w[2], "number")?,
                tol: words.option("tol", 1e-6)?,
            }
        }
        "param" => {
            if w.len() < 4 {
                return Err("expected `param NAME X Y V... [tol=T]`".into());
            }
            words.unknown_option(&["tol"])?;
            Check::Param {
                name: w[0].to_string(),
                x: num(w[1], "pixel coordinate")?,
                y: num(w[2], "pixel coordinate")?,
                values: w[3..].iter().map(|v| num(v, "number")).collect::<Result<_, _>>()?,
                tol: words.option("tol", 1e-4)?,
            }
        }
        "coverage" => {
            arity(w, 1, "coverage N [tol=T]")?;
            words.unknown_option(&["tol"])?;
            Check::Coverage {
                count: num(w[0], "pixel count")?,
                tol: words.option("tol", 0)?,
            }
        }
        "coverage-in" => {
            arity(w, 5, "coverage-in X0 Y0 X1 Y1 N")?;
            words.unknown_option(&[])?;
            Check::CoverageIn {
                rect: rect(w)?,
                count: num(w[4], "pixel count")?,
            }
        }
        "writes-at-most" => {
            arity(w, 1, "writes-at-most K")?;
            words.unknown_option(&[])?;
            Check::WritesAtMost {
                max: num(w[0], "count")?,
            }
        }
        "writes-exactly" => {
            arity(w, 5, "writes-exactly K X0 Y0 X1 Y1")?;
            words.unknown_option(&[])?;
            Check::WritesExactly {
                count: num(w[0], "count")?,
                rect: rect(&w[1..])?,
            }
        }
        "golden" => {
            arity(w, 1, "golden FILE.png [tol=T] [bad=N]")?;
            words.unknown_option(&["tol", "bad"])?;
            Check::Golden {
                file: base.join(w[0]),
                tol: words.option("tol", 0)?,
                bad: words.option("bad", 0)?,
            }
        }
        "diag" => {
            arity(w, 1, "diag CODE")?;
            words.unknown_option(&[])?;
            let code = w[0];
            let well_formed = code.len() == 5
                && (code.starts_with('E') || code.starts_with('W'))
                && code[1..].chars().all(|c| c.is_ascii_digit());
            if !well_formed {
                return Err(format!("`{code}` is not a diagnostic code (E0123 or W0123)"));
            }
            Check::Diag { code: code.to_string() }
        }
        other => {
            return Err(format!(
                "unknown expectation `{other}` (covered, empty, depth, param, coverage, coverage-in, writes-at-most, writes-exactly, golden, diag)"
            ))
        }
    };
    Ok(check)
}

/// Render `path` and check its expectations.
pub fn run_case(path: &Path, options: &TestOptions) -> CaseResult {
    let mut result = CaseResult {
        path: path.to_path_buf(),
        checked: 0,
        failures: vec![],
    };
    let at = |line: usize, why: &str| format!("{}:{line}: {why}", path.display());
    let text = match std::fs::read_to_string(path) {
        Ok(t) => t,
        Err(e) => {
            result
                .failures
                .push(format!("{}: cannot read the case: {e}", path.display()));
            return result;
        }
    };
    let base = path.parent().unwrap_or(Path::new("."));
    let (expectations, errors) = parse_expectations(&text, base);
    // A malformed line fails the case; the well-formed ones are still checked.
    result.failures.extend(errors.iter().map(|(line, e)| at(*line, e)));
    if expectations.is_empty() {
        if errors.is_empty() {
            result
                .failures
                .push(format!("{}: no `# expect:` lines: nothing to check", path.display()));
        }
        return result;
    }
    let expected_codes: BTreeSet<&str> = expectations
        .iter()
        .filter_map(|e| match &e.check {
            Check::Diag { code } => Some(code.as_str()),
            _ => None,
        })
        .collect();
    let count_writes = expectations
        .iter()
        .any(|e| matches!(e.check, Check::WritesAtMost { .. } | Check::WritesExactly { .. }));

    // The parameters the expectations read stay in the G-buffer whether or not a shader
    // reads them.
    let keep_params = expectations
        .iter()
        .filter_map(|e| match &e.check {
            Check::Param { name, .. } => Some(name.clone()),
            _ => None,
        })
        .collect();
    let (frame, diags, sources) = render_case(path, base, options, count_writes, keep_params);
    // Diagnostics: every announced code must appear, nothing unannounced may.
    let seen: Vec<(String, String)> = diags
        .items
        .iter()
        .map(|d| {
            let place = match d.primary_span() {
                Some(s) => {
                    let (l, c) = sources.line_col(s.file, s.start);
                    format!("{}:{l}:{c}", sources.file(s.file).name)
                }
                None => path.display().to_string(),
            };
            (d.code.to_string(), format!("{place}: {} {}", d.code, d.message))
        })
        .collect();
    for (code, text) in &seen {
        if !expected_codes.contains(code.as_str()) {
            result.failures.push(format!("unexpected diagnostic {text}"));
        }
    }
    for e in &expectations {
        if let Check::Diag { code } = &e.check {
            result.checked += 1;
            if !seen.iter().any(|(c, _)| c == code) {
                result
                    .failures
                    .push(at(e.line, &format!("expected diagnostic {code}, none reported")));
            }
        }
    }
    let Some(frame) = frame else {
        let frame_checks = expectations.iter().filter(|e| !matches!(e.check, Check::Diag { .. }));
        for e in frame_checks {
            result.failures.push(at(e.line, "nothing was rendered to check"));
        }
        return result;
    };
    // Golden images last: `--bless` writes one only for a case whose other checks passed.
    let (golden, others): (Vec<&Expectation>, Vec<&Expectation>) = expectations
        .iter()
        .filter(|e| !matches!(e.check, Check::Diag { .. }))
        .partition(|e| matches!(e.check, Check::Golden { .. }));
    for e in others {
        result.checked += 1;
        if let Err(why) = check_frame(&e.check, &frame, options) {
            result.failures.push(at(e.line, &why));
        }
    }
    let failed = result.failures.len();
    let bless = TestOptions {
        bless: options.bless && failed == 0,
        ..options.clone()
    };
    for e in golden {
        result.checked += 1;
        match check_frame(&e.check, &frame, &bless) {
            Err(why) if options.bless && failed > 0 => result.failures.push(at(
                e.line,
                &format!("{why}; not blessed: {failed} other check(s) of this case failed"),
            )),
            Err(why) => result.failures.push(at(e.line, &why)),
            Ok(()) => {}
        }
    }
    result
}

/// Render the scene as `primflow render` would. `None` if it had errors (they are in the
/// returned diagnostics).
fn render_case(
    path: &Path,
    base: &Path,
    options: &TestOptions,
    count_writes: bool,
    keep_params: Vec<String>,
) -> (Option<Frame>, Diagnostics, SourceMap) {
    let mut sources = SourceMap::new();
    let mut diags = Diagnostics::new();
    let file = match sources.load(path) {
        Ok(f) => f,
        Err(e) => {
            diags.push(crate::diag::Diagnostic::error(
                "E0709",
                format!("cannot read the scene: {e}"),
            ));
            return (None, diags, sources);
        }
    };
    let scene = crate::scene::parse(&sources, file, &mut diags);
    if diags.has_errors() {
        return (None, diags, sources);
    }
    let mut dirs = options.prim_dirs.clone();
    dirs.extend(scene.prim_dirs(base));
    let Some(registry) = Registry::load(&mut sources, &dirs, &[], &mut diags) else {
        return (None, diags, sources);
    };
    let mut renderer = Renderer::new(registry.program.clone());
    renderer.options.count_writes = count_writes;
    renderer.options.keep_params = keep_params;
    crate::scene::apply(&scene, &mut renderer, &mut diags);
    if diags.has_errors() {
        return (None, diags, sources);
    }
    // Tiered, as `primflow render`: one frame per test scene, so tier-0 kernels start it and
    // tier-1 ones take over mid-frame if they are ready in time (the same pixels either way).
    let mut jit = match Jit::tiered(registry.program.clone()) {
        Ok(j) => j,
        Err(e) => {
            diags.push(crate::diag::Diagnostic::error(
                "E0801",
                format!("cannot start the JIT: {e}"),
            ));
            return (None, diags, sources);
        }
    };
    let pool = match crate::runtime::render_pool(options.threads) {
        Ok(p) => p,
        Err(e) => {
            diags.push(crate::diag::Diagnostic::error(
                "E0801",
                format!("cannot start threads: {e}"),
            ));
            return (None, diags, sources);
        }
    };
    let out = pool.install(|| renderer.render(&mut jit));
    jit.detach_tier_up();
    diags.extend(out.diags);
    let frame = (!diags.has_errors()).then_some(out.frame);
    (frame, diags, sources)
}

fn pixel_in(frame: &Frame, x: u32, y: u32) -> Result<(), String> {
    if x < frame.width && y < frame.height {
        Ok(())
    } else {
        Err(format!(
            "pixel ({x}, {y}) is outside the {}x{} image",
            frame.width, frame.height
        ))
    }
}

fn rect_in(frame: &Frame, r: [u32; 4]) -> Result<(), String> {
    if r[2] <= frame.width && r[3] <= frame.height {
        Ok(())
    } else {
        Err(format!(
            "rectangle {r:?} is outside the {}x{} image",
            frame.width, frame.height
        ))
    }
}

/// Check one frame expectation; `Err` says what was seen instead.
pub fn check_frame(check: &Check, frame: &Frame, options: &TestOptions) -> Result<(), String> {
    match check {
        Check::Covered { x, y } => {
            pixel_in(frame, *x, *y)?;
            if frame.written(*x, *y) {
                Ok(())
            } else {
                Err(format!("pixel ({x}, {y}) is not covered"))
            }
        }
        Check::Empty { x, y } => {
            pixel_in(frame, *x, *y)?;
            if frame.written(*x, *y) {
                Err(format!(
                    "pixel ({x}, {y}) is covered (depth {})",
                    frame.depth_f32_at(*x, *y).unwrap_or(0.0)
                ))
            } else {
                Ok(())
            }
        }
        Check::Depth { x, y, value, tol } => {
            pixel_in(frame, *x, *y)?;
            if !frame.written(*x, *y) {
                return Err(format!("pixel ({x}, {y}) is not covered; expected depth {value}"));
            }
            let raw = frame.depth_at(*x, *y).unwrap_or(0);
            let got = f64::from(raw) / DEPTH_STEPS;
            let want = stored_depth(*value);
            if (got - want).abs() <= *tol {
                Ok(())
            } else {
                let stored = if want == *value {
                    String::new()
                } else {
                    format!(" (stored as {want})")
                };
                Err(format!(
                    "depth at ({x}, {y}) is {got}, expected {value}{stored} ± {tol} (off by {:.3e})",
                    (got - want).abs()
                ))
            }
        }
        Check::Param {
            name,
            x,
            y,
            values,
            tol,
        } => {
            pixel_in(frame, *x, *y)?;
            let Some(got) = frame.param_at(name, *x, *y) else {
                return Err(frame.no_param_message(name));
            };
            if got.len() != values.len() {
                return Err(format!(
                    "`{name}` has {} components, the expectation gives {}",
                    got.len(),
                    values.len()
                ));
            }
            if !frame.written(*x, *y) {
                return Err(format!(
                    "pixel ({x}, {y}) is not covered; expected `{name}` = {values:?}"
                ));
            }
            let worst = got
                .iter()
                .zip(values)
                .map(|(&g, &v)| {
                    // As stored: the nearest f32 (a decimal like 0.1 has no exact one).
                    let d = (f64::from(g) - f64::from(v as f32)).abs();
                    if d.is_nan() {
                        f64::INFINITY
                    } else {
                        d
                    }
                })
                .fold(0.0, f64::max);
            if worst <= *tol {
                Ok(())
            } else {
                Err(format!(
                    "`{name}` at ({x}, {y}) is {got:?}, expected {values:?} ± {tol} (off by {worst:.3e})"
                ))
            }
        }
        Check::Coverage { count, tol } => {
            let got = covered_in(frame, [0, 0, frame.width, frame.height]);
            if got.abs_diff(*count) <= *tol {
                Ok(())
            } else {
                Err(format!("{got} pixels covered, expected {count} ± {tol}"))
            }
        }
        Check::CoverageIn { rect, count } => {
            rect_in(frame, *rect)?;
            let got = covered_in(frame, *rect);
            if got == *count {
                Ok(())
            } else {
                Err(format!("{got} pixels covered in {rect:?}, expected {count}"))
            }
        }
        Check::WritesAtMost { max } => {
            let mut worst = None;
            let mut over = 0u64;
            for y in 0..frame.height {
                for x in 0..frame.width {
                    let n = frame.write_count_at(x, y).unwrap_or(0);
                    if n > *max {
                        over += 1;
                        worst.get_or_insert((x, y, n));
                    }
                }
            }
            match worst {
                None => Ok(()),
                Some((x, y, n)) => Err(format!(
                    "{over} pixel(s) written more than {max} time(s), first ({x}, {y}) {n} times"
                )),
            }
        }
        Check::WritesExactly { count, rect } => {
            rect_in(frame, *rect)?;
            let mut wrong = 0u64;
            let mut first = None;
            for y in rect[1]..rect[3] {
                for x in rect[0]..rect[2] {
                    let n = frame.write_count_at(x, y).unwrap_or(0);
                    if n != *count {
                        wrong += 1;
                        first.get_or_insert((x, y, n));
                    }
                }
            }
            match first {
                None => Ok(()),
                Some((x, y, n)) => Err(format!(
                    "{wrong} pixel(s) in {rect:?} not written exactly {count} time(s), first ({x}, {y}) {n} times"
                )),
            }
        }
        Check::Golden { file, tol, bad } => check_golden(frame, file, *tol, *bad, options.bless),
        Check::Diag { .. } => Ok(()),
    }
}

/// Depth steps per unit: the frame keeps depth as a fraction of 2^32.
const DEPTH_STEPS: f64 = 4294967296.0;

/// `value` as a scene gives it and the frame holds it: the nearest f32 (a scene's numbers
/// are f32), then the nearest depth step in [0, 1).
fn stored_depth(value: f64) -> f64 {
    let value = f64::from(value as f32);
    if value.is_nan() {
        return value;
    }
    (value * DEPTH_STEPS).round().clamp(0.0, DEPTH_STEPS - 1.0) / DEPTH_STEPS
}

fn covered_in(frame: &Frame, r: [u32; 4]) -> u64 {
    let mut n = 0;
    for y in r[1]..r[3] {
        for x in r[0]..r[2] {
            n += u64::from(frame.written(x, y));
        }
    }
    n
}

fn check_golden(frame: &Frame, file: &Path, tol: u8, bad: u64, bless: bool) -> Result<(), String> {
    let image = frame.to_rgb8();
    if !file.exists() {
        if bless {
            return image
                .save(file)
                .map_err(|e| format!("cannot write golden `{}`: {e}", file.display()));
        }
        return Err(format!(
            "golden image `{}` does not exist (run `primflow test --bless` to create it)",
            file.display()
        ));
    }
    let golden = image::open(file)
        .map_err(|e| format!("cannot read golden `{}`: {e}", file.display()))?
        .to_rgb8();
    if golden.dimensions() != image.dimensions() {
        return Err(format!(
            "golden `{}` is {:?}, the frame is {:?}",
            file.display(),
            golden.dimensions(),
            image.dimensions()
        ));
    }
    let mut differing = 0u64;
    let mut first = None;
    for (x, y, p) in image.enumerate_pixels() {
        let g = golden.get_pixel(x, y);
        let worst = (0..3).map(|c| p[c].abs_diff(g[c])).max().unwrap_or(0);
        if worst > tol {
            differing += 1;
            first.get_or_insert((x, y, p.0, g.0));
        }
    }
    match first {
        Some((x, y, p, g)) if differing > bad => Err(format!(
            "{differing} pixel(s) differ from `{}` by more than {tol} (at most {bad} allowed); first ({x}, {y}): {p:?} vs {g:?}",
            file.display()
        )),
        _ => Ok(()),
    }
}

/// Run every case under `paths`, printing one line per case (and its reasons) to `out`.
/// Returns the results; the caller decides the exit code.
pub fn run_all(paths: &[PathBuf], options: &TestOptions, out: &mut dyn std::io::Write) -> Vec<CaseResult> {
    let (mut cases, errors) = collect_cases(paths);
    // A case reached twice (a `--prims` directory inside another path) runs once.
    let mut seen = std::collections::HashSet::new();
    cases.retain(|c| seen.insert(std::fs::canonicalize(c).unwrap_or_else(|_| c.clone())));
    let mut results: Vec<CaseResult> = errors
        .into_iter()
        .map(|e| CaseResult {
            path: PathBuf::new(),
            checked: 0,
            failures: vec![e],
        })
        .collect();
    for case in cases {
        let r = run_case(&case, options);
        if r.passed() {
            let _ = writeln!(out, "test {} ... ok ({} checks)", case.display(), r.checked);
        } else {
            let _ = writeln!(out, "test {} ... FAILED", case.display());
            for f in &r.failures {
                let _ = writeln!(out, "    {f}");
            }
        }
        results.push(r);
    }
    for r in results.iter().filter(|r| r.path.as_os_str().is_empty()) {
        let _ = writeln!(out, "error: {}", r.failures.join("; "));
    }
    let passed = results.iter().filter(|r| r.passed()).count();
    let _ = writeln!(
        out,
        "test result: {}. {passed} passed; {} failed",
        if passed == results.len() && !results.is_empty() {
            "ok"
        } else {
            "FAILED"
        },
        results.len() - passed
    );
    results
}
