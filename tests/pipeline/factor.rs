//! V = G Q E / S H E on random canonical views, detection of non-canonical ones, and the
//! adapted W-clip in lighting coordinates.

use glam::{DMat3, DMat4, DVec3, DVec4};
use primflow::pipeline::clip::*;
use primflow::pipeline::face::projected_area;
use primflow::pipeline::factor::*;
use primflow::pipeline::transform::{look_at_matrix, oblique_matrix, orthographic_matrix};

struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * ((self.next() >> 11) as f64 / (1u64 << 53) as f64)
    }
    fn vec3(&mut self, r: f64) -> DVec3 {
        DVec3::new(self.range(-r, r), self.range(-r, r), self.range(-r, r))
    }
}

/// An off-axis perspective frustum (reversed depth: near -> z = 1, far -> z = 0).
fn frustum(l: f64, r: f64, b: f64, t: f64, n: f64, f: f64) -> DMat4 {
    DMat4::from_cols(
        DVec4::new(2.0 * n / (r - l), 0.0, 0.0, 0.0),
        DVec4::new(0.0, 2.0 * n / (t - b), 0.0, 0.0),
        DVec4::new((r + l) / (r - l), (t + b) / (t - b), n / (f - n), -1.0),
        DVec4::new(0.0, 0.0, n * f / (f - n), 0.0),
    )
}

fn random_camera(rng: &mut Rng) -> DMat4 {
    let eye = rng.vec3(20.0);
    let centre = eye + rng.vec3(1.0) + DVec3::new(0.0, 0.0, 0.1);
    let up = rng.vec3(1.0);
    look_at_matrix(eye, centre, up)
}

fn rel_err(a: &DMat4, b: &DMat4) -> f64 {
    let scale = b.to_cols_array().iter().fold(0.0f64, |m, v| m.max(v.abs()));
    (*a - *b).to_cols_array().iter().fold(0.0f64, |m, v| m.max(v.abs())) / scale
}

fn check_euclidean(e: &DMat4) {
    let r = DMat3::from_mat4(*e);
    let ete = r.transpose() * r;
    assert!(
        (ete - DMat3::IDENTITY).to_cols_array().iter().all(|v| v.abs() <= 1e-12),
        "E^T E = {ete}"
    );
    assert!((r.determinant() - 1.0).abs() <= 1e-12);
    assert_eq!(e.row(3), DVec4::new(0.0, 0.0, 0.0, 1.0));
}

#[test]
fn random_canonical_perspective_views_factor_as_g_q_e() {
    let mut rng = Rng(3);
    for _ in 0..2000 {
        let n = rng.range(0.01, 5.0);
        let f = n * rng.range(1.5, 1000.0);
        let (l, r) = (rng.range(-2.0, 0.5) * n, 0.0);
        let r = r + l + rng.range(0.1, 3.0) * n;
        let (b, t) = (rng.range(-2.0, 0.5) * n, 0.0);
        let t = t + b + rng.range(0.1, 3.0) * n;
        // A random homogeneous scale too (V and lambda V are the same view).
        let lambda = rng.range(0.1, 10.0);
        let v = frustum(l, r, b, t, n, f) * random_camera(&mut rng) * lambda;
        let factors = factor_view(&v).unwrap_or_else(|e| panic!("{e}: {v}"));
        let ViewFactors::Perspective(p) = factors else {
            panic!("perspective view factored as parallel")
        };
        assert!(
            rel_err(&(p.g * p.q * p.e), &v) <= 1e-12,
            "GQE != V: {}",
            rel_err(&(p.g * p.q * p.e), &v)
        );
        check_euclidean(&p.e);
        // Q: identity but for qz; G: scale/translate without z translation.
        let mut q_expected = DMat4::IDENTITY;
        q_expected.col_mut(2)[3] = p.qz;
        assert_eq!(p.q, q_expected);
        for (row, col) in [
            (0, 1),
            (0, 2),
            (1, 0),
            (1, 2),
            (2, 0),
            (2, 1),
            (2, 3),
            (3, 0),
            (3, 1),
            (3, 2),
        ] {
            assert_eq!(p.g.col(col)[row], 0.0, "G[{row}][{col}]");
        }
        // The eye is on the LC z axis at -1/qz, in front of the far plane.
        assert!(p.qz < 0.0);
    }
}

