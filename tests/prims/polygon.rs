//! The polygon and triangle primitives (prims/polygon.prim, prims/triangle.prim) through the
//! whole stack, against f64 references: hither clipping (coverage of the exactly clipped
//! polygon, perspective-correct values and depth at every covered pixel, in particular at
//! the clip edge), and a quad split along either diagonal covering the same pixels once.

use crate::support;
use support::*;

use glam::{Mat4, Vec4};
use primflow::runtime::{Renderer, Value};

const W: u32 = 64;
const H: u32 = 48;
const NEAR: f64 = 1.0;
const FAR: f64 = 20.0;
const FOV: f32 = 60.0;

/// The renderer's perspective matrix, in f64 (device = M * eye, then divide by w).
fn device_from_eye() -> [[f64; 4]; 4] {
    let m = primflow::runtime::transform::perspective(FOV, NEAR as f32, FAR as f32, W, H);
    let rows = primflow::runtime::transform::to_rows(&m);
    std::array::from_fn(|i| std::array::from_fn(|j| f64::from(rows[4 * i + j])))
}

fn project(m: &[[f64; 4]; 4], p: [f64; 3]) -> [f64; 3] {
    let h: Vec<f64> = (0..4)
        .map(|i| m[i][0] * p[0] + m[i][1] * p[1] + m[i][2] * p[2] + m[i][3])
        .collect();
    [h[0] / h[3], h[1] / h[3], h[2] / h[3]]
}

/// Sutherland-Hodgman against the hither plane z = -NEAR in eye space (inside: z <= -NEAR).
fn clip_hither(poly: &[[f64; 3]]) -> Vec<[f64; 3]> {
    let d = |p: [f64; 3]| -p[2] - NEAR;
    let mut out = vec![];
    for i in 0..poly.len() {
        let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
        if d(a) >= 0.0 {
            out.push(a);
        }
        if (d(a) >= 0.0) != (d(b) >= 0.0) {
            let t = d(a) / (d(a) - d(b));
            out.push(std::array::from_fn(|k| a[k] + t * (b[k] - a[k])));
        }
    }
    out
}

/// Signed distance (pixels) of (x, y) inside a convex screen polygon: the minimum over its
/// edges, positive inside.
fn inside_distance(poly: &[[f64; 3]], x: f64, y: f64) -> f64 {
    let n = poly.len();
    let area: f64 = (0..n)
        .map(|i| {
            let (a, b) = (poly[i], poly[(i + 1) % n]);
            a[0] * b[1] - b[0] * a[1]
        })
        .sum();
    let orient = area.signum();
    (0..n)
        .map(|i| {
            let (a, b) = (poly[i], poly[(i + 1) % n]);
            let (ex, ey) = (b[0] - a[0], b[1] - a[1]);
            orient * (ex * (y - a[1]) - ey * (x - a[0])) / (ex * ex + ey * ey).sqrt()
        })
        .fold(f64::INFINITY, f64::min)
}

/// The eye-space point of the plane through `poly` seen through pixel centre (x, y).
fn eye_point_under_pixel(m: &[[f64; 4]; 4], poly: &[[f64; 3]], x: f64, y: f64) -> [f64; 3] {
    // Ray direction in eye space: invert the x, y rows of the projection for z = -1.
    // x_dev = (m00 X + m02 Z) / -Z etc. with Z = -1: X = (x - m02) / m00 ... written out
    // generally by solving for the eye direction d with d.z = -1.
    let dx = (x + m[0][2]) / m[0][0];
    let dy = (y + m[1][2]) / m[1][1];
    let dir = [dx, dy, -1.0];
    let (a, b, c) = (poly[0], poly[1], poly[2]);
    let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
    let n = [
        u[1] * v[2] - u[2] * v[1],
        u[2] * v[0] - u[0] * v[2],
        u[0] * v[1] - u[1] * v[0],
    ];
    let t = (n[0] * a[0] + n[1] * a[1] + n[2] * a[2]) / (n[0] * dir[0] + n[1] * dir[1] + n[2] * dir[2]);
    [dir[0] * t, dir[1] * t, dir[2] * t]
}

fn submit(r: &mut Renderer, prim: &str, poly: &[[f64; 3]]) {
    r.begin(prim).unwrap();
    for p in poly {
        r.material("P", &Value(p.iter().map(|&c| c as f32).collect())).unwrap();
        r.vertex(p[0] as f32, p[1] as f32, p[2] as f32, 1.0).unwrap();
    }
    r.end().unwrap();
    assert!(r.take_warnings().is_empty());
}

