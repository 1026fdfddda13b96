//! The transform state: lazy cached composites, the clip and device conventions, normals,
//! the ill-behaved cases, and pipeline selection.

use glam::{DMat4, DVec3, DVec4};
use primflow::pipeline::clip::PyramidMode;
use primflow::pipeline::factor::NotFactorizable;
use primflow::pipeline::transform::*;
use primflow::pipeline::*;

fn project(m: DMat4, p: DVec3) -> DVec3 {
    let h = m.mul_vec4(p.extend(1.0));
    h.truncate() / h.w
}

fn scene() -> TransformState {
    let mut t = TransformState::new();
    t.look_at(DVec3::new(0.0, 0.0, 5.0), DVec3::ZERO, DVec3::Y).unwrap();
    t.perspective(90f64.to_radians(), 2.0, 1.0, 9.0).unwrap();
    t.set_viewport(0.0, 0.0, 200.0, 100.0).unwrap();
    t
}

#[test]
fn device_from_object_is_computed_once_until_something_changes() {
    let mut t = scene();
    let before = t.evaluations();
    let first = t.device_from_object();
    let after_first = t.evaluations();
    assert!(after_first > before);
    let second = t.device_from_object();
    assert_eq!(first, second);
    assert_eq!(t.evaluations(), after_first, "asking again must not recompute");
    // A model change recomputes only the object-dependent product (V and D stay cached).
    t.translate(DVec3::new(1.0, 0.0, 0.0)).unwrap();
    let moved = t.device_from_object();
    assert_eq!(t.evaluations(), after_first + 1);
    assert_eq!(moved, t.device_from_world() * DMat4::from_translation(DVec3::X));
    // A viewport change recomputes D, D V and D V M.
    t.set_viewport(0.0, 0.0, 400.0, 200.0).unwrap();
    t.device_from_object();
    assert_eq!(t.evaluations(), after_first + 4);
}

#[test]
fn clip_and_device_conventions() {
    let t = scene();
    let clip_from_world = t.clip_from_world();
    // Near plane (world z = 4) -> z/w = 1, far plane (world z = -4) -> 0, centre -> middle.
    assert!((project(clip_from_world, DVec3::new(0.0, 0.0, 4.0)).z - 1.0).abs() < 1e-12);
    assert!(project(clip_from_world, DVec3::new(0.0, 0.0, -4.0)).z.abs() < 1e-12);
    let d = t.device_from_world();
    let centre = project(d, DVec3::ZERO);
    assert!((centre.x - 100.0).abs() < 1e-9 && (centre.y - 50.0).abs() < 1e-9);
    // fov 90, aspect 2, distance 5: world (10, 5) at z = 0 is the top-right corner; y down.
    let corner = project(d, DVec3::new(10.0, 5.0, 0.0));
    assert!((corner.x - 200.0).abs() < 1e-9 && corner.y.abs() < 1e-9, "{corner}");
    // Nearer points have larger depth.
    assert!(project(d, DVec3::new(0.0, 0.0, 2.0)).z > project(d, DVec3::new(0.0, 0.0, -2.0)).z);
    assert_eq!(t.pyramid_mode(), PyramidMode::Single);
    assert!(t.warnings().is_empty());
}

#[test]
fn abi_spaces_are_row_major_in_abi_order() {
    let mut t = scene();
    t.scale(DVec3::new(2.0, 3.0, 4.0)).unwrap();
    let spaces = t.abi_spaces();
    let dfo = t.device_from_object();
    for r in 0..4 {
        for c in 0..4 {
            assert_eq!(spaces[0][r * 4 + c], dfo.col(c)[r] as f32);
        }
    }
    // object_from_device * device_from_object = I.
    let ofd = DMat4::from_cols_array(&spaces[3].map(|v| v as f64)).transpose();
    let id = ofd * dfo;
    assert!(id.abs_diff_eq(DMat4::IDENTITY, 1e-5), "{id}");
}

