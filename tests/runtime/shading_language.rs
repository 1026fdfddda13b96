//! Language shaders in the deferred pass (`runtime::shading::language`, `link`): the
//! library surfaces, lights and fog of `prims/shaders.prim` driven through the scene
//! reader, pixels against analytic values computed here in f64.

use std::path::PathBuf;

use primflow::diag::{Diagnostics, SourceMap};
use primflow::jit::Jit;
use primflow::runtime::{Frame, Registry, Renderer};

/// Load the library (plus `extra`, written to a temporary .prim file), read `text` as a
/// scene, render with `threads` threads.
fn render(text: &str, extra: Option<&str>, threads: usize) -> (Frame, Vec<String>) {
    let (out, codes) = render_output(text, extra, threads);
    (out.frame, codes)
}

fn render_output(text: &str, extra: Option<&str>, threads: usize) -> (primflow::runtime::RenderOutput, Vec<String>) {
    let mut sources = SourceMap::new();
    let mut diags = Diagnostics::new();
    let files: Vec<PathBuf> = extra
        .map(|src| {
            let dir = std::env::temp_dir().join(format!("primflow-shading-{}", std::process::id()));
            std::fs::create_dir_all(&dir).unwrap();
            let path = dir.join(format!("extra-{:x}.prim", fxhash(src)));
            std::fs::write(&path, src).unwrap();
            path
        })
        .into_iter()
        .collect();
    let registry = Registry::load(&mut sources, &[], &files, &mut diags)
        .unwrap_or_else(|| panic!("library does not compile:\n{}", diags.render(&sources)));
    let file = sources.add("shading.scene", text);
    let mut renderer = Renderer::new(registry.program.clone());
    primflow::scene::load_into(&sources, file, &mut renderer, &mut diags);
    let mut jit = Jit::new(registry.program.clone()).unwrap();
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
    let mut out = pool.install(|| renderer.render(&mut jit));
    diags.extend(std::mem::take(&mut out.diags));
    let codes = diags.codes_at(&sources);
    // Every diagnostic, the scene reader's too, back in the output for tests that read them.
    out.diags = diags;
    (out, codes)
}

fn fxhash(s: &str) -> u64 {
    s.bytes().fold(0xcbf29ce484222325, |h, b| {
        (h ^ u64::from(b)).wrapping_mul(0x100000001b3)
    })
}

/// A camera at z = 4 looking at a 2 x 2 quad in the z = 0 plane (normal +z), then `rest`.
fn quad_scene(setup: &str, rest: &str) -> String {
    format!(
        "image 64 64
perspective 40 0.5 50
look_at 0 0 4   0 0 0   0 1 0
{setup}
material Cs 0.8 0.4 0.2
material N 0 0 1
{rest}
begin polygon
vertex -1 -1 0
vertex 1 -1 0
vertex 1 1 0
vertex -1 1 0
end
"
    )
}

fn close(got: [f32; 3], want: [f64; 3], tol: f64, what: &str) {
    for c in 0..3 {
        assert!(
            (f64::from(got[c]) - want[c]).abs() <= tol,
            "{what}: channel {c} is {}, want {} (within {tol})",
            got[c],
            want[c]
        );
    }
}

const CS: [f64; 3] = [0.8, 0.4, 0.2];

#[test]
fn constant_surface_gives_cs_exactly_and_leaves_uncovered_pixels_black() {
    let (frame, codes) = render(&quad_scene("", "shader constant"), None, 2);
    assert!(codes.is_empty(), "{codes:?}");
    assert!(frame.written(32, 32));
    assert_eq!(frame.shaded_at(32, 32), Some([0.8f32, 0.4, 0.2]));
    assert!(!frame.written(0, 0));
    assert_eq!(frame.shaded_at(0, 0), Some([0.0; 3]));
}

