//! `primflow render --explain` on examples/geometry.scene: the pipelines taken, the kernel
//! variants compiled (with and without clipping code), the shading effects and the render
//! threads are listed.

#[test]
fn explain_lists_pipelines_variants_and_effects() {
    let dir = std::env::temp_dir().join(format!("primflow-explain-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let png = dir.join("geometry.png");
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/examples/geometry.scene");
    let (mut out, mut err) = (vec![], vec![]);
    let code = primflow::cli::run(
        ["primflow", "render", scene, "-o", png.to_str().unwrap(), "--explain"],
        &mut out,
        &mut err,
    );
    let out = String::from_utf8(out).unwrap();
    let err = String::from_utf8(err).unwrap();
    assert_eq!(code, 0, "{err}");
    assert!(
        out.contains("polygon x1: trivially accepted; LC facet")
            || out.contains("polygon x1: trivially accepted; CC facet"),
        "{out}"
    );
    assert!(out.contains("lit in lighting coordinates"), "{out}");
    assert!(out.contains("triangle x2: clipped by the runtime"), "{out}");
    assert!(out.contains("model clipping on"), "{out}");
    assert!(out.contains("trivially accepted: no clipping code"), "{out}");
    assert!(out.contains("with clipping code"), "{out}");
    assert!(
        out.contains("shading effects: Phong lighting, fog, checker texture (lights: 2, lit in lighting coordinates)"),
        "{out}"
    );
    // The render threads and where they run (the default: one per CPU, pinned when 2+).
    let threads = primflow::runtime::render_pool(0).unwrap().current_num_threads();
    let pinned = primflow::runtime::pool::pinning_plan(threads);
    let line = match &pinned {
        Some(cpus) => format!("render threads: {threads}, pinned to CPUs {cpus:?}"),
        None => format!("render threads: {threads}, not pinned"),
    };
    assert!(out.contains(&line), "{line} in {out}");
    let img = image::open(&png).unwrap().to_rgb8();
    assert_eq!(img.dimensions(), (160, 120));
    std::fs::remove_dir_all(&dir).unwrap();
}
