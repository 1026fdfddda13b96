//! The NURB surface (prims/nurb_surface.prim): evaluation of the 9-point rational quadratic
//! circle, a bicubic patch after tessellation against an f64 de Boor reference, two patches
//! sharing a curved edge without gaps or double writes, the normals, and the rejection of
//! bad weights and knots. Weights and coordinates at the extremes are in the hard-case suite,
//! tests/prims/hard_cases/nurb_extremes.rs.

use crate::support;
use support::*;

use std::sync::Arc;

use glam::DVec3;

use primflow::diag::{Diagnostics, SourceMap};
use primflow::handwritten::{Flavor, Handwritten};
use primflow::ir::Program;
use primflow::jit::Jit;
use primflow::runtime::{Frame, Registry, Renderer, Value};

/// The library plus the test probes of prims/tests/prims.
fn library_with_probes() -> Arc<Program> {
    let mut sources = SourceMap::new();
    let mut diags = Diagnostics::new();
    let probes = Registry::source_dir().join("tests").join("prims");
    match Registry::load(&mut sources, &[probes], &[], &mut diags) {
        Some(reg) => reg.program,
        None => panic!("library does not compile:\n{}", diags.render(&sources)),
    }
}

fn padded(knots: &[f32]) -> Vec<f32> {
    let mut k = knots.to_vec();
    k.resize(16, *knots.last().unwrap());
    k
}

#[test]
fn rational_quadratic_circle_has_constant_radius() {
    let program = library_with_probes();
    let radius = 3.7f64;
    let s = std::f64::consts::FRAC_1_SQRT_2;
    let corners = [
        (1.0, 0.0),
        (1.0, 1.0),
        (0.0, 1.0),
        (-1.0, 1.0),
        (-1.0, 0.0),
        (-1.0, -1.0),
        (0.0, -1.0),
        (1.0, -1.0),
        (1.0, 0.0),
    ];
    let mut points = vec![];
    for (k, (x, y)) in corners.iter().enumerate() {
        let w = if k % 2 == 1 { s } else { 1.0 };
        points.extend([(x * radius * w) as f32, (y * radius * w) as f32, 0.0, w as f32]);
    }
    points.resize(64, 0.0);
    let (columns, rows) = (64u32, 16u32);
    let mut r = renderer(&program, columns, rows, false);
    r.material_interp("C", "implicit", &[]).unwrap();
    r.material("C", &Value(vec![0.0; 3])).unwrap();
    r.begin("nurb_curve_probe").unwrap();
    r.rast_param(
        "knots",
        &Value(padded(&[0.0, 0.0, 0.0, 1.0, 1.0, 2.0, 2.0, 3.0, 3.0, 4.0, 4.0, 4.0])),
    )
    .unwrap();
    r.rast_param("points", &Value(points)).unwrap();
    r.rast_param("t_end", &Value(vec![4.0])).unwrap();
    r.rast_param("samples", &Value(vec![(columns * rows) as f32])).unwrap();
    r.end().unwrap();
    let mut jit = Jit::new(program.clone()).unwrap();
    let frame = render_with(&r, &mut jit, 2);
    let mut worst = 0.0f64;
    let mut samples = 0;
    for y in 0..rows {
        for x in 0..columns {
            assert!(frame.written(x, y), "sample ({x}, {y}) not evaluated");
            let c = frame.param_at("C", x, y).unwrap();
            let length = (f64::from(c[0]).powi(2) + f64::from(c[1]).powi(2)).sqrt();
            worst = worst.max((length - radius).abs() / radius);
            samples += 1;
        }
    }
    // The ends and the knots are the control points: (r, 0) at t = 0 and t = 4.
    let first = frame.param_at("C", 0, 0).unwrap();
    assert!(
        (f64::from(first[0]) - radius).abs() < 1e-6 && first[1].abs() < 1e-6,
        "{first:?}"
    );
    println!("circle: {samples} samples, |C(t)| relative error {worst:.2e}");
    assert!(worst < 1e-5, "|C(t)| off the radius by {worst:e} (relative)");
}