#[test]
fn matte_sums_ambient_and_lambert_over_the_lights() {
    // Ambient 0.3, a distant light of 0.8 head-on and one of 0.5 at 60 degrees from the
    // normal: Cs * (Ka * 0.3 + Kd * (0.8 * 1 + 0.5 * cos 60)).
    let lights = "lightsource ambientlight intensity=0.3
lightsource distantlight intensity=0.8 from=0,0,1 to=0,0,0
lightsource distantlight intensity=0.5 from=0,0.8660254037844386,0.5 to=0,0,0";
    let (frame, codes) = render(&quad_scene(lights, "shader matte Ka=1 Kd=0.5"), None, 2);
    assert!(codes.is_empty(), "{codes:?}");
    let k = 0.3 + 0.5 * (0.8 + 0.5 * 0.5);
    for (x, y) in [(32, 32), (25, 40), (40, 25)] {
        close(
            frame.shaded_at(x, y).unwrap(),
            CS.map(|c| c * k),
            2e-5,
            &format!("pixel {x},{y}"),
        );
    }
}

#[test]
fn a_light_behind_the_surface_adds_nothing() {
    let lights = "lightsource distantlight intensity=1 from=0,0,-1 to=0,0,0";
    let (frame, codes) = render(&quad_scene(lights, "shader matte"), None, 1);
    assert!(codes.is_empty(), "{codes:?}");
    close(frame.shaded_at(32, 32).unwrap(), [0.0; 3], 0.0, "centre");
}

#[test]
fn point_light_falls_off_with_the_square_of_the_distance() {
    // A point light of intensity 4 at (0, 0, 2): at the quad's centre L = (0, 0, 2),
    // Cl = 4 / 4 = 1, head-on: Cs * 1. Off centre the analytic value at the pixel's point
    // is computed from the ray through the pixel centre.
    let lights = "lightsource pointlight intensity=4 from=0,0,2";
    let (frame, codes) = render(&quad_scene(lights, "shader matte Ka=0"), None, 2);
    assert!(codes.is_empty(), "{codes:?}");
    // Pixel (x, y) centre -> the point on z = 0 seen through it (fov 40, 64 x 64, eye at z=4).
    let at = |x: u32, y: u32| {
        let t = (20f64).to_radians().tan();
        let ndc = |p: u32| (f64::from(p) + 0.5) / 32.0 - 1.0;
        (4.0 * t * ndc(x), -4.0 * t * ndc(y))
    };
    for (x, y) in [(32u32, 32u32), (20, 30), (45, 38)] {
        let (px, py) = at(x, y);
        let l = [-px, -py, 2.0];
        let d2 = l[0] * l[0] + l[1] * l[1] + l[2] * l[2];
        let cos = l[2] / d2.sqrt();
        let want = CS.map(|c| c * 4.0 / d2 * cos);
        close(frame.shaded_at(x, y).unwrap(), want, 1e-4, &format!("pixel {x},{y}"));
    }
}

#[test]
fn each_primitive_is_shaded_by_the_surface_bound_before_it() {
    // Left half constant, right half matte under ambient 0.5 only.
    let scene = "image 32 16
lightsource ambientlight intensity=0.5
material Cs 0.8 0.4 0.2
shader constant
begin screen_triangle
rast_param screen_vertex 0 0 0.5 1   16 0 0.5 1   0 16 0.5 1
end
shader matte
begin screen_triangle
rast_param screen_vertex 16 0 0.5 1   32 0 0.5 1   32 16 0.5 1
end
";
    let (frame, codes) = render(scene, None, 2);
    assert!(codes.is_empty(), "{codes:?}");
    assert_eq!(frame.shaded_at(2, 2), Some([0.8f32, 0.4, 0.2]));
    close(frame.shaded_at(29, 2).unwrap(), CS.map(|c| c * 0.5), 1e-6, "matte side");
}

#[test]
fn pixels_drawn_before_any_shader_line_get_the_default_matte() {
    let scene = "image 16 16
lightsource ambientlight intensity=0.25
material Cs 1 1 1
begin screen_triangle
rast_param screen_vertex 0 0 0.5 1   16 0 0.5 1   0 16 0.5 1
end
";
    let (frame, codes) = render(scene, None, 1);
    assert!(codes.is_empty(), "{codes:?}");
    close(frame.shaded_at(2, 2).unwrap(), [0.25; 3], 1e-7, "default surface");
}

#[test]
fn fog_past_its_end_gives_the_background() {
    let (frame, codes) = render(
        &quad_scene(
            "atmosphere fog background=0.1,0.2,0.3 start=0 end=0.001",
            "shader constant",
        ),
        None,
        2,
    );
    assert!(codes.is_empty(), "{codes:?}");
    close(frame.shaded_at(32, 32).unwrap(), [0.1, 0.2, 0.3], 1e-7, "fogged");
}

