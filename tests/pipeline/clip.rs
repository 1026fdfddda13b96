//! Clip codes, trivial accept/reject and the homogeneous clipper, against references written
//! independently (if-based codes, 2D clipping of projected polygons in f64).

use glam::{DMat4, DVec3, DVec4};
use primflow::pipeline::clip::*;
use primflow::pipeline::face::projected_area;
use primflow::pipeline::transform::{look_at_matrix, perspective_matrix};

/// splitmix64: a small deterministic generator for the tests.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
    fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }
}

/// An f32 from a pool that stresses the bit tricks: signed zeros, denormals, infinities,
/// NaNs with either sign, extremes, ordinary values, and values a few ulps from `w` or `-w`.
fn special_f32(rng: &mut Rng, w: f32) -> f32 {
    match rng.next() % 14 {
        0 => 0.0,
        1 => -0.0,
        2 => f32::from_bits((rng.next() % 0x0080_0000) as u32), // positive denormal
        3 => -f32::from_bits((rng.next() % 0x0080_0000) as u32),
        4 => f32::INFINITY,
        5 => f32::NEG_INFINITY,
        6 => f32::from_bits(0x7fc0_0000 | (rng.next() as u32 & 0xff)),
        7 => f32::from_bits(0xff80_0001 | (rng.next() as u32 & 0xffff)),
        8 => {
            if rng.next().is_multiple_of(2) {
                f32::MAX
            } else {
                -f32::MAX
            }
        }
        9 => f32::from_bits(w.to_bits().wrapping_add((rng.next() % 5) as u32).wrapping_sub(2)),
        10 => -f32::from_bits(w.to_bits().wrapping_add((rng.next() % 5) as u32).wrapping_sub(2)),
        11 => f32::from_bits(rng.next() as u32),
        _ => rng.range(-2.0, 2.0) as f32,
    }
}

fn special_f64(rng: &mut Rng, w: f64) -> f64 {
    match rng.next() % 14 {
        0 => 0.0,
        1 => -0.0,
        2 => f64::from_bits(rng.next() % 0x0010_0000_0000_0000),
        3 => -f64::from_bits(rng.next() % 0x0010_0000_0000_0000),
        4 => f64::INFINITY,
        5 => f64::NEG_INFINITY,
        6 => f64::from_bits(0x7ff8_0000_0000_0000 | (rng.next() & 0xff)),
        7 => f64::from_bits(0xfff0_0000_0000_0001 | (rng.next() & 0xffff)),
        8 => f64::MAX * if rng.next().is_multiple_of(2) { 1.0 } else { -1.0 },
        9 => f64::from_bits(w.to_bits().wrapping_add(rng.next() % 5).wrapping_sub(2)),
        10 => -f64::from_bits(w.to_bits().wrapping_add(rng.next() % 5).wrapping_sub(2)),
        11 => f64::from_bits(rng.next()),
        _ => rng.range(-2.0, 2.0),
    }
}

#[test]
fn branch_free_codes_match_reference_on_a_million_f32_vertices() {
    let mut rng = Rng(1);
    let mut disagreements = 0;
    let mut seen = [0u32; 2];
    for i in 0..1_000_000 {
        let w0 = rng.range(-2.0, 2.0) as f32;
        let w = special_f32(&mut rng, w0);
        let v = [
            special_f32(&mut rng, w),
            special_f32(&mut rng, w),
            special_f32(&mut rng, w),
            w,
        ];
        for (m, mode) in [PyramidMode::Single, PyramidMode::Double].into_iter().enumerate() {
            let fast = clip_code_f32(v, mode);
            let slow = clip_code_reference(v, mode);
            if fast != slow {
                disagreements += 1;
                if disagreements < 5 {
                    eprintln!("vertex {i} {v:?} {mode:?}: branch-free {fast:#09b}, reference {slow:#09b}");
                }
            }
            seen[m] |= fast;
        }
    }
    assert_eq!(disagreements, 0);
    // Every bit was exercised in both modes.
    assert_eq!(seen, [CLIP_ALL, CLIP_ALL]);
}

#[test]
fn branch_free_codes_match_reference_on_a_million_f64_vertices() {
    let mut rng = Rng(2);
    let mut disagreements = 0;
    for _ in 0..1_000_000 {
        let w0 = rng.range(-2.0, 2.0);
        let w = special_f64(&mut rng, w0);
        let v = [
            special_f64(&mut rng, w),
            special_f64(&mut rng, w),
            special_f64(&mut rng, w),
            w,
        ];
        for mode in [PyramidMode::Single, PyramidMode::Double] {
            if clip_code_f64(v, mode) != clip_code_reference(v, mode) {
                disagreements += 1;
            }
        }
    }
    assert_eq!(disagreements, 0);
}

