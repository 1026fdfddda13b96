//! The geometry pipeline through the renderer (real library, real JIT): near-plane and
//! w <= 0 crossings, huge coordinates against an f64 coverage reference, model clip planes,
//! trivial reject / accept and the variant key they select.

use crate::support;

use glam::{DMat4, DVec4};
use primflow::runtime::{Frame, Renderer};

const W: u32 = 64;
const H: u32 = 48;

fn no_nan_or_inf(frame: &Frame) {
    for (p, plane) in frame.all_plane_values().iter().enumerate() {
        assert!(plane.iter().all(|v| v.is_finite()), "plane {p} has a NaN or inf");
    }
}

fn covered(frame: &Frame) -> usize {
    frame.depth_values().iter().filter(|&&d| d != 0).count()
}

/// Camera at the origin looking down -z, 90 degree fov, near 1, far 100.
fn perspective_renderer(count_writes: bool) -> Renderer {
    let program = support::library();
    let mut r = support::renderer(&program, W, H, count_writes);
    r.perspective_checked(90.0, 1.0, 100.0).unwrap();
    r.material_interp("Cs", "perspective_linear", &[]).unwrap();
    r.material("Cs", &[1.0, 0.5, 0.25].into()).unwrap();
    r
}

fn triangle(r: &mut Renderer, v: [[f32; 4]; 3]) {
    r.begin("triangle").unwrap();
    for p in v {
        r.vertex(p[0], p[1], p[2], p[3]).unwrap();
    }
    r.end().unwrap();
}

#[test]
fn small_zero_and_negative_w_vertices_render_only_the_part_in_front() {
    // The triangle (-2,-1,-3) (2,-1,-3) (0, 1, z) with its apex given with w = 1e-7, 0 and
    // -1 (model data, seed 000 9.2: negative w is the same projective point negated, zero
    // w a tiny positive one) and once with the apex behind the eye.
    for apex in [
        [0.0, 1e-7, -3e-7, 1e-7],
        [0.0, 1.0, -3.0, 0.0],
        [0.0, -1.0, 3.0, -1.0],
        [0.0, 1.0, 5.0, 1.0],
    ] {
        let mut r = perspective_renderer(true);
        triangle(&mut r, [[-2.0, -1.0, -3.0, 1.0], [2.0, -1.0, -3.0, 1.0], apex]);
        let frame = support::render(&r, 2);
        no_nan_or_inf(&frame);
        let n = covered(&frame);
        assert!(n > 0, "apex {apex:?}: the in-front part must render");
        // Nothing is written twice and nothing above the horizon row of the base edge's far
        // side is impossible to check generally; check the base edge's screen row: the base
        // is at y = -1, z = -3: row 24 + 24/3 = 32 (pixel centres 32.5 and up are below).
        for y in 0..H {
            for x in 0..W {
                assert!(frame.write_count_at(x, y).unwrap() <= 1, "pixel {x},{y} written twice");
            }
        }
        // The base edge bounds the visible part from below when the apex is in front (the
        // part of an edge running behind the eye projects below it: checked next).
        let rows = if apex[2] > 0.0 && apex[3] > 0.0 { H..H } else { 33..H };
        for y in rows {
            for x in 0..W {
                assert!(!frame.written(x, y), "apex {apex:?}: pixel {x},{y} below the base edge");
            }
        }
    }
}

