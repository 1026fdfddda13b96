//! The frame's language shading computed again by the IR evaluator
//! (`runtime::shading::reference`, `Renderer::evaluate_shading`): at f32 it is the kernels'
//! own bits for every library surface, light and the fog atmosphere, on rows and on quads.

use primflow::diag::{Diagnostics, SourceMap};
use primflow::ir::eval::Precision;
use primflow::jit::Jit;
use primflow::runtime::{Frame, Registry, Renderer};

/// Render `text` with the library; the renderer and frame.
fn render(text: &str) -> (Renderer, Frame) {
    let mut sources = SourceMap::new();
    let mut diags = Diagnostics::new();
    let registry = Registry::load(&mut sources, &[], &[], &mut diags).expect("library compiles");
    let file = sources.add("reference.scene", text);
    let mut renderer = Renderer::new(registry.program.clone());
    primflow::scene::load_into(&sources, file, &mut renderer, &mut diags);
    assert!(!diags.has_errors(), "{}", diags.render(&sources));
    let mut jit = Jit::new(registry.program.clone()).unwrap();
    let out = renderer.render(&mut jit);
    assert!(!out.diags.has_errors(), "{}", out.diags.render(&sources));
    (renderer, out.frame)
}

/// A 4x4 RGB image of distinct colours, written once per test process.
fn texture_file() -> String {
    let dir = std::env::temp_dir().join(format!("primflow-reference-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("paint.png");
    let img = image::RgbImage::from_fn(4, 4, |x, y| image::Rgb([(x * 60) as u8, (y * 60) as u8, 200]));
    img.save(&path).unwrap();
    path.to_str().unwrap().to_string()
}

/// The accuracy knob's scene: every library light and the fog around a floor (per-vertex
/// st) and a sphere, both shaded by `surface`.
fn scene(surface: &str) -> String {
    primflow::accuracy::shading::scene_text(40, 32, surface)
}

fn surfaces() -> Vec<String> {
    vec![
        "constant".into(),
        "matte".into(),
        "plastic Ks=0.8 roughness=0.05".into(),
        "metal roughness=0.2".into(),
        "phong_plastic Ks=0.5 shininess=20".into(),
        "checker frequency=3".into(),
        "filtered_checker frequency=6".into(),
        "textured_plastic".into(),
        "marble scale=2".into(),
        format!("paintedplastic texturename=\"{}\"", texture_file()),
    ]
}

#[test]
fn the_f32_evaluation_is_the_kernels_bits() {
    for surface in surfaces() {
        let (renderer, frame) = render(&scene(&surface));
        let colours = renderer
            .evaluate_shading(&frame, Precision::F32)
            .unwrap_or_else(|e| panic!("{surface}: {e}"));
        let mut shaded = 0;
        for y in 0..frame.height {
            for x in 0..frame.width {
                let got = colours[(y * frame.width + x) as usize];
                if !frame.written(x, y) {
                    assert_eq!(got, [0.0; 3], "{surface}: unwritten ({x}, {y})");
                    continue;
                }
                shaded += 1;
                let want = frame.param_at("Ci", x, y).unwrap();
                assert_eq!(
                    got.map(f32::to_bits).to_vec(),
                    want.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                    "{surface}: Ci at ({x}, {y}): evaluator {got:?}, kernel {want:?}"
                );
            }
        }
        assert!(shaded > 300, "{surface}: only {shaded} pixels shaded");
    }
}

#[test]
fn a_frame_the_renderer_did_not_shade_is_refused() {
    let (renderer, _) = render(&scene("matte"));
    let unshaded: String = scene("matte")
        .lines()
        .filter(|l| !["lightsource", "atmosphere", "shader"].iter().any(|k| l.starts_with(k)))
        .map(|l| format!("{l}\n"))
        .collect();
    let (_, other) = render(&unshaded);
    assert!(!other.is_shaded());
    assert!(renderer.evaluate_shading(&other, Precision::F32).is_err());
}
