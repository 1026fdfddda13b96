//! Huge coordinates: the homogeneous clipper with projected vertices tens of thousands of
//! view widths away, against a 2D f64 reference; and end to end through the renderer, far
//! vertices with the runtime's clipping (facets 1e6 to 1e30 px out in device space, 1e6 to
//! 2e14 units out under a perspective camera) and without it (screen triangles up to
//! 2^24 px out).

use super::{
    area_2d, assert_inside_and_finite, clip_square_2d, compare, exact_coverage, eye_renderer, nearest,
    screen_triangle_depth, submit_triangle, widen, EyeCamera,
};
use crate::support::*;

use glam::DVec3;
use primflow::jit::Jit;

use primflow::pipeline::clip::{clip_polygon_to_view, ClipOptions, ClipPolygon, PyramidMode};
use primflow::pipeline::face::projected_area;

/// 2,000 triangles with projected coordinates up to 3e4 and 1e5 (as dEQP's clipping cases
/// place vertices 3e4 to 7e4 outside the view) clipped in f64 and f32: no NaN, every piece
/// inside the view volume, the clipped area that of the projected triangle clipped to the
/// square in f64. Source: the 2D Sutherland-Hodgman reference in f64; tolerance 1e-6 of the
/// area in f64, 1e-6 of a screen-sized area in f32 (one rounding of each output vertex).
#[test]
fn huge_coordinates_clip_without_nan_and_match_an_f64_reference() {
    let mut rng = SplitMix(7);
    let mut checked = 0;
    let mut partial = 0;
    let mut worst32 = 0.0f64;
    for _ in 0..2000 {
        let tri: Vec<[f64; 4]> = if rng.next().is_multiple_of(2) {
            (0..3)
                .map(|_| {
                    let w = rng.range(0.2, 16.0);
                    // x, y up to 30000 w (projected +-30000) and sometimes +-1e5 outright.
                    let big = if rng.next().is_multiple_of(4) { 1e5 } else { 30000.0 * w };
                    [rng.range(-big, big), rng.range(-big, big), rng.range(0.0, w), w]
                })
                .collect()
        } else {
            // Projected vertices 30000 away, with one edge through a random point of the
            // screen, so the triangle covers it only partly.
            let c = [rng.range(-1.0, 1.0), rng.range(-1.0, 1.0)];
            let a = rng.range(0.0, std::f64::consts::TAU);
            let (d, n) = ([a.cos(), a.sin()], [-a.sin(), a.cos()]);
            let reach = [(30000.0, 0.0), (-30000.0, 0.0), (rng.range(-3e4, 3e4), 30000.0)];
            reach
                .iter()
                .map(|&(along, across)| {
                    let w = rng.range(0.2, 16.0);
                    let x = c[0] + along * d[0] + across * n[0];
                    let y = c[1] + along * d[1] + across * n[1];
                    [x * w, y * w, rng.range(0.0, w), w]
                })
                .collect()
        };
        let projected: Vec<[f64; 2]> = tri.iter().map(|p| [p[0] / p[3], p[1] / p[3]]).collect();
        let reference = area_2d(&clip_square_2d(projected)).abs();
        let poly64 = ClipPolygon::from_positions(&tri);
        let pieces64 = clip_polygon_to_view(&poly64, &[], PyramidMode::Single, ClipOptions::default()).unwrap();
        let tri32: Vec<[f32; 4]> = tri.iter().map(|p| p.map(|c| c as f32)).collect();
        let poly32 = ClipPolygon::from_positions(&tri32);
        let pieces32 = clip_polygon_to_view(&poly32, &[], PyramidMode::Single, ClipOptions::default()).unwrap();
        for p in &pieces64 {
            assert_inside_and_finite(p, 1e-12);
        }
        for p in &pieces32 {
            assert_inside_and_finite(p, 1e-5);
        }
        let area64: f64 = pieces64.iter().map(|p| projected_area(p.positions()).abs()).sum();
        // The f32 reference is the same triangle rounded to f32, projected in f64.
        let projected32: Vec<[f64; 2]> = tri32
            .iter()
            .map(|p| [p[0] as f64 / p[3] as f64, p[1] as f64 / p[3] as f64])
            .collect();
        let reference32 = area_2d(&clip_square_2d(projected32)).abs();
        let area32: f64 = pieces32
            .iter()
            .map(|p| projected_area(p.positions().map(|v| v.map(|c| c as f64))).abs())
            .sum();
        if reference > 1e-3 {
            checked += 1;
            if reference < 4.0 - 1e-3 {
                partial += 1;
            }
            assert!(
                (area64 - reference).abs() <= 1e-6 * reference,
                "f64: {area64} vs {reference}"
            );
            // f32 output coordinates carry a rounding of ~6e-8 of the screen each; measure
            // the area error against the area of a screen-sized polygon at least.
            worst32 = worst32.max((area32 - reference32).abs() / reference32.max(1.0));
        } else {
            assert!(area64 <= 1e-3 + 1e-9);
        }
    }
    assert!(checked > 100, "only {checked} triangles reached the screen");
    assert!(partial > 50, "only {partial} triangles cut the screen partially");
    // f32 polygons are clipped in f64 too; only the final rounding of each output vertex
    // to f32 remains, well below 1e-6 of the screen area.
    assert!(worst32 <= 1e-6, "worst f32 relative area error {worst32}");
    eprintln!("huge coordinates: {checked} visible ({partial} partial), worst f32 relative area error {worst32:.2e}");
}

