//! The primitive registry (src/runtime/registry.rs): loading directories (sorted, `.prim`
//! only, an unreadable one an error), what a file defines and calls, and `load_for`, which
//! compiles only the files a scene's names lead to unless in doubt.

use std::path::{Path, PathBuf};

use primflow::diag::{Diagnostics, SourceMap};
use primflow::runtime::registry::file_items;
use primflow::runtime::Registry;

#[test]
fn unreadable_directory_is_an_error_not_a_panic() {
    let mut sources = SourceMap::new();
    let mut diags = Diagnostics::new();
    let missing = PathBuf::from("/nonexistent/primflow/prims");
    // The built-in directory loads without a diagnostic; the user directory is the error.
    Registry::load_sources(&mut sources, &[missing], &[], &mut diags);
    assert_eq!(diags.codes_at(&sources), vec!["E0709"]);
}

#[test]
fn a_file_defines_its_items_and_uses_every_callee() {
    let text = "float f(float a = g(1)) { return h(a); }\n\
                primitive p(varying float X, Y) { if (X > 0) { float x = f(k(X)); } }\n// q(\n";
    let mut diags = Diagnostics::new();
    let items = file_items(&primflow::syntax::parse(0, text, &mut diags));
    assert!(!diags.has_errors());
    assert_eq!(items.defines, ["f", "p"]);
    let mut uses = items.uses;
    uses.sort();
    assert_eq!(uses, ["f", "g", "h", "k"]);
}