#[test]
fn model_stack_push_pop_and_errors() {
    let mut t = TransformState::new();
    t.push();
    t.rotate_degrees(90.0, DVec3::Z).unwrap();
    let p = t.world_from_object().transform_point3(DVec3::X);
    assert!((p - DVec3::Y).length() < 1e-12);
    t.pop().unwrap();
    assert_eq!(t.world_from_object(), DMat4::IDENTITY);
    assert_eq!(t.pop(), Err(TransformError::StackUnderflow));
    assert_eq!(t.rotate_degrees(10.0, DVec3::ZERO), Err(TransformError::ZeroAxis));
    assert!(matches!(
        t.perspective(1.0, 1.0, 0.0, 10.0),
        Err(TransformError::BadParameter(_))
    ));
    assert!(matches!(
        t.perspective(4.0, 1.0, 0.1, 10.0),
        Err(TransformError::BadParameter(_))
    ));
    assert!(matches!(
        t.set_view_matrix(DMat4::NAN),
        Err(TransformError::NonFinite(_))
    ));
    assert_eq!(
        t.look_at(DVec3::ZERO, DVec3::Y, DVec3::Y),
        Err(TransformError::DegenerateLookAt)
    );
    assert!(matches!(
        t.set_viewport(0.0, 0.0, 0.0, 10.0),
        Err(TransformError::BadParameter(_))
    ));
    // Infinite far plane is allowed: far maps to z = 0 at infinity.
    let m = perspective_matrix(1.0, 1.0, 0.5, f64::INFINITY).unwrap();
    assert!((project(m, DVec3::new(0.0, 0.0, -0.5)).z - 1.0).abs() < 1e-12);
    assert!(project(m, DVec3::new(0.0, 0.0, -1e12)).z < 1e-12);
}

#[test]
fn oblique_projection_keeps_points_along_its_direction_together() {
    let dir = DVec3::new(0.5, -0.25, -1.0);
    let m = oblique_matrix([-1.0, 1.0, -1.0, 1.0], 1.0, 10.0, dir).unwrap();
    let a = project(m, DVec3::new(0.2, 0.3, -2.0));
    let b = project(m, DVec3::new(0.2, 0.3, -2.0) + dir * 3.0);
    assert!((a.x - b.x).abs() < 1e-12 && (a.y - b.y).abs() < 1e-12 && a.z != b.z);
    // The near-plane window maps to the clip square.
    let c = project(m, DVec3::new(1.0, 1.0, -1.0));
    assert!((c - DVec3::new(1.0, 1.0, 1.0)).length() < 1e-12);
}

#[test]
fn normals_use_the_inverse_transpose_and_survive_singular_models() {
    // Non-uniform scale: the normal of the plane x + y = 1 stays perpendicular to it.
    let m = DMat4::from_scale(DVec3::new(4.0, 1.0, 1.0));
    let nm = NormalMatrix::of(&m);
    assert!(!nm.singular);
    let (n, ok) = nm.transform(DVec3::new(1.0, 1.0, 0.0).normalize());
    assert!(ok);
    let tangent = m.transform_vector3(DVec3::new(1.0, -1.0, 0.0));
    assert!(n.dot(tangent).abs() < 1e-12 && (n.length() - 1.0).abs() < 1e-12);
    // A reflection keeps the normal on the side the surface's front moved to.
    let mirror = DMat4::from_scale(DVec3::new(-1.0, 1.0, 1.0));
    let (n, _) = NormalMatrix::of(&mirror).transform(DVec3::X);
    assert!((n - DVec3::new(-1.0, 0.0, 0.0)).length() < 1e-12);
    // Singular (a "fake shadow" flattening z): every normal goes to +-z, the image's normal.
    let flatten = DMat4::from_scale(DVec3::new(1.0, 1.0, 0.0));
    let nm = NormalMatrix::of(&flatten);
    assert!(nm.singular);
    let (n, ok) = nm.transform(DVec3::new(0.3, 0.4, 0.5).normalize());
    assert!(ok && (n.z.abs() - 1.0).abs() < 1e-12);
    // A normal lying in the flattened plane maps to zero: substituted by +z, flagged.
    assert_eq!(nm.transform(DVec3::X), (DVec3::Z, false));
    let mut t = TransformState::new();
    t.set_model(flatten).unwrap();
    assert_eq!(t.model_class(), ModelClass::Singular);
    assert!(t.warnings().contains(&Warning::SingularModel));
}