#[test]
fn shaded_colours_are_the_same_for_any_thread_count_and_tile_size() {
    let lights = "lightsource ambientlight intensity=0.2
lightsource pointlight intensity=3 from=1,1,2
lightsource spotlight intensity=5 from=0,2,2 to=0,0,0";
    let a = render(&quad_scene(&format!("tile 16\n{lights}"), "shader plastic"), None, 1).0;
    let b = render(&quad_scene(&format!("tile 64\n{lights}"), "shader marble"), None, 2).0;
    let c = render(&quad_scene(&format!("tile 64\n{lights}"), "shader plastic"), None, 2).0;
    assert_eq!(a.color_values(), c.color_values());
    assert_ne!(a.color_values(), b.color_values(), "marble and plastic differ");
}

#[test]
fn a_varying_parameter_no_primitive_provides_takes_its_default_with_a_warning() {
    let extra = "surface tinted(varying color tint = {0.5, 0.5, 0.5}) { Ci = Cs * tint; }";
    let scene = "image 16 16
material Cs 1 1 1
shader tinted
begin screen_triangle
rast_param screen_vertex 0 0 0.5 1   16 0 0.5 1   0 16 0.5 1
end
";
    let (frame, codes) = render(scene, Some(extra), 1);
    assert_eq!(codes, ["W1001"]);
    close(frame.shaded_at(2, 2).unwrap(), [0.5; 3], 0.0, "default tint");
    // With the parameter bound per vertex, the plane is read per pixel.
    let scene = scene.replace("shader tinted", "material tint 0.25 1 0.5\nshader tinted");
    let (frame, codes) = render(&scene, Some(extra), 1);
    assert!(codes.is_empty(), "{codes:?}");
    close(frame.shaded_at(2, 2).unwrap(), [0.25, 1.0, 0.5], 0.0, "tint plane");
}

#[test]
fn unknown_shaders_and_arguments_are_scene_errors() {
    let (_, codes) = render(&quad_scene("", "shader no_such_surface"), None, 1);
    assert!(codes.iter().any(|c| c.starts_with("E1002")), "{codes:?}");
    let (_, codes) = render(&quad_scene("lightsource pointlight wattage=3", "shader matte"), None, 1);
    assert!(codes.iter().any(|c| c.starts_with("E0702")), "{codes:?}");
}

/// Largest channel difference between two frames' shaded colours over covered pixels.
fn max_colour_difference(a: &Frame, b: &Frame) -> f32 {
    let (ca, cb) = (a.color_values().unwrap(), b.color_values().unwrap());
    let depth = a.depth_values();
    ca.iter()
        .zip(&cb)
        .zip(&depth)
        .filter(|(_, &d)| d != 0)
        .flat_map(|((p, q), _)| (0..3).map(move |c| (p[c] - q[c]).abs()))
        .fold(0.0, f32::max)
}

#[test]
fn fixed_lines_mapped_to_library_shaders_match_the_rust_pass() {
    // Perspective: a directional and an attenuated point light, ambient, Phong with a
    // specular term, a checker over st and fog; then the same in a parallel (device
    // coordinate) view, where fog is measured from the near plane.
    let lit = "light directional 1 2 1   0.8 0.8 0.8
light point -0.5 0.5 1.5   0.6 0.5 0.3   1 0.1 0
ambient 0.2 0.2 0.2
surface front 1 0.8 0.4 24
fog 0.05 0.05 0.1 3 8
texture checker st 2
material_interp st perspective_linear
material st 0 0";
    let perspective = quad_scene(lit, "");
    let rust = render(&perspective, None, 2);
    let language = render(&format!("shading_pass language\n{perspective}"), None, 2);
    assert!(
        rust.1.is_empty() && language.1.is_empty(),
        "{:?} {:?}",
        rust.1,
        language.1
    );
    let d = max_colour_difference(&rust.0, &language.0);
    assert!(d < 2e-3, "perspective: largest difference {d}");
    assert!(rust.0.covered_pixels() > 1000);

    let parallel = "image 32 32
light directional 0.3 0.2 1   0.7 0.7 0.7
ambient 0.1 0.1 0.1
surface front 1 0.9 0.5 16
fog 0.6 0.7 0.9 0 0.5
material_interp N linear
material Cs 0.8 0.5 0.3
begin screen_triangle
rast_param screen_vertex 0 0 0.3 1   32 0 0.6 1   0 32 0.5 1
material N 0 0 1
sequence_point
material N 0.3 0 1
sequence_point
material N 0 -0.3 1
sequence_point
end
";
    let rust = render(parallel, None, 1);
    let language = render(&format!("shading_pass language\n{parallel}"), None, 1);
    assert!(
        rust.1.is_empty() && language.1.is_empty(),
        "{:?} {:?}",
        rust.1,
        language.1
    );
    let d = max_colour_difference(&rust.0, &language.0);
    assert!(d < 2e-3, "parallel: largest difference {d}");
}

