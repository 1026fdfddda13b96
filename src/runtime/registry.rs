//! The primitive registry: every `*.prim` file of the built-in library (`prims/` of the
//! crate) and of the user's directories, compiled together as one program.
//!
//! Files are loaded directory by directory in the order given, each directory's files sorted
//! by name, so diagnostics and function ids are the same on every machine. The source files
//! go into the caller's [`SourceMap`] so that compile errors, and later kernel run-time
//! errors (which point into `Program::sites`), can be rendered against them.

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
