//! The hard-case suite: numerical extremes of the primitive library, organised by the
//! families the trusted rasterizer and ray-tracer suites test. Every case asserts a real
//! outcome (coverage against an exact or f64 reference, write counts) and names its source
//! of truth and its tolerance.
//!
//! Families: shared edges at every size (including triangles far over the 1,024 px exact
//! integer path), spheres crossing the eye plane.

use crate::support;
use support::*;

use std::sync::Arc;

use glam::{DMat4, DVec3, Mat4};
use primflow::ir::Program;
use primflow::runtime::{transform, Frame, Value};

// ---- Shared edges at every size --------------------------------------------------------

/// Exact coverage of a triangle by pixel centres on the 1/16 grid with the top-left rule, in
/// i64, snapping as the prim does (nearest, ties to even). The D3D11 functional spec's
/// rasterization rules (3.4.2 fixed-point vertex snapping, 3.4.3 top-left rule): two
/// triangles sharing an edge cover each pixel centre on it exactly once.
fn exact_coverage(v: [[f32; 2]; 3], width: u32, height: u32) -> Vec<u32> {
    let p: Vec<(i64, i64)> = v
        .iter()
        .map(|q| {
            let s = |c: f32| (f64::from(c) * 16.0).round_ties_even() as i64;
            (s(q[0]), s(q[1]))
        })
        .collect();
    let det = (p[1].0 - p[0].0) * (p[2].1 - p[0].1) - (p[2].0 - p[0].0) * (p[1].1 - p[0].1);
    let mut out = vec![0; (width * height) as usize];
    if det == 0 {
        return out;
    }
    let orient = det.signum();
    for py in 0..i64::from(height) {
        for px in 0..i64::from(width) {
            let (x, y) = (16 * px + 8, 16 * py + 8);
            let inside = (0..3).all(|i| {
                let j = (i + 1) % 3;
                let a = -orient * (p[j].1 - p[i].1);
                let b = orient * (p[j].0 - p[i].0);
                let top_left = a > 0 || (a == 0 && b < 0);
                let e = i128::from(a) * i128::from(x - p[i].0) + i128::from(b) * i128::from(y - p[i].1);
                e > 0 || (e == 0 && top_left)
            });
            out[(py * i64::from(width) + px) as usize] = u32::from(inside);
        }
    }
    out
}

/// Render `triangles` (flat, depth 0.5) with write counting and return the counts.
fn write_counts(program: &Arc<Program>, triangles: &[[[f32; 2]; 3]], width: u32, height: u32) -> Vec<u32> {
    let mut r = renderer(program, width, height, true);
    for t in triangles {
        let v = |i: usize| [t[i][0], t[i][1], 0.5, 1.0];
        screen_triangle(&mut r, [v(0), v(1), v(2)], &[]);
    }
    let frame = render(&r, 2);
    (0..height)
        .flat_map(|y| (0..width).map(move |x| (x, y)))
        .map(|(x, y)| frame.write_count_at(x, y).unwrap())
        .collect()
}

/// (pixels written twice or more, pixels not written) where each should be written once.
fn twice_and_holes(counts: &[u32]) -> (usize, usize) {
    (
        counts.iter().filter(|&&c| c > 1).count(),
        counts.iter().filter(|&&c| c == 0).count(),
    )
}

/// A fan of `n` triangles around `centre` whose outer vertices lie at `radius` px, at
/// irregular angles (some triangles narrow, some wider than 90 degrees), so its triangles
/// mix every edge path: under and over 1,024 px, near-axis and diagonal edges.
fn fan(centre: [f64; 2], radius: f64, n: usize, seed: u64) -> Vec<[[f32; 2]; 3]> {
    let mut rng = Lcg(seed);
    let mut angles: Vec<f64> = (0..n).map(|k| (k as f64 + rng.range(-0.45, 0.45)) / n as f64).collect();
    angles.sort_by(f64::total_cmp);
    let ring: Vec<[f32; 2]> = angles
        .iter()
        .map(|t| {
            let t = t * std::f64::consts::TAU;
            [
                (centre[0] + radius * t.cos()) as f32,
                (centre[1] + radius * t.sin()) as f32,
            ]
        })
        .collect();
    let c = [centre[0] as f32, centre[1] as f32];
    (0..n).map(|k| [c, ring[k], ring[(k + 1) % n]]).collect()
}