#[test]
fn only_the_planes_a_shader_names_are_read_and_explain_says_which() {
    // The frame has Cs, N and st; plastic names Cs and N (through N and I), checker also
    // s and t.
    let st = "material_interp st perspective_linear\nmaterial st 0 0";
    let (out, codes) = render_output(&quad_scene(st, "shader plastic"), None, 1);
    assert!(codes.is_empty(), "{codes:?}");
    let plastic = out
        .language_shading
        .iter()
        .find(|l| l.contains("`plastic`"))
        .expect("a plastic line");
    assert!(plastic.contains("reads plane(s) of [Cs, N]"), "{plastic}");
    let (out, _) = render_output(&quad_scene(st, "shader checker"), None, 1);
    let checker = out
        .language_shading
        .iter()
        .find(|l| l.contains("`checker`"))
        .expect("a checker line");
    assert!(checker.contains("reads plane(s) of [Cs, N, st]"), "{checker}");
    // The Rust pass reports no language shading.
    let (out, _) = render_output(&quad_scene("light directional 0 0 1 1 1 1", ""), None, 1);
    assert!(out.language_shading.is_empty());
}

#[test]
fn a_renderer_reuses_its_compiled_shading_until_the_shading_changes() {
    let mut sources = SourceMap::new();
    let mut diags = Diagnostics::new();
    let registry = Registry::load(&mut sources, &[], &[], &mut diags).expect("library");
    let file = sources.add(
        "reuse.scene",
        quad_scene(
            "lightsource distantlight intensity=0.5 from=0,0,1 to=0,0,0",
            "shader matte Ka=0",
        ),
    );
    let mut renderer = Renderer::new(registry.program.clone());
    primflow::scene::load_into(&sources, file, &mut renderer, &mut diags);
    assert!(!diags.has_errors());
    let mut jit = Jit::new(registry.program.clone()).unwrap();
    let first = renderer.render(&mut jit);
    let second = renderer.render(&mut jit);
    assert_eq!(first.frame.color_values(), second.frame.color_values());
    assert_eq!(first.language_shading, second.language_shading);
    close(
        second.frame.shaded_at(32, 32).unwrap(),
        CS.map(|c| c * 0.5),
        1e-6,
        "cached",
    );
    // A changed argument is a new compile (here only the argument block differs).
    renderer.language.lights[0].args[0].1 = vec![0.25];
    let third = renderer.render(&mut jit);
    close(
        third.frame.shaded_at(32, 32).unwrap(),
        CS.map(|c| c * 0.25),
        1e-6,
        "recompiled",
    );
}

/// A surface showing `Dx(s)`, `Dy(s)` and `filterwidth(t)` as its colour.
const DERIVATIVES: &str = "surface derivatives() { Ci = {Dx(s), Dy(s), filterwidth(t)}; }";

/// A 64 x 64 screen triangle with s = x/4 + y/2 and t = (x - y)/8, affine in screen space,
/// shaded by `derivatives`, in tiles of `tile`.
fn affine_scene(tile: u32) -> String {
    format!(
        "image 64 64
tile {tile}
material_interp s linear
material_interp t linear
shader derivatives
begin screen_triangle
rast_param screen_vertex 0 0 0.5 1   64 0 0.5 1   0 64 0.5 1
material s 0
material t 0
sequence_point
material s 16
material t 8
sequence_point
material s 32
material t -8
sequence_point
end
"
    )
}

