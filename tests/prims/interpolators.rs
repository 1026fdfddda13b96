//! The shared interpolators (prims/interpolators.prim) on different primitives: the
//! cylindrical interpolator gives the same value on a sphere and on a triangle at the same
//! screen point and depth, and both match its formula in f64; the solid-space interpolator
//! on a sphere gives back the sphere's surface point; the planar one is linear on a triangle.

use crate::support;
use support::*;

use glam::Mat4;
use primflow::runtime::{transform, Frame, Renderer, Value};

const W: u32 = 64;
const H: u32 = 48;

/// Device (X, Y, Z) to cylinder space: the angle turns with x around the centre column and
/// depends on depth strongly (500 per depth unit), so a wrong Z would show.
const CYLINDER: [f32; 16] = [
    1.0, 0.0, 0.0, 0.0, //
    1.0, 0.0, 0.0, -32.0, //
    0.0, 1.0, 500.0, -474.0, //
    0.0, 0.0, 0.0, 1.0,
];
const START: f32 = 0.25;
const END: f32 = 2.0;

/// Figure 10's formula in f64.
fn cylindrical(x: f64, y: f64, z: f64) -> f64 {
    let m = |i: usize| f64::from(CYLINDER[i]);
    let p = [x, y, z, 1.0];
    let row = |r: usize| (0..4).map(|k| m(4 * r + k) * p[k]).sum::<f64>();
    let (start, end) = (f64::from(START), f64::from(END));
    (end - start) * row(1).atan2(row(2)) / 2.0 / std::f64::consts::PI + start
}

fn bind_cylinder(r: &mut Renderer) {
    r.material_interp(
        "u",
        "cylindrical_interpolation",
        &[
            ("cylinder_transform".to_string(), Value(CYLINDER.to_vec())),
            ("cylinder_start".to_string(), Value(vec![START])),
            ("cylinder_end".to_string(), Value(vec![END])),
        ],
    )
    .unwrap();
    r.material("u", &Value(vec![0.0])).unwrap();
}

fn camera() -> Mat4 {
    transform::perspective(50.0, 1.0, 20.0, W, H)
}

fn sphere(r: &mut Renderer, center: [f32; 3], radius: f32) {
    r.begin("sphere").unwrap();
    r.rast_param("center", &Value(center.to_vec())).unwrap();
    r.rast_param("radius", &Value(vec![radius])).unwrap();
    r.end().unwrap();
}

fn depth(frame: &Frame, x: u32, y: u32) -> f64 {
    f64::from(frame.depth_at(x, y).unwrap()) / 4294967296.0
}

#[test]
fn cylindrical_interpolator_agrees_on_a_sphere_and_a_triangle() {
    let program = library();
    let mut r = renderer(&program, W, H, false);
    r.set_transform(camera());
    bind_cylinder(&mut r);
    sphere(&mut r, [0.2, -0.1, -4.0], 1.2);
    let spheres = render(&r, 2);

    // For a handful of covered pixels, a device-space triangle around the pixel at the
    // sphere's depth there: same screen point, same Z.
    let pixels: Vec<(u32, u32)> = [(32, 24), (25, 20), (40, 30), (30, 33), (38, 17)]
        .into_iter()
        .filter(|&(x, y)| spheres.written(x, y))
        .collect();
    assert_eq!(pixels.len(), 5, "the chosen pixels must be on the sphere");
    let mut r = renderer(&program, W, H, false);
    bind_cylinder(&mut r);
    for &(x, y) in &pixels {
        let z = depth(&spheres, x, y) as f32;
        let (cx, cy) = (x as f32 + 0.5, y as f32 + 0.5);
        r.begin("triangle").unwrap();
        for (dx, dy) in [(-1.0, -1.0), (1.5, -0.5), (0.0, 1.5)] {
            r.vertex(cx + dx, cy + dy, z, 1.0).unwrap();
        }
        r.end().unwrap();
    }
    let triangles = render(&r, 2);

    let mut worst_between = 0.0f64;
    let mut worst_formula = 0.0f64;
    for &(x, y) in &pixels {
        let on_sphere = f64::from(spheres.param_at("u", x, y).unwrap()[0]);
        let on_triangle = f64::from(triangles.param_at("u", x, y).unwrap()[0]);
        let (zs, zt) = (depth(&spheres, x, y), depth(&triangles, x, y));
        assert!((zs - zt).abs() < 1e-6, "pixel ({x}, {y}): depths {zs} and {zt} differ");
        worst_between = worst_between.max((on_sphere - on_triangle).abs());
        let want = cylindrical(x as f64 + 0.5, y as f64 + 0.5, zs);
        worst_formula = worst_formula
            .max((on_sphere - want).abs())
            .max((on_triangle - want).abs());
    }
    println!("cylindrical: sphere vs triangle {worst_between:.2e}, vs f64 formula {worst_formula:.2e}");
    assert!(worst_between < 1e-5, "sphere and triangle differ by {worst_between:e}");
    assert!(
        worst_formula < 1e-5,
        "interpolator off its formula by {worst_formula:e}"
    );
    // The values are not all the same (the test would prove nothing).
    let values: Vec<f32> = pixels
        .iter()
        .map(|&(x, y)| spheres.param_at("u", x, y).unwrap()[0])
        .collect();
    let spread = values.iter().fold(f32::MIN, |a, &b| a.max(b)) - values.iter().fold(f32::MAX, |a, &b| a.min(b));
    assert!(spread > 0.1, "values {values:?}");
}