#[test]
fn projective_models_transform_normals_per_point() {
    let mut m = DMat4::IDENTITY;
    m.col_mut(0)[3] = 0.1; // w = 0.1 x + 1
    assert_eq!(classify_model(&m), ModelClass::Projective);
    // The plane z = 0 stays z = 0 under this map, so its normal stays +z everywhere.
    let (n, ok) = transform_normal_projective(&m, DVec3::Z, DVec3::new(3.0, 1.0, 0.0));
    assert!(ok && (n - DVec3::Z).length() < 1e-12);
    // The plane x = 1 maps to x' = 1 / 1.1: normal +x.
    let (n, _) = transform_normal_projective(&m, DVec3::X, DVec3::new(1.0, 2.0, 3.0));
    assert!((n - DVec3::X).length() < 1e-12);
}

#[test]
fn model_classes() {
    assert_eq!(classify_model(&DMat4::from_rotation_y(0.3)), ModelClass::Euclidean);
    assert_eq!(
        classify_model(&(DMat4::from_rotation_y(0.3) * DMat4::from_scale(DVec3::splat(2.0)))),
        ModelClass::Isotropic
    );
    assert_eq!(
        classify_model(&DMat4::from_scale(DVec3::new(1.0, 2.0, 3.0))),
        ModelClass::Affine
    );
    assert_eq!(classify_model(&DMat4::ZERO), ModelClass::Singular);
}

#[test]
fn non_positive_model_w_is_made_positive() {
    assert_eq!(
        sanitize_model_w(DVec4::new(1.0, 2.0, 3.0, 1.0)),
        (DVec4::new(1.0, 2.0, 3.0, 1.0), false)
    );
    assert_eq!(
        sanitize_model_w(DVec4::new(1.0, 2.0, 3.0, -2.0)),
        (DVec4::new(-1.0, -2.0, -3.0, 2.0), true)
    );
    let (p, changed) = sanitize_model_w(DVec4::new(1.0, 2.0, 3.0, 0.0));
    assert!(changed && p.w > 0.0 && p.w <= 1e-6);
}

#[test]
fn negative_and_double_pyramid_views() {
    let mut t = scene();
    let v = t.clip_from_world();
    // The same view written with w < 0 inside is negated back.
    t.set_view_matrix(-v).unwrap();
    assert!(t.clip_from_world().abs_diff_eq(v, 1e-15));
    assert_eq!(t.pyramid_mode(), PyramidMode::Single);
    // Far plane behind the eye: the view volume wraps around infinity.
    let mut p = perspective_matrix(1.0, 1.0, 1.0, 10.0).unwrap();
    let (n, f) = (1.0, -5.0);
    p.col_mut(2)[2] = n / (f - n);
    p.col_mut(3)[2] = n * f / (f - n);
    t.set_view_matrix(p).unwrap();
    assert_eq!(t.pyramid_mode(), PyramidMode::Double);
    assert!(t.warnings().contains(&Warning::DoublePyramidView));
}