/// The 4 x 4 Bezier patch of the accuracy test, in device coordinates (identity camera).
pub(crate) fn bicubic_net() -> Vec<[f64; 3]> {
    let mut net = vec![];
    for j in 0..4 {
        for i in 0..4 {
            let (u, v) = (i as f64 / 3.0, j as f64 / 3.0);
            // A curved, non-folding map of the unit square onto about 56 x 40 pixels.
            let x = 4.0 + 54.0 * u + 6.0 * (v * 3.0 - 1.5).powi(2) * (i as f64 - 1.5).signum();
            let y = 4.0 + 38.0 * v + 5.0 * ((i as f64 * 1.7).sin());
            let z = 0.5 + 0.1 * ((i + j) as f64 / 6.0);
            net.push([x, y, z]);
        }
    }
    net
}

fn bernstein(t: f64) -> [f64; 4] {
    let s = 1.0 - t;
    [s * s * s, 3.0 * s * s * t, 3.0 * s * t * t, t * t * t]
}

fn bezier_point(net: &[[f64; 3]], u: f64, v: f64) -> [f64; 3] {
    let (bu, bv) = (bernstein(u), bernstein(v));
    let mut p = [0.0; 3];
    for j in 0..4 {
        for i in 0..4 {
            for k in 0..3 {
                p[k] += bu[i] * bv[j] * net[j * 4 + i][k];
            }
        }
    }
    p
}

/// Submit a 4 x 4 bicubic Bezier patch with `uv` (the Greville abscissae, which the spline
/// reproduces as the parameters themselves) and an implicit normal.
fn submit_patch(r: &mut Renderer, net: &[[f64; 3]], tolerance: f32) {
    r.begin("nurb_surface").unwrap();
    r.rast_param("weight", &Value(vec![1.0])).unwrap();
    r.rast_param("tolerance", &Value(vec![tolerance])).unwrap();
    for j in 0..4 {
        for i in 0..4 {
            r.material("uv", &Value(vec![i as f32 / 3.0, j as f32 / 3.0])).unwrap();
            let p = net[j * 4 + i];
            r.vertex(p[0] as f32, p[1] as f32, p[2] as f32, 1.0).unwrap();
        }
    }
    r.end().unwrap();
    assert!(r.take_warnings().is_empty());
}

#[test]
fn bicubic_patch_is_within_the_pixel_tolerance_after_tessellation() {
    let program = library();
    let net = bicubic_net();
    for tolerance in [0.5f32, 0.1] {
        let mut r = renderer(&program, 64, 48, true);
        r.material_interp("uv", "perspective_linear", &[]).unwrap();
        submit_patch(&mut r, &net, tolerance);
        let frame = render(&r, 2);
        let mut worst = 0.0f64;
        let mut covered = 0;
        for y in 0..48 {
            for x in 0..64 {
                if !frame.written(x, y) {
                    continue;
                }
                covered += 1;
                assert_eq!(frame.write_count_at(x, y), Some(1), "pixel ({x}, {y}) written twice");
                let uv = frame.param_at("uv", x, y).unwrap();
                let p = bezier_point(&net, f64::from(uv[0]), f64::from(uv[1]));
                let d = ((p[0] - (x as f64 + 0.5)).powi(2) + (p[1] - (y as f64 + 0.5)).powi(2)).sqrt();
                worst = worst.max(d);
            }
        }
        println!("bicubic tolerance {tolerance}: {covered} px, worst distance to the surface {worst:.3} px");
        assert!(covered > 1500);
        assert!(
            worst <= f64::from(tolerance),
            "tolerance {tolerance}: {worst} px off the surface"
        );
    }
}

