//! The primitive registry: every `*.prim` file of the built-in library (`prims/` of the
//! crate) and of the user's directories, compiled together as one program.
//!
//! Files are loaded directory by directory in the order given, each directory's files sorted
//! by name, so diagnostics and function ids are the same on every machine. The source files
//! go into the caller's [`SourceMap`] so that compile errors, and later kernel run-time
//! errors (which point into `Program::sites`), can be rendered against them.

use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};
use std::sync::Arc;

use crate::diag::{Diagnostic, Diagnostics, FileId, SourceMap};
use crate::ir::Program;
use crate::syntax::ast;

/// The compiled primitives, shared interpolators and the files they came from.
#[derive(Clone, Debug)]
pub struct Registry {
    pub program: Arc<Program>,
    /// The `.prim` files compiled, in load order.
    pub files: Vec<FileId>,
}

impl Registry {
    /// The crate's own primitive library.
    pub fn builtin_dir() -> PathBuf {
        PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/prims"))
    }

    /// Load the built-in library, then every directory of `dirs`, plus the single `files`
    /// (for `primflow check a.prim b.prim`), and compile them as one program. Unreadable
    /// directories or files and compile errors go to `diags`; `None` if there were errors.
    pub fn load(
        sources: &mut SourceMap,
        dirs: &[PathBuf],
        files: &[PathBuf],
        diags: &mut Diagnostics,
    ) -> Option<Registry> {
        let (loaded, _) = Registry::load_sources(sources, dirs, files, diags);
        if diags.has_errors() {
            return None;
        }
        Registry::compile(sources, loaded, diags)
    }

    /// Load the sources without compiling: all loaded files in order, and the ids of the
    /// single `files` (a file that is also in a library directory is loaded once, so
    /// checking `prims/polygon.prim` does not define `polygon` twice). A missing built-in
    /// directory is not an error (a binary installed without it simply has no library).
    pub fn load_sources(
        sources: &mut SourceMap,
        dirs: &[PathBuf],
        files: &[PathBuf],
        diags: &mut Diagnostics,
    ) -> (Vec<FileId>, Vec<FileId>) {
        let mut loaded = vec![];
        let builtin = Registry::builtin_dir();
        if builtin.is_dir() {
            load_dir(sources, &builtin, &mut loaded, diags);
        }
        for dir in dirs {
            load_dir(sources, dir, &mut loaded, diags);
        }
        let mut given = vec![];
        for file in files {
            let canonical = std::fs::canonicalize(file).ok();
            let already = loaded.iter().copied().find(|&id| {
                let path = sources.file(id).path.as_deref();
                canonical.is_some() && path.and_then(|p| std::fs::canonicalize(p).ok()) == canonical
            });
            match already {
                Some(id) => given.push(id),
                None => {
                    let before = loaded.len();
                    load_file(sources, file, &mut loaded, diags);
                    given.extend(loaded[before..].iter().copied());
                }
            }
        }
        (loaded, given)
    }

    /// [`Registry::load`] for a scene that names the primitives `prims` and the interpolation
    /// kinds `kinds`: it compiles only the files that define a name the scene needs and,
    /// through their calls, the files those need, as a renderer only ever asks for what the
    /// scene names (checking nurb_surface.prim costs more than the rest of a small scene).
    /// Every file is parsed, and its AST says what it defines and calls. Diagnostics come
    /// from the files checked; when in doubt (a named primitive no file defines, errors in
    /// the files picked) the whole library is checked, so a scene never sees an error
    /// `load` would not give it.
    pub fn load_for(
        sources: &mut SourceMap,
        dirs: &[PathBuf],
        prims: &[&str],
        kinds: &[&str],
        diags: &mut Diagnostics,
    ) -> Option<Registry> {
        let (loaded, _) = Registry::load_sources(sources, dirs, &[], diags);
        if diags.has_errors() {
            return None;
        }
        // Each file is parsed once: its AST says what it defines and calls, and the check
        // of the files picked (or of all of them) reads the same ASTs.
        let parsed: Vec<Parsed> = loaded
            .iter()
            .map(|&file| {
                let mut diags = Diagnostics::new();
                let module = crate::syntax::parse(file, sources.text(file), &mut diags);
                Parsed { file, module, diags }
            })
            .collect();
        if let Some(picked) = files_for(&parsed, prims, kinds) {
            if picked.len() < parsed.len() {
                let mut picked_diags = Diagnostics::new();
                let picked: Vec<&Parsed> = picked.into_iter().map(|k| &parsed[k]).collect();
                if let Some(registry) = check_parsed(&picked, &mut picked_diags) {
                    if !picked_diags.has_errors() {
                        diags.extend(picked_diags);
                        return Some(registry);
                    }
                }
            }
        }
        check_parsed(&parsed.iter().collect::<Vec<_>>(), diags)
    }

    /// Compile already loaded files as one program.
    pub fn compile(sources: &SourceMap, files: Vec<FileId>, diags: &mut Diagnostics) -> Option<Registry> {
        let program = if files.is_empty() {
            Program::default()
        } else {
            crate::compile(sources, &files, diags)?
        };
        Some(Registry {
            program: Arc::new(program),
            files,
        })
    }
}

fn load_dir(sources: &mut SourceMap, dir: &Path, loaded: &mut Vec<FileId>, diags: &mut Diagnostics) {
    let entries = match std::fs::read_dir(dir) {
        Ok(entries) => entries,
        Err(e) => {
            diags.push(Diagnostic::error(
                "E0709",
                format!("cannot read primitive directory `{}`: {e}", dir.display()),
            ));
            return;
        }
    };
    let mut paths: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "prim") && p.is_file())
        .collect();
    paths.sort();
    for path in paths {
        load_file(sources, &path, loaded, diags);
    }
}

