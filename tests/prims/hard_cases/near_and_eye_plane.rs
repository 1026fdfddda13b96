//! Spheres crossing the eye plane (beside, around and across the view), against an f64
//! ray-sphere reference (pbrt-v4).

use crate::support::*;

use glam::{DMat4, DVec3, Mat4};
use primflow::runtime::{transform, Frame, Value};

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