/// Loads the built-in library plus `user` (name, text) files from a fresh directory for
/// a scene naming `prims`; the file names compiled and the diagnostics' codes.
fn load_for_user(tag: &str, user: &[(&str, &str)], prims: &[&str]) -> (Vec<String>, Vec<String>) {
    let dir = std::env::temp_dir().join(format!("primflow-load-for-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for (name, text) in user {
        std::fs::write(dir.join(name), text).unwrap();
    }
    let mut sources = SourceMap::new();
    let mut diags = Diagnostics::new();
    let registry = Registry::load_for(&mut sources, std::slice::from_ref(&dir), prims, &[], &mut diags);
    std::fs::remove_dir_all(&dir).unwrap();
    let names = registry
        .map(|r| {
            r.files
                .iter()
                .map(|&f| {
                    Path::new(&sources.file(f).name)
                        .file_name()
                        .unwrap()
                        .to_string_lossy()
                        .into_owned()
                })
                .collect()
        })
        .unwrap_or_default();
    (names, diags.codes_at(&sources))
}

#[test]
fn a_scene_compiles_the_files_its_names_lead_to() {
    // screen_triangle only: nothing else of the library.
    let (files, codes) = load_for_user("tri", &[], &["screen_triangle"]);
    assert_eq!(files, ["screen_triangle.prim"], "{codes:?}");
    // nurb_surface calls polygon and screen_triangle.
    let (files, _) = load_for_user("nurb", &[], &["nurb_surface"]);
    assert_eq!(files, ["nurb_surface.prim", "polygon.prim", "screen_triangle.prim"]);
    // A user primitive calling a helper of another user file, beside a broken file it
    // does not need: compiled without it (a renderer only asks for what its scene names).
    let user = [
        (
            "mine.prim",
            "primitive mine(varying float X, Y; inout varying fixed<32,32> Z) { Z = half(); }",
        ),
        ("helpers.prim", "float half() { return 0.5; }"),
        ("broken.prim", "primitive broken(varying float X, Y) { float = ; }"),
    ];
    let (files, codes) = load_for_user("user", &user, &["mine"]);
    assert_eq!(files, ["helpers.prim", "mine.prim"], "{codes:?}");
}

#[test]
fn in_doubt_the_whole_library_compiles_with_its_diagnostics() {
    let all = Registry::load(&mut SourceMap::new(), &[], &[], &mut Diagnostics::new())
        .unwrap()
        .files
        .len();
    // A name no file defines: everything, so the scene's error is the usual one.
    let (files, codes) = load_for_user("unknown", &[], &["no_such_primitive"]);
    assert_eq!((files.len(), codes.len()), (all, 0));
    // The needed primitive follows an unbalanced brace: the file's error is reported.
    let user = [(
        "odd.prim",
        "primitive a(varying float X, Y) { {\nprimitive b(varying float X, Y) { }",
    )];
    let (files, codes) = load_for_user("odd", &user, &["b"]);
    assert!(files.is_empty() && !codes.is_empty(), "{files:?} {codes:?}");
    // The files picked do not compile: the whole library's diagnostics, as `load` gives.
    let user = [(
        "bad.prim",
        "primitive c(varying float X, Y) { float x = undefined_thing; }",
    )];
    let (files, codes) = load_for_user("bad", &user, &["c"]);
    let mut sources = SourceMap::new();
    let mut diags = Diagnostics::new();
    let dir = std::env::temp_dir().join(format!("primflow-load-for-badref-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join(user[0].0), user[0].1).unwrap();
    let full = Registry::load(&mut sources, std::slice::from_ref(&dir), &[], &mut diags);
    std::fs::remove_dir_all(&dir).unwrap();
    assert!(full.is_none() && files.is_empty());
    assert_eq!(codes, diags.codes_at(&sources));
}

#[test]
fn directory_files_load_sorted_by_name() {
    let dir = std::env::temp_dir().join(format!("primflow-registry-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for name in ["b.prim", "a.prim", "notes.txt"] {
        std::fs::write(dir.join(name), "// empty").unwrap();
    }
    let mut sources = SourceMap::new();
    let mut diags = Diagnostics::new();
    // The built-in library's files come first, then the directory's.
    let (builtin, _) = Registry::load_sources(&mut SourceMap::new(), &[], &[], &mut Diagnostics::new());
    let (loaded, _) = Registry::load_sources(&mut sources, std::slice::from_ref(&dir), &[], &mut diags);
    let names: Vec<_> = loaded[builtin.len()..]
        .iter()
        .map(|&f| Path::new(&sources.file(f).name).file_name().unwrap().to_owned())
        .collect();
    assert_eq!(names, vec!["a.prim", "b.prim"]);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The loaded files' names (as diagnostics show them), in load order.
fn loaded_names(dirs: &[PathBuf], files: &[PathBuf]) -> (Vec<String>, Vec<String>, Vec<String>) {
    let mut sources = SourceMap::new();
    let mut diags = Diagnostics::new();
    let (loaded, given) = Registry::load_sources(&mut sources, dirs, files, &mut diags);
    let name = |&f: &u32| sources.file(f).name.clone();
    (
        loaded.iter().map(name).collect(),
        given.iter().map(name).collect(),
        diags.codes_at(&sources),
    )
}

#[test]
fn the_library_is_embedded_and_named_after_its_source_files() {
    // Every prims/*.prim of the source tree, by name, with the text on disk: the binary
    // needs no prims/ directory at run time.
    let mut on_disk: Vec<(String, String)> = std::fs::read_dir(Registry::source_dir())
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "prim"))
        .map(|p| {
            let text = std::fs::read_to_string(&p).unwrap();
            (p.file_name().unwrap().to_string_lossy().into_owned(), text)
        })
        .collect();
    on_disk.sort();
    let embedded: Vec<(String, String)> = primflow::runtime::LIBRARY
        .iter()
        .map(|(n, t)| (n.to_string(), t.to_string()))
        .collect();
    assert_eq!(embedded, on_disk);
    let (names, _, codes) = loaded_names(&[], &[]);
    let expected: Vec<String> = on_disk.iter().map(|(n, _)| format!("prims/{n}")).collect();
    assert_eq!((names, codes), (expected, vec![]));
}

#[test]
fn a_user_file_named_like_a_library_file_replaces_it() {
    let dir = std::env::temp_dir().join(format!("primflow-override-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mine = "primitive sphere(varying float X, Y; inout varying fixed<32,32> Z) { Z = 0.25; }";
    std::fs::write(dir.join("sphere.prim"), mine).unwrap();
    let (names, _, codes) = loaded_names(std::slice::from_ref(&dir), &[]);
    assert!(codes.is_empty(), "{codes:?}");
    assert!(!names.contains(&"prims/sphere.prim".to_string()), "{names:?}");
    assert_eq!(names.last().unwrap(), &dir.join("sphere.prim").display().to_string());
    // It compiles as the library's replacement: `sphere` defined once, by the user's file.
    let mut sources = SourceMap::new();
    let mut diags = Diagnostics::new();
    let registry = Registry::load(&mut sources, std::slice::from_ref(&dir), &[], &mut diags).unwrap();
    let sphere = registry.program.find("sphere").unwrap();
    assert_eq!(registry.program.func(sphere).params.len(), 3);
    std::fs::remove_dir_all(&dir).unwrap();

    // A single file does the same: checking the source tree's own prims/polygon.prim
    // defines `polygon` once, from that file.
    let polygon = Registry::source_dir().join("polygon.prim");
    let (names, given, codes) = loaded_names(&[], std::slice::from_ref(&polygon));
    assert!(codes.is_empty(), "{codes:?}");
    assert_eq!(given, [polygon.display().to_string()]);
    assert_eq!(names.len(), primflow::runtime::LIBRARY.len());
}
