//! The deferred shading pass through the renderer: lighting in lighting coordinates equals
//! lighting in world coordinates (the f64 reference) on a lit sphere and a lit bicubic patch
//! under a strong perspective, while lighting in device coordinates differs visibly (seed 001
//! figure 2; the error is printed). Also: a scene with no effects runs no shading code, and
//! front/back materials, fog and texture change exactly the pixels they should.

use crate::support;

use std::f64::consts::PI;

use primflow::runtime::shading::{Fog, LightingSpaceChoice, SceneLight, SurfaceMaterial, Texture};
use primflow::runtime::{Frame, Renderer};

const W: u32 = 64;
const H: u32 = 64;

/// A strong perspective (wide field of view, close camera) with two lights.
fn lit_renderer(space: LightingSpaceChoice) -> Renderer {
    let program = support::library();
    let mut r = support::renderer(&program, W, H, false);
    r.perspective_checked(100.0, 0.2, 20.0).unwrap();
    r.look_at([0.4, 0.6, 1.8], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0]).unwrap();
    r.shading_setup.lights = vec![
        SceneLight::Directional {
            towards_light: [1.0, 1.0, 0.5],
            colour: [0.7, 0.7, 0.7],
        },
        SceneLight::Positional {
            position: [-1.0, 1.5, 1.5],
            colour: [0.6, 0.5, 0.4],
            attenuation: [1.0, 0.1, 0.05],
        },
    ];
    r.shading_setup.front = SurfaceMaterial {
        ka: 1.0,
        kd: 0.8,
        ks: 0.5,
        shininess: 20.0,
        specular_colour: [1.0; 3],
    };
    r.shading_setup.space = space;
    r.material_interp("Cs", "perspective_linear", &[]).unwrap();
    r.material_interp("N", "perspective_linear", &[]).unwrap();
    r.material("Cs", &[0.9, 0.7, 0.5].into()).unwrap();
    r.material("N", &[0.0, 0.0, 1.0].into()).unwrap();
    r
}

/// A triangle with per-vertex normals.
fn lit_triangle(r: &mut Renderer, p: [[f64; 3]; 3], n: [[f64; 3]; 3]) {
    r.begin("triangle").unwrap();
    for k in 0..3 {
        r.material("N", &n[k].map(|c| c as f32).into()).unwrap();
        r.vertex(p[k][0] as f32, p[k][1] as f32, p[k][2] as f32, 1.0).unwrap();
    }
    r.end().unwrap();
}

/// A unit sphere of `rings x segments` quads (two triangles each), normals = positions.
fn sphere(r: &mut Renderer, rings: usize, segments: usize) {
    let at = |i: usize, j: usize| {
        let theta = PI * i as f64 / rings as f64;
        let phi = 2.0 * PI * j as f64 / segments as f64;
        [theta.sin() * phi.cos(), theta.cos(), theta.sin() * phi.sin()]
    };
    for i in 0..rings {
        for j in 0..segments {
            let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
            lit_triangle(r, [a, c, b], [a, c, b]);
            lit_triangle(r, [a, d, c], [a, d, c]);
        }
    }
}

