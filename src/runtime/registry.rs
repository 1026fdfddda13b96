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
    /// scene names. The library's nurb_surface.prim is half of its parse and check,
    /// ~2 ms of a small scene's ~11 ms process. Diagnostics come from the files compiled;
    /// when in doubt (a named primitive no file seems to define, a file whose items cannot
    /// be told apart, errors in the files picked) the whole library is compiled, so a
    /// scene never sees an error `load` would not give it.
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
        if let Some(picked) = files_for(sources, &loaded, prims, kinds) {
            if picked.len() < loaded.len() {
                let mut picked_diags = Diagnostics::new();
                if let Some(registry) = Registry::compile(sources, picked, &mut picked_diags) {
                    if !picked_diags.has_errors() {
                        diags.extend(picked_diags);
                        return Some(registry);
                    }
                }
            }
        }
        Registry::compile(sources, loaded, diags)
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

/// Of `files` (in order), those defining a name of `prims` or `kinds`, and the files those
/// call into, transitively; `None` when that cannot be told (see [`Registry::load_for`]).
fn files_for(sources: &SourceMap, files: &[FileId], prims: &[&str], kinds: &[&str]) -> Option<Vec<FileId>> {
    let items: Vec<Option<FileItems>> = files.iter().map(|&f| file_items(sources.text(f))).collect();
    // Name -> the files defining it.
    let mut definers: HashMap<&str, Vec<usize>> = HashMap::new();
    for (k, i) in items.iter().enumerate() {
        for name in i.iter().flat_map(|i| &i.defines) {
            definers.entry(name).or_default().push(k);
        }
    }
    if prims.iter().any(|p| !definers.contains_key(p)) {
        return None;
    }
    // Files whose items could not be told apart are compiled whatever they define.
    let mut picked: Vec<bool> = items.iter().map(Option::is_none).collect();
    // (Their calls cannot be told either: a name they need in another file is one the
    // scene's names lead to, or the compile of the files picked fails and all are compiled.)
    let mut wanted: Vec<&str> = prims.iter().chain(kinds).copied().collect();
    let mut seen = HashSet::new();
    while let Some(name) = wanted.pop() {
        if !seen.insert(name) {
            continue;
        }
        for &k in definers.get(name).into_iter().flatten() {
            if !picked[k] {
                picked[k] = true;
                if let Some(i) = &items[k] {
                    wanted.extend(i.uses.iter().map(String::as_str));
                }
            }
        }
    }
    Some(files.iter().zip(&picked).filter(|(_, &p)| p).map(|(&f, _)| f).collect())
}

/// What a file defines and calls, by name, as its tokens show: `name (` outside any braces
/// and parentheses starts an item (a primitive, interpolator or function), anywhere else it
/// is a call.
struct FileItems {
    defines: Vec<String>,
    uses: Vec<String>,
}

/// `None` when the tokens do not make items one can tell apart: lexical errors, or braces
/// or parentheses that do not balance (the file has errors the compile will report).
fn file_items(text: &str) -> Option<FileItems> {
    use crate::syntax::lexer::{lex, Tok};
    let mut lex_diags = Diagnostics::new();
    let mut items = FileItems {
        defines: vec![],
        uses: vec![],
    };
    let (mut braces, mut parens) = (0i64, 0i64);
    let mut name: Option<String> = None;
    for (_, tok, _) in lex(0, text, &mut lex_diags) {
        match &tok {
            Tok::LParen => {
                if let Some(n) = name.take() {
                    if braces == 0 && parens == 0 {
                        items.defines.push(n);
                    } else {
                        items.uses.push(n);
                    }
                }
                parens += 1;
            }
            Tok::RParen => parens -= 1,
            Tok::LBrace => braces += 1,
            Tok::RBrace => braces -= 1,
            _ => {}
        }
        name = match tok {
            Tok::Ident(n) => Some(n),
            _ => None,
        };
        if braces < 0 || parens < 0 {
            return None;
        }
    }
    (braces == 0 && parens == 0 && !lex_diags.has_errors()).then_some(items)
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
    fn items_are_names_called_outside_braces_and_calls_inside() {
        let text = "float f(float a = g(1)) { return h(a); }\n\
                    primitive p(varying float X, Y) { float x = f(X); }\n// q(\n";
        let items = file_items(text).unwrap();
        assert_eq!(items.defines, ["f", "p"]);
        assert_eq!(items.uses, ["g", "h", "f"]);
        // Unbalanced, or not lexable: cannot be told apart.
        assert!(file_items("primitive p() { {").is_none());
        assert!(file_items("primitive p() } {").is_none());
        assert!(file_items("primitive p() { @ }").is_none());
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
