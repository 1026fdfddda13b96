//! The sphere primitive (prims/sphere.prim) against the analytic ray-sphere answer in f64:
//! depth and normal at every covered pixel, and silhouette coverage except within half a
//! pixel of the edge, for an ordinary sphere, one stretched in the corner of a very wide
//! view, and one under an orthographic camera. The extreme cases (a tiny far sphere through
//! a very narrow field of view, a huge one whose surface is one unit in front of the eye, one
//! cut by the hither plane, spheres behind or around the eye) use [`check`] from the
//! hard-case suite, tests/prims/hard_cases/.

use crate::support;
use support::*;

use glam::{DMat4, DVec3, Mat4};
use primflow::runtime::{transform, Value};

/// What the f64 reference sees through one pixel position.
struct Hit {
    depth: f64,
    normal: DVec3,
}

/// The nearest visible point of the sphere on the device line through (x, y): the largest
/// device depth in [0, 1] (the hither plane is depth 1).
///
/// No matrix is inverted (a narrow field of view makes `device_from_object` too badly
/// conditioned for that, even in f64): the line is the intersection of the two object-space
/// planes (row0 - x row3) . p = 0 and (row1 - y row3) . p = 0. Its point closest to the
/// centre is found as an offset from the centre, so nothing of the size of the distance is
/// subtracted from anything of the size of the radius.
fn reference(device_from_object: &DMat4, center: DVec3, radius: f64, x: f64, y: f64) -> Option<Hit> {
    let row = |i: usize| device_from_object.row(i);
    let plane_a = row(0) - row(3) * x;
    let plane_b = row(1) - row(3) * y;
    let (na, nb) = (plane_a.truncate(), plane_b.truncate());
    let c1 = center.extend(1.0);
    // Offset m = -(alpha na + beta nb) from the centre onto both planes.
    let (aa, ab, bb) = (na.dot(na), na.dot(nb), nb.dot(nb));
    let (ra, rb) = (plane_a.dot(c1), plane_b.dot(c1));
    let det = aa * bb - ab * ab;
    let alpha = (ra * bb - rb * ab) / det;
    let beta = (rb * aa - ra * ab) / det;
    let m = -(na * alpha + nb * beta);
    let d = na.cross(nb).normalize();
    let h2 = radius * radius - m.length_squared();
    if h2 < 0.0 {
        return None;
    }
    let mut best: Option<Hit> = None;
    for s in [h2.sqrt(), -h2.sqrt()] {
        let rel = m + d * s;
        let num = row(2).dot(c1) + row(2).truncate().dot(rel);
        let den = row(3).dot(c1) + row(3).truncate().dot(rel);
        let depth = num / den;
        // Behind the eye (den < 0 for these cameras) is not seen.
        if den > 0.0 && (0.0..=1.0).contains(&depth) && best.as_ref().is_none_or(|b| depth > b.depth) {
            best = Some(Hit {
                depth,
                normal: rel / radius,
            });
        }
    }
    best
}

pub(crate) struct Figures {
    pub(crate) covered: usize,
    pub(crate) depth_err: f64,
    pub(crate) normal_err: f64,
}

/// Render one sphere under `device_from_object` and compare every pixel with the reference.
pub(crate) fn check(device_from_object: Mat4, width: u32, height: u32, center: [f32; 3], radius: f32) -> Figures {
    let program = library();
    let mut r = renderer(&program, width, height, true);
    r.set_transform(device_from_object);
    r.material_interp("N", "implicit", &[]).unwrap();
    r.material("N", &Value(vec![0.0, 0.0, 1.0])).unwrap();
    r.begin("sphere").unwrap();
    r.rast_param("center", &Value(center.to_vec())).unwrap();
    r.rast_param("radius", &Value(vec![radius])).unwrap();
    r.end().unwrap();
    assert!(r.take_warnings().is_empty());
    let frame = render(&r, 2);

    let m = device_from_object.as_dmat4();
    let c = DVec3::new(center[0] as f64, center[1] as f64, center[2] as f64);
    let radius = radius as f64;
    let mut fig = Figures {
        covered: 0,
        depth_err: 0.0,
        normal_err: 0.0,
    };
    let mut wrong_coverage = vec![];
    for py in 0..height {
        for px in 0..width {
            let (x, y) = (px as f64 + 0.5, py as f64 + 0.5);
            let want = reference(&m, c, radius, x, y);
            let got = frame.written(px, py);
            assert!(frame.write_count_at(px, py).unwrap() <= 1);
            // Within half a pixel of the edge (silhouette or hither cut) either answer is
            // accepted: look for a change of the reference's answer on a ring of radius 0.5.
            let near_edge = (0..16).any(|k| {
                let t = k as f64 / 16.0 * std::f64::consts::TAU;
                reference(&m, c, radius, x + 0.5 * t.cos(), y + 0.5 * t.sin()).is_some() != want.is_some()
            });
            if got != want.is_some() && !near_edge {
                wrong_coverage.push((px, py, got));
            }
            let (true, Some(hit)) = (got, want) else { continue };
            fig.covered += 1;
            let depth = f64::from(frame.depth_at(px, py).unwrap()) / 4294967296.0;
            fig.depth_err = fig.depth_err.max((depth - hit.depth).abs() / hit.depth.abs());
            let n = frame.param_at("N", px, py).unwrap();
            let n = DVec3::new(n[0] as f64, n[1] as f64, n[2] as f64);
            fig.normal_err = fig.normal_err.max((n - hit.normal).abs().max_element());
        }
    }
    assert!(
        wrong_coverage.is_empty(),
        "{} pixels away from the edge differ from the analytic coverage (x, y, covered): {:?}",
        wrong_coverage.len(),
        &wrong_coverage[..wrong_coverage.len().min(12)]
    );
    fig
}

