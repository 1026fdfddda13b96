//! `primflow bench --scene`: a user's own scene measured as the built-in workloads are. The
//! report's counts are the scene's real ones (pixels written as a counting render of the
//! scene gives them, draws after expansion, every kernel variant), the hand-written kernels
//! are timed exactly where they can draw the scene (and their frames were checked against
//! the JIT's), a primitive from a user directory gets the JIT's rows alone, and a broken
//! scene is refused with its diagnostics. Outcomes only: nothing here asserts a timing.

use crate::support;

use std::path::{Path, PathBuf};

use primflow::bench::{format_scene_report, run_scene, KernelKind, SceneBenchOptions};
use primflow::diag::{Diagnostics, SourceMap};
use primflow::handwritten::Flavor;
use primflow::jit::Jit;
use support::cli;

fn temp_dir(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("primflow-bench-scene-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Pixels written (depth writes) by one counting render of the scene file, as
/// `primflow render --count-writes` would count them.
fn depth_writes(scene: &Path, dirs: &[PathBuf]) -> u64 {
    let mut sources = SourceMap::new();
    let mut diags = Diagnostics::new();
    let file = sources.load(scene).unwrap();
    let base = scene.parent().unwrap();
    let mut r = primflow::scene::load_for_render(&mut sources, file, base, dirs, &mut diags)
        .unwrap_or_else(|| panic!("{}", diags.render(&sources)));
    r.options.count_writes = true;
    let mut jit = Jit::new(r.program().clone()).unwrap();
    let out = r.render(&mut jit);
    assert!(!out.diags.has_errors(), "{:?}", out.diags.items);
    out.frame
        .write_count_values()
        .unwrap()
        .iter()
        .map(|&c| u64::from(c))
        .sum()
}

fn options(scene: &Path, prims: &[PathBuf]) -> SceneBenchOptions {
    SceneBenchOptions {
        scene: scene.to_path_buf(),
        prims: prims.to_vec(),
        runs: 1,
        progress: false,
    }
}

#[test]
fn the_spheres_example_is_measured_with_every_hand_written_form() {
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/spheres.scene");
    let report = run_scene(&options(&scene, &[])).unwrap();
    let w = &report.frames;
    assert_eq!((report.width, report.height), (320, 240));
    // Five spheres, drawn as themselves: five draws, one variant.
    assert_eq!(w.primitives, 5);
    assert_eq!(w.draws, 5);
    assert_eq!(report.compile.len(), 1, "{:?}", report.compile);
    assert!(report.compile[0].variant.starts_with("sphere "), "{:?}", report.compile);
    assert!(report.compile[0].clif_insts > 0 && report.compile[0].tier1_cpu_micros > 0);
    assert_eq!(w.pixels_written, depth_writes(&scene, &[]));
    assert!(w.pixels_written > 10_000, "{}", w.pixels_written);
    // The sphere has scalar, SSE and AVX2 kernels for its implicit normal: all timed.
    assert!(
        report.handwritten_skipped.is_empty(),
        "{:?}",
        report.handwritten_skipped
    );
    for kind in [
        KernelKind::Jit,
        KernelKind::JitTier0,
        KernelKind::Handwritten(Flavor::Scalar),
        KernelKind::Handwritten(Flavor::Sse),
        KernelKind::Handwritten(Flavor::Avx2),
    ] {
        let t = w.timing(kind, 1).unwrap_or_else(|| panic!("no {kind:?} row"));
        assert!(t.median_ms > 0.0 && t.tiles_ms <= t.median_ms, "{t:?}");
        assert_eq!(t.mpixels_per_s, w.pixels_written as f64 / t.median_ms / 1e3);
    }
    assert!(w.timing(KernelKind::Jit, report.machine.threads).is_some());
    // Spheres call nothing: no per-tile row.
    assert!(w.timing(KernelKind::JitSetupPerTile, 1).is_none());
    assert!(w.expand_speedup.is_none());
    let f = &report.first_frame;
    assert!(f.load_ms > 0.0 && f.compile_ms > 0.0, "{f:?}");
    assert!(f.load_ms + f.compile_ms + f.render_ms <= f.ms + 1e-9, "{f:?}");
    assert!(f.setup_ms + f.tiles_ms + f.shade_ms <= f.render_ms + 1e-9, "{f:?}");
    let text = format_scene_report(&report);
    assert!(text.contains("5 primitives, 5 draws after expansion"), "{text}");
    assert!(text.contains("JIT tier 0") && text.contains("JIT/tier 0"), "{text}");
    assert!(!text.contains("not timed"), "{text}");
}

#[test]
fn a_nurb_scene_counts_its_draws_after_expansion_and_times_the_per_tile_path() {
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/nurb_surface.scene");
    let report = run_scene(&options(&scene, &[])).unwrap();
    let w = &report.frames;
    assert_eq!(w.primitives, 2);
    // Two patches tessellated into thousands of triangles.
    assert!(w.draws > 1000, "{}", w.draws);
    assert_eq!(w.pixels_written, depth_writes(&scene, &[]));
    assert!(w.timing(KernelKind::JitSetupPerTile, 1).is_some());
    assert!(w.expand_speedup.is_some());
    // NURB has scalar and AVX2 forms only; the SSE one is skipped with the reason.
    assert!(w.timing(KernelKind::Handwritten(Flavor::Scalar), 1).is_some());
    assert!(w.timing(KernelKind::Handwritten(Flavor::Avx2), 1).is_some());
    assert!(w.timing(KernelKind::Handwritten(Flavor::Sse), 1).is_none());
    assert_eq!(report.handwritten_skipped.len(), 1, "{:?}", report.handwritten_skipped);
    assert!(report.handwritten_skipped[0].1.contains("nurb_surface"));
    // The expansion is the setup part of every expanded frame.
    assert!(w.timing(KernelKind::Jit, 1).unwrap().setup_ms > 0.0);
}

/// A primitive of the user's own (a disc of radius 8 at the pixel centre given), from a
/// `--prims` directory, and another from the scene's own `prims` line.
const DISC: &str = "primitive disc(float cx = 16, cy = 16; varying float X, Y; inout varying fixed<32,32> Z)
{
    bound(cx - 8, cy - 8, cx + 8, cy + 8);
    float dx = X - cx, dy = Y - cy;
    if (dx * dx + dy * dy > 64)
        return;
    Z = 0.5;
}
";

#[test]
fn a_user_primitive_gets_the_jit_rows_and_the_hand_written_forms_say_why_not() {
    let dir = temp_dir("user");
    let prims = dir.join("prims");
    std::fs::create_dir_all(&prims).unwrap();
    std::fs::write(prims.join("disc.prim"), DISC).unwrap();
    let own = dir.join("own");
    std::fs::create_dir_all(&own).unwrap();
    std::fs::write(
        own.join("ring.prim"),
        DISC.replace("disc", "ring").replace("> 64", "< 16"),
    )
    .unwrap();
    let scene = dir.join("discs.scene");
    std::fs::write(
        &scene,
        "image 32 32\nprims own\nbegin disc\nend\nbegin ring\nrast_param cx 10\nend\n",
    )
    .unwrap();
    let report = run_scene(&options(&scene, std::slice::from_ref(&prims))).unwrap();
    let w = &report.frames;
    assert_eq!(report.compile.len(), 2, "{:?}", report.compile);
    assert_eq!(w.pixels_written, depth_writes(&scene, &[prims]));
    // The disc covers the pixel centres within 8 of (16, 16); the ring those within 8 of
    // (10, 16) but not within 4: both at depth 0.5, so the ring's later writes fail the
    // depth test where the disc was first.
    assert!(w.pixels_written > 150, "{}", w.pixels_written);
    assert!(w.timing(KernelKind::Jit, 1).is_some() && w.timing(KernelKind::JitTier0, 1).is_some());
    assert!(w.jit_vs_scalar.is_none() && w.jit_vs_sse.is_none() && w.jit_vs_simd.is_none());
    assert_eq!(report.handwritten_skipped.len(), 3, "{:?}", report.handwritten_skipped);
    for (_, why) in &report.handwritten_skipped {
        assert!(why.contains("disc"), "{why}");
    }
}

#[test]
fn the_cli_prints_the_report_and_writes_json() {
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/triangles.scene");
    let json = temp_dir("json").join("report.json");
    let (code, out, err) = cli(&[
        "bench",
        "--scene",
        scene.to_str().unwrap(),
        "--runs",
        "1",
        "--json",
        json.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("first frame, as `primflow render`"), "{out}");
    assert!(out.contains("JIT compile time per variant"), "{out}");
    // A build with debug assertions (`cargo test`'s) says its times are not a release's.
    assert_eq!(
        err.contains("note: this build has debug assertions"),
        cfg!(debug_assertions),
        "{err}"
    );
    let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(
        report["frames"]["pixels_written"].as_u64(),
        Some(depth_writes(&scene, &[]))
    );
    let kinds: Vec<&serde_json::Value> = report["frames"]["timings"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| &t["kind"])
        .collect();
    assert!(kinds.contains(&&serde_json::json!("JitTier0")), "{kinds:?}");
}

#[test]
fn a_broken_scene_is_refused_with_its_diagnostics() {
    let scene = temp_dir("broken").join("broken.scene");
    std::fs::write(&scene, "image 32 32\nbegin no_such_primitive\nend\n").unwrap();
    let (code, out, err) = cli(&["bench", "--scene", scene.to_str().unwrap(), "--runs", "1"]);
    assert_eq!(code, 1);
    assert!(out.is_empty(), "{out}");
    assert!(err.contains("broken.scene:2:7"), "{err}");
    assert!(err.contains("no_such_primitive"), "{err}");
    let (code, _, err) = cli(&["bench", "--scene", "/nonexistent/x.scene"]);
    assert_eq!(code, 1);
    assert!(err.contains("cannot read scene `/nonexistent/x.scene`"), "{err}");
}

#[test]
fn scene_mode_takes_neither_a_filter_nor_quick() {
    for extra in ["--quick", "--filter=fill"] {
        let (code, _, err) = cli(&["bench", "--scene", "x.scene", extra]);
        assert_eq!(code, 2, "{extra}: {err}");
        assert!(err.contains("cannot be used with"), "{err}");
    }
    let (code, _, err) = cli(&["bench", "--prims", "dir"]);
    assert_eq!(code, 2, "{err}");
}
