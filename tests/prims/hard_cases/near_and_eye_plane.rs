//! Spheres at the near (hither) plane and the eye plane: one a unit in front of the eye,
//! one cut by the hither plane, spheres crossing the eye plane (beside, around and across
//! the view), and spheres behind the eye, against f64 ray-sphere references (pbrt-v4).

use crate::sphere::{assert_figures, check};
use crate::support::*;

use glam::{DMat4, DVec3, Mat4};
use primflow::runtime::{transform, Frame, Value};

/// Source (this test and the next): the f64 ray-sphere reference of tests/prims/sphere.rs
/// (pbrt-v4 `Sphere::BasicIntersect`: both roots, the nearer one between the hither and
/// yon planes); tolerance (`assert_figures`): coverage exact except within 0.5 px of the
/// silhouette or the hither cut, depth within 1e-4 relative, normal components within 1e-4.
#[test]
fn huge_sphere_one_unit_in_front_of_the_eye() {
    // Radius 1e4, centre 10001 away, slightly off axis: the surface is about one unit in
    // front of the eye and fills the view. The near plane is at 0.5.
    let m = transform::perspective(60.0, 0.5, 3e4, 64, 48);
    let fig = check(m, 64, 48, [3.0, -2.0, -10001.0], 1e4);
    assert_figures("huge near", &fig, 64 * 48);
}

#[test]
fn sphere_cut_by_the_hither_plane_shows_its_far_side() {
    // Centre 1.2 in front of the eye, radius 0.8: the near plane at 1 cuts it; through the
    // cut the far side is visible (depth below 1, normals pointing away).
    let m = transform::perspective(90.0, 1.0, 10.0, 64, 48);
    let fig = check(m, 64, 48, [0.0, 0.0, -1.2], 0.8);
    assert_figures("hither cut", &fig, 500);
}

/// Spheres whose nearest point is 1e-2 to 1e-6 in front of or behind the hither plane, or
/// exactly on it (a tangent cut), and spheres whose centre lies on the hither plane, one
/// small (half of it cut away: its inside shows through the cut) and one holding the eye (a
/// sky sphere). Source: the f64 ray-sphere reference of tests/prims/sphere.rs (pbrt-v4's
/// two roots, the nearer one between the hither and yon planes: where the hither plane cuts
/// the sphere the far side shows, docs/primitives.md); tolerance (`assert_figures`): coverage
/// exact except within 0.5 px of the silhouette or the cut, depth within 1e-4 relative,
/// normal components within 1e-4.
#[test]
fn spheres_touching_or_centred_on_the_hither_plane_match_the_analytic_answer() {
    let near = 1.0f32;
    let m = transform::perspective(60.0, near, 20.0, 64, 48);
    for gap in [1e-2f32, 1e-4, 1e-6, 0.0, -1e-6, -1e-4, -1e-2] {
        // Radius 1, nearest point `gap` beyond the hither plane (negative: cut).
        let fig = check(m, 64, 48, [0.2, -0.1, -(near + 1.0 + gap)], 1.0);
        assert_figures(&format!("hither gap {gap:e}"), &fig, 1000);
    }
    let fig = check(m, 64, 48, [0.1, 0.05, -near], 0.5);
    assert_figures("centre on the hither plane", &fig, 500);
    let fig = check(m, 64, 48, [0.1, 0.05, -near], 3.0);
    assert_figures("eye inside, centre on the hither plane", &fig, 64 * 48);
}

/// Spheres wholly behind the eye, beyond the yon plane, or with a radius or centre that is
/// not a sphere: nothing is drawn. Source: pbrt-v4's ray-sphere intersection (no root in the
/// ray's range, no hit) and docs/primitives.md; tolerance 0 pixels.
#[test]
fn spheres_behind_the_eye_or_degenerate_draw_nothing() {
    let program = library();
    let mut r = renderer(&program, 32, 24, false);
    r.perspective(60.0, 1.0, 10.0);
    for (center, radius) in [
        ([0.0, 0.0, 5.0], 1.0),            // behind the eye
        ([0.0, 0.0, -5.0], 0.0),           // zero radius
        ([0.0, 0.0, -5.0], -1.0),          // negative radius
        ([f32::NAN, 0.0, -5.0], 1.0),      // not finite
        ([0.0, 0.0, -5.0], f32::INFINITY), // not finite
        ([0.0, 0.0, -50.0], 1.0),          // beyond the far plane
    ] {
        r.begin("sphere").unwrap();
        r.rast_param("center", &Value(center.to_vec())).unwrap();
        r.rast_param("radius", &Value(vec![radius])).unwrap();
        r.end().unwrap();
    }
    let frame = render(&r, 1);
    let covered = (0..24)
        .flat_map(|y| (0..32).map(move |x| (x, y)))
        .filter(|&(x, y)| frame.written(x, y))
        .count();
    assert_eq!(covered, 0);
}