/// Two patches side by side sharing the curved column i = 3 / i = 0: outer edges straight
/// (x = 4 and 60, y = 4 and 44), the shared edge wiggling, and different interiors.
fn two_patches() -> [Vec<[f64; 3]>; 2] {
    let shared_x = [32.0, 36.5, 27.25, 33.0];
    let mut left = vec![];
    let mut right = vec![];
    for (j, &shared) in shared_x.iter().enumerate() {
        let y = 4.0 + 40.0 * j as f64 / 3.0;
        for i in 0..4 {
            let t = i as f64 / 3.0;
            let xl = 4.0
                + (shared - 4.0) * t
                + if i == 1 || i == 2 {
                    3.0 * ((j as f64) - 1.5)
                } else {
                    0.0
                };
            let xr = shared + (60.0 - shared) * t + if i == 1 { -2.0 * (j as f64) } else { 0.0 };
            left.push([xl, y, 0.5]);
            right.push([xr, y, 0.5]);
        }
    }
    [left, right]
}

#[test]
fn patches_sharing_a_curved_edge_cover_every_pixel_once() {
    let program = library();
    let [left, right] = two_patches();
    let mut r = renderer(&program, 64, 48, true);
    r.material_interp("uv", "perspective_linear", &[]).unwrap();
    submit_patch(&mut r, &left, 0.25);
    submit_patch(&mut r, &right, 0.1); // a finer interior: different step counts inside
    let frame = render(&r, 2);
    let mut wrong = vec![];
    for y in 0..48u32 {
        for x in 0..64u32 {
            let inside = (4..60).contains(&x) && (4..44).contains(&y);
            let n = frame.write_count_at(x, y).unwrap();
            if n != u32::from(inside) {
                wrong.push((x, y, n));
            }
        }
    }
    assert!(
        wrong.is_empty(),
        "{} pixels not written exactly once inside / never outside: {:?}",
        wrong.len(),
        &wrong[..wrong.len().min(16)]
    );
}

#[test]
fn normals_come_from_the_surface_derivatives() {
    // A cylinder piece z = sqrt(R^2 - x^2) seen from above (orthographic, identity camera):
    // a rational quadratic in u (a 90-degree arc), straight in v.
    let program = library();
    let mut r = renderer(&program, 64, 48, false);
    r.material_interp("N", "implicit", &[]).unwrap();
    r.material("N", &Value(vec![0.0, 0.0, 1.0])).unwrap();
    let (cx, radius) = (32.0f32, 24.0f32);
    let s = std::f32::consts::FRAC_1_SQRT_2;
    r.begin("nurb_surface").unwrap();
    r.rast_param("u_count", &Value(vec![3.0])).unwrap();
    r.rast_param("u_order", &Value(vec![3.0])).unwrap();
    r.rast_param("v_count", &Value(vec![2.0])).unwrap();
    r.rast_param("v_order", &Value(vec![2.0])).unwrap();
    r.rast_param("u_knots", &Value(padded(&[0.0, 0.0, 0.0, 1.0, 1.0, 1.0])))
        .unwrap();
    r.rast_param("v_knots", &Value(padded(&[0.0, 0.0, 1.0, 1.0]))).unwrap();
    r.rast_param("tolerance", &Value(vec![0.1])).unwrap();
    // The arc from angle 135 to 45 degrees over the x axis, height in z (scaled to depth):
    // Euclidean control points (x, z) and weights; the middle one is where the end
    // tangents meet, (0, R sqrt 2), with weight cos 45.
    let arc = [(-s, s, 1.0), (0.0, 2.0 * s, s), (s, s, 1.0)];
    for y in [4.0f32, 44.0] {
        for &(ax, az, w) in &arc {
            r.rast_param("weight", &Value(vec![w])).unwrap();
            r.vertex(cx + radius * ax, y, radius * az / 64.0, 1.0).unwrap();
        }
    }
    r.end().unwrap();
    assert!(r.take_warnings().is_empty());
    let frame = render(&r, 1);
    // Device space here is the object space: x, y in pixels, z scaled by 1/64. The surface
    // is x' = x - cx, z' = 64 z with x'^2 + z'^2 = R^2; its normal in object coordinates is
    // the gradient of (x'^2 + (64 z)^2), i.e. (x', 0, 64 * 64 z) normalised.
    let mut worst = 0.0f64;
    let mut checked = 0;
    for y in 6..42 {
        for x in 16..48 {
            if !frame.written(x, y) {
                continue;
            }
            let n = frame.param_at("N", x, y).unwrap();
            let xp = x as f64 + 0.5 - cx as f64;
            let zp = (radius as f64 * radius as f64 - xp * xp).sqrt();
            let g = [xp, 0.0, 64.0 * zp];
            let gl = (g[0] * g[0] + g[2] * g[2]).sqrt();
            // Oriented either way by the parametrisation: compare up to sign.
            let sign = if f64::from(n[2]) * g[2] < 0.0 { -1.0 } else { 1.0 };
            let err = (0..3)
                .map(|k| (sign * f64::from(n[k]) - g[k] / gl).abs())
                .fold(0.0, f64::max);
            worst = worst.max(err);
            checked += 1;
        }
    }
    println!("cylinder normals: {checked} px, worst error {worst:.2e}");
    assert!(checked > 500);
    // Normals are exact at the tessellation vertices and interpolated (not renormalised)
    // between them: about 1 - cos(half the angle step) off in between.
    assert!(worst < 5e-3, "normal off by {worst}");
}