#[test]
fn clip_codes_of_known_vertices() {
    use PyramidMode::*;
    let c = |v: [f32; 4], m| clip_code_f32(v, m);
    assert_eq!(c([0.0, 0.0, 0.5, 1.0], Single), 0);
    assert_eq!(c([1.0, -1.0, 1.0, 1.0], Single), 0, "the boundary is inside");
    assert_eq!(c([0.0, 0.0, -0.0, 1.0], Single), 0, "-0 is not beyond the far plane");
    assert_eq!(c([2.0, 0.0, 0.5, 1.0], Single), CLIP_X_POS);
    assert_eq!(c([-2.0, 3.0, 0.5, 1.0], Single), CLIP_X_NEG | CLIP_Y_POS);
    assert_eq!(c([0.0, -2.0, 2.0, 1.0], Single), CLIP_Y_NEG | CLIP_Z_NEAR);
    assert_eq!(c([0.0, 0.0, -0.5, 1.0], Single), CLIP_Z_FAR);
    assert_eq!(c([0.0, 0.0, 0.0, 0.0], Single), CLIP_W);
    assert_eq!(c([0.0, 0.0, 0.0, 1e-7], Single), 0);
    // w < 0: outside both x planes at once in the single pyramid.
    assert_eq!(
        c([0.0, 0.0, 0.0, -1.0], Single) & (CLIP_W | CLIP_X_POS | CLIP_X_NEG),
        CLIP_W | CLIP_X_POS | CLIP_X_NEG
    );
    assert_eq!(c([f32::NAN, 0.0, 0.5, 1.0], Single), CLIP_ALL);
    assert_eq!(c([0.0, 0.0, 0.5, f32::INFINITY], Double), CLIP_ALL);
    // Double pyramid: the back pyramid is inside, with the W bit set.
    assert_eq!(c([0.5, 0.5, -0.5, -1.0], Double), CLIP_W);
    assert_eq!(c([0.5, 0.5, 0.5, -1.0], Double), CLIP_W | CLIP_Z_NEAR);
    assert_eq!(c([0.0, 0.0, 0.0, 0.0], Double), CLIP_ALL);
}

#[test]
fn accumulation_rejects_accepts_and_names_crossed_planes() {
    use PyramidMode::*;
    let v = |x: f32, y: f32, z: f32, w: f32| [x, y, z, w];
    assert_eq!(
        classify(
            [v(0.0, 0.0, 0.5, 1.0), v(0.5, 0.5, 0.2, 1.0), v(-1.0, 1.0, 1.0, 1.0)],
            Single
        ),
        ClipVerdict::Accept
    );
    assert_eq!(
        classify(
            [v(2.0, 0.0, 0.5, 1.0), v(3.0, -5.0, 0.2, 1.0), v(1.5, 5.0, 1.0, 1.0)],
            Single
        ),
        ClipVerdict::Reject
    );
    assert_eq!(
        classify(
            [v(2.0, 0.0, 0.5, 1.0), v(0.0, 0.0, 0.5, 1.0), v(0.0, 0.0, -0.5, 1.0)],
            Single
        ),
        ClipVerdict::Clip(CLIP_X_POS | CLIP_Z_FAR)
    );
    // Outside different planes: not rejected.
    assert_eq!(
        classify(
            [v(2.0, 0.0, 0.5, 1.0), v(-2.0, 0.0, 0.5, 1.0), v(0.0, 2.0, 0.5, 1.0)],
            Single
        ),
        ClipVerdict::Clip(CLIP_X_POS | CLIP_X_NEG | CLIP_Y_POS)
    );
    // Double pyramid: all in the back pyramid is accepted, mixed signs need clipping.
    assert_eq!(
        classify(
            [
                v(0.1, 0.0, -0.5, -1.0),
                v(0.0, 0.2, -0.2, -1.0),
                v(0.0, 0.0, -0.9, -1.0)
            ],
            Double
        ),
        ClipVerdict::Accept
    );
    assert_eq!(
        classify(
            [v(0.1, 0.0, 0.5, 1.0), v(0.0, 0.2, -0.2, -1.0), v(0.0, 0.0, 0.9, 1.0)],
            Double
        ),
        ClipVerdict::Clip(CLIP_W)
    );
    assert_eq!(classify(Vec::<[f32; 4]>::new(), Single), ClipVerdict::Reject);
}