pub(crate) fn assert_figures(name: &str, fig: &Figures, min_covered: usize) {
    println!(
        "{name}: {} px, depth err {:.2e} (relative), normal err {:.2e}",
        fig.covered, fig.depth_err, fig.normal_err
    );
    assert!(
        fig.covered >= min_covered,
        "{name}: only {} pixels covered",
        fig.covered
    );
    assert!(
        fig.depth_err < 1e-4,
        "{name}: depth off by {:e} (relative)",
        fig.depth_err
    );
    assert!(fig.normal_err < 1e-4, "{name}: normal off by {:e}", fig.normal_err);
}

#[test]
fn ordinary_sphere_matches_the_analytic_answer() {
    let m = transform::perspective(40.0, 1.0, 100.0, 64, 48);
    let fig = check(m, 64, 48, [0.4, -0.3, -7.0], 1.5);
    assert_figures("ordinary", &fig, 500);
}

#[test]
fn wide_angle_sphere_in_the_corner_of_the_view() {
    // A 150-degree field of view with the sphere near the top-left corner: the strongest
    // perspective stretch along a row, so the per-row polynomials in dx have their largest
    // coefficients and the silhouette is a long ellipse.
    let m = transform::perspective(150.0, 0.5, 100.0, 96, 72);
    let fig = check(m, 96, 72, [-7.0, 4.5, -2.5], 1.5);
    assert_figures("wide corner", &fig, 400);
}

#[test]
fn sphere_under_an_orthographic_camera() {
    let m = transform::ortho(-2.0, 2.0, -1.5, 1.5, 1.0, 10.0, [64, 48]);
    let fig = check(m, 64, 48, [0.3, 0.2, -5.0], 1.1);
    assert_figures("ortho", &fig, 400);
}

/// The normal the sphere returns is in lighting coordinates: a sphere turned about its own
/// centre by the model matrix (and seen from an oblique camera) looks the same and must
/// return the same normals; an object-space normal would turn with the model matrix.
#[test]
fn normals_are_returned_in_lighting_coordinates_whatever_the_model_matrix() {
    let program = library();
    let render_with = |model: &dyn Fn(&mut primflow::runtime::Renderer)| {
        let mut r = renderer(&program, 64, 64, false);
        r.perspective_checked(40.0, 1.0, 50.0).unwrap();
        r.look_at([3.0, 2.0, 4.0], [0.0, 0.0, -6.0], [0.0, 1.0, 0.0]).unwrap();
        r.translate([0.0, 0.0, -6.0]).unwrap();
        model(&mut r);
        r.material_interp("N", "implicit", &[]).unwrap();
        r.material("N", &Value(vec![0.0, 0.0, 1.0])).unwrap();
        r.begin("sphere").unwrap();
        r.rast_param("radius", &Value(vec![1.5])).unwrap();
        r.end().unwrap();
        assert!(r.take_warnings().is_empty());
        render(&r, 1)
    };
    let plain = render_with(&|_| {});
    let turned = render_with(&|r| r.rotate(90.0, [0.3, 1.0, 0.2]).unwrap());
    let mut compared = 0;
    let mut worst = 0f32;
    for y in 0..64 {
        for x in 0..64 {
            if !(plain.written(x, y) && turned.written(x, y)) {
                continue;
            }
            let (a, b) = (plain.param_at("N", x, y).unwrap(), turned.param_at("N", x, y).unwrap());
            worst = worst.max((0..3).map(|c| (a[c] - b[c]).abs()).fold(0.0, f32::max));
            compared += 1;
        }
    }
    assert!(compared > 300, "only {compared} pixels");
    assert!(
        worst < 1e-3,
        "normals differ by {worst} when the sphere is turned about its centre"
    );
}