/// Render one patch with the given changes (and control point 5 weighted `weight5`) and
/// return its frame and diagnostic codes.
fn render_patch(weight5: f32, edit: impl Fn(&mut Renderer)) -> (Frame, Vec<String>) {
    let program = library();
    let mut r = renderer(&program, 64, 48, false);
    r.begin("nurb_surface").unwrap();
    edit(&mut r);
    let net = bicubic_net();
    for (i, p) in net.iter().enumerate() {
        r.rast_param("weight", &Value(vec![if i == 5 { weight5 } else { 1.0 }]))
            .unwrap();
        r.vertex(p[0] as f32, p[1] as f32, p[2] as f32, 1.0).unwrap();
    }
    r.end().unwrap();
    let mut jit = Jit::new(program.clone()).unwrap();
    let out = r.render(&mut jit);
    let messages = out
        .diags
        .items
        .iter()
        .map(|d| format!("{} {:?}", d.code, d.labels))
        .collect();
    (out.frame, messages)
}

pub(crate) fn covered(frame: &Frame) -> usize {
    (0..frame.height)
        .flat_map(|y| (0..frame.width).map(move |x| (x, y)))
        .filter(|&(x, y)| frame.written(x, y))
        .count()
}

#[test]
fn bad_weights_and_knots_are_rejected_with_the_reason() {
    type Edit = Box<dyn Fn(&mut Renderer)>;
    let cases: [(&str, f32, Edit); 6] = [
        ("weight near zero", 1e-9, Box::new(|_: &mut Renderer| {})),
        ("weight zero", 0.0, Box::new(|_: &mut Renderer| {})),
        ("weight negative", -0.5, Box::new(|_: &mut Renderer| {})),
        (
            "knots_must_not_decrease",
            1.0,
            Box::new(|r: &mut Renderer| {
                r.rast_param("u_knots", &Value(padded(&[0.0, 0.0, 0.0, 0.0, 1.0, 0.5, 1.0, 1.0])))
                    .unwrap()
            }),
        ),
        (
            "order_must_be_2_to_4",
            1.0,
            Box::new(|r: &mut Renderer| r.rast_param("u_order", &Value(vec![5.0])).unwrap()),
        ),
        (
            "count_must_be_order_to_12",
            1.0,
            Box::new(|r: &mut Renderer| r.rast_param("u_count", &Value(vec![5.0])).unwrap()),
        ),
    ];
    for (reason, weight5, edit) in cases {
        let (frame, diags) = render_patch(weight5, edit);
        assert_eq!(covered(&frame), 0, "{reason}: something was drawn");
        assert_eq!(diags.len(), 1, "{reason}: {diags:?}");
        assert!(diags[0].starts_with("W0801"), "{reason}: {diags:?}");
    }
    // The label of the warning names the reason through the array the check indexes.
    let mut sources = SourceMap::new();
    let mut d = Diagnostics::new();
    let reg = Registry::load(&mut sources, &[], &[], &mut d).unwrap();
    let mut r = Renderer::new(reg.program.clone());
    r.set_image_size(64, 48).unwrap();
    r.begin("nurb_surface").unwrap();
    for (i, p) in bicubic_net().iter().enumerate() {
        r.rast_param("weight", &Value(vec![if i == 5 { 0.0 } else { 1.0 }]))
            .unwrap();
        r.vertex(p[0] as f32, p[1] as f32, p[2] as f32, 1.0).unwrap();
    }
    r.end().unwrap();
    let mut jit = Jit::new(reg.program.clone()).unwrap();
    let out = r.render(&mut jit);
    let text = out.diags.render(&sources);
    assert!(text.contains("rejected_weights_must_be_positive"), "{text}");
    assert!(text.contains("nurb_surface.prim:"), "{text}");
}