fn assert_inside_and_finite<T: primflow::pipeline::real::Real>(piece: &ClipPolygon<T>, tol: f64) {
    for p in piece.positions() {
        let [x, y, z, w] = p.map(|c| c.to_f64());
        assert!(p.iter().all(|c| c.is_finite()), "non-finite vertex {p:?}");
        assert!(w >= DEFAULT_W_EPSILON, "w {w} below the floor");
        let (x, y, z) = (x / w, y / w, z / w);
        assert!(x.is_finite() && y.is_finite() && z.is_finite());
        assert!(
            x.abs() <= 1.0 + tol && y.abs() <= 1.0 + tol && (-tol..=1.0 + tol).contains(&z),
            "outside: {p:?}"
        );
    }
}

#[test]
fn vertices_with_tiny_zero_and_negative_w_clip_without_dividing_by_nonpositive_w() {
    for w_bad in [1e-7f64, 0.0, -1.0] {
        let tri = ClipPolygon::from_positions(&[
            [0.5, 0.2, 0.5, 1.0],
            [-0.3, 0.4, 0.3, 1.0],
            [0.1, -0.1, w_bad * 0.5, w_bad],
        ]);
        let pieces = clip_polygon_to_view(&tri, &[], PyramidMode::Single, ClipOptions::default()).unwrap();
        assert_eq!(pieces.len(), 1, "w = {w_bad}");
        assert_inside_and_finite(&pieces[0], 1e-12);
        // f32 too.
        let tri32 = ClipPolygon::from_positions(&tri.positions().map(|p| p.map(|c| c as f32)).collect::<Vec<_>>());
        let pieces32 = clip_polygon_to_view(&tri32, &[], PyramidMode::Single, ClipOptions::default()).unwrap();
        assert_eq!(pieces32.len(), 1);
        assert_inside_and_finite(&pieces32[0], 1e-6);
    }
}

/// Sutherland-Hodgman in 2D against the square [-1, 1]^2, f64: the reference for projected
/// polygons whose vertices all have w > 0.
fn clip_square_2d(mut poly: Vec<[f64; 2]>) -> Vec<[f64; 2]> {
    let planes: [fn([f64; 2]) -> f64; 4] = [|p| 1.0 - p[0], |p| 1.0 + p[0], |p| 1.0 - p[1], |p| 1.0 + p[1]];
    for d in planes {
        let mut out = vec![];
        for i in 0..poly.len() {
            let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
            let (da, db) = (d(a), d(b));
            if da >= 0.0 {
                out.push(a);
            }
            if (da >= 0.0) != (db >= 0.0) {
                let t = da / (da - db);
                out.push([a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]);
            }
        }
        poly = out;
        if poly.is_empty() {
            break;
        }
    }
    poly
}

fn area_2d(poly: &[[f64; 2]]) -> f64 {
    let n = poly.len();
    (0..n)
        .map(|i| poly[i][0] * poly[(i + 1) % n][1] - poly[(i + 1) % n][0] * poly[i][1])
        .sum::<f64>()
        * 0.5
}

#[test]
fn triangle_with_a_vertex_behind_the_eye_keeps_only_its_front_part() {
    let clip_from_camera = perspective_matrix(80f64.to_radians(), 1.0, 0.5, 50.0).unwrap();
    // Camera space: two vertices in front of the eye, one behind it (z_e > 0).
    let tri_camera = [
        DVec3::new(-1.0, -0.5, -3.0),
        DVec3::new(1.5, -0.2, -4.0),
        DVec3::new(0.2, 0.8, 2.0),
    ];
    let tri_clip: Vec<[f64; 4]> = tri_camera
        .iter()
        .map(|p| clip_from_camera.mul_vec4(p.extend(1.0)).to_array())
        .collect();
    assert!(tri_clip[2][3] < 0.0, "the third vertex is behind the eye");
    let poly = ClipPolygon::from_positions(&tri_clip);
    let pieces = clip_polygon_to_view(&poly, &[], PyramidMode::Single, ClipOptions::default()).unwrap();
    assert_eq!(pieces.len(), 1);
    assert_inside_and_finite(&pieces[0], 1e-12);
    // Reference: clip in camera space against the near plane z_e <= -near (plain 3D), then
    // project and clip to the square in 2D.
    let near = 0.5;
    let mut front = vec![];
    for i in 0..3 {
        let (a, b) = (tri_camera[i], tri_camera[(i + 1) % 3]);
        let (da, db) = (-near - a.z, -near - b.z);
        if da >= 0.0 {
            front.push(a);
        }
        if (da >= 0.0) != (db >= 0.0) {
            front.push(a + (b - a) * (da / (da - db)));
        }
    }
    let projected: Vec<[f64; 2]> = front
        .iter()
        .map(|p| {
            let c = clip_from_camera.mul_vec4(p.extend(1.0));
            [c.x / c.w, c.y / c.w]
        })
        .collect();
    let reference = area_2d(&clip_square_2d(projected));
    let area = projected_area(pieces[0].positions());
    assert!(reference > 0.1, "the test triangle should cover part of the screen");
    assert!((area - reference).abs() <= 1e-9 * reference, "{area} vs {reference}");
}

