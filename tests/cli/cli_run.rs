//! The command line: exit codes and messages of `check` and `render` on bad input, and the
//! `--key` syntax. (Rendering real scenes end to end needs the checker and the JIT.)

use crate::support;

use std::path::{Path, PathBuf};

use primflow::abi::{Binding, BindingKind};
use primflow::cli::parse_key;
use primflow::ir::Program;
use support::cli;

fn temp_file(name: &str, text: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("primflow-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn render_reports_every_scene_error_with_its_location_and_exits_1() {
    let scene = temp_file("bad.scene", "image 32 x\nbegn screen_triangle\nvertex 1 2\n");
    let out_png = scene.with_extension("png");
    let (code, out, err) = cli(&["render", scene.to_str().unwrap(), "-o", out_png.to_str().unwrap()]);
    assert_eq!(code, 1);
    assert!(out.is_empty(), "{out}");
    assert!(err.contains("bad.scene:1:10"), "{err}");
    assert!(err.contains("E0601") && err.contains("bad.scene:2:1"), "{err}");
    assert!(err.contains("did you mean `begin`?"), "{err}");
    assert!(err.contains("E0602") && err.contains("bad.scene:3:8"), "{err}");
    assert!(!out_png.exists(), "no image on errors");
}

#[test]
fn render_of_a_missing_scene_is_a_clear_error() {
    let (code, _, err) = cli(&["render", "/nonexistent/x.scene", "-o", "/tmp/never.png"]);
    assert_eq!(code, 1);
    assert!(
        err.starts_with("error: cannot read scene `/nonexistent/x.scene`"),
        "{err}"
    );
}

#[test]
fn check_reports_syntax_errors_at_file_line_col_and_exits_1() {
    let prim = temp_file(
        "broken.prim",
        "primitive broken(varying float X, Y) {\n    float a = ;\n}\n",
    );
    let (code, _, err) = cli(&["check", prim.to_str().unwrap()]);
    assert_eq!(code, 1);
    assert!(err.contains("broken.prim:2:"), "{err}");
}

#[test]
fn check_emit_ast_prints_the_tree_of_each_given_file_only() {
    let prim = temp_file(
        "ast.prim",
        "primitive p(varying float X, Y) {\n    float a = ;\n    return;\n}\n",
    );
    let (code, out, err) = cli(&["check", prim.to_str().unwrap(), "--emit", "ast"]);
    assert_eq!(code, 1, "the syntax error is reported");
    assert!(err.contains("E0011") && err.contains("ast.prim:2:15"), "{err}");
    // No library file: one header, then the tree, the broken statement an error node.
    assert_eq!(
        out,
        format!(
            "// {}\nprimitive p @1:1\n  param varying float X @1:27\n  param varying float Y @1:30\n  body: block @1:33\n    error (did not parse) @2:5\n    return @3:5\n",
            prim.display()
        )
    );
}

/// A primitive of the user's that calls a helper and a library primitive.
const TWO_USER_PRIMITIVES: &str = r#"
float half(float v) { return v * 0.5; }
primitive user_rect(float rect[4]; varying float X, Y; inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    Z = fixed<32,32>(half(0.5));
}
primitive user_tri(float v[3][4]; interpolation_data d[3]; varying float X, Y; inout varying fixed<32,32> Z)
{
    screen_triangle(v, d, X, Y, Z);
}
"#;

#[test]
fn check_emit_ir_prints_only_the_given_files_items() {
    let prim = temp_file("ir.prim", TWO_USER_PRIMITIVES);
    let (code, out, err) = cli(&["check", prim.to_str().unwrap(), "--emit", "ir"]);
    assert_eq!(code, 0, "{err}");
    let items: Vec<&str> = out.lines().filter(|l| !l.is_empty() && !l.starts_with(' ')).collect();
    assert_eq!(items, ["primitive user_rect", "primitive user_tri"], "{out}");
    // The helper is inlined (its result a temporary); the library primitive is named at its call.
    assert!(out.contains("half_result%"), "{out}");
    assert!(out.contains("    call screen_triangle#"), "{out}");

    let helpers = temp_file("ir_helpers.prim", "float half(float v) { return v * 0.5; }\n");
    let (code, out, _) = cli(&["check", helpers.to_str().unwrap(), "--emit", "ir"]);
    assert_eq!(code, 0);
    assert_eq!(
        out,
        "// no primitive or interpolator in the given files (helpers are inlined into their callers)\n"
    );
}

#[test]
fn check_emit_asm_prints_each_primitives_machine_code() {
    let prim = temp_file("asm.prim", TWO_USER_PRIMITIVES);
    let (code, out, err) = cli(&["check", prim.to_str().unwrap(), "--emit", "asm", "--key", "linear:2"]);
    assert_eq!(code, 0, "{err}");
    assert!(out.lines().next().unwrap().contains("opt_level=speed"), "{out}");
    let headers: Vec<&str> = out.lines().filter(|l| l.starts_with("; primitive ")).collect();
    assert_eq!(headers.len(), 2, "{out}");
    for (header, name) in headers.iter().zip(["user_rect", "user_tri"]) {
        let rest = header
            .strip_prefix(&format!("; primitive {name} key linear:2: "))
            .unwrap_or_else(|| panic!("{header}"));
        let count: usize = rest.split(' ').next().unwrap().parse().unwrap();
        assert!(count > 20, "{header}");
    }
    // Machine instructions, each kernel ending in a return, and no CLIF.
    let first_words: Vec<&str> = out.lines().filter_map(|l| l.split_whitespace().next()).collect();
    assert!(
        first_words.iter().filter(|w| w.starts_with("ret")).count() >= 2,
        "{out}"
    );
    assert!(first_words.iter().any(|w| w.starts_with("mov")), "{out}");
    assert!(!out.contains("function u0:"), "{out}");
}

#[test]
fn check_of_a_missing_file_or_directory_is_e0709() {
    let (code, _, err) = cli(&["check", "/nonexistent/a.prim"]);
    assert_eq!(code, 1);
    assert!(err.contains("E0709") && err.contains("/nonexistent/a.prim"), "{err}");
    let (code, _, err) = cli(&["check", "/nonexistent/a.prim", "--prims", "/nonexistent/dir"]);
    assert_eq!(code, 1);
    assert!(err.contains("/nonexistent/dir"), "{err}");
}

#[test]
fn usage_errors_exit_2_from_the_binary() {
    let status = std::process::Command::new(env!("CARGO_BIN_EXE_primflow"))
        .args(["render", "scene.scene"])
        .output()
        .unwrap();
    assert_eq!(status.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&status.stderr).contains("--output"));
    let status = std::process::Command::new(env!("CARGO_BIN_EXE_primflow"))
        .args(["render", "/nonexistent.scene", "-o", "x.png", "--threads", "lots"])
        .output()
        .unwrap();
    assert_eq!(status.status.code(), Some(2));
}