fn load_file(sources: &mut SourceMap, path: &Path, loaded: &mut Vec<FileId>, diags: &mut Diagnostics) {
    match sources.load(path) {
        Ok(id) => loaded.push(id),
        Err(e) => diags.push(Diagnostic::error(
            "E0709",
            format!("cannot read primitive file `{}`: {e}", path.display()),
        )),
    }
}

/// A loaded file's parse: its AST and its syntax diagnostics.
struct Parsed {
    file: FileId,
    module: ast::Module,
    diags: Diagnostics,
}

/// Check parsed files as one program, as [`crate::compile`] checks the files it parses.
fn check_parsed(parsed: &[&Parsed], diags: &mut Diagnostics) -> Option<Registry> {
    for p in parsed {
        diags.extend(p.diags.clone());
    }
    if diags.has_errors() {
        return None;
    }
    let modules: Vec<&ast::Module> = parsed.iter().map(|p| &p.module).collect();
    let program = crate::check::check(&modules, diags);
    if diags.has_errors() {
        return None;
    }
    Some(Registry {
        program: Arc::new(program),
        files: parsed.iter().map(|p| p.file).collect(),
    })
}

/// Of `parsed` (in order), the indices of those defining a name of `prims` or `kinds`, and
/// of the files those call into, transitively; `None` when a name of `prims` is defined
/// nowhere (see [`Registry::load_for`]).
fn files_for(parsed: &[Parsed], prims: &[&str], kinds: &[&str]) -> Option<Vec<usize>> {
    let items: Vec<FileItems> = parsed.iter().map(|p| file_items(&p.module)).collect();
    // Name -> the files defining it.
    let mut definers: HashMap<&str, Vec<usize>> = HashMap::new();
    for (k, i) in items.iter().enumerate() {
        for name in &i.defines {
            definers.entry(name).or_default().push(k);
        }
    }
    if prims.iter().any(|p| !definers.contains_key(p)) {
        return None;
    }
    // A file with syntax errors counts by the items its parse recovered: one the scene
    // needs is picked and its errors then send `load_for` to the whole library; one it
    // does not need stays out, as a renderer only asks for what its scene names.
    let mut picked = vec![false; parsed.len()];
    let mut wanted: Vec<&str> = prims.iter().chain(kinds).copied().collect();
    let mut seen = HashSet::new();
    while let Some(name) = wanted.pop() {
        if !seen.insert(name) {
            continue;
        }
        for &k in definers.get(name).into_iter().flatten() {
            if !picked[k] {
                picked[k] = true;
                wanted.extend(items[k].uses.iter().map(String::as_str));
            }
        }
    }
    Some(picked.iter().enumerate().filter(|(_, &p)| p).map(|(k, _)| k).collect())
}

/// What a file defines (its items' names) and calls (every callee name in its items'
/// bodies and parameter defaults, built-ins included: they have no definer).
struct FileItems {
    defines: Vec<String>,
    uses: Vec<String>,
}

/// Walks the AST with explicit stacks, so a deeply nested file cannot overflow this one.
fn file_items(module: &ast::Module) -> FileItems {
    let defines = module.items.iter().map(|i| i.name.name.clone()).collect();
    let mut uses = vec![];
    let mut stmts: Vec<&ast::Stmt> = vec![];
    let mut exprs: Vec<&ast::Expr> = vec![];
    for item in &module.items {
        stmts.extend(item.body.stmts.iter().rev());
        for param in &item.params {
            exprs.extend(&param.default);
            for dim in &param.dims {
                if let ast::ArrayDim::Sized(e) = dim {
                    exprs.push(e);
                }
            }
        }
    }
    loop {
        if let Some(e) = exprs.pop() {
            if let ast::ExprKind::Call { callee, .. } = &e.kind {
                uses.push(callee.name.clone());
            }
            e.for_each_child(|c| exprs.push(c));
        } else if let Some(s) = stmts.pop() {
            s.for_each_child(|c| stmts.push(c), |e| exprs.push(e));
        } else {
            break;
        }
    }
    FileItems { defines, uses }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unreadable_directory_is_an_error_not_a_panic() {
        let mut sources = SourceMap::new();
        let mut diags = Diagnostics::new();
        let missing = PathBuf::from("/nonexistent/primflow/prims");
        // Only the user directory is checked here; the built-in dir may or may not exist.
        load_dir(&mut sources, &missing, &mut vec![], &mut diags);
        assert_eq!(diags.codes_at(&sources), vec!["E0709"]);
    }

    #[test]
    fn a_file_defines_its_items_and_uses_every_callee() {
        let text = "float f(float a = g(1)) { return h(a); }\n\
                    primitive p(varying float X, Y) { if (X > 0) { float x = f(k(X)); } }\n// q(\n";
        let mut diags = Diagnostics::new();
        let items = file_items(&crate::syntax::parse(0, text, &mut diags));
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
        let mut loaded = vec![];
        let mut diags = Diagnostics::new();
        load_dir(&mut sources, &dir, &mut loaded, &mut diags);
        let names: Vec<_> = loaded
            .iter()
            .map(|&f| Path::new(&sources.file(f).name).file_name().unwrap().to_owned())
            .collect();
        assert_eq!(names, vec!["a.prim", "b.prim"]);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
