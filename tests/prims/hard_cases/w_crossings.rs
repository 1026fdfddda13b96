//! w at, near and below 0: the homogeneous clipper with vertices at w = 1e-7, 0 and -1, with
//! a vertex behind the eye, and in a double-pyramid view.

use super::{area_2d, assert_inside_and_finite, clip_square_2d};

use glam::DVec3;
use primflow::pipeline::clip::{clip_polygon_to_view, ClipOptions, ClipPolygon, PyramidMode};
use primflow::pipeline::face::projected_area;
use primflow::pipeline::transform::perspective_matrix;

/// A triangle with one vertex at w = 1e-7, 0 and -1: the clipper's pieces have every w at or
/// above its floor and project into the view volume. Source: seed 000 9.2 and dEQP's
/// `clipping.triangle_vertex.*` cases (vertices outside the w > 0 half-space clip without a
/// divide by w <= 0); tolerance 1e-12 (f64) / 1e-6 (f32) of the view volume.
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

/// A triangle with a vertex behind the eye, clipped in homogeneous space, against the same
/// triangle clipped in camera space against the near plane, projected and clipped to the
/// square in f64. Source: Blinn and Newell's homogeneous clipping (the clip-space and the
/// camera-space answers are the same polygon); tolerance 1e-9 of the projected area.
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

/// A double-pyramid view (seed 000 9.6): a triangle with a vertex in the back pyramid
/// (w < 0) splits into two pieces, each with w > 0 and inside the view volume, the back one
/// holding the projected w < 0 vertex. Source: seed 000 9.6 (the view volume wraps around
/// infinity); tolerance 1e-12 (f64 positions).
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