#[test]
fn derivatives_are_exact_on_affine_fields_and_zero_for_a_pixel_alone_in_its_quad() {
    let (frame, codes) = render(&affine_scene(16), Some(DERIVATIVES), 2);
    assert!(codes.is_empty(), "{codes:?}");
    let on = |x: u32, y: u32| frame.written(x, y);
    let (mut exact, mut alone) = (0, 0);
    for y in 0..64 {
        for x in 0..64 {
            if !on(x, y) {
                continue;
            }
            // The pixel's quad starts at even coordinates: a derivative needs a row
            // (column) of it whose two pixels are both shaded.
            let (qx, qy) = (x & !1, y & !1);
            let row = |r: u32| on(qx, r) && on(qx + 1, r);
            let col = |c: u32| on(c, qy) && on(c, qy + 1);
            let (has_dx, has_dy) = (row(qy) || row(qy + 1), col(qx) || col(qx + 1));
            let got = frame.shaded_at(x, y).unwrap();
            let want_dx = if has_dx { 0.25 } else { 0.0 };
            let want_dy = if has_dy { 0.5 } else { 0.0 };
            let want_fw = match (has_dx, has_dy) {
                (true, true) => 0.125 * 2f64.sqrt(),
                (false, false) => 0.0,
                _ => 0.125,
            };
            close(got, [want_dx, want_dy, want_fw], 1e-5, &format!("pixel {x},{y}"));
            if has_dx && has_dy {
                exact += 1;
            } else {
                alone += 1;
            }
        }
    }
    assert!(exact > 1800, "{exact} pixels with both derivatives");
    assert!(alone > 0, "no pixel on the diagonal edge tested the fallback");
}

#[test]
fn quad_shading_is_the_same_for_any_thread_count_and_tile_size() {
    let a = render(&affine_scene(16), Some(DERIVATIVES), 1).0;
    let b = render(&affine_scene(64), Some(DERIVATIVES), 2).0;
    assert_eq!(a.color_values(), b.color_values());
    let lights = "lightsource ambientlight intensity=0.2
lightsource distantlight intensity=0.8 from=0,1,2 to=0,0,0
material_interp st perspective_linear";
    let checker = |tile: u32, threads: usize| {
        let scene = quad_scene(&format!("tile {tile}\n{lights}"), "shader filtered_checker frequency=9")
            .replace("vertex -1 -1 0", "material st 0 0\nvertex -1 -1 0")
            .replace("vertex 1 -1 0", "material st 1 0\nvertex 1 -1 0")
            .replace("vertex 1 1 0", "material st 1 1\nvertex 1 1 0")
            .replace("vertex -1 1 0", "material st 0 1\nvertex -1 1 0");
        render(&scene, None, threads)
    };
    let (c, codes) = checker(16, 1);
    assert!(codes.is_empty(), "{codes:?}");
    assert_eq!(c.color_values(), checker(64, 2).0.color_values());
}

#[test]
fn the_filtered_checker_averages_squares_smaller_than_a_pixel() {
    // 64 x 64 pixels over s, t in [0, 1] at 256 squares a side: each pixel spans 4 x 4
    // squares, half of them black, so every interior pixel is Cs half-way to black; the
    // point-sampled checker gives Cs or black.
    let scene = |shader: &str| {
        format!(
            "image 64 64
material_interp s linear
material_interp t linear
material Cs 0.8 0.8 0.8
shader {shader} frequency=256 Kd=0
lightsource ambientlight intensity=1
begin screen_triangle
rast_param screen_vertex -64 0 0.5 1   128 0 0.5 1   -64 192 0.5 1
material s -1
material t 0
sequence_point
material s 2
material t 0
sequence_point
material s -1
material t 3
sequence_point
end
"
        )
    };
    let (filtered, codes) = render(&scene("filtered_checker"), None, 2);
    assert!(codes.is_empty(), "{codes:?}");
    let (point, _) = render(&scene("checker"), None, 2);
    for (x, y) in [(10, 10), (30, 20), (50, 5)] {
        close(
            filtered.shaded_at(x, y).unwrap(),
            [0.4; 3],
            1e-3,
            &format!("filtered {x},{y}"),
        );
        let p = point.shaded_at(x, y).unwrap()[0];
        assert!(p == 0.0 || (p - 0.8).abs() < 1e-6, "point-sampled {x},{y}: {p}");
    }
}