#[test]
fn non_factorizable_view_lights_in_world_coordinates() {
    let mut t = scene();
    assert!(t.view_factors().is_ok());
    assert_ne!(t.lighting_from_world(), DMat4::IDENTITY);
    let mut shear = DMat4::IDENTITY;
    shear.col_mut(1)[0] = 0.3;
    t.set_view_matrix(shear * t.clip_from_world()).unwrap();
    assert_eq!(t.view_factors(), Err(NotFactorizable::NotRectangular));
    assert_eq!(t.lighting_from_world(), DMat4::IDENTITY);
    assert!(t.device_from_lighting().abs_diff_eq(t.device_from_world(), 1e-12));
    assert_eq!(
        t.warnings(),
        vec![Warning::NonFactorizableView(NotFactorizable::NotRectangular)]
    );
}

#[test]
fn pipeline_selection_follows_seed_000() {
    let facet = |t: &TransformState| {
        choose_pipeline(&PipelineState::from_transforms(
            t,
            GeometryType::Facet,
            true,
            true,
            false,
        ))
    };
    let mut t = scene();
    t.rotate_degrees(30.0, DVec3::Y).unwrap();
    t.scale(DVec3::splat(2.0)).unwrap();
    let c = facet(&t);
    assert_eq!((c.kind, c.lighting), (PipelineKind::CcFacet, LightingSpace::Model));
    assert!(c.warnings.is_empty());
    // Non-uniform scale: light in LC.
    t.scale(DVec3::new(1.0, 3.0, 1.0)).unwrap();
    let c = facet(&t);
    assert_eq!((c.kind, c.lighting), (PipelineKind::LcFacet, LightingSpace::Lighting));
    assert!(
        c.to_string()
            .starts_with("LC facet pipeline (seed 000 7.2), lit in lighting coordinates"),
        "{c}"
    );
    // Projective M: WC.
    let mut projective = DMat4::IDENTITY;
    projective.col_mut(0)[3] = 0.1;
    t.set_model(projective).unwrap();
    let c = facet(&t);
    assert_eq!((c.kind, c.lighting), (PipelineKind::WcFacet, LightingSpace::World));
    assert_eq!(c.warnings, vec![Warning::ProjectiveModel]);
    // Singular M: the CC facet pipeline (its `N` values are zeroed by the API: ambient only,
    // tests/pipeline/geometry_render.rs).
    t.set_model(DMat4::from_scale(DVec3::new(1.0, 0.0, 1.0))).unwrap();
    let c = facet(&t);
    assert_eq!(c.kind, PipelineKind::CcFacet);
    assert_eq!(c.warnings, vec![Warning::SingularModel]);
    // Non-factorizable V with an affine M: WC.
    t.set_model(DMat4::from_scale(DVec3::new(1.0, 2.0, 3.0))).unwrap();
    let mut shear = DMat4::IDENTITY;
    shear.col_mut(1)[0] = 0.3;
    t.set_view_matrix(shear * t.clip_from_world()).unwrap();
    let c = facet(&t);
    assert_eq!(c.kind, PipelineKind::WcFacet);
    assert_eq!(
        c.warnings,
        vec![Warning::NonFactorizableView(NotFactorizable::NotRectangular)]
    );
    // Other geometry types.
    let t = scene();
    let of = |g, lit| choose_pipeline(&PipelineState::from_transforms(&t, g, lit, true, true)).kind;
    assert_eq!(of(GeometryType::Point, false), PipelineKind::CcPoint);
    assert_eq!(
        of(GeometryType::PointWithExtent, false),
        PipelineKind::CcPointWithExtent
    );
    assert_eq!(of(GeometryType::Line, false), PipelineKind::CcLine);
    assert_eq!(of(GeometryType::Curve, false), PipelineKind::LcCurve);
    assert_eq!(of(GeometryType::Surface, true), PipelineKind::LcSurface);
    // Singular V: no model clipping.
    let mut state = PipelineState::from_transforms(&t, GeometryType::Line, false, true, true);
    state.view_factoring = Err(NotFactorizable::Singular);
    let c = choose_pipeline(&state);
    assert!(!c.do_model_clipping && c.warnings == vec![Warning::SingularView]);
}