#[test]
fn random_canonical_parallel_views_factor_as_s_h_e() {
    let mut rng = Rng(4);
    for i in 0..2000 {
        let bounds = [
            rng.range(-5.0, -0.1),
            rng.range(0.1, 5.0),
            rng.range(-5.0, -0.1),
            rng.range(0.1, 5.0),
        ];
        let near = rng.range(-10.0, 10.0);
        let far = near + rng.range(0.5, 100.0);
        let projection = if i % 2 == 0 {
            orthographic_matrix(bounds, near, far).unwrap()
        } else {
            let dir = DVec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), -rng.range(0.2, 1.0));
            oblique_matrix(bounds, near, far, dir).unwrap()
        };
        let v = projection * random_camera(&mut rng) * rng.range(0.1, 10.0);
        let ViewFactors::Parallel(p) = factor_view(&v).unwrap_or_else(|e| panic!("{e}")) else {
            panic!("parallel view factored as perspective")
        };
        assert!(rel_err(&(p.s * p.h * p.e), &v) <= 1e-12);
        check_euclidean(&p.e);
        for (row, col) in [(0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1), (3, 0), (3, 1), (3, 2)] {
            assert_eq!(p.s.col(col)[row], 0.0, "S[{row}][{col}]");
        }
        if i % 2 == 0 {
            // Orthographic: no shear.
            assert!(p.h.col(2)[0].abs() < 1e-9 && p.h.col(2)[1].abs() < 1e-9);
        }
    }
}

#[test]
fn non_canonical_views_are_detected() {
    let mut rng = Rng(9);
    let camera = random_camera(&mut rng);
    let persp = frustum(-1.0, 1.0, -0.8, 0.8, 1.0, 100.0);
    // Shearing x by y makes the near and far faces parallelograms, not rectangles.
    let mut shear = DMat4::IDENTITY;
    shear.col_mut(1)[0] = 0.3;
    assert_eq!(
        factor_view(&(shear * persp * camera)),
        Err(NotFactorizable::NotRectangular)
    );
    // w depending on x: the x lines meet at a finite point.
    let mut tilt = persp;
    tilt.col_mut(0)[3] = 0.2;
    assert_eq!(factor_view(&(tilt * camera)), Err(NotFactorizable::SidesNotParallel));
    // Singular and NaN views.
    assert_eq!(
        factor_view(&(DMat4::from_scale(DVec3::new(1.0, 0.0, 1.0)) * persp)),
        Err(NotFactorizable::Singular)
    );
    let mut nan = persp;
    nan.col_mut(3)[3] = f64::NAN;
    assert_eq!(factor_view(&nan), Err(NotFactorizable::NonFinite));
    // Parallel but with non-orthogonal image axes.
    let ortho = orthographic_matrix([-1.0, 1.0, -1.0, 1.0], 0.0, 10.0).unwrap();
    assert_eq!(
        factor_view(&(shear * ortho * camera)),
        Err(NotFactorizable::NotRectangular)
    );
}

