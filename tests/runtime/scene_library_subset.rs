//! A scene compiles only the library files its names lead to (`Registry::load_for`, what
//! `primflow render` uses): every example scene and every prims/tests scene renders the
//! same frame, bit for bit, as with the whole library, from fewer files where it can.

use crate::support;

use primflow::diag::{Diagnostics, SourceMap};
use primflow::jit::{Jit, Tier};
use primflow::runtime::{Frame, Registry, Renderer};

/// `path` rendered (tier 0, two threads) with the program `subset` or the whole library;
/// the frame and how many files were compiled.
fn render(path: &str, subset: bool) -> (Frame, usize) {
    let mut sources = SourceMap::new();
    let mut diags = Diagnostics::new();
    let file = sources.load(std::path::Path::new(path)).unwrap();
    let scene = primflow::scene::parse(&sources, file, &mut diags);
    let dirs = scene.prim_dirs(std::path::Path::new(path).parent().unwrap());
    let (prims, kinds) = scene.library_names();
    let registry = if subset {
        Registry::load_for(&mut sources, &dirs, &prims, &kinds, &mut diags)
    } else {
        Registry::load(&mut sources, &dirs, &[], &mut diags)
    }
    .unwrap_or_else(|| panic!("{path}: {}", diags.render(&sources)));
    let mut r = Renderer::new(registry.program.clone());
    primflow::scene::apply(&scene, &mut r, &mut diags);
    assert!(!diags.has_errors(), "{path}: {}", diags.render(&sources));
    let mut jit = Jit::at_tier(registry.program.clone(), Tier::Fast).unwrap();
    (support::render_with(&r, &mut jit, 2), registry.files.len())
}

#[test]
fn every_scene_renders_the_same_from_the_files_it_needs() {
    let root = env!("CARGO_MANIFEST_DIR");
    let mut paths: Vec<String> = ["examples", "prims/tests"]
        .iter()
        .flat_map(|d| std::fs::read_dir(format!("{root}/{d}")).unwrap())
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "scene"))
        .map(|p| p.to_string_lossy().into_owned())
        .collect();
    paths.sort();
    assert!(paths.len() >= 10, "{paths:?}");
    let mut fewer = 0;
    for path in &paths {
        let (whole, all_files) = render(path, false);
        let (picked, files) = render(path, true);
        assert_eq!(picked.depth_values(), whole.depth_values(), "{path}: depth");
        let bits = |f: &Frame| -> Vec<Vec<u32>> {
            f.all_plane_values()
                .iter()
                .map(|p| p.iter().map(|v| v.to_bits()).collect())
                .collect()
        };
        assert_eq!(bits(&picked), bits(&whole), "{path}: planes");
        assert!(files <= all_files, "{path}");
        fewer += usize::from(files < all_files);
    }
    // Every scene uses only part of the library (none uses both spheres and NURBs).
    assert_eq!(fewer, paths.len(), "{fewer} of {}", paths.len());
}