#[test]
fn key_specs_parse_into_bindings() {
    let program = Program::default();
    let key = parse_key("linear:3, perspective_linear:1,constant:2,bumpy:4", &program).unwrap();
    assert_eq!(
        key.bindings,
        vec![
            Binding {
                kind: BindingKind::Kind("linear".into()),
                components: 3
            },
            Binding {
                kind: BindingKind::Kind("perspective_linear".into()),
                components: 1
            },
            Binding {
                kind: BindingKind::Constant,
                components: 2
            },
            Binding {
                kind: BindingKind::Kind("bumpy".into()),
                components: 4
            },
        ]
    );
    assert!(parse_key("linear", &program).unwrap_err().contains("KIND:COMPONENTS"));
    assert!(parse_key("linear:0", &program).is_err());
    assert!(parse_key("lin ear:1", &program).is_err());
    assert_eq!(parse_key("", &program).unwrap().bindings, vec![]);
}

#[test]
fn render_writes_the_image_depth_and_parameter_and_prints_a_summary() {
    let dir = std::env::temp_dir().join(format!("primflow-cli-render-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (img, depth, cs) = (dir.join("t.png"), dir.join("d.png"), dir.join("cs.png"));
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/examples/triangles.scene");
    let (code, out, err) = cli(&[
        "render",
        scene,
        "-o",
        img.to_str().unwrap(),
        "--depth",
        depth.to_str().unwrap(),
        "--param",
        "Cs",
        cs.to_str().unwrap(),
        "--threads",
        "2",
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(
        out.starts_with("rendered 320x240: 4 primitive(s), 2 kernel(s) compiled"),
        "{out}"
    );
    let rgb = image::open(&img).unwrap().to_rgb8();
    assert_eq!(rgb.dimensions(), (320, 240));
    assert_eq!(rgb.get_pixel(2, 2).0, [26, 26, 31], "background 0.1 0.1 0.12");
    let depth = image::open(&depth).unwrap().to_luma16();
    assert!(
        depth.get_pixel(250, 110).0[0] > depth.get_pixel(100, 40).0[0],
        "0.6 is nearer than 0.2"
    );
    assert_eq!(
        image::open(&cs).unwrap().to_rgb8().get_pixel(300, 232).0,
        [204, 77, 230]
    );

    let (code, _, err) = cli(&[
        "render",
        scene,
        "-o",
        img.to_str().unwrap(),
        "--param",
        "nosuch",
        "x.png",
    ]);
    assert_eq!(code, 1);
    assert!(err.contains("no shading parameter `nosuch`"), "{err}");
}

#[test]
fn check_of_a_library_file_loads_it_once_and_emits_clif_per_primitive() {
    let prim = concat!(env!("CARGO_MANIFEST_DIR"), "/prims/screen_triangle.prim");
    let (code, out, err) = cli(&["check", prim, "--emit", "clif", "--key", "linear:3,constant:1"]);
    assert_eq!(code, 0, "{err}");
    let mut lines = out.lines();
    assert!(lines.next().unwrap().contains("4 pixels per group"), "{out}");
    assert_eq!(
        lines.next(),
        Some("; primitive screen_triangle key linear:3,constant:1")
    );
    assert!(out.contains("function "), "{out}");
    let (code, out, _) = cli(&["check", prim, "--emit", "ir"]);
    assert_eq!(code, 0);
    assert!(out.contains("primitive screen_triangle"), "{out}");
}

/// The binary turns transparent huge pages off for its process before anything else
/// (`disable_transparent_huge_pages`, src/main.rs): the kernel then reports them disabled
/// for the process, which is what keeps a first compile from zeroing 2 MiB pages.
#[test]
#[cfg(target_os = "linux")]
fn transparent_huge_pages_are_off_for_the_process() {
    let status = || std::fs::read_to_string("/proc/self/status").unwrap();
    let thp = |s: String| {
        s.lines()
            .find(|l| l.starts_with("THP_enabled:"))
            .map(|l| l.split_whitespace().nth(1).unwrap_or("").to_string())
    };
    // Kernels before 5.0 do not report it; the call must still succeed.
    assert!(primflow::cli::disable_transparent_huge_pages());
    if let Some(enabled) = thp(status()) {
        assert_eq!(enabled, "0", "{}", status());
    }
}

#[test]
fn a_prims_line_naming_a_missing_directory_is_e0709_at_that_line() {
    let scene = temp_file(
        "prims_missing.scene",
        "image 8 8\nprims no_such_directory_here\nbegin screen_triangle\nrast_param screen_vertex 0 0 0.5 1  8 0 0.5 1  0 8 0.5 1\nend\n",
    );
    let out = scene.with_extension("png");
    let (code, _, err) = cli(&["render", scene.to_str().unwrap(), "-o", out.to_str().unwrap()]);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("E0709") && err.contains("no_such_directory_here"), "{err}");
    assert!(
        err.contains("prims_missing.scene:2:7"),
        "located at the directory: {err}"
    );
    assert!(!out.exists(), "nothing rendered");
}

#[test]
fn a_scene_past_the_size_limit_is_refused_before_it_is_read() {
    // A sparse file: its length is past the limit, its blocks are never written or read.
    let path = temp_file("huge.scene", "");
    std::fs::File::options()
        .write(true)
        .open(&path)
        .unwrap()
        .set_len(primflow::scene::MAX_SCENE_BYTES + 1)
        .unwrap();
    let out = path.with_extension("png");
    let (code, _, err) = cli(&["render", path.to_str().unwrap(), "-o", out.to_str().unwrap()]);
    std::fs::remove_file(&path).unwrap();
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("E0606") && err.contains("huge.scene"), "{err}");
    assert!(!out.exists(), "nothing rendered");
}

/// The numbers of a `check` summary line, in order: files, primitives, interpolators,
/// helpers, shaders.
fn summary_counts(err: &str) -> Vec<usize> {
    let line = err.lines().last().unwrap_or_default();
    assert!(line.starts_with("ok: ") && line.contains(" checked ("), "{err}");
    line.split(|c: char| !c.is_ascii_digit())
        .filter_map(|w| w.parse().ok())
        .take(5)
        .collect()
}

#[test]
fn check_prints_a_summary_of_what_it_checked() {
    let library_file = concat!(env!("CARGO_MANIFEST_DIR"), "/prims/screen_triangle.prim");
    let (code, out, err) = cli(&["check", library_file]);
    assert_eq!(code, 0, "{err}");
    assert!(out.is_empty(), "the summary goes to stderr: {out}");
    assert!(err.ends_with(" checked (no warnings)\n"), "{err}");
    let library = summary_counts(&err);
    // One more file: one primitive, two helpers, and a warning (W0001, Z not inout).
    let prim = temp_file(
        "summary.prim",
        "float h1(float x) { return x; }\nfloat h2(float x) { return x; }\n\
         primitive summed(varying float X, Y; varying float Z) { bound(0, 0, 1, 1); Z = h1(h2(0.5)); }\n",
    );
    let (code, _, err) = cli(&["check", prim.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    assert!(
        err.contains("W0001") && err.ends_with(" checked (1 warning)\n"),
        "{err}"
    );
    let with_file = summary_counts(&err);
    let added: Vec<usize> = with_file.iter().zip(&library).map(|(a, b)| a - b).collect();
    assert_eq!(
        added,
        [1, 1, 0, 2, 0],
        "files, primitives, interpolators, helpers, shaders: {err}"
    );
}

/// A directory of primitives named twice, spelled differently (with `./`, `..`, a trailing
/// slash; by `--prims` and by a scene's `prims` line), is loaded once.
#[test]
fn one_directory_given_twice_is_loaded_once() {
    let dir = std::env::temp_dir().join(format!("primflow-cli-twice-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let prim = dir.join("twice.prim");
    std::fs::write(
        &prim,
        "primitive twice_fill(varying float X, Y; inout varying float Z) { Z = 0.5; }\n",
    )
    .unwrap();
    let name = dir.file_name().unwrap().to_str().unwrap();
    let spellings = [
        dir.display().to_string(),
        format!("{}/./", dir.display()),
        format!("{}/../{name}", dir.display()),
    ];
    let (code, _, err) = cli(&[
        "check",
        "--prims",
        &spellings[0],
        "--prims",
        &spellings[1],
        "--prims",
        &spellings[2],
        prim.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(!err.contains("defined twice"), "{err}");

    let scene = dir.join("twice.scene");
    std::fs::write(&scene, "image 8 8\nprims .\nbegin twice_fill\nend\n").unwrap();
    let png = dir.join("twice.png");
    let (code, out, err) = cli(&[
        "render",
        scene.to_str().unwrap(),
        "-o",
        png.to_str().unwrap(),
        "--prims",
        &spellings[1],
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(!err.contains("defined twice"), "{err}");
    assert!(out.starts_with("rendered 8x8: 1 primitive(s)"), "{out}");
}

/// The binary run from a directory of its own, as an installed one is: the library is
/// embedded (the example scene's triangles render), and `PRIMFLOW_PRIMS` adds a directory
/// whose primitive a scene draws.
#[test]
fn the_binary_renders_from_any_directory_and_reads_primflow_prims() {
    let dir = std::env::temp_dir().join(format!("primflow-installed-{}", std::process::id()));
    let prims = dir.join("my-prims");
    std::fs::create_dir_all(&prims).unwrap();
    std::fs::write(
        prims.join("halfplane.prim"),
        "primitive halfplane(float depth; varying float X, Y; inout varying fixed<32,32> Z) {\n\
         \x20   if (X > 8) return;\n    Z = depth;\n    interpolator_return;\n}\n",
    )
    .unwrap();
    std::fs::write(
        dir.join("mine.scene"),
        "image 16 4\nmaterial_interp Cs constant\nmaterial Cs 1 0 0\nbegin halfplane\nrast_param depth 0.5\nend\n",
    )
    .unwrap();
    let triangles = concat!(env!("CARGO_MANIFEST_DIR"), "/examples/triangles.scene");
    let run = |args: &[&str], env: Option<&Path>| {
        let mut cmd = std::process::Command::new(env!("CARGO_BIN_EXE_primflow"));
        cmd.args(args).current_dir(&dir).env_remove("PRIMFLOW_PRIMS");
        if let Some(p) = env {
            cmd.env("PRIMFLOW_PRIMS", p);
        }
        cmd.output().unwrap()
    };
    let out = run(&["render", triangles, "-o", "t.png"], None);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let out = run(&["render", "mine.scene", "-o", "m.png"], None);
    assert_eq!(out.status.code(), Some(1), "halfplane is not in the library");
    let out = run(&["render", "mine.scene", "-o", "m.png"], Some(&prims));
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let image = image::open(dir.join("m.png")).unwrap().to_rgb8();
    let red: Vec<bool> = (0..16).map(|x| image.get_pixel(x, 1).0 == [255, 0, 0]).collect();
    assert_eq!(red, (0..16).map(|x| x < 8).collect::<Vec<_>>());
    std::fs::remove_dir_all(&dir).unwrap();
}