/// Depth error allowed for a facet whose vertices are far away: its depth plane near the
/// view is computed from vertices the clipper made on the guard band (f64, rounded to f32
/// once) in f32, a few ulps of depth 1. Asserted: 1e-6 in depth units (docs/primitives.md's
/// hither tests reach 6.8e-7 relative).
const FAR_FACET_DEPTH_TOLERANCE: f64 = 1e-6;

/// Triangle pairs sharing an edge, one vertex in the view and the others 1e6 to 1e15 px away
/// (device space: no camera), through `triangle`, so the runtime's clipper cuts them to the
/// guard band in f64 before the kernel sees them: each pixel is written at most once, the
/// coverage is that of the f64 triangles, and the depth their f64 plane. Source: the f64
/// triangles (f32 inputs widened; edges through the view have an end in it, so the
/// reference is exact to rounding), as dEQP's `clipping.polygon_edge.poly_fan` and
/// `triangle_vertex.*` cases clip vertices 3e4 to 7e4 view widths out; tolerance: coverage
/// exact except within `SNAP_BAND` of an edge, no pixel twice, depth within
/// `FAR_FACET_DEPTH_TOLERANCE`.
#[test]
fn huge_device_triangles_clipped_by_the_runtime_draw_their_visible_part() {
    let covered = device_pairs_clipped_by_the_runtime(&[1e6, 1e8, 1e10, 1e12, 1e15], 29);
    assert!(covered > 20_000, "only {covered} pixels drawn");
}

/// The same pairs with their far vertices 1e18 to 1e30 px out (f32 inputs up to 1e30).
/// Before the clipper measured the intersection parameter from the endpoint nearer the
/// plane, it took the bit-order-smaller endpoint, often the far one, and a new vertex moved
/// by 2^-53 of the edge's length: every pair at 1e20 and 1e30 was off by 33 to 1,536 pixels.
/// Source and tolerance as above (the f64 triangles; `SNAP_BAND`, no pixel twice, depth
/// within `FAR_FACET_DEPTH_TOLERANCE`).
#[test]
fn device_triangles_1e30_px_out_clipped_by_the_runtime_draw_their_visible_part() {
    let covered = device_pairs_clipped_by_the_runtime(&[1e18, 1e20, 1e25, 1e30], 32);
    assert!(covered > 15_000, "only {covered} pixels drawn");
}