/// A bicubic Bezier patch, tessellated `n x n`, with analytic normals.
fn patch(r: &mut Renderer, n: usize) {
    let ctrl = |i: usize, j: usize| {
        let h = [
            [0.0, 0.3, 0.2, 0.0],
            [0.4, 0.9, 0.7, 0.1],
            [0.2, 0.8, 1.0, 0.3],
            [0.0, 0.2, 0.4, 0.0],
        ];
        [i as f64 * 0.8 - 1.2, h[i][j] - 0.3, j as f64 * 0.8 - 1.2]
    };
    let bern = |t: f64| {
        [
            (1.0 - t).powi(3),
            3.0 * t * (1.0 - t).powi(2),
            3.0 * t * t * (1.0 - t),
            t.powi(3),
        ]
    };
    let dbern = |t: f64| {
        [
            -3.0 * (1.0 - t).powi(2),
            3.0 * (1.0 - t).powi(2) - 6.0 * t * (1.0 - t),
            6.0 * t * (1.0 - t) - 3.0 * t * t,
            3.0 * t * t,
        ]
    };
    let eval = |u: f64, v: f64| {
        let (bu, bv, du, dv) = (bern(u), bern(v), dbern(u), dbern(v));
        let mut p = [0.0; 3];
        let mut pu = [0.0; 3];
        let mut pv = [0.0; 3];
        for i in 0..4 {
            for j in 0..4 {
                let c = ctrl(i, j);
                for k in 0..3 {
                    p[k] += bu[i] * bv[j] * c[k];
                    pu[k] += du[i] * bv[j] * c[k];
                    pv[k] += bu[i] * dv[j] * c[k];
                }
            }
        }
        let nrm = glam::DVec3::from_array(pv)
            .cross(glam::DVec3::from_array(pu))
            .normalize();
        (p, nrm.to_array())
    };
    for i in 0..n {
        for j in 0..n {
            let f = |a: usize, b: usize| eval(a as f64 / n as f64, b as f64 / n as f64);
            let (a, b, c, d) = (f(i, j), f(i + 1, j), f(i + 1, j + 1), f(i, j + 1));
            lit_triangle(r, [a.0, b.0, c.0], [a.1, b.1, c.1]);
            lit_triangle(r, [a.0, c.0, d.0], [a.1, c.1, d.1]);
        }
    }
}

fn render(r: &Renderer) -> Frame {
    support::render(r, 2)
}

/// Largest per-channel difference over the pixels both frames shaded, and how many.
fn max_difference(a: &Frame, b: &Frame) -> (f64, usize) {
    let mut worst = 0f64;
    let mut n = 0;
    for y in 0..H {
        for x in 0..W {
            if !a.written(x, y) {
                continue;
            }
            let (ca, cb) = (a.shaded_at(x, y).unwrap(), b.shaded_at(x, y).unwrap());
            for k in 0..3 {
                worst = worst.max((f64::from(ca[k]) - f64::from(cb[k])).abs());
            }
            n += 1;
        }
    }
    (worst, n)
}

fn compare_spaces(name: &str, build: impl Fn(&mut Renderer)) {
    let frames: Vec<Frame> = [
        LightingSpaceChoice::Lighting,
        LightingSpaceChoice::World,
        LightingSpaceChoice::Device,
    ]
    .into_iter()
    .map(|space| {
        let mut r = lit_renderer(space);
        // LC is a genuinely different space here (V factored, E a real rotation).
        let e = r.geometry.lighting_from_world();
        assert!(!e.abs_diff_eq(glam::DMat4::IDENTITY, 1e-3), "E = {e:?}");
        build(&mut r);
        render(&r)
    })
    .collect();
    let (lc_vs_wc, n) = max_difference(&frames[0], &frames[1]);
    let (dc_vs_wc, _) = max_difference(&frames[2], &frames[1]);
    println!("{name}: {n} lit pixels; max |LC - WC| = {lc_vs_wc:.3e}, max |DC - WC| = {dc_vs_wc:.3e}");
    assert!(n > 500, "{name}: the object covers the image ({n} px)");
    assert!(lc_vs_wc <= 1e-5, "{name}: LC differs from WC by {lc_vs_wc}");
    assert!(
        dc_vs_wc > 0.05,
        "{name}: DC lighting should differ visibly, got {dc_vs_wc}"
    );
    // Lit colours are real colours: finite, varying across the object.
    let c0 = frames[0].shaded_at(W / 2, H / 2).unwrap();
    assert!(c0.iter().all(|v| v.is_finite()));
}

#[test]
fn lighting_in_lc_equals_wc_and_dc_differs_on_a_lit_sphere() {
    compare_spaces("sphere", |r| sphere(r, 16, 24));
}