#[test]
fn a_triangle_reaching_behind_the_eye_draws_its_near_clipped_part() {
    let mut r = perspective_renderer(true);
    let tri: [[f32; 3]; 3] = [[-2.0, -1.0, -3.0], [2.0, -1.0, -3.0], [0.0, 1.0, 5.0]];
    triangle(&mut r, tri.map(|p| [p[0], p[1], p[2], 1.0]));
    let frame = support::render(&r, 2);
    no_nan_or_inf(&frame);
    // Reference: the triangle clipped to z <= -1 (the near plane) in camera space, in f64,
    // then projected.
    let pts: Vec<glam::DVec3> = tri
        .iter()
        .map(|p| glam::DVec3::new(p[0].into(), p[1].into(), p[2].into()))
        .collect();
    let mut clipped = vec![];
    for i in 0..3 {
        let (a, b) = (pts[i], pts[(i + 1) % 3]);
        let (da, db) = (-1.0 - a.z, -1.0 - b.z);
        if da >= 0.0 {
            clipped.push(a);
        }
        if (da >= 0.0) != (db >= 0.0) {
            clipped.push(a + (b - a) * (da / (da - db)));
        }
    }
    let m = r.geometry.device_from_object();
    let dev: Vec<[f64; 2]> = clipped
        .iter()
        .map(|p| {
            let q = m * p.extend(1.0);
            [q.x / q.w, q.y / q.w]
        })
        .collect();
    let inside = |px: f64, py: f64| {
        let n = dev.len();
        let e: Vec<f64> = (0..n)
            .map(|i| {
                let (a, b) = (dev[i], dev[(i + 1) % n]);
                (b[0] - a[0]) * (py - a[1]) - (b[1] - a[1]) * (px - a[0])
            })
            .collect();
        e.iter().all(|&x| x >= 0.0) || e.iter().all(|&x| x <= 0.0)
    };
    let mut wrong = vec![];
    for y in 0..H {
        for x in 0..W {
            let (px, py) = (f64::from(x) + 0.5, f64::from(y) + 0.5);
            let want = inside(px, py);
            let near_edge = [(-1.0, 0.0), (1.0, 0.0), (0.0, -1.0), (0.0, 1.0)]
                .iter()
                .any(|(dx, dy)| inside(px + dx, py + dy) != want);
            if frame.written(x, y) != want && !near_edge {
                wrong.push((x, y));
            }
        }
    }
    assert!(wrong.is_empty(), "{wrong:?}");
    assert!(covered(&frame) > 100);
}

#[test]
fn a_triangle_behind_the_eye_is_trivially_rejected_and_runs_no_kernel() {
    let mut r = perspective_renderer(false);
    triangle(
        &mut r,
        [[-1.0, 0.0, 2.0, 1.0], [1.0, 0.0, 2.0, 1.0], [0.0, 1.0, 3.0, 1.0]],
    );
    assert!(r.instances().is_empty(), "rejected by the clip codes at `end`");
    assert!(r.explain_lines().iter().any(|l| l.contains("trivially rejected")));
}

#[test]
fn inside_triangles_get_the_variant_without_clipping_code() {
    let mut r = perspective_renderer(false);
    triangle(
        &mut r,
        [[-1.0, -1.0, -3.0, 1.0], [1.0, -1.0, -3.0, 1.0], [0.0, 1.0, -3.0, 1.0]],
    );
    // Crosses the near plane: keeps the clipping code.
    triangle(
        &mut r,
        [[-1.0, -1.0, -3.0, 1.0], [1.0, -1.0, -3.0, 1.0], [0.0, -0.5, -0.5, 1.0]],
    );
    let keys: Vec<bool> = r.instances().iter().map(|i| i.key.trivial_accept).collect();
    assert_eq!(keys, vec![true, false]);
    let mut jit = primflow::jit::Jit::new(r.program().clone()).unwrap();
    let out = r.render(&mut jit);
    assert_eq!(out.kernels.len(), 2);
    assert_eq!(out.kernels.iter().filter(|k| k.trivial_accept).count(), 1);
    // The two variants are different code: `if (!clipping())` selects one branch of
    // polygon.prim at compile time.
    let polygon = r.program().find("polygon").unwrap();
    let accepted = jit.clif(polygon, &r.instances()[0].key).unwrap();
    let clipping = jit.clif(polygon, &r.instances()[1].key).unwrap();
    assert_ne!(accepted, clipping);
    // Both render the inside triangle's pixels the same way.
    assert!(out.frame.written(W / 2, H / 2 + 4));
}

/// Is the pixel centre (px, py) inside the device-space triangle (f64, either winding)?
fn inside_f64(v: &[[f64; 2]; 3], px: f64, py: f64) -> bool {
    let edge = |a: [f64; 2], b: [f64; 2]| (b[0] - a[0]) * (py - a[1]) - (b[1] - a[1]) * (px - a[0]);
    let e = [edge(v[0], v[1]), edge(v[1], v[2]), edge(v[2], v[0])];
    e.iter().all(|&x| x >= 0.0) || e.iter().all(|&x| x <= 0.0)
}