/// A 4 x 4 RGB texture written to a temporary PNG: texel (i, j) is (i, j, i + j) * 17 / 255.
fn texture_file(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("primflow-shading-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    let img = image::RgbImage::from_fn(4, 4, |i, j| {
        image::Rgb([(i * 17) as u8, (j * 17) as u8, ((i + j) * 17) as u8])
    });
    img.save(&path).unwrap();
    path
}

/// A triangle over the 64 x 64 image with (s, t) = (x, y) / 64, after `setup` (its
/// shader lines).
fn st_triangle(setup: &str) -> String {
    format!(
        "image 64 64
material_interp s linear
material_interp t linear
{setup}
begin screen_triangle
rast_param screen_vertex 0 0 0.5 1   128 0 0.5 1   0 128 0.5 1
material s 0
material t 0
sequence_point
material s 2
material t 0
sequence_point
material s 0
material t 2
sequence_point
end
"
    )
}

/// [`st_triangle`] in tiles of `tile`, shaded by `textured` with `scale`.
fn texture_scene(tile: u32, scale: f32) -> String {
    st_triangle(&format!("tile {tile}\nshader textured scale={scale}"))
}

/// The test texture's texel (i, j) of level 0 (see [`texture_file`]), in f64.
fn grid_texel(i: i64, j: i64) -> [f64; 3] {
    [i, j, i + j].map(|v| v as f64 * 17.0 / 255.0)
}

/// Bilinear filtering in f64 over a level of `n` x `n` texels, `texel` applying the wrap
/// mode to its indices.
fn bilinear_reference(texel: &dyn Fn(i64, i64) -> [f64; 3], n: i64, s: f64, t: f64) -> [f64; 3] {
    let (u, v) = (s * n as f64 - 0.5, t * n as f64 - 0.5);
    let (i0, j0) = (u.floor() as i64, v.floor() as i64);
    let (fu, fv) = (u - i0 as f64, v - j0 as f64);
    std::array::from_fn(|c| {
        texel(i0, j0)[c] * (1.0 - fu) * (1.0 - fv)
            + texel(i0 + 1, j0)[c] * fu * (1.0 - fv)
            + texel(i0, j0 + 1)[c] * (1.0 - fu) * fv
            + texel(i0 + 1, j0 + 1)[c] * fu * fv
    })
}

#[test]
fn texture_lookups_pick_the_mip_level_of_the_footprint_and_filter_bilinearly() {
    let file = texture_file("grid.png");
    let shader = format!(
        "surface textured(float scale = 1) {{ Ci = texture(\"{}\", s * scale, t * scale, \"wrap\", \"clamp\"); }}",
        file.display()
    );
    let bilinear = |level: &dyn Fn(i64, i64) -> [f64; 3], n: i64, s: f64, t: f64| {
        bilinear_reference(&|i, j| level(i.clamp(0, n - 1), j.clamp(0, n - 1)), n, s, t)
    };
    let level0 = grid_texel;
    // Level 1 averages 2 x 2 texels of level 0.
    let level1 = |i: i64, j: i64| {
        let (a, b) = ((2 * i) as f64 + 0.5, (2 * j) as f64 + 0.5);
        [a * 17.0 / 255.0, b * 17.0 / 255.0, (a + b) * 17.0 / 255.0]
    };
    // Scale 1: 64 pixels over 4 texels, a footprint of 1/16 texel: level 0.
    let (frame, codes) = render(&texture_scene(16, 1.0), Some(&shader), 2);
    assert!(codes.is_empty(), "{codes:?}");
    for (x, y) in [(3, 5), (10, 20), (20, 10), (31, 2), (0, 0)] {
        let (s, t) = ((x as f64 + 0.5) / 64.0, (y as f64 + 0.5) / 64.0);
        close(
            frame.shaded_at(x, y).unwrap(),
            bilinear(&level0, 4, s, t),
            1e-5,
            &format!("level 0 at {x},{y}"),
        );
    }
    // Scale 32: each pixel spans 2 texels (s moves by 0.5 a pixel): level 1, bilinear there.
    let (frame, _) = render(&texture_scene(16, 32.0), Some(&shader), 2);
    for (x, y) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
        let (s, t) = ((x as f64 + 0.5) / 2.0, (y as f64 + 0.5) / 2.0);
        close(
            frame.shaded_at(x, y).unwrap(),
            bilinear(&level1, 2, s, t),
            1e-4,
            &format!("level 1 at {x},{y}"),
        );
    }
}