#[test]
fn solid_interpolator_on_a_sphere_gives_its_surface_point() {
    let program = library();
    let mut r = renderer(&program, W, H, false);
    let device_from_object = camera();
    r.set_transform(device_from_object);
    let object_from_device = device_from_object.as_dmat4().inverse().as_mat4();
    let rows = transform::to_rows(&object_from_device);
    r.material_interp(
        "P",
        "solid_interpolation",
        &[("solid_transform".to_string(), Value(rows.to_vec()))],
    )
    .unwrap();
    r.material("P", &Value(vec![0.0; 3])).unwrap();
    r.material_interp("N", "implicit", &[]).unwrap();
    r.material("N", &Value(vec![0.0, 0.0, 1.0])).unwrap();
    let (center, radius) = ([0.3f32, 0.2, -5.0], 1.5f32);
    sphere(&mut r, center, radius);
    let frame = render(&r, 2);
    let mut covered = 0;
    let mut worst = 0.0f64;
    for y in 0..H {
        for x in 0..W {
            if !frame.written(x, y) {
                continue;
            }
            covered += 1;
            let p = frame.param_at("P", x, y).unwrap();
            let n = frame.param_at("N", x, y).unwrap();
            for k in 0..3 {
                // The surface point from the sphere's own normal: c + r n.
                let want = f64::from(center[k]) + f64::from(radius) * f64::from(n[k]);
                worst = worst.max((f64::from(p[k]) - want).abs());
            }
        }
    }
    println!("solid: {covered} px, surface point error {worst:.2e}");
    assert!(covered > 300);
    // The depth buffer's 32 bits, through the projective inverse, bound the accuracy.
    assert!(worst < 1e-5, "solid point off by {worst:e}");
}

#[test]
fn planar_interpolator_is_linear_on_a_triangle() {
    let program = library();
    let mut r = renderer(&program, W, H, false);
    // Identity solid space (device space itself); plane x + 2y - 40 = 0 scaled by 0.5.
    r.material_interp(
        "h",
        "planar_interpolation",
        &[
            ("plane".to_string(), Value(vec![1.0, 2.0, 0.0, -40.0])),
            ("scale".to_string(), Value(vec![0.5])),
            ("offset".to_string(), Value(vec![3.0])),
        ],
    )
    .unwrap();
    r.material("h", &Value(vec![0.0])).unwrap();
    r.begin("polygon").unwrap();
    for (x, y) in [(4.0, 4.0), (60.0, 6.0), (50.0, 44.0), (6.0, 40.0)] {
        r.vertex(x, y, 0.5, 1.0).unwrap();
    }
    r.end().unwrap();
    let frame = render(&r, 1);
    let mut covered = 0;
    for y in 0..H {
        for x in 0..W {
            if frame.written(x, y) {
                covered += 1;
                let want = 0.5 * ((x as f64 + 0.5) + 2.0 * (y as f64 + 0.5) - 40.0) + 3.0;
                let got = f64::from(frame.param_at("h", x, y).unwrap()[0]);
                assert!((got - want).abs() < 1e-4, "({x}, {y}): {got} vs {want}");
            }
        }
    }
    assert!(covered > 1000);
}

#[test]
fn unknown_interpolator_argument_is_rejected() {
    let program = library();
    let mut r = renderer(&program, W, H, false);
    let issue = r
        .material_interp(
            "u",
            "cylindrical_interpolation",
            &[("radius".to_string(), Value(vec![1.0]))],
        )
        .unwrap_err();
    assert_eq!(issue.code, "E0707");
    assert!(issue.message.contains("no parameter `radius`"), "{}", issue.message);
}