#[test]
fn huge_coordinates_cover_what_the_f64_reference_covers_within_one_pixel() {
    // Clip space = camera space under this view: x_c = x, y_c = y, z_c = z, w = w. Vertices
    // at 30000 w (and -1e5) with w from 0.2 to 16.
    let program = support::library();
    let cases: [[[f64; 4]; 3]; 3] = [
        [
            [-30000.0 * 0.2, -0.1, 0.5 * 0.2, 0.2],
            [30000.0 * 16.0, -0.3 * 16.0, 0.5 * 16.0, 16.0],
            [0.1, 30000.0 * 2.0, 0.5 * 2.0, 2.0],
        ],
        [[-1e5, -1e5, 0.5, 1.0], [1e5, -1e5, 0.5, 1.0], [0.0, 0.4, 0.5, 1.0]],
        [
            [-30000.0 * 4.0, 0.2 * 4.0, 0.3 * 4.0, 4.0],
            [0.3 * 0.2, -30000.0 * 0.2, 0.3 * 0.2, 0.2],
            [30000.0 * 16.0, 30000.0 * 16.0, 0.3 * 16.0, 16.0],
        ],
    ];
    for case in cases {
        let mut r = support::renderer(&program, W, H, true);
        r.view_matrix(DMat4::IDENTITY).unwrap();
        r.begin("triangle").unwrap();
        for p in case {
            r.vertex(p[0] as f32, p[1] as f32, p[2] as f32, p[3] as f32).unwrap();
        }
        r.end().unwrap();
        let frame = support::render(&r, 2);
        no_nan_or_inf(&frame);
        // Reference: the device-space triangle in f64 (every w > 0 here, so the divide is
        // the true projection).
        let d = r.geometry.device_from_clip();
        let dev: Vec<[f64; 2]> = case
            .iter()
            .map(|p| {
                let q = d * DVec4::from_array(*p);
                [q.x / q.w, q.y / q.w]
            })
            .collect();
        let dev = [dev[0], dev[1], dev[2]];
        let mut mismatches = vec![];
        for y in 0..H {
            for x in 0..W {
                let (px, py) = (f64::from(x) + 0.5, f64::from(y) + 0.5);
                let want = inside_f64(&dev, px, py);
                if frame.written(x, y) != want {
                    // Allowed only within one pixel of the reference's edge.
                    let near = [(-1.0, 0.0), (1.0, 0.0), (0.0, -1.0), (0.0, 1.0)]
                        .iter()
                        .any(|(dx, dy)| inside_f64(&dev, px + dx, py + dy) != want);
                    if !near {
                        mismatches.push((x, y));
                    }
                }
                assert!(frame.write_count_at(x, y).unwrap() <= 1);
            }
        }
        assert!(mismatches.is_empty(), "pixels off by more than 1 px: {mismatches:?}");
        assert!(covered(&frame) > 0);
    }
}

#[test]
fn a_model_clip_plane_and_its_negation_cover_every_pixel_exactly_once() {
    let program = support::library();
    let render_half = |plane: Option<[f64; 4]>| {
        let mut r = support::renderer(&program, W, H, true);
        r.perspective_checked(70.0, 0.5, 20.0).unwrap();
        r.look_at([0.3, 0.5, 3.0], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0]).unwrap();
        r.rotate(30.0, [0.0, 1.0, 0.0]).unwrap();
        if let Some(p) = plane {
            r.clip_plane(p).unwrap();
        }
        r
    };
    let submit = |r: &mut Renderer| {
        r.begin("polygon").unwrap();
        for p in [[-1.0, -1.0, 0.0], [1.2, -0.9, 0.1], [1.0, 1.1, -0.2], [-0.8, 1.0, 0.0]] {
            r.vertex(p[0], p[1], p[2], 1.0).unwrap();
        }
        r.end().unwrap();
    };
    let plane = [0.7, -0.4, 0.2, 0.13];
    let neg = plane.map(|c| -c);
    // Both halves in one frame, and the whole object alone.
    let mut both = render_half(None);
    both.clip_plane(plane).unwrap();
    submit(&mut both);
    both.clear_clip_planes();
    both.clip_plane(neg).unwrap();
    submit(&mut both);
    let mut whole = render_half(None);
    submit(&mut whole);
    let (a, b) = (support::render(&both, 2), support::render(&whole, 2));
    let mut count = 0;
    for y in 0..H {
        for x in 0..W {
            let want = u32::from(b.written(x, y));
            assert_eq!(a.write_count_at(x, y).unwrap(), want, "pixel {x},{y}");
            count += want;
        }
    }
    assert!(count > 200, "the object covers a good part of the image ({count} px)");
    // Each half alone covers part of it.
    let mut half = render_half(Some(plane));
    submit(&mut half);
    let h = support::render(&half, 1);
    let n = covered(&h) as u32;
    assert!(n > 0 && n < count, "{n} of {count}");
}