#[test]
fn huge_coordinates_clip_without_nan_and_match_an_f64_reference() {
    let mut rng = Rng(7);
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

#[test]
fn shared_edge_clips_to_bit_identical_vertices_from_both_sides() {
    let mut rng = Rng(11);
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

#[test]
fn attributes_are_interpolated_linearly_in_clip_space() {
    // A triangle crossing the near and the x planes with w varying strongly.
    let pos = [[0.2, 0.1, 1.5, 1.0], [3.0, -0.2, 0.5, 2.0], [-0.5, 0.4, 0.2, 5.0]];
    let attrs = [[1.0, 0.0], [0.0, 1.0], [0.25, 0.5]];
    let mut poly = ClipPolygon::new(2);
    for i in 0..3 {
        poly.push(pos[i], &attrs[i]).unwrap();
    }
    let pieces = clip_polygon_to_view(&poly, &[], PyramidMode::Single, ClipOptions::default()).unwrap();
    assert_eq!(pieces.len(), 1);
    let m = glam::DMat3::from_cols(
        DVec3::new(pos[0][0], pos[0][1], pos[0][3]),
        DVec3::new(pos[1][0], pos[1][1], pos[1][3]),
        DVec3::new(pos[2][0], pos[2][1], pos[2][3]),
    );
    let m_inv = m.inverse();
    let out = &pieces[0];
    assert!(out.len() >= 4);
    for i in 0..out.len() {
        let p = out.position(i);
        // Barycentric weights of the 4D point from (x, y, w); z must then agree too.
        let b = m_inv * DVec3::new(p[0], p[1], p[3]);
        let z = b.x * pos[0][2] + b.y * pos[1][2] + b.z * pos[2][2];
        assert!((z - p[2]).abs() < 1e-12, "vertex {i} is not in the triangle's 4D plane");
        for (k, got) in out.attrs(i).iter().enumerate() {
            let expected = b.x * attrs[0][k] + b.y * attrs[1][k] + b.z * attrs[2][k];
            assert!((got - expected).abs() < 1e-12, "attribute {k} of vertex {i}");
        }
    }
}

fn polygon_area_3d(poly: &ClipPolygon<f64>) -> f64 {
    let pts: Vec<DVec3> = poly.positions().map(|p| DVec3::new(p[0], p[1], p[2]) / p[3]).collect();
    let mut sum = DVec3::ZERO;
    for i in 0..pts.len() {
        sum += pts[i].cross(pts[(i + 1) % pts.len()]);
    }
    sum.length() * 0.5
}

#[test]
fn model_clip_plane_and_its_negation_split_a_polygon_into_parts_summing_to_the_whole() {
    let mut rng = Rng(5);
    for _ in 0..200 {
        // A random planar convex polygon (a hexagon on a random plane) in world space.
        let centre = DVec3::new(rng.range(-5.0, 5.0), rng.range(-5.0, 5.0), rng.range(-5.0, 5.0));
        let u = DVec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0)).normalize();
        let v = u.any_orthonormal_vector();
        let radius = rng.range(0.5, 3.0);
        let hexagon: Vec<[f64; 4]> = (0..6)
            .map(|k| {
                let a = k as f64 * std::f64::consts::TAU / 6.0;
                (centre + (u * a.cos() + v * a.sin()) * radius).extend(1.0).to_array()
            })
            .collect();
        let poly = ClipPolygon::from_positions(&hexagon);
        let normal = DVec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0));
        let through = centre + u * rng.range(-radius, radius) * 0.8;
        let plane = plane_from_point_normal(through, normal).to_array();
        let negated = plane.map(|c| -c);
        let opts = ClipOptions::default();
        let part = |pl: [f64; 4]| -> f64 {
            clip_polygon(&poly, 0, &[pl], PyramidMode::Single, opts)
                .unwrap()
                .iter()
                .map(polygon_area_3d)
                .sum()
        };
        let (a, b, whole) = (part(plane), part(negated), polygon_area_3d(&poly));
        assert!(a > 0.0 && b > 0.0, "the plane should cut the polygon");
        assert!((a + b - whole).abs() <= 1e-9 * whole, "{a} + {b} != {whole}");
    }
}