/// Six pairs per distance in `fars` (seeded by `seed`) through `triangle`, compared with the
/// f64 triangles: asserts the coverage, write-once and the depth; returns the pixels drawn.
fn device_pairs_clipped_by_the_runtime(fars: &[f64], seed: u64) -> usize {
    let (w, h) = (48, 48);
    let program = library();
    let mut jit = Jit::new(program.clone()).unwrap();
    let mut rng = Lcg(seed);
    let (mut covered, mut worst) = (0, 0f64);
    for &far in fars {
        for case in 0..6 {
            let a = [rng.range(4.0, 44.0), rng.range(4.0, 44.0)];
            let t1 = rng.range(0.0, std::f64::consts::TAU);
            let (s1, s2) = (rng.range(0.35, 2.6), rng.range(0.35, 2.6));
            let away = |t: f64, rng: &mut Lcg| {
                [
                    (a[0] + far * t.cos()) as f32,
                    (a[1] + far * t.sin()) as f32,
                    rng.range(0.1, 0.9) as f32,
                ]
            };
            let a32 = [a[0] as f32, a[1] as f32, rng.range(0.3, 0.7) as f32];
            let b = away(t1, &mut rng);
            let (c, d) = (away(t1 + s1, &mut rng), away(t1 - s2, &mut rng));
            // Opposite sides of the shared edge a-b.
            let tris = [[a32, b, c], [b, a32, d]];
            let mut r = renderer(&program, w, h, true);
            for t in &tris {
                submit_triangle(&mut r, "triangle", t);
            }
            assert!(r.take_warnings().is_empty(), "{far:e} case {case}: warnings");
            let frame = render_with(&r, &mut jit, 2);
            let t64 = tris.map(|t| t.map(|p| p.map(f64::from)));
            let cmp = compare(&frame, |x, y| {
                nearest(t64.iter().map(|t| screen_triangle_depth(t, x, y)))
            });
            assert!(
                cmp.wrong.is_empty() && cmp.twice == 0,
                "{far:e} case {case} {tris:?}: {} pixels off the f64 coverage {:?}, {} written twice",
                cmp.wrong.len(),
                &cmp.wrong[..cmp.wrong.len().min(8)],
                cmp.twice
            );
            covered += cmp.covered;
            worst = worst.max(cmp.depth_err);
        }
    }
    println!("huge device triangles {fars:?}: {covered} pixels, worst depth error {worst:.2e}");
    assert!(worst <= FAR_FACET_DEPTH_TOLERANCE, "depth off by {worst:e}");
    covered
}

/// The same pairs as screen triangles, which nothing clips: with every vertex within 2^24 px
/// of the origin (1e6 to 1.6e7 px out) the kernel's two-limb integer edges are exact, so the
/// coverage is the exact i64 rasterizer's pixel for pixel, and the depth the f64 plane.
/// Source: the D3D11 rasterization rules in i64 (`exact_coverage`) and the f64 plane through
/// the given vertices; tolerance 0 pixels, depth within `FAR_FACET_DEPTH_TOLERANCE`.
#[test]
fn huge_screen_triangles_within_two_to_the_24_px_are_exact_without_clipping() {
    let (w, h) = (48, 48);
    let program = library();
    let mut jit = Jit::new(program.clone()).unwrap();
    let mut rng = Lcg(30);
    let (mut covered, mut worst) = (0u32, 0f64);
    for far in [1e6, 4e6, 1.6e7] {
        for case in 0..8 {
            let a = [rng.range(4.0, 44.0), rng.range(4.0, 44.0)];
            let t1 = rng.range(0.0, std::f64::consts::TAU);
            let (s1, s2) = (rng.range(0.35, 2.6), rng.range(0.35, 2.6));
            let away = |t: f64, rng: &mut Lcg| {
                [
                    (a[0] + far * t.cos()) as f32,
                    (a[1] + far * t.sin()) as f32,
                    rng.range(0.1, 0.9) as f32,
                ]
            };
            let a32 = [a[0] as f32, a[1] as f32, rng.range(0.3, 0.7) as f32];
            let b = away(t1, &mut rng);
            let (c, d) = (away(t1 + s1, &mut rng), away(t1 - s2, &mut rng));
            let tris = [[a32, b, c], [b, a32, d]];
            let mut r = renderer(&program, w, h, true);
            for t in &tris {
                screen_triangle(&mut r, t.map(|p| [p[0], p[1], p[2], 1.0]), &[]);
            }
            let frame = render_with(&r, &mut jit, 2);
            let xy = tris.map(|t| t.map(|p| [p[0], p[1]]));
            let want: Vec<u32> = exact_coverage(xy[0], w, h)
                .iter()
                .zip(exact_coverage(xy[1], w, h))
                .map(|(p, q)| p + q)
                .collect();
            let got = frame.write_count_values().unwrap();
            assert_eq!(got, want, "{far:e} case {case} {tris:?}: coverage");
            covered += got.iter().sum::<u32>();
            let t64 = tris.map(|t| t.map(|p| p.map(f64::from)));
            let cmp = compare(&frame, |x, y| {
                nearest(t64.iter().map(|t| screen_triangle_depth(t, x, y)))
            });
            worst = worst.max(cmp.depth_err);
        }
    }
    println!("huge screen triangles: {covered} pixels, worst depth error {worst:.2e}");
    assert!(covered > 10_000, "only {covered} pixels drawn");
    assert!(worst <= FAR_FACET_DEPTH_TOLERANCE, "depth off by {worst:e}");
}

