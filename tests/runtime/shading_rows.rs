//! The fused row pass of the fast shading kernels (`Shader::shade_row`) on what the scenes
//! of tests/runtime/shading_fast.rs do not reach: rows whose width is not a whole number of chunks
//! (the tail chunk), bands of rows shaded in parallel (any thread count gives the same bits),
//! a texture naming a parameter the frame lacks (the base colour stays `Cs`, as in the
//! reference), and shininess on both power paths (integer exponents by repeated squaring,
//! others and two-sided exponents by the polynomial power).
//!
//! Bound as in tests/runtime/shading_fast.rs: every shaded channel within 1/4096 of
//! `ShadingKernel::ReferenceF64`, the 8-bit image off by one on at most 2% of covered pixels.

use crate::support;

use std::f64::consts::PI;

use primflow::runtime::shading::{Fog, SceneLight, ShadingKernel, SurfaceMaterial, Texture};
use primflow::runtime::{Frame, Renderer, Value};

/// Neither a multiple of the 8-pixel chunk nor of the 8-row band.
const W: u32 = 61;
const H: u32 = 43;
const CHANNEL_BOUND: f32 = 1.0 / 4096.0;

/// A lit sphere filling most of a `W x H` view (so the row tails are covered), four lights
/// (directional and positional), a highlight of `shininess`.
fn sphere_scene(shininess: f64) -> Renderer {
    let program = support::library();
    let mut r = support::renderer(&program, W, H, false);
    r.perspective_checked(60.0, 0.2, 20.0).unwrap();
    r.look_at([0.2, 0.3, 1.4], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0]).unwrap();
    r.shading_setup.front = SurfaceMaterial {
        ka: 0.3,
        kd: 0.8,
        ks: 0.6,
        shininess,
        specular_colour: [1.0, 0.9, 0.8],
    };
    r.shading_setup.lights = vec![
        SceneLight::Directional {
            towards_light: [1.0, 1.0, 0.8],
            colour: [0.7, 0.7, 0.7],
        },
        SceneLight::Directional {
            towards_light: [-0.3, -0.2, -1.0],
            colour: [0.5, 0.2, 0.9],
        },
        SceneLight::Positional {
            position: [-1.2, 1.5, 1.5],
            colour: [0.6, 0.5, 0.4],
            attenuation: [1.0, 0.1, 0.05],
        },
    ];
    for name in ["Cs", "N", "st"] {
        r.material_interp(name, "perspective_linear", &[]).unwrap();
    }
    r.material("Cs", &Value(vec![0.9, 0.7, 0.5])).unwrap();
    let (rings, segments) = (12, 18);
    let at = |i: usize, j: usize| {
        let theta = PI * i as f64 / rings as f64;
        let phi = 2.0 * PI * j as f64 / segments as f64;
        [theta.sin() * phi.cos(), theta.cos(), theta.sin() * phi.sin()]
    };
    let mut triangle = |p: [[f64; 3]; 3]| {
        r.begin("triangle").unwrap();
        for q in p {
            r.material("N", &Value(q.map(|c| c as f32).to_vec())).unwrap();
            r.material("st", &Value(vec![(q[0] * 2.0) as f32, (q[1] * 2.0) as f32]))
                .unwrap();
            r.vertex(q[0] as f32, q[1] as f32, q[2] as f32, 1.0).unwrap();
        }
        r.end().unwrap();
    };
    for i in 0..rings {
        for j in 0..segments {
            let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
            triangle([a, c, b]);
            triangle([a, d, c]);
        }
    }
    r
}

fn frame(r: &mut Renderer, kernel: ShadingKernel, threads: usize) -> Frame {
    r.take_warnings();
    r.shading_setup.kernel = kernel;
    support::render(r, threads)
}

/// Asserts the bound between the reference and the fast frame; returns (covered pixels,
/// worst channel error, covered pixels in the last, partial chunk of their row).
fn check(name: &str, reference: &Frame, fast: &Frame) -> (usize, f32, usize) {
    let (mut covered, mut worst, mut off_by_one, mut in_tail) = (0, 0f32, 0, 0);
    let (ri, fi) = (reference.to_rgb8(), fast.to_rgb8());
    for y in 0..H {
        for x in 0..W {
            assert_eq!(reference.written(x, y), fast.written(x, y), "{name}: ({x}, {y})");
            let (a, b) = (reference.shaded_at(x, y).unwrap(), fast.shaded_at(x, y).unwrap());
            if !reference.written(x, y) {
                assert_eq!(b, [0.0; 3], "{name}: unwritten pixel ({x}, {y}) was shaded");
                continue;
            }
            covered += 1;
            in_tail += usize::from(x >= W / 8 * 8);
            for k in 0..3 {
                assert!(b[k].is_finite(), "{name}: non-finite colour at ({x}, {y})");
                worst = worst.max((a[k] - b[k]).abs());
            }
            let (p, q) = (ri.get_pixel(x, y).0, fi.get_pixel(x, y).0);
            let diff = (0..3).map(|k| p[k].abs_diff(q[k])).max().unwrap_or(0);
            assert!(diff <= 1, "{name}: 8-bit colour off by {diff} at ({x}, {y})");
            off_by_one += usize::from(diff == 1);
        }
    }
    println!(
        "{name}: {covered} covered ({in_tail} in row tails), worst channel error {worst:.3e}, {off_by_one} off by one"
    );
    assert!(worst <= CHANNEL_BOUND, "{name}: channel error {worst} > 1/4096");
    assert!(
        off_by_one * 50 <= covered,
        "{name}: {off_by_one} of {covered} off by one"
    );
    (covered, worst, in_tail)
}