/// The nearest visible point of the sphere on the device line through (x, y) (largest
/// device depth in [0, 1], in front of the eye), in f64: pbrt-v4's sphere intersection
/// (`Sphere::BasicIntersect`: both roots, the nearer one in the ray's range, so a sphere
/// around the eye is seen from inside), with the ray from the inverted camera matrix.
fn sphere_depth(device_from_object: &DMat4, center: DVec3, radius: f64, x: f64, y: f64) -> Option<f64> {
    let object_from_device = device_from_object.inverse();
    let point = |z: f64| {
        let p = object_from_device * glam::DVec4::new(x, y, z, 1.0);
        p.truncate() / p.w
    };
    // Two points of the line of sight (between hither and yon): origin and direction.
    let (o, far) = (point(1.0), point(0.0));
    let d = (far - o).normalize();
    let oc = o - center;
    let b = oc.dot(d);
    let c = oc.length_squared() - radius * radius;
    let disc = b * b - c;
    if disc < 0.0 {
        return None;
    }
    let mut best: Option<f64> = None;
    for t in [-b - disc.sqrt(), -b + disc.sqrt()] {
        let p = o + d * t;
        let q = *device_from_object * p.extend(1.0);
        let depth = q.z / q.w;
        if q.w > 0.0 && (0.0..=1.0).contains(&depth) && best.is_none_or(|b| depth > b) {
            best = Some(depth);
        }
    }
    best
}

/// Render one sphere; (pixels drawn, pixels where the f64 answer differs away from its
/// silhouette: within half a pixel of it either answer is accepted).
fn sphere_against_reference(m: Mat4, w: u32, h: u32, center: [f32; 3], radius: f32) -> (usize, usize, usize) {
    let program = library();
    let mut r = renderer(&program, w, h, true);
    r.set_transform(m);
    r.begin("sphere").unwrap();
    r.rast_param("center", &Value(center.to_vec())).unwrap();
    r.rast_param("radius", &Value(vec![radius])).unwrap();
    r.end().unwrap();
    assert!(r.take_warnings().is_empty());
    let frame: Frame = render(&r, 2);
    let md = m.as_dmat4();
    let c = DVec3::new(center[0].into(), center[1].into(), center[2].into());
    let want = |x: f64, y: f64| sphere_depth(&md, c, radius.into(), x, y).is_some();
    let (mut drawn, mut expected, mut wrong) = (0, 0, 0);
    for py in 0..h {
        for px in 0..w {
            let (x, y) = (f64::from(px) + 0.5, f64::from(py) + 0.5);
            let got = frame.written(px, py);
            assert!(frame.write_count_at(px, py).unwrap() <= 1);
            drawn += usize::from(got);
            expected += usize::from(want(x, y));
            let near_edge = (0..16).any(|k| {
                let t = f64::from(k) / 16.0 * std::f64::consts::TAU;
                want(x + 0.5 * t.cos(), y + 0.5 * t.sin()) != want(x, y)
            });
            wrong += usize::from(got != want(x, y) && !near_edge);
        }
    }
    (drawn, expected, wrong)
}

/// Spheres whose centre lies 1e-6 to 1e-4 from the eye plane. Beside the eye (all of the
/// sphere outside the field of view) the analytic answer is no pixel; with the eye inside
/// (a sky sphere around the camera) it is every pixel: the far side, seen from inside, as
/// pbrt-v4 and RenderMan draw it (docs/primitives.md). Source: pbrt-v4's ray-sphere
/// intersection in f64; tolerance: 0 pixels away from the silhouette (within half a pixel
/// of it either answer). Before the fix: 2,048 pixels drawn beside the eye where the answer
/// is 0, and 1,856 of 4,096 with the eye inside.
#[test]
fn spheres_crossing_the_eye_plane_match_the_analytic_coverage() {
    let m = transform::perspective(40.0, 0.5, 100.0, 64, 64);
    for offset in [1e-6f32, -1e-6, 1e-5, -3e-5, 1e-4, -1e-4, 0.0] {
        // Beside the eye: centre 3 to the side, radius 1; nothing of it in a 40 degree view.
        let (drawn, expected, wrong) = sphere_against_reference(m, 64, 64, [3.0, 0.5, offset], 1.0);
        assert_eq!((expected, drawn, wrong), (0, 0, 0), "beside the eye, offset {offset:e}");
        // Around the eye: radius 10, every line of sight meets its far side at distance ~10.
        let (drawn, expected, wrong) = sphere_against_reference(m, 64, 64, [0.3, -0.2, offset], 10.0);
        assert_eq!(
            (expected, drawn, wrong),
            (4096, 4096, 0),
            "around the eye, offset {offset:e}"
        );
        // Crossing the eye plane in front of and beside the view: a partial, curved coverage.
        let (drawn, expected, wrong) = sphere_against_reference(m, 64, 64, [1.5, 0.0, offset], 1.49);
        assert_eq!(
            wrong, 0,
            "crossing beside the eye, offset {offset:e}: {drawn} drawn, {expected} expected"
        );
    }
}