#[test]
fn a_missing_or_corrupt_texture_is_an_error_naming_the_file_before_anything_renders() {
    let missing = std::env::temp_dir().join("primflow-no-such-texture.png");
    let corrupt = std::env::temp_dir().join(format!("primflow-corrupt-{}.png", std::process::id()));
    std::fs::write(&corrupt, b"\x89PNG\r\n\x1a\nnot really").unwrap();
    for file in [missing, corrupt] {
        let shader = format!(
            "surface textured(float scale = 1) {{ Ci = texture(\"{}\", s, t); }}",
            file.display()
        );
        let (out, codes) = render_output(&texture_scene(16, 1.0), Some(&shader), 1);
        assert!(codes.iter().any(|c| c.starts_with("E1004")), "{codes:?}");
        let messages = format!("{:?}", out.diags);
        assert!(messages.contains(&file.display().to_string()), "{messages}");
        assert!(
            out.frame.shaded_at(10, 10).is_none_or(|c| c == [0.0; 3]),
            "nothing shaded"
        );
    }
}

#[test]
fn textured_quads_are_the_same_for_any_thread_count_and_tile_size() {
    let file = texture_file("grid2.png");
    let shader = format!(
        "surface textured(float scale = 1) {{ Ci = texture(\"{}\", s * scale, t * 3); }}",
        file.display()
    );
    let a = render(&texture_scene(16, 7.0), Some(&shader), 1).0;
    let b = render(&texture_scene(64, 7.0), Some(&shader), 2).0;
    assert_eq!(a.color_values(), b.color_values());
    assert!(
        a.color_values().unwrap().iter().any(|c| c[0] > 0.1),
        "something textured"
    );
}

#[test]
fn a_string_parameter_names_the_texture_from_the_scene_and_empty_means_white() {
    let file = texture_file("painted.png");
    let scene = |texture_arg: &str| {
        st_triangle(&format!(
            "material Cs 0.5 1 1\nlightsource ambientlight intensity=1\nshader paintedplastic Kd=0 Ks=0 {texture_arg}"
        ))
    };
    let (frame, codes) = render(&scene(&format!("texturename=\"{}\"", file.display())), None, 2);
    assert!(codes.is_empty(), "{codes:?}");
    // Ci = Cs * texture: bilinear over the 4 x 4 texels, periodic (level 0: a footprint of
    // 1/16 texel), against an f64 reference.
    for (x, y) in [(7u32, 7u32), (20, 30), (40, 10), (5, 50)] {
        let (s, t) = ((x as f64 + 0.5) / 64.0, (y as f64 + 0.5) / 64.0);
        let tex = bilinear_reference(&|i, j| grid_texel(i.rem_euclid(4), j.rem_euclid(4)), 4, s, t);
        let want = [0.5 * tex[0], tex[1], tex[2]];
        close(frame.shaded_at(x, y).unwrap(), want, 1e-5, &format!("pixel {x},{y}"));
    }
    let (plain, codes) = render(&scene(""), None, 2);
    assert!(codes.is_empty(), "{codes:?}");
    close(
        plain.shaded_at(20, 20).unwrap(),
        [0.5, 1.0, 1.0],
        1e-6,
        "no texture: white",
    );
    let (_, codes) = render(&scene("texturename=3"), None, 1);
    assert!(codes.iter().any(|c| c.starts_with("E0703")), "{codes:?}");
    let (_, codes) = render(&scene("Ka=\"x\""), None, 1);
    assert!(codes.iter().any(|c| c.starts_with("E0703")), "{codes:?}");
}

#[test]
fn a_nan_or_infinite_shading_result_is_magenta_with_a_warning() {
    let shader = "surface broken() { float z = s * 0; Ci = {z / z, 1 / z, 0.5}; }";
    let scene = quad_scene("material s 0", "shader broken");
    let (frame, codes) = render(&scene, Some(shader), 2);
    assert!(codes.iter().any(|c| c.starts_with("W1004")), "{codes:?}");
    assert_eq!(frame.shaded_at(32, 32), Some([1.0, 0.0, 1.0]));
    assert_eq!(frame.shaded_at(0, 0), Some([0.0; 3]), "not drawn: black");
}