#[test]
fn small_positive_weights_and_double_knots_are_handled() {
    // A small weight (1e-4 of the others) pushes the surface away from its control point but
    // is a valid rational surface: drawn. The step-count bound divides by the smallest
    // control weight, so it asks for more than the 128-step cap here: drawn at the cap with
    // that one W0801 warning (the surface itself is far smoother than the bound says).
    let (frame, diags) = render_patch(1e-4, |_: &mut Renderer| {});
    assert_eq!(diags.len(), 1, "{diags:?}");
    assert!(diags[0].starts_with("W0801"), "{diags:?}");
    assert!(covered(&frame) > 1000);
    // An interior knot (order 3, 4 control points per row: knots 0 0 0 0.5 1 1 1).
    let (frame, diags) = render_patch(1.0, |r: &mut Renderer| {
        r.rast_param("u_order", &Value(vec![3.0])).unwrap();
        r.rast_param("u_knots", &Value(padded(&[0.0, 0.0, 0.0, 0.5, 1.0, 1.0, 1.0])))
            .unwrap();
    });
    assert!(diags.is_empty(), "{diags:?}");
    assert!(covered(&frame) > 1000);
    // Order 2 with an interior knot repeated twice (multiplicity = order): the surface would
    // break apart there; rejected.
    let (frame, diags) = render_patch(1.0, |r: &mut Renderer| {
        r.rast_param("u_order", &Value(vec![2.0])).unwrap();
        r.rast_param("u_knots", &Value(padded(&[0.0, 0.0, 0.5, 0.5, 1.0, 1.0])))
            .unwrap();
    });
    assert_eq!(covered(&frame), 0);
    assert_eq!(diags.len(), 1, "{diags:?}");
}

/// The language extension nurb_surface relies on: a list of numbers converts to
/// interpolation data only inside a named `interpolation` arm (where the data is narrowed to
/// that kind's parameters), and an `interpolation` construct may compute in setup code.
#[test]
fn number_list_is_interpolation_data_only_inside_a_named_arm() {
    let compile = |body: &str| {
        let text = format!(
            "primitive p(interpolator_data d[3]; varying float X, Y; inout varying fixed<32,32> Z) {{\n\
             float n[3] = {{0, 0, 1}};\ninterpolation_data v = d[0];\n{body}\n}}\n"
        );
        let mut sources = SourceMap::new();
        let file = sources.add("p.prim", text);
        let mut diags = Diagnostics::new();
        let program = primflow::compile(&sources, &[file], &mut diags);
        (program.is_some(), diags.codes_at(&sources))
    };
    let (ok, codes) = compile("interpolation { implicit: v = n; }");
    assert!(ok, "{codes:?}");
    let (ok, codes) = compile("v = n;");
    assert!(!ok);
    assert_eq!(codes, vec!["E0205@4:5"]);
    let (ok, codes) = compile("interpolation { default: v = n; }");
    assert!(!ok);
    assert_eq!(codes, vec!["E0205@4:30"]);
}