#[test]
fn model_clip_plane_moved_to_clip_space_cuts_the_same_part() {
    let clip_from_world = perspective_matrix(60f64.to_radians(), 1.5, 0.1, 100.0).unwrap()
        * look_at_matrix(DVec3::new(1.0, 2.0, 5.0), DVec3::ZERO, DVec3::Y);
    let square_world = [
        [-1.0, -1.0, 0.0, 1.0],
        [1.0, -1.0, 0.0, 1.0],
        [1.0, 1.0, 0.0, 1.0],
        [-1.0, 1.0, 0.0, 1.0],
    ];
    let plane_world = plane_from_point_normal(DVec3::new(0.3, 0.0, 0.0), DVec3::new(1.0, 0.5, 0.0));
    let opts = ClipOptions::default();
    // Clip in world space, then project.
    let world_piece = clip_polygon(
        &ClipPolygon::from_positions(&square_world),
        0,
        &[plane_world.to_array()],
        PyramidMode::Single,
        opts,
    )
    .unwrap();
    let to_clip = |p: [f64; 4]| clip_from_world.mul_vec4(DVec4::from_array(p)).to_array();
    let area_world_first = projected_area(world_piece[0].positions().map(to_clip));
    // Move the plane to clip space and clip there.
    let plane_clip = transform_plane(plane_world, &clip_from_world).unwrap();
    let square_clip: Vec<[f64; 4]> = square_world.iter().map(|&p| to_clip(p)).collect();
    let clip_piece = clip_polygon(
        &ClipPolygon::from_positions(&square_clip),
        0,
        &[plane_clip.to_array()],
        PyramidMode::Single,
        opts,
    )
    .unwrap();
    let area_clip = projected_area(clip_piece[0].positions());
    assert!(area_clip.abs() > 1e-3);
    assert!((area_clip - area_world_first).abs() <= 1e-12 * area_clip.abs());
    assert!(transform_plane(plane_world, &DMat4::from_scale(DVec3::new(1.0, 0.0, 1.0))).is_none());
}

#[test]
fn non_finite_vertices_are_an_error_not_a_nan_polygon() {
    let opts = ClipOptions::default();
    let poly = ClipPolygon::from_positions(&[[0.0f32, 0.0, 0.5, 1.0], [f32::NAN, 0.0, 0.5, 1.0], [0.5, 0.5, 0.5, 1.0]]);
    assert_eq!(
        clip_polygon_to_view(&poly, &[], PyramidMode::Single, opts),
        Err(ClipError::NonFinite)
    );
    let all_bad = ClipPolygon::from_positions(&[[f32::NAN; 4], [f32::INFINITY; 4], [f32::NAN; 4]]);
    assert_eq!(
        clip_polygon_to_view(&all_bad, &[], PyramidMode::Single, opts),
        Err(ClipError::NonFinite)
    );
    let mut wrong = ClipPolygon::<f32>::new(2);
    assert_eq!(
        wrong.push([0.0; 4], &[1.0]),
        Err(ClipError::AttributeCount { expected: 2, got: 1 })
    );
}

#[test]
fn double_pyramid_splits_a_primitive_through_infinity_into_two_positive_w_pieces() {
    // One vertex in the back pyramid (w < 0), two in the front one.
    let tri = ClipPolygon::from_positions(&[[0.2f64, 0.1, 0.5, 1.0], [-0.3, 0.2, 0.4, 1.0], [0.1, -0.2, -0.5, -1.0]]);
    let pieces = clip_polygon_to_view(&tri, &[], PyramidMode::Double, ClipOptions::default()).unwrap();
    assert_eq!(pieces.len(), 2);
    for p in &pieces {
        assert_inside_and_finite(p, 1e-12);
    }
    // The back-pyramid piece contains the w < 0 vertex, projected: (0.1, -0.2) / -1.
    let back = &pieces[1];
    assert!(back
        .positions()
        .any(|p| (p[0] / p[3] + 0.1).abs() < 1e-12 && (p[1] / p[3] - 0.2).abs() < 1e-12));
    // In the single pyramid only the front piece survives.
    let single = clip_polygon_to_view(&tri, &[], PyramidMode::Single, ClipOptions::default()).unwrap();
    assert_eq!(single.len(), 1);
    assert_eq!(single[0], pieces[0]);
}
