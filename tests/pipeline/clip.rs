//! Clip codes, trivial accept/reject and the homogeneous clipper, against references written
//! independently (if-based codes, clipped areas in 3D). The clipper's extreme inputs (tiny,
//! zero and negative w, a vertex behind the eye, huge coordinates, shared clipped edges, the
//! double pyramid) are in the hard-case suite, tests/prims/hard_cases/.

use glam::{DMat4, DVec3, DVec4};
use primflow::pipeline::clip::*;
use primflow::pipeline::face::projected_area;
use primflow::pipeline::transform::{look_at_matrix, perspective_matrix};

use crate::support::SplitMix;

/// An f32 from a pool that stresses the bit tricks: signed zeros, denormals, infinities,
/// NaNs with either sign, extremes, ordinary values, and values a few ulps from `w` or `-w`.
fn special_f32(rng: &mut SplitMix, w: f32) -> f32 {
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

fn special_f64(rng: &mut SplitMix, w: f64) -> f64 {
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
    let mut rng = SplitMix(1);
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
    let mut rng = SplitMix(2);
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
    let mut rng = SplitMix(5);
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