/// Render the flat bilinear patch z = 0, x, y in [-1, 1] (object space; u along x, v along
/// y, so its object-space normal is +z) through a perspective camera under the model
/// transform `model`, N bound `implicit`; return the frame and lighting_from_object.
fn render_flat_patch_under(model: &dyn Fn(&mut Renderer)) -> (Frame, glam::DMat4) {
    let program = library();
    let mut r = renderer(&program, 64, 64, false);
    r.perspective_checked(40.0, 1.0, 50.0).unwrap();
    r.look_at([1.0, 0.5, 5.0], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0]).unwrap();
    model(&mut r);
    r.material_interp("N", "implicit", &[]).unwrap();
    r.material("N", &Value(vec![0.0, 0.0, 1.0])).unwrap();
    r.begin("nurb_surface").unwrap();
    for (name, value) in [("u_count", 2.0), ("v_count", 2.0), ("u_order", 2.0), ("v_order", 2.0)] {
        r.rast_param(name, &Value(vec![value])).unwrap();
    }
    r.rast_param("u_knots", &Value(padded(&[0.0, 0.0, 1.0, 1.0]))).unwrap();
    r.rast_param("v_knots", &Value(padded(&[0.0, 0.0, 1.0, 1.0]))).unwrap();
    r.rast_param("weight", &Value(vec![1.0])).unwrap();
    for y in [-1.0f32, 1.0] {
        for x in [-1.0f32, 1.0] {
            r.vertex(x, y, 0.0, 1.0).unwrap();
        }
    }
    r.end().unwrap();
    let warnings = r.take_warnings();
    assert!(warnings.is_empty(), "{warnings:?}");
    let lighting_from_object = r.geometry.lighting_from_object();
    (render(&r, 1), lighting_from_object)
}

/// The implicit normal is returned in LIGHTING coordinates (where the shading pass lights),
/// not in object coordinates: under a rotating, a non-uniformly scaling and a mirroring
/// model transform, every covered pixel's N equals the analytic lighting-space normal of
/// the flat patch, normalise(inverse transpose of lighting_from_object * (0, 0, 1)) in f64,
/// on the same side of the surface (the mirror flips the cofactor matrix, the handedness
/// flips it back). Each case's answer differs from the object-space normal (0, 0, 1),
/// which the prim returned before.
#[test]
fn normals_are_returned_in_lighting_coordinates_under_model_transforms() {
    type Model = fn(&mut Renderer);
    let cases: [(&str, Model); 3] = [
        ("rotated", |r| r.rotate(50.0, [0.3, 1.0, 0.2]).unwrap()),
        ("non-uniformly scaled", |r| {
            // Scale after the rotation (in world), so the scale axes are oblique to the
            // patch: the normal is not the scaled normal.
            r.scale([1.8, 0.5, 1.3]).unwrap();
            r.rotate(40.0, [1.0, 1.0, 0.0]).unwrap();
        }),
        ("mirrored", |r| {
            r.scale([1.0, 1.0, -1.0]).unwrap();
            r.rotate(35.0, [1.0, 0.2, 0.0]).unwrap();
        }),
    ];
    for (name, model) in cases {
        let (frame, lighting_from_object) = render_flat_patch_under(&model);
        let linear = glam::DMat3::from_mat4(lighting_from_object);
        let expected = (linear.inverse().transpose() * DVec3::Z).normalize();
        assert!(
            (expected - DVec3::Z).abs().max_element() > 0.1,
            "{name}: the case does not tell lighting from object space ({expected:?})"
        );
        let (mut covered, mut worst) = (0, 0.0f64);
        for y in 0..frame.height {
            for x in 0..frame.width {
                if !frame.written(x, y) {
                    continue;
                }
                let n = frame.param_at("N", x, y).unwrap();
                let got = DVec3::new(n[0].into(), n[1].into(), n[2].into());
                worst = worst.max((got - expected).abs().max_element());
                covered += 1;
            }
        }
        println!("{name}: {covered} px, expected {expected:.4?}, worst error {worst:.2e}");
        assert!(covered > 200, "{name}: only {covered} pixels covered");
        assert!(worst < 1e-4, "{name}: N off the lighting-space normal by {worst:e}");
    }
}