/// Under a perspective camera, triangles with one vertex in front of the eye and two 1e6 to
/// 1e12 away in random directions (in front, beside, behind the eye: the runtime clips them
/// against w = epsilon, the guard band and the yon plane in f64, polygon.prim against the
/// hither plane): each draws its visible part, each pixel once, at the right depth. Source:
/// the f64 ray cast against the unclipped eye-space triangle (`EyeCamera::triangle_depth`),
/// whose edges through the view have an end in front of the eye; tolerance: coverage exact
/// except within `SNAP_BAND` of an edge, depth within `FAR_FACET_DEPTH_TOLERANCE`.
#[test]
fn huge_world_triangles_under_a_perspective_camera_draw_their_visible_part() {
    let covered = world_triangles_under_the_camera(&[1e6, 1e8, 1e10, 1e12], 31);
    assert!(covered > 5_000, "only {covered} pixels drawn");
}

/// The same with the far vertices 1e13 to 2e14 units out. Before the clipper measured the
/// intersection parameter from the endpoint nearer the plane, the far endpoint's 2^-53
/// rounding lost the depth from 1e14 on (6.7e-5 off here) and then the coverage. (Further
/// out it still fails, not yet explained: at 3e14 one of these triangles, with both far
/// vertices behind the eye, misses a pixel; at 1e16 one misses 11 along an edge, at depths
/// 0.06 to 0.1.) Source and tolerance as above (the f64 ray cast; `SNAP_BAND`, no pixel
/// twice, `FAR_FACET_DEPTH_TOLERANCE`).
#[test]
fn world_triangles_2e14_units_out_under_a_perspective_camera_draw_their_visible_part() {
    let covered = world_triangles_under_the_camera(&[1e13, 5e13, 1e14, 2e14], 33);
    assert!(covered > 5_000, "only {covered} pixels drawn");
}

/// Ten triangles per distance in `fars` (seeded by `seed`) under the eye-space camera,
/// compared with the f64 ray cast: asserts the coverage, write-once and the depth; returns
/// the pixels drawn.
fn world_triangles_under_the_camera(fars: &[f64], seed: u64) -> usize {
    let program = library();
    let mut jit = Jit::new(program.clone()).unwrap();
    let camera = EyeCamera::new();
    let mut rng = Lcg(seed);
    let (mut covered, mut worst) = (0, 0f64);
    let unit = |rng: &mut Lcg| loop {
        let v = DVec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0));
        if v.length() > 0.1 && v.length() <= 1.0 {
            return v.normalize();
        }
    };
    for &far in fars {
        for case in 0..10 {
            let z = rng.range(-30.0, -3.0);
            let a = DVec3::new(rng.range(-0.5, 0.5) * z, rng.range(-0.5, 0.5) * z, z);
            // Two directions 20 to 150 degrees apart, so the far edge stays far away.
            let (u, v) = loop {
                let (u, v) = (unit(&mut rng), unit(&mut rng));
                let angle = u.dot(v).clamp(-1.0, 1.0).acos();
                if (0.35..2.6).contains(&angle) {
                    break (u, v);
                }
            };
            let to32 = |p: DVec3| [p.x as f32, p.y as f32, p.z as f32];
            let t32 = [to32(a), to32(a + u * far), to32(a + v * far)];
            let mut r = eye_renderer(&program);
            submit_triangle(&mut r, "triangle", &t32);
            assert!(r.take_warnings().is_empty(), "{far:e} case {case}: warnings");
            let frame = render_with(&r, &mut jit, 2);
            let t64 = widen(&t32);
            let cmp = compare(&frame, |x, y| camera.triangle_depth(&t64, x, y).map(|d| (d, 0)));
            assert!(
                cmp.wrong.is_empty() && cmp.twice == 0,
                "{far:e} case {case} {t32:?}: {} pixels off the f64 coverage {:?}, {} written twice",
                cmp.wrong.len(),
                &cmp.wrong[..cmp.wrong.len().min(8)],
                cmp.twice
            );
            covered += cmp.covered;
            worst = worst.max(cmp.depth_err);
        }
    }
    println!("huge world triangles {fars:?}: {covered} pixels, worst depth error {worst:.2e}");
    assert!(worst <= FAR_FACET_DEPTH_TOLERANCE, "depth off by {worst:e}");
    covered
}