#[test]
fn lighting_in_lc_equals_wc_and_dc_differs_on_a_lit_bicubic_patch() {
    compare_spaces("bicubic patch", |r| patch(r, 12));
}

#[test]
fn a_scene_without_effects_runs_no_shading_and_shows_cs() {
    let program = support::library();
    let mut r = support::renderer(&program, W, H, false);
    r.perspective_checked(60.0, 0.5, 10.0).unwrap();
    r.material("Cs", &[0.25, 0.5, 0.75].into()).unwrap();
    lit_triangle(
        &mut r,
        [[-1.0, -1.0, -3.0], [1.0, -1.0, -3.0], [0.0, 1.0, -3.0]],
        [[0.0, 0.0, 1.0]; 3],
    );
    let mut jit = primflow::jit::Jit::new(r.program().clone()).unwrap();
    let out = r.render(&mut jit);
    assert!(!out.effects.any());
    assert!(!out.frame.is_shaded(), "no shading pass ran");
    assert_eq!(out.frame.color_at(W / 2, H / 2), [0.25, 0.5, 0.75]);
}

#[test]
fn back_faces_take_the_back_material_fog_and_texture_change_colours() {
    let build = |back: Option<SurfaceMaterial>, fog: Option<Fog>, texture: Option<Texture>| {
        let mut r = lit_renderer(LightingSpaceChoice::Lighting);
        r.shading_setup.back = back;
        r.shading_setup.fog = fog;
        r.shading_setup.texture = texture;
        r.set_distinguish(true);
        r.material_interp("st", "perspective_linear", &[]).unwrap();
        r.material("st", &[0.0, 0.0].into()).unwrap();
        // A clockwise (back-facing) quad as two triangles, texture coordinates 0..2.
        r.begin("polygon").unwrap();
        for (p, st) in [
            ([-1.0, -1.0, -1.0], [0.0, 0.0]),
            ([-1.0, 1.0, -1.0], [0.0, 2.0]),
            ([1.0, 1.0, -1.0], [2.0, 2.0]),
            ([1.0, -1.0, -1.0], [2.0, 0.0]),
        ] {
            r.material("st", &Value(st.to_vec())).unwrap();
            r.vertex(p[0], p[1], p[2], 1.0).unwrap();
        }
        r.end().unwrap();
        render(&r)
    };
    use primflow::runtime::Value;
    let plain = build(None, None, None);
    let dark_back = SurfaceMaterial {
        ka: 0.1,
        kd: 0.1,
        ks: 0.0,
        shininess: 1.0,
        specular_colour: [0.0; 3],
    };
    let backed = build(Some(dark_back), None, None);
    let fogged = build(
        None,
        Some(Fog {
            colour: [0.0, 0.0, 1.0],
            start: 0.0,
            end: 2.0,
        }),
        None,
    );
    let textured = build(
        None,
        None,
        Some(Texture {
            param: "st".into(),
            scale: 1.0,
            dark: 0.25,
        }),
    );
    let (mut darker, mut bluer, mut textured_px, mut n) = (0, 0, 0, 0);
    for y in 0..H {
        for x in 0..W {
            if !plain.written(x, y) {
                continue;
            }
            n += 1;
            let p = plain.shaded_at(x, y).unwrap();
            let b = backed.shaded_at(x, y).unwrap();
            let f = fogged.shaded_at(x, y).unwrap();
            let t = textured.shaded_at(x, y).unwrap();
            darker += usize::from(b[0] < p[0]);
            bluer += usize::from(f[2] > p[2] && f[0] < p[0]);
            textured_px += usize::from((t[0] - p[0]).abs() > 1e-6);
        }
    }
    assert!(n > 100);
    assert_eq!(darker, n, "every pixel of the back face uses the back material");
    assert_eq!(bluer, n, "fog pulls every pixel towards the fog colour");
    assert!(
        textured_px > n / 4 && textured_px < 3 * n / 4,
        "{textured_px} of {n} on dark squares"
    );
}