/// The hand-written NURB kernels (scalar and AVX2) map the normal to lighting coordinates
/// with the prim's operations in the prim's order: on a curved rational patch under a
/// mirroring, non-uniformly scaling, turning model matrix (every cofactor column and the
/// handedness matter), their N planes and depth equal the JIT's bit for bit.
#[test]
fn handwritten_kernels_map_the_normal_like_the_prim_bit_for_bit() {
    let program = library();
    let mut r = renderer(&program, 64, 64, false);
    r.perspective_checked(40.0, 1.0, 50.0).unwrap();
    r.look_at([1.0, 0.5, 5.0], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0]).unwrap();
    r.scale([1.0, 1.6, -0.7]).unwrap();
    r.rotate(35.0, [1.0, 0.2, 0.3]).unwrap();
    r.material_interp("N", "implicit", &[]).unwrap();
    r.material("N", &Value(vec![0.0, 0.0, 1.0])).unwrap();
    r.begin("nurb_surface").unwrap();
    for (name, value) in [("u_count", 3.0), ("v_count", 3.0), ("u_order", 3.0), ("v_order", 3.0)] {
        r.rast_param(name, &Value(vec![value])).unwrap();
    }
    r.rast_param("u_knots", &Value(padded(&[0.0, 0.0, 0.0, 1.0, 1.0, 1.0])))
        .unwrap();
    r.rast_param("v_knots", &Value(padded(&[0.0, 0.0, 0.0, 1.0, 1.0, 1.0])))
        .unwrap();
    r.rast_param("tolerance", &Value(vec![0.25])).unwrap();
    for j in 0..3 {
        for i in 0..3 {
            let (x, y) = (i as f32 - 1.0, j as f32 - 1.0);
            let bulge = if i == 1 && j == 1 { 0.9 } else { 0.3 * (x * y) };
            r.rast_param("weight", &Value(vec![if i == 1 && j == 1 { 1.7 } else { 1.0 }]))
                .unwrap();
            r.vertex(x, y, bulge, 1.0).unwrap();
        }
    }
    r.end().unwrap();
    let warnings = r.take_warnings();
    assert!(warnings.is_empty(), "{warnings:?}");
    let jit = render(&r, 2);
    let covered = (0..jit.height)
        .flat_map(|y| (0..jit.width).map(move |x| (x, y)))
        .filter(|&(x, y)| jit.written(x, y))
        .count();
    assert!(covered > 300, "only {covered} pixels");
    for flavor in [Flavor::Scalar, Flavor::Avx2] {
        let mut hand = Handwritten::new(program.clone(), flavor);
        let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
        let out = pool.install(|| r.render(&mut hand));
        assert!(
            out.diags.items.is_empty(),
            "{}: {:?}",
            flavor.describe(),
            out.diags.items
        );
        let depth_diff = jit
            .depth_values()
            .iter()
            .zip(&out.frame.depth_values())
            .filter(|(a, b)| a != b)
            .count();
        assert_eq!(
            depth_diff,
            0,
            "{}: depth differs in {depth_diff} pixels",
            flavor.describe()
        );
        assert_eq!(jit.num_planes(), out.frame.num_planes());
        for (p, (a, b)) in jit
            .all_plane_values()
            .iter()
            .zip(&out.frame.all_plane_values())
            .enumerate()
        {
            let differing = a.iter().zip(b).filter(|(x, y)| x.to_bits() != y.to_bits()).count();
            assert_eq!(
                differing,
                0,
                "{}: plane {p} differs in {differing} pixels",
                flavor.describe()
            );
        }
    }
}