/// Render `poly` (eye space) crossing the hither plane and compare against the exactly
/// clipped polygon: coverage except within `band` px of its edges, and the eye-space point
/// (a perspective_linear parameter) and depth at every covered pixel.
fn check_hither_crossing(prim: &str, poly: &[[f64; 3]]) -> (usize, f64, f64) {
    let program = library();
    let mut r = renderer(&program, W, H, true);
    r.perspective(FOV, NEAR as f32, FAR as f32);
    r.material_interp("P", "perspective_linear", &[]).unwrap();
    submit(&mut r, prim, poly);
    let frame = render(&r, 2);

    let m = device_from_eye();
    let clipped = clip_hither(poly);
    assert!(
        clipped.len() > poly.len() - 1,
        "the test polygon must cross the hither plane"
    );
    let screen: Vec<[f64; 3]> = clipped.iter().map(|&p| project(&m, p)).collect();
    // The kernel snaps vertices to 1/16 pixel: an edge moves by at most 1/32 px per axis.
    let band = 0.05;
    let (mut covered, mut worst_value, mut worst_depth) = (0, 0.0f64, 0.0f64);
    let mut bad_coverage = vec![];
    for y in 0..H {
        for x in 0..W {
            let (cx, cy) = (x as f64 + 0.5, y as f64 + 0.5);
            let d = inside_distance(&screen, cx, cy);
            let got = frame.written(x, y);
            if d.abs() > band && got != (d > 0.0) {
                bad_coverage.push((x, y, got, d));
            }
            if !got {
                continue;
            }
            covered += 1;
            let eye = eye_point_under_pixel(&m, poly, cx, cy);
            let value = frame.param_at("P", x, y).unwrap();
            for k in 0..3 {
                let err = (f64::from(value[k]) - eye[k]).abs() / eye[k].abs().max(1.0);
                worst_value = worst_value.max(err);
            }
            let depth = project(&m, eye)[2];
            let got_depth = f64::from(frame.depth_at(x, y).unwrap()) / 4294967296.0;
            worst_depth = worst_depth.max((got_depth - depth).abs() / depth.abs());
        }
    }
    assert!(
        bad_coverage.is_empty(),
        "{} pixels differ from the clipped polygon (x, y, covered, distance): {:?}",
        bad_coverage.len(),
        &bad_coverage[..bad_coverage.len().min(10)]
    );
    let counts_ok = (0..H).all(|y| (0..W).all(|x| frame.write_count_at(x, y).unwrap() <= 1));
    assert!(counts_ok, "a pixel was written twice by the fan");
    (covered, worst_value, worst_depth)
}

#[test]
fn polygon_crossing_the_hither_plane_matches_the_clipped_polygon() {
    // A planar quad leaning towards the eye (y = -0.9 + 0.1 z + 0.05 x): its near edge is
    // 0.4 units in front of the eye, its far edge at 6; the hither plane (1) cuts it.
    let plane = |x: f64, z: f64| [x, -0.9 + 0.1 * z + 0.05 * x, z];
    let quad = [plane(-2.0, -6.0), plane(2.5, -6.0), plane(1.0, -0.4), plane(-0.8, -0.4)];
    let (covered, value_err, depth_err) = check_hither_crossing("polygon", &quad);
    println!("polygon: {covered} px, eye point err {value_err:.2e}, depth err {depth_err:.2e} (relative)");
    assert!(covered > 300, "only {covered} pixels covered");
    assert!(value_err < 1e-4, "eye-space point off by {value_err:e} (relative)");
    assert!(depth_err < 1e-4, "depth off by {depth_err:e} (relative)");
}

#[test]
fn triangle_crossing_the_hither_plane_matches_the_clipped_triangle() {
    // One vertex behind the eye (w < 0): the clip must happen before any divide.
    let tri = [[-2.0, -1.0, -5.0], [2.0, -1.4, -4.0], [0.2, 0.5, 1.5]];
    let (covered, value_err, depth_err) = check_hither_crossing("triangle", &tri);
    println!("triangle: {covered} px, eye point err {value_err:.2e}, depth err {depth_err:.2e} (relative)");
    assert!(covered > 100, "only {covered} pixels covered");
    assert!(value_err < 1e-4, "eye-space point off by {value_err:e} (relative)");
    assert!(depth_err < 1e-4, "depth off by {depth_err:e} (relative)");
}