#[test]
fn backface_culling_happens_in_device_space() {
    let program = support::library();
    let mut r = support::renderer(&program, W, H, false);
    r.perspective_checked(90.0, 1.0, 10.0).unwrap();
    r.set_cull(primflow::pipeline::face::CullMode::Back);
    // Counter-clockwise on screen (front) and its mirror (back).
    triangle(
        &mut r,
        [[-1.0, -1.0, -3.0, 1.0], [1.0, -1.0, -3.0, 1.0], [0.0, 1.0, -3.0, 1.0]],
    );
    triangle(
        &mut r,
        [[-1.0, -1.0, -3.0, 1.0], [0.0, 1.0, -3.0, 1.0], [1.0, -1.0, -3.0, 1.0]],
    );
    assert_eq!(r.instances().len(), 1);
    assert!(r.explain_lines().iter().any(|l| l.contains("culled")));
}

#[test]
fn ill_behaved_views_warn_and_never_panic() {
    let program = support::library();
    let mut r = support::renderer(&program, W, H, false);
    // A singular view.
    let mut v = DMat4::IDENTITY;
    v.z_axis = DVec4::ZERO;
    r.view_matrix(v).unwrap();
    triangle(
        &mut r,
        [[-0.5, -0.5, 0.5, 1.0], [0.5, -0.5, 0.5, 1.0], [0.0, 0.5, 0.5, 1.0]],
    );
    let warnings: Vec<String> = r.take_warnings().iter().map(|w| w.message.clone()).collect();
    assert!(
        warnings.iter().any(|w| w.contains("view transform is singular")),
        "{warnings:?}"
    );
    // A singular model matrix: normals by the cofactor matrix, a warning.
    let mut r = support::renderer(&program, W, H, false);
    r.perspective_checked(60.0, 1.0, 10.0).unwrap();
    r.scale([1.0, 0.0, 1.0]).unwrap();
    triangle(
        &mut r,
        [[-0.5, -0.5, -3.0, 1.0], [0.5, -0.5, -3.0, 1.0], [0.0, 0.5, -3.0, 1.0]],
    );
    let warnings: Vec<String> = r.take_warnings().iter().map(|w| w.message.clone()).collect();
    assert!(
        warnings.iter().any(|w| w.contains("model transform is singular")),
        "{warnings:?}"
    );
    let frame = support::render(&r, 1);
    no_nan_or_inf(&frame);
}