#[test]
fn adapted_w_clip_in_lc_matches_clipping_in_clip_space() {
    let mut rng = Rng(21);
    let mut compared = 0;
    for _ in 0..300 {
        let v = frustum(-1.0, 1.2, -0.7, 0.9, 0.5, 40.0) * random_camera(&mut rng);
        let factors = factor_view(&v).unwrap();
        let w_clip = AdaptedWClip::new(&factors);
        assert!(matches!(w_clip.region, WClipRegion::Slab { .. }));
        let lighting_from_world = factors.lighting_from_world();
        let clip_from_lighting = factors.clip_from_lighting();
        // A big random triangle around the camera: it usually crosses the eye plane.
        let eye_world = lighting_from_world
            .inverse()
            .mul_vec4(DVec4::new(0.0, 0.0, w_clip.z_eye, 1.0))
            .truncate();
        let tri_world: Vec<DVec3> = (0..3).map(|_| eye_world + rng.vec3(30.0)).collect();
        let tri_lc: Vec<[f64; 4]> = tri_world
            .iter()
            .map(|p| lighting_from_world.mul_vec4(p.extend(1.0)).to_array())
            .collect();
        let pieces = w_clip.clip(&ClipPolygon::from_positions(&tri_lc)).unwrap();
        // After the LC clip every point has w > 0 and 0 <= z/w <= 1 in clip space.
        let mut area_lc = 0.0;
        for piece in &pieces {
            let in_clip: Vec<[f64; 4]> = piece
                .positions()
                .map(|p| clip_from_lighting.mul_vec4(DVec4::from_array(p)).to_array())
                .collect();
            for c in &in_clip {
                assert!(c[3] > 0.0);
                assert!(c[2] / c[3] >= -1e-9 && c[2] / c[3] <= 1.0 + 1e-9);
            }
            // Then x and y are clipped as usual (only those planes).
            let xy = clip_polygon(
                &ClipPolygon::from_positions(&in_clip),
                CLIP_X_POS | CLIP_X_NEG | CLIP_Y_POS | CLIP_Y_NEG,
                &[],
                PyramidMode::Single,
                ClipOptions::default(),
            )
            .unwrap();
            area_lc += xy.iter().map(|p| projected_area(p.positions()).abs()).sum::<f64>();
        }
        // Reference: the whole clip in clip space, W plane included.
        let tri_clip: Vec<[f64; 4]> = tri_world.iter().map(|p| v.mul_vec4(p.extend(1.0)).to_array()).collect();
        let reference: f64 = clip_polygon(
            &ClipPolygon::from_positions(&tri_clip),
            CLIP_ALL,
            &[],
            PyramidMode::Single,
            ClipOptions::default(),
        )
        .unwrap()
        .iter()
        .map(|p| projected_area(p.positions()).abs())
        .sum();
        if reference > 1e-6 {
            compared += 1;
        }
        assert!(
            (area_lc - reference).abs() <= 1e-9 * reference.max(1e-3),
            "{area_lc} vs {reference}"
        );
    }
    assert!(compared > 50, "only {compared} triangles were visible");
}

#[test]
fn viewport_straddling_the_eye_plane_keeps_outside_the_slab() {
    // near and far on opposite sides of the eye: z_c / w_c runs 1 -> 0 through infinity.
    let mut v = frustum(-1.0, 1.0, -1.0, 1.0, 1.0, 10.0);
    // Put the far plane behind the eye: clip z = a z_e + b with far at z_e = +5.
    let (n, f) = (1.0, -5.0);
    v.col_mut(2)[2] = n / (f - n);
    v.col_mut(3)[2] = n * f / (f - n);
    let factors = factor_view(&v).unwrap();
    let w_clip = AdaptedWClip::new(&factors);
    let WClipRegion::OutsideSlab { z_min, z_max } = w_clip.region else {
        panic!("expected a double-pyramid region, got {:?}", w_clip.region)
    };
    assert!(z_min < w_clip.z_eye && w_clip.z_eye < z_max);
    // A triangle spanning the slab is cut into two pieces, none touching the eye plane.
    let tri = ClipPolygon::from_positions(&[
        [0.0, 0.0, z_min - 1.0, 1.0],
        [1.0, 0.0, z_max + 1.0, 1.0],
        [0.0, 1.0, z_max + 2.0, 1.0],
    ]);
    let pieces = w_clip.clip(&tri).unwrap();
    assert_eq!(pieces.len(), 2);
    for piece in &pieces {
        for p in piece.positions() {
            assert!(p[2] <= z_min + 1e-12 || p[2] >= z_max - 1e-12);
        }
    }
}
