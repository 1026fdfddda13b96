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
    /// checking `prims/polygon.prim` does not define `polygon` twice). A directory is loaded
    /// once however often and however spelled it is given (`prims`, `./prims/`, an absolute
    /// path, a symbolic link: compared canonicalised), so `--prims DIR` and a scene's own
    /// `prims DIR` line for the same directory do not define its items twice. A missing
    /// built-in directory is not an error (a binary installed without it simply has no
    /// library).
    pub fn load_sources(
        sources: &mut SourceMap,
        dirs: &[PathBuf],
        files: &[PathBuf],
        diags: &mut Diagnostics,
    ) -> (Vec<FileId>, Vec<FileId>) {
        let mut loaded = vec![];
        let builtin = Registry::builtin_dir();
        let builtin = builtin.is_dir().then_some(builtin);
        // A directory that cannot be canonicalised (a missing one) is kept as written, for
        // `load_dir` to report.
        let mut seen: Vec<PathBuf> = vec![];
        for dir in builtin.iter().chain(dirs) {
            let canonical = std::fs::canonicalize(dir).unwrap_or_else(|_| dir.clone());
            if !seen.contains(&canonical) {
                seen.push(canonical);
                load_dir(sources, dir, &mut loaded, diags);
            }
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
#[doc(hidden)]
pub struct FileItems {
    pub defines: Vec<String>,
    pub uses: Vec<String>,
}

/// Walks the AST with explicit stacks, so a deeply nested file cannot overflow this one.
#[doc(hidden)]
pub fn file_items(module: &ast::Module) -> FileItems {
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
