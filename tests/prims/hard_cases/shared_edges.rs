//! Shared edges at every size: triangle fans and pairs whose far vertices are 1e3 to 1e7 px
//! away (over the 1,024 px exact path, through the two-limb path), against the exact i64
//! rasterizer, and shared edges clipped by the runtime's homogeneous clipper.

use super::{exact_coverage_at, twice_and_holes, write_counts_at};
use crate::support::*;
use primflow::jit::Jit;
use primflow::runtime::samples::ALLOWED_SAMPLES;

use glam::DVec4;
use primflow::pipeline::clip::{clip_polygon_to_view, ClipOptions, ClipPolygon, PyramidMode};

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
/// centre: every pixel (every sample of every pixel, at each allowed sample count) is inside
/// exactly one triangle. Source: the D3D11 functional spec's
/// top-left rule and dEQP's `rasterization.fill_rules` cases (shared edges never produce
/// holes or double hits); tolerance 0 (every pixel written exactly once), and the coverage of
/// each triangle is checked against the exact i64 rasterizer. Before the fix (float edges
/// over 1,024 px): 4 double-covered pixels and 7 holes at 1e5, several hundred at 1e7.
#[test]
fn fans_far_outside_the_viewport_cover_every_pixel_once() {
    let (w, h) = (64, 64);
    let program = library();
    let mut jit = Jit::new(program.clone()).unwrap();
    for samples in ALLOWED_SAMPLES {
        let cover = |t: &[[f32; 2]; 3]| exact_coverage_at(*t, w, h, samples);
        for radius in [1e3, 3e3, 1e5, 1e6, 1e7] {
            for (seed, n) in [(1u64, 7usize), (2, 12), (3, 5), (4, 16)] {
                let tris = fan([32.3, 31.6], radius, n, seed);
                let counts = write_counts_at(&program, &mut jit, &tris, w, h, samples);
                let (twice, holes) = twice_and_holes(&counts);
                assert_eq!(
                    (twice, holes),
                    (0, 0),
                    "fan of {n} at radius {radius:e} (seed {seed}), {samples} sample(s): pixel samples written twice, not written"
                );
                // Each triangle's share against the exact rasterizer.
                let mut expected = vec![0u32; (w * h * samples) as usize];
                for t in &tris {
                    for (e, c) in expected.iter_mut().zip(cover(t)) {
                        *e += c;
                    }
                }
                assert!(expected.iter().all(|&c| c == 1), "the reference fan is not a partition");
                let per_triangle: Vec<u32> = tris
                    .iter()
                    .map(|t| write_counts_at(&program, &mut jit, &[*t], w, h, samples).iter().sum())
                    .collect();
                let want: Vec<u32> = tris.iter().map(|t| cover(t).iter().sum()).collect();
                assert_eq!(
                    per_triangle, want,
                    "fan at {radius:e}, {samples} sample(s): samples per triangle"
                );
            }
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
    let mut jit = Jit::new(program.clone()).unwrap();
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
        for samples in ALLOWED_SAMPLES {
            let counts = write_counts_at(&program, &mut jit, &tris, w, h, samples);
            let expected: Vec<u32> = exact_coverage_at(tris[0], w, h, samples)
                .iter()
                .zip(exact_coverage_at(tris[1], w, h, samples))
                .map(|(x, y)| x + y)
                .collect();
            assert!(expected.iter().all(|&c| c <= 1), "reference pair overlaps");
            if counts != expected {
                failed.push((
                    case,
                    samples,
                    counts.iter().zip(&expected).filter(|(a, b)| a != b).count(),
                ));
            }
        }
    }
    assert!(
        failed.is_empty(),
        "pairs (case, samples, differing pixel samples): {failed:?}"
    );
}

/// Random triangle pairs sharing an edge, with vertices beyond the view and behind the eye,
/// clipped by the homogeneous clipper from either side: every new vertex made on the shared
/// edge is bit-identical in both neighbours. Source: the D3D11 rasterization rules' promise
/// that a shared edge covers each pixel once, which after clipping holds only if both sides
/// clip the edge to the same vertices (docs/pipeline.md: "a shared edge clips to
/// bit-identical vertices from either side"); tolerance 0 (bits).
#[test]
fn shared_edge_clips_to_bit_identical_vertices_from_both_sides() {
    let mut rng = SplitMix(11);
    let mut shared_new_vertices = 0;
    for _ in 0..3000 {
        let mut vert = || -> [f32; 4] {
            let w = rng.range(0.1, 4.0);
            [
                rng.range(-3.0 * w, 3.0 * w) as f32,
                rng.range(-3.0 * w, 3.0 * w) as f32,
                rng.range(-w, 2.0 * w) as f32,
                if rng.next().is_multiple_of(8) {
                    -w as f32
                } else {
                    w as f32
                },
            ]
        };
        let (p, q, r, s) = (vert(), vert(), vert(), vert());
        let attrs = |i: f32| [i, 2.0 * i + 1.0, -i];
        let mut a = ClipPolygon::new(3);
        a.push(p, &attrs(1.0)).unwrap();
        a.push(q, &attrs(2.0)).unwrap();
        a.push(r, &attrs(3.0)).unwrap();
        // The neighbour runs the shared edge the other way: q -> p.
        let mut b = ClipPolygon::new(3);
        b.push(q, &attrs(2.0)).unwrap();
        b.push(p, &attrs(1.0)).unwrap();
        b.push(s, &attrs(4.0)).unwrap();
        let opts = ClipOptions::default();
        let out_a = clip_polygon_to_view(&a, &[], PyramidMode::Single, opts).unwrap();
        let out_b = clip_polygon_to_view(&b, &[], PyramidMode::Single, opts).unwrap();
        let verts = |out: &[ClipPolygon<f32>]| -> Vec<Vec<u32>> {
            out.iter()
                .flat_map(|poly| (0..poly.len()).map(move |i| poly.vertex(i).iter().map(|c| c.to_bits()).collect()))
                .collect()
        };
        let (va, vb) = (verts(&out_a), verts(&out_b));
        // Every vertex of A on the segment pq (by f64 collinearity) appears bit for bit in B.
        let (p64, q64) = (
            DVec4::from_array(p.map(|c| c as f64)),
            DVec4::from_array(q.map(|c| c as f64)),
        );
        let d = q64 - p64;
        for v in &va {
            let pos = DVec4::new(
                f32::from_bits(v[0]) as f64,
                f32::from_bits(v[1]) as f64,
                f32::from_bits(v[2]) as f64,
                f32::from_bits(v[3]) as f64,
            );
            let t = (pos - p64).dot(d) / d.dot(d);
            let residual = (pos - (p64 + d * t)).length();
            let on_edge = (-1e-6..=1.0 + 1e-6).contains(&t) && residual <= 1e-5 * (p64.length() + q64.length());
            // Only vertices made by clipping the shared edge can be checked (originals p, q
            // are trivially shared); an attribute value that is not 1 or 2 marks a new one.
            let attr0 = f32::from_bits(v[4]);
            if on_edge && attr0 != 1.0 && attr0 != 2.0 {
                shared_new_vertices += 1;
                assert!(
                    vb.contains(v),
                    "new vertex {pos} on the shared edge differs between neighbours"
                );
            }
        }
    }
    assert!(
        shared_new_vertices > 200,
        "only {shared_new_vertices} shared-edge vertices exercised"
    );
}
