//! The `shading` knob: each library surface (prims/shaders.prim), lit by every library
//! light and seen through the fog atmosphere, rendered by the f32 shading kernels and
//! measured against the same shaders evaluated in f64 by the IR evaluator over the same
//! G-buffer (`Renderer::evaluate_shading`, `ir::eval::Precision::F64`).
//!
//! The geometry and G-buffer are the kernels' in both, so the figure is the error of the
//! shading arithmetic alone: f32 operations, libm's f32 functions, `pow` by repeated
//! squaring. A setting's time is the whole frame with that surface (render and shading).
//! The second figure counts pixels off by more than [`OFF`]; the third, pixels where the f32
//! evaluator disagrees with the kernels in any bit (0 unless the JIT and its oracle part
//! ways).

use std::rc::Rc;

use crate::diag::{Diagnostics, SourceMap};
use crate::ir::eval::Precision;
use crate::runtime::Renderer;

use super::{Ctx, Knob, Metric, Output, Setting};

/// The surfaces, with the arguments the scene gives them (`paintedplastic` gets a generated
/// texture).
const SURFACES: [&str; 10] = [
    "constant",
    "matte",
    "plastic Ks=0.8 roughness=0.05",
    "metal roughness=0.2",
    "phong_plastic Ks=0.5 shininess=20",
    "checker frequency=3",
    "filtered_checker frequency=6",
    "textured_plastic",
    "marble scale=2",
    "paintedplastic",
];

/// A colour error the smooth library shaders stay far below (docs/accuracy.md, knob 7):
/// pixels past it are where f32 rounding is amplified, by noise of many octaves or by a
/// discontinuity (`floor` in a checker) that f32 puts on the other side.
const OFF: f64 = 1e-4;

/// A floor with per-vertex (s, t) and a sphere, both shaded by `surface`, under every
/// library light and the fog.
pub fn scene_text(width: u32, height: u32, surface: &str) -> String {
    format!(
        "image {width} {height}
perspective 60 0.5 50
look_at 0 1.5 4   0 0 0   0 1 0
lightsource ambientlight intensity=0.2
lightsource distantlight intensity=0.6 from=1,2,1 to=0,0,0
lightsource pointlight intensity=2 lightcolor=1,0.8,0.6 from=-2,2,2
lightsource attenuated_pointlight intensity=1 from=2,1,2
lightsource spotlight intensity=4 from=0,3,1 to=0,0,0 coneangle=0.6
atmosphere fog background=0.05,0.05,0.1 start=3 end=8
material_interp Cs perspective_linear
material_interp N perspective_linear
material_interp st perspective_linear
material Cs 0.9 0.6 0.3
material N 0 1 0
material st 0 0
shader {surface}
begin polygon
material st 0 0
vertex -2 0 2
material st 1 0
vertex 2 0 2
material st 1 1
vertex 2 0 -2
material st 0 1
vertex -2 0 -2
end
material_interp N implicit
material_interp Cs constant
material_interp st constant
begin sphere
rast_param center 0.3 0.6 0.2
rast_param radius 0.6
end
"
    )
}

/// A 16x16 image of smooth colour ramps for `paintedplastic`, written to the temporary
/// directory.
fn paint_texture() -> Result<String, String> {
    let path = std::env::temp_dir().join(format!("primflow-accuracy-paint-{}.png", std::process::id()));
    let img = image::RgbImage::from_fn(16, 16, |x, y| image::Rgb([(x * 16) as u8, (y * 16) as u8, 180]));
    img.save(&path).map_err(|e| format!("{}: {e}", path.display()))?;
    Ok(path.to_string_lossy().into_owned())
}

fn renderer(ctx: &Ctx, text: &str) -> Result<Renderer, String> {
    let mut sources = SourceMap::new();
    let mut diags = Diagnostics::new();
    let file = sources.add("shading.scene", text);
    let mut r = Renderer::new(ctx.program.clone());
    crate::scene::load_into(&sources, file, &mut r, &mut diags);
    if diags.has_errors() {
        return Err(diags.render(&sources));
    }
    Ok(r)
}

pub fn shading_knob<'a>(ctx: &Ctx, quick: bool) -> Knob<'a> {
    let (w, h) = if quick { (64, 48) } else { (256, 192) };
    let mut settings = vec![];
    let mut renderers: Vec<Rc<Renderer>> = vec![];
    let mut missing = vec![];
    for surface in SURFACES {
        let args = if surface == "paintedplastic" {
            match paint_texture() {
                Ok(path) => format!("paintedplastic texturename=\"{path}\""),
                Err(e) => {
                    missing.push(format!("paintedplastic: cannot write its texture ({e})"));
                    continue;
                }
            }
        } else {
            surface.to_string()
        };
        let r = match renderer(ctx, &scene_text(w, h, &args)) {
            Ok(r) => Rc::new(r),
            Err(e) => {
                missing.push(format!("{surface}: {e}"));
                continue;
            }
        };
        let label = surface.split(' ').next().unwrap_or(surface);
        let mine = r.clone();
        settings.push(Setting::new(label, move |ctx: &mut Ctx| {
            Ok(Output::Jit(ctx.render(&mine)?))
        }));
        renderers.push(r);
    }
    Knob {
        name: "shading",
        title: "language shaders: f32 kernels against the f64 evaluator (colour error)",
        settings,
        measure: Box::new(move |setting, out| {
            let Output::Jit(frame) = out else {
                return Err("the shading knob measures JIT frames".into());
            };
            let r = renderers.get(setting).ok_or("no renderer for the setting")?;
            let f64_colours = r.evaluate_shading(frame, Precision::F64)?;
            let f32_colours = r.evaluate_shading(frame, Precision::F32)?;
            let mut errors = vec![];
            let mut unlike = 0;
            let mut off = 0;
            for y in 0..frame.height {
                for x in 0..frame.width {
                    if !frame.written(x, y) {
                        continue;
                    }
                    let i = (y * frame.width + x) as usize;
                    let ci = frame.param_at("Ci", x, y).ok_or("no Ci planes")?;
                    let e = (0..3)
                        .map(|c| (f64::from(ci[c]) - f64::from(f64_colours[i][c])).abs())
                        .fold(0.0, f64::max);
                    errors.push(e);
                    off += u64::from(e.is_nan() || e > OFF);
                    unlike += u64::from((0..3).any(|c| ci[c].to_bits() != f32_colours[i][c].to_bits()));
                }
            }
            let total = errors.len() as u64;
            Ok(vec![
                Metric::of("colour", "colour units", &errors),
                Metric::count("pixels off by more than 1e-4", off, total),
                Metric::count("pixels unlike the f32 evaluator", unlike, total),
            ])
        }),
        missing,
    }
}