#[test]
fn values_at_the_clip_points_match_the_analytic_ones() {
    // Where the clip edge crosses pixel rows, compare the interpolated eye point with the
    // analytic point on the hither plane: z must be -NEAR there (within one pixel's change).
    let quad = [
        [-1.5, -0.3, -4.0],
        [1.5, -0.3, -4.0],
        [1.5, -0.3, -0.5],
        [-1.5, -0.3, -0.5],
    ];
    let program = library();
    let mut r = renderer(&program, W, H, false);
    r.perspective(FOV, NEAR as f32, FAR as f32);
    r.material_interp("P", "perspective_linear", &[]).unwrap();
    submit(&mut r, "polygon", &quad);
    let frame = render(&r, 1);
    let m = device_from_eye();
    // The floor y = -0.3: the clip edge is the screen row where z = -NEAR.
    let clip_row = project(&m, [0.0, -0.3, -NEAR])[1];
    let y = clip_row.floor() as u32 - 1; // the last covered row above the clip edge
    let mut checked = 0;
    for x in 0..W {
        if !frame.written(x, y) {
            continue;
        }
        let eye = eye_point_under_pixel(&m, &quad, x as f64 + 0.5, y as f64 + 0.5);
        assert!(
            eye[2] < -NEAR && eye[2] > -NEAR - 0.2,
            "row {y} is not next to the clip edge: {eye:?}"
        );
        let got = frame.param_at("P", x, y).unwrap();
        for k in 0..3 {
            assert!(
                (f64::from(got[k]) - eye[k]).abs() < 1e-4,
                "pixel ({x}, {y}) component {k}: {} vs analytic {}",
                got[k],
                eye[k]
            );
        }
        checked += 1;
    }
    assert!(checked > 20, "only {checked} pixels on the clip row");
}

/// Write counts of a frame as one vector.
fn counts(frame: &primflow::runtime::Frame) -> Vec<u32> {
    (0..frame.height)
        .flat_map(|y| (0..frame.width).map(move |x| (x, y)))
        .map(|(x, y)| frame.write_count_at(x, y).unwrap())
        .collect()
}

#[test]
fn quad_split_along_either_diagonal_covers_the_same_pixels_once() {
    let program = library();
    let mut rng = Lcg(11);
    for case in 0..6 {
        // A random convex quad in device space (identity transform: device coordinates).
        let (cx, cy) = (rng.range(20.0, 44.0), rng.range(16.0, 32.0));
        let quad: Vec<[f32; 2]> = (0..4)
            .map(|k| {
                let t = (k as f64 + rng.range(-0.3, 0.3)) * std::f64::consts::FRAC_PI_2;
                let radius = rng.range(10.0, 22.0);
                [(cx + radius * t.cos()) as f32, (cy + radius * t.sin()) as f32]
            })
            .collect();
        let render_split = |pairs: [[usize; 3]; 2]| {
            let mut r = renderer(&program, W, H, true);
            for tri in pairs {
                r.begin("triangle").unwrap();
                for i in tri {
                    r.vertex(quad[i][0], quad[i][1], 0.5, 1.0).unwrap();
                }
                r.end().unwrap();
            }
            counts(&render(&r, 2))
        };
        let a = render_split([[0, 1, 2], [0, 2, 3]]);
        let b = render_split([[1, 2, 3], [1, 3, 0]]);
        let mut r = renderer(&program, W, H, true);
        r.begin("polygon").unwrap();
        for q in &quad {
            r.vertex(q[0], q[1], 0.5, 1.0).unwrap();
        }
        r.end().unwrap();
        let whole = counts(&render(&r, 2));
        assert!(a.iter().all(|&c| c <= 1), "case {case}: diagonal 0-2 overdraws");
        assert!(b.iter().all(|&c| c <= 1), "case {case}: diagonal 1-3 overdraws");
        let differ = a.iter().zip(&b).filter(|(x, y)| x != y).count();
        assert_eq!(
            differ, 0,
            "case {case}: the two splits of {quad:?} differ in {differ} pixels"
        );
        assert_eq!(a, whole, "case {case}: the polygon differs from its split");
        assert!(a.iter().sum::<u32>() > 200, "case {case}: quad too small");
    }
}

#[test]
fn polygon_with_fewer_than_three_vertices_draws_nothing() {
    let program = library();
    let mut r = renderer(&program, W, H, false);
    r.begin("polygon").unwrap();
    r.vertex(1.0, 1.0, 0.5, 1.0).unwrap();
    r.vertex(60.0, 1.0, 0.5, 1.0).unwrap();
    r.end().unwrap();
    let frame = render(&r, 1);
    assert_eq!(
        (0..H)
            .flat_map(|y| (0..W).map(move |x| (x, y)))
            .filter(|&(x, y)| frame.written(x, y))
            .count(),
        0
    );
}

#[test]
fn polygon_entirely_behind_the_eye_draws_nothing() {
    let program = library();
    let mut r = renderer(&program, W, H, false);
    r.set_transform(Mat4::from_cols(Vec4::X, Vec4::Y, Vec4::Z, Vec4::W));
    r.perspective(FOV, NEAR as f32, FAR as f32);
    r.begin("polygon").unwrap();
    for p in [[-1.0, -1.0, 2.0], [1.0, -1.0, 2.0], [0.0, 1.0, 0.5]] {
        r.vertex(p[0], p[1], p[2], 1.0).unwrap();
    }
    r.end().unwrap();
    let frame = render(&r, 1);
    let n = (0..H)
        .flat_map(|y| (0..W).map(move |x| (x, y)))
        .filter(|&(x, y)| frame.written(x, y))
        .count();
    assert_eq!(n, 0);
}