/// The ill-behaved cases of seed 000 section 9 that the renderer must survive: each one is
/// named by its warning, and the frame holds no NaN or infinity.
#[test]
fn projective_model_non_factorizable_view_and_double_pyramid_are_named_and_survived() {
    let program = support::library();
    let tri = [[-0.5, -0.5, -3.0, 1.0], [0.5, -0.5, -3.0, 1.0], [0.0, 0.5, -3.0, 1.0]];
    let reversed_perspective = |near: f64, far: f64| {
        // z_c = a z_e + b, w_c = -z_e: depth 1 at z_e = -near, 0 at z_e = -far.
        let (a, b) = (near / (far - near), near * far / (far - near));
        DMat4::from_cols(
            DVec4::new(1.0, 0.0, 0.0, 0.0),
            DVec4::new(0.0, 1.0, 0.0, 0.0),
            DVec4::new(0.0, 0.0, a, -1.0),
            DVec4::new(0.0, 0.0, b, 0.0),
        )
    };
    let cases: Vec<(&str, Box<dyn Fn(&mut Renderer)>)> = vec![
        (
            "model transform is projective",
            Box::new(|r: &mut Renderer| {
                r.perspective_checked(60.0, 1.0, 10.0).unwrap();
                let mut m = DMat4::IDENTITY;
                m.z_axis.w = 0.05; // w' = w + 0.05 z: a projective model matrix
                r.concat(m).unwrap();
            }),
        ),
        (
            "lighting happens in world coordinates",
            Box::new(move |r: &mut Renderer| {
                // A view whose image is sheared (x += 0.5 y): not of the canonical form.
                let mut shear = DMat4::IDENTITY;
                shear.y_axis.x = 0.5;
                r.view_matrix(shear * reversed_perspective(1.0, 10.0)).unwrap();
            }),
        ),
        (
            "double pyramid",
            Box::new(move |r: &mut Renderer| {
                // Near and far planes on opposite sides of the eye.
                r.view_matrix(reversed_perspective(-1.0, 10.0)).unwrap();
            }),
        ),
    ];
    for (expected, setup) in cases {
        let mut r = support::renderer(&program, W, H, true);
        // Lit, so the lighting space matters (an unlit scene does not warn about it).
        r.shading_setup
            .lights
            .push(primflow::runtime::shading::SceneLight::Directional {
                towards_light: [0.0, 0.0, 1.0],
                colour: [1.0; 3],
            });
        r.material_interp("N", "perspective_linear", &[]).unwrap();
        r.material("N", &[0.0, 0.0, 1.0].into()).unwrap();
        setup(&mut r);
        r.material_interp("Cs", "perspective_linear", &[]).unwrap();
        r.material("Cs", &[1.0, 0.5, 0.25].into()).unwrap();
        triangle(&mut r, tri);
        let warnings: Vec<String> = r.take_warnings().iter().map(|w| w.message.clone()).collect();
        assert!(
            warnings.iter().any(|w| w.contains(expected)),
            "{expected}: {warnings:?}"
        );
        let frame = support::render(&r, 1);
        no_nan_or_inf(&frame);
        assert!(
            frame.write_count_values().unwrap().iter().all(|&c| c <= 1),
            "{expected}: a pixel written twice"
        );
    }
}

/// A lit quad facing the camera with `N = (0, 0, 1)`, under the model transform `model`
/// (a scene line), with the directional light on or black (ambient light only: a scene
/// with no light at all is not shaded); the shaded centre pixel and the warnings.
fn lit_quad_centre(model: &str, light: bool) -> ([f32; 3], Vec<String>) {
    let light = if light { "0.8 0.8 0.8" } else { "0 0 0" };
    let light = format!("light directional 0 0 1   {light}");
    let text = format!(
        "image 32 32\nperspective 60 0.5 50\nlook_at 0 0 3   0 0 0   0 1 0\n{light}\nambient 0.2 0.2 0.2\n\
         material_interp Cs perspective_linear\nmaterial_interp N perspective_linear\n\
         material Cs 0.9 0.6 0.3\n{model}\nmaterial N 0 0 1\n\
         begin polygon\nvertex -1 -1 0\nvertex 1 -1 0\nvertex 1 1 0\nvertex -1 1 0\nend\n"
    );
    let mut sources = primflow::diag::SourceMap::new();
    let program = support::library();
    let file = sources.add("quad.scene", text);
    let mut r = Renderer::new(program);
    let mut diags = primflow::diag::Diagnostics::new();
    primflow::scene::load_into(&sources, file, &mut r, &mut diags);
    assert!(!diags.has_errors(), "{}", diags.render(&sources));
    let warnings = diags.items.iter().map(|d| d.message.clone()).collect();
    let frame = support::render(&r, 1);
    (frame.shaded_at(16, 16).expect("the quad covers the centre"), warnings)
}

#[test]
fn a_singular_model_transform_lights_its_normals_with_ambient_light_only() {
    // Seed 000 9.4 and the W0704 text: `N` given under a singular M (here z scaled to 0,
    // which leaves the quad in z = 0 where it was) shades with ambient light only. Source of
    // truth: the same quad under a black directional light, which must match exactly; the
    // invertible M must be brighter (the light faces the quad).
    let (singular, warnings) = lit_quad_centre("scale 1 1 0", true);
    let (ambient, _) = lit_quad_centre("", false);
    let (lit, _) = lit_quad_centre("", true);
    assert_eq!(singular, ambient, "singular M: ambient only");
    assert!(
        lit[0] > ambient[0] + 0.3,
        "invertible M: lit {lit:?} vs ambient {ambient:?}"
    );
    assert!(
        warnings
            .iter()
            .any(|w| w.contains("model transform is singular") && w.contains("ambient light only")),
        "{warnings:?}"
    );
}