#[test]
fn row_tails_match_the_reference_and_any_thread_count_gives_the_same_bits() {
    let mut r = sphere_scene(90.0);
    r.shading_setup.fog = Some(Fog {
        colour: [0.1, 0.2, 0.6],
        start: 0.5,
        end: 1.2,
    });
    r.shading_setup.texture = Some(Texture {
        param: "st".into(),
        scale: 3.0,
        dark: 0.3,
    });
    let reference = frame(&mut r, ShadingKernel::ReferenceF64, 1);
    let one = frame(&mut r, ShadingKernel::Simd, 1);
    let (covered, _, in_tail) = check("61 x 43, fog and texture", &reference, &one);
    assert!(covered > 1000, "only {covered} pixels covered");
    assert!(in_tail > 50, "only {in_tail} covered pixels in row tails");
    for threads in [2, 3] {
        let many = frame(&mut r, ShadingKernel::Simd, threads);
        for y in 0..H {
            for x in 0..W {
                let bits = |f: &Frame| f.shaded_at(x, y).unwrap().map(f32::to_bits);
                assert_eq!(bits(&one), bits(&many), "{threads} threads differ at ({x}, {y})");
            }
        }
    }
    let portable = frame(&mut r, ShadingKernel::Portable, 2);
    for y in 0..H {
        for x in 0..W {
            let bits = |f: &Frame| f.shaded_at(x, y).unwrap().map(f32::to_bits);
            assert_eq!(bits(&one), bits(&portable), "portable differs at ({x}, {y})");
        }
    }
}

#[test]
fn a_texture_naming_a_missing_parameter_keeps_cs() {
    // The reference leaves the base colour at `Cs` when the texture's parameter is absent;
    // the fast pass must too (not black).
    let mut r = sphere_scene(32.0);
    r.shading_setup.texture = Some(Texture {
        param: "no_such_parameter".into(),
        scale: 3.0,
        dark: 0.3,
    });
    let reference = frame(&mut r, ShadingKernel::ReferenceF64, 1);
    let fast = frame(&mut r, ShadingKernel::Simd, 1);
    check("texture without its parameter", &reference, &fast);
    // Ambient 0.2 x ka 0.3 x Cs red 0.9 at least, everywhere covered.
    let mut covered = 0;
    for y in 0..H {
        for x in 0..W {
            if fast.written(x, y) {
                covered += 1;
                assert!(fast.shaded_at(x, y).unwrap()[0] >= 0.05, "({x}, {y}) is dark");
            }
        }
    }
    assert!(covered > 1000);
}

#[test]
fn shininess_on_both_power_paths_matches_the_reference() {
    // Integer exponents up to 128 shared by both sides take repeated squaring; fractional,
    // larger, or different per side take the polynomial power.
    let back = |shininess: f64| SurfaceMaterial {
        ka: 0.2,
        kd: 0.5,
        ks: 0.9,
        shininess,
        specular_colour: [0.3, 1.0, 0.3],
    };
    let cases: [(&str, f64, Option<SurfaceMaterial>); 9] = [
        ("shininess 1", 1.0, None),
        ("shininess 7", 7.0, None),
        ("shininess 32", 32.0, None),
        ("shininess 128", 128.0, None),
        ("shininess 128.5", 128.5, None),
        ("shininess 1000", 1000.0, None),
        ("shininess 1024 (the fast domain's end)", 1024.0, None),
        ("shininess 32, back 32", 32.0, Some(back(32.0))),
        ("shininess 32, back 400", 32.0, Some(back(400.0))),
    ];
    for (name, shininess, back_material) in cases {
        let mut r = sphere_scene(shininess);
        r.shading_setup.back = back_material;
        let reference = frame(&mut r, ShadingKernel::ReferenceF64, 1);
        let fast = frame(&mut r, ShadingKernel::Simd, 1);
        check(name, &reference, &fast);
    }
}