/// Fans whose outer vertices are far outside the viewport, the viewport at the fan's
/// centre: every pixel is inside exactly one triangle. Source: the D3D11 functional spec's
/// top-left rule and dEQP's `rasterization.fill_rules` cases (shared edges never produce
/// holes or double hits); tolerance 0 (every pixel written exactly once), and the coverage of
/// each triangle is checked against the exact i64 rasterizer. Before the fix (float edges
/// over 1,024 px): 4 double-covered pixels and 7 holes at 1e5, several hundred at 1e7.
#[test]
fn fans_far_outside_the_viewport_cover_every_pixel_once() {
    let (w, h) = (64, 64);
    let program = library();
    for radius in [1e3, 3e3, 1e5, 1e6, 1e7] {
        for (seed, n) in [(1u64, 7usize), (2, 12), (3, 5), (4, 16)] {
            let tris = fan([32.3, 31.6], radius, n, seed);
            let counts = write_counts(&program, &tris, w, h);
            let (twice, holes) = twice_and_holes(&counts);
            assert_eq!(
                (twice, holes),
                (0, 0),
                "fan of {n} at radius {radius:e} (seed {seed}): pixels written twice, not written"
            );
            // Each triangle's share against the exact rasterizer.
            let mut expected = vec![0u32; (w * h) as usize];
            for t in &tris {
                for (e, c) in expected.iter_mut().zip(exact_coverage(*t, w, h)) {
                    *e += c;
                }
            }
            assert!(expected.iter().all(|&c| c == 1), "the reference fan is not a partition");
            let per_triangle: Vec<u32> = tris
                .iter()
                .map(|t| write_counts(&program, &[*t], w, h).iter().sum())
                .collect();
            let want: Vec<u32> = tris.iter().map(|t| exact_coverage(*t, w, h).iter().sum()).collect();
            assert_eq!(per_triangle, want, "fan at {radius:e}: pixels per triangle");
        }
    }
}

/// Random pairs of triangles sharing an edge through the viewport, their other vertices
/// ~1e5 px away: the union is covered exactly as the exact rasterizer covers it, each pixel
/// once. Source: D3D11 rasterization rules (exact on the 1/16 grid); tolerance 0. Before
/// the fix 6 of 175 such pairs failed.
#[test]
fn random_pairs_far_away_share_their_edge_exactly() {
    let (w, h) = (48, 48);
    let program = library();
    let mut rng = Lcg(39);
    let mut failed = vec![];
    for case in 0..175 {
        let far = if case % 2 == 0 { 1e5 } else { 3e6 };
        let inner = |rng: &mut Lcg| [rng.range(-8.0, 56.0) as f32, rng.range(-8.0, 56.0) as f32];
        let outer = |rng: &mut Lcg| {
            let t = rng.range(0.0, std::f64::consts::TAU);
            let d = far * rng.range(0.5, 1.5);
            [(24.0 + d * t.cos()) as f32, (24.0 + d * t.sin()) as f32]
        };
        let (p, q) = (
            inner(&mut rng),
            if case % 3 == 0 {
                outer(&mut rng)
            } else {
                inner(&mut rng)
            },
        );
        let (a, b) = (outer(&mut rng), outer(&mut rng));
        // Keep a and b on opposite sides of the shared edge pq.
        let side = |r: [f32; 2]| {
            let (pq, pr) = (
                [f64::from(q[0] - p[0]), f64::from(q[1] - p[1])],
                [f64::from(r[0] - p[0]), f64::from(r[1] - p[1])],
            );
            (pq[0] * pr[1] - pq[1] * pr[0]).signum()
        };
        if side(a) == side(b) {
            continue;
        }
        let tris = [[p, q, a], [q, p, b]];
        let counts = write_counts(&program, &tris, w, h);
        let expected: Vec<u32> = exact_coverage(tris[0], w, h)
            .iter()
            .zip(exact_coverage(tris[1], w, h))
            .map(|(x, y)| x + y)
            .collect();
        assert!(expected.iter().all(|&c| c <= 1), "reference pair overlaps");
        if counts != expected {
            failed.push((case, counts.iter().zip(&expected).filter(|(a, b)| a != b).count()));
        }
    }
    assert!(failed.is_empty(), "pairs (case, differing pixels): {failed:?}");
}

// ---- Spheres crossing the eye plane ------------------------------------------------------

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
