//! The geometry stage for `line` primitives (docs/pipeline.md, "Lines"): each polyline
//! segment clipped alone by Liang-Barsky in homogeneous clip space, joints handed the same
//! three points from both sides; and primitives with no geometry type, whose points the
//! runtime neither clips, culls nor fans.

use crate::support;

use glam::{DVec3, DVec4};
use primflow::diag::SourceMap;
use primflow::pipeline::face::CullMode;
use primflow::runtime::geometry::{ClipOutcome, GeometryState, Segment};

const W: u32 = 64;
const H: u32 = 48;

/// A camera at the origin looking down -z, 90 degree fov, near 1, far 100 (as the
/// renderer's `perspective_checked(90, 1, 100)` sets it).
fn perspective_state() -> GeometryState {
    let mut g = GeometryState::new(W, H);
    g.direct = None;
    g.transforms
        .perspective(90f64.to_radians(), f64::from(W) / f64::from(H), 1.0, 100.0)
        .unwrap();
    g
}

fn clip(g: &GeometryState, points: &[[f64; 3]], attrs: &[f32]) -> (ClipOutcome, Vec<Segment>) {
    let objects: Vec<DVec4> = points.iter().map(|p| DVec3::from_array(*p).extend(1.0)).collect();
    let positions: Vec<DVec4> = objects.iter().map(|p| g.clip_from_object() * *p).collect();
    let device: Vec<DVec4> = objects.iter().map(|p| g.device_from_object() * *p).collect();
    let attrs: Vec<Vec<f32>> = attrs.iter().map(|&a| vec![a]).collect();
    let mut warnings = vec![];
    let r = g.clip_polyline(&positions, &device, &attrs, &mut warnings);
    (r.outcome, r.segments)
}

#[test]
fn segments_inside_keep_their_vertices_bit_for_bit() {
    // Source of truth: the vertices' own `device_from_object` transform, which the facet
    // path also keeps for unclipped vertices; exact (bits).
    let g = perspective_state();
    let pts = [[-1.0, -0.5, -4.0], [0.5, 0.25, -3.0], [1.0, -0.75, -5.0]];
    let (outcome, segs) = clip(&g, &pts, &[0.0, 1.0, 2.0]);
    assert_eq!(outcome, ClipOutcome::TriviallyAccepted);
    assert_eq!(segs.len(), 2);
    for (k, s) in segs.iter().enumerate() {
        assert_eq!(s.index, k);
        assert_eq!(s.original, [true, true]);
        for e in 0..2 {
            let want = g.device_from_object() * DVec3::from_array(pts[k + e]).extend(1.0);
            assert_eq!(s.ends[e].0, want);
            assert_eq!(s.ends[e].1, vec![(k + e) as f32]);
        }
    }
}

#[test]
fn a_segment_through_the_eye_plane_keeps_its_part_in_front_with_interpolated_data() {
    // From z = -3 (in front) to z = +1 (behind the eye): Liang-Barsky against the near plane
    // z_eye = -1 (clip z = w) cuts it at t = 0.5, where the attribute is halfway; the f64
    // reference is the line's own parametrisation. Tolerance 1e-12 relative (f64 clipping).
    let g = perspective_state();
    let (outcome, segs) = clip(&g, &[[0.0, 0.0, -3.0], [0.0, 0.4, 1.0]], &[0.0, 8.0]);
    assert_eq!(outcome, ClipOutcome::Clipped);
    assert_eq!(segs.len(), 1);
    let s = &segs[0];
    assert_eq!(s.original, [true, false]);
    let want = g.device_from_object() * DVec4::new(0.0, 0.2, -1.0, 1.0);
    let got = s.ends[1].0;
    assert!(got.w > 0.0, "a clipped end has w > 0");
    for (g, w) in got.to_array().iter().zip(want.to_array()) {
        assert!((g - w).abs() <= 1e-12 * w.abs().max(1.0), "end {got:?}, want {want:?}");
    }
    assert_eq!(s.ends[1].1, vec![4.0]);
}

#[test]
fn a_segment_outside_one_plane_is_dropped_and_its_neighbours_lose_the_joint() {
    // Source of truth: the clip-code AND rule (seed 002) applied per segment; exact.
    let g = perspective_state();
    // The middle segment lies entirely beyond the right guard band (x > w).
    let pts = [
        [-0.5, 0.0, -4.0],
        [30.0, 0.0, -4.0],
        [30.0, 1.0, -4.0],
        [0.5, 1.0, -4.0],
    ];
    let (outcome, segs) = clip(&g, &pts, &[0.0; 4]);
    assert_eq!(outcome, ClipOutcome::Clipped);
    let indices: Vec<usize> = segs.iter().map(|s| s.index).collect();
    assert_eq!(indices, [0, 2], "segment 1 is outside x > w");
    assert_eq!(segs[0].original, [true, false]);
    assert_eq!(segs[1].original, [false, true]);
    // Entirely behind the eye: nothing.
    let (outcome, segs) = clip(&g, &[[0.0, 0.0, 2.0], [1.0, 0.0, 3.0]], &[0.0; 2]);
    assert_eq!(outcome, ClipOutcome::TriviallyRejected);
    assert!(segs.is_empty());
}

#[test]
fn model_clip_planes_cut_segments() {
    // The plane x >= 0 (world) keeps the right half of a segment from x = -1 to x = 1: the
    // new end lies on it, up to f64 rounding (1e-12).
    let mut g = perspective_state();
    g.clip_planes.push(DVec4::new(1.0, 0.0, 0.0, 0.0));
    let (_, segs) = clip(&g, &[[-1.0, 0.0, -4.0], [1.0, 0.0, -4.0]], &[0.0, 2.0]);
    assert_eq!(segs.len(), 1);
    assert_eq!(segs[0].original, [false, true]);
    let start = segs[0].ends[0].0;
    let centre = g.device_from_object() * DVec4::new(0.0, 0.0, -4.0, 1.0);
    assert!(
        (start.x / start.w - centre.x / centre.w).abs() < 1e-9,
        "{start:?} vs {centre:?}"
    );
    assert!((segs[0].ends[0].1[0] - 1.0).abs() < 1e-6);
}

/// A primitive with no geometry type that marks the pixel under each of its points.
const DOTS: &str = "
primitive dots(point vertex[]; varying float X, Y; inout varying fixed<32,32> Z)
{
    bound(0, 0, 1e6, 1e6);
    for (int i = 0; i < len(vertex); i++) {
        float x = vertex[i][0] / vertex[i][3], y = vertex[i][1] / vertex[i][3];
        if (floor(x) + 0.5 == X && floor(y) + 0.5 == Y)
            Z = 0.5;
    }
}
";

#[test]
fn a_primitive_without_a_geometry_type_is_neither_culled_nor_clipped() {
    // Three points in clockwise order on screen (a back face, were it a facet) and a fourth
    // far outside the viewport: with `cull back` a facet would be culled, and clipped
    // against the guard band. Source of truth: the points themselves; exact pixel count.
    let mut sources = SourceMap::new();
    let program = support::library_with(&mut sources, &[("dots.prim", DOTS)]);
    let mut r = support::renderer(&program, W, H, true);
    r.set_cull(CullMode::Back);
    r.begin("dots").unwrap();
    for p in [[10.2, 10.7], [30.5, 20.1], [12.9, 40.3], [-5000.0, 20.0]] {
        r.vertex(p[0], p[1], 0.0, 1.0).unwrap();
    }
    r.end().unwrap();
    let frame = support::render(&r, 2);
    let written: Vec<(u32, u32)> = (0..H)
        .flat_map(|y| (0..W).map(move |x| (x, y)))
        .filter(|&(x, y)| frame.written(x, y))
        .collect();
    assert_eq!(written, [(10, 10), (30, 20), (12, 40)]);
}

/// A perspective renderer (the camera of [`perspective_state`]) with write counting.
fn perspective_renderer() -> primflow::runtime::Renderer {
    let program = support::library();
    let mut r = support::renderer(&program, W, H, true);
    r.perspective_checked(90.0, 1.0, 100.0).unwrap();
    r
}

fn polyline(r: &mut primflow::runtime::Renderer, width: f32, points: &[[f32; 3]]) {
    r.begin("polyline").unwrap();
    r.rast_param("width", &primflow::runtime::Value(vec![width])).unwrap();
    for p in points {
        r.vertex(p[0], p[1], p[2], 1.0).unwrap();
    }
    r.end().unwrap();
}

#[test]
fn a_segment_reaching_behind_the_eye_draws_what_its_front_part_draws() {
    // From z = -3 to z = +1 (behind the eye), cut by the near plane z = -1 at t = 0.5,
    // i.e. at (0.25, 0.2, -1). Source of truth: the same segment given only up to that
    // point; tolerance 0 pixels (the cut is at a grid-friendly point, far from pixel ties).
    let mut clipped = perspective_renderer();
    polyline(&mut clipped, 2.0, &[[-0.5, -0.4, -3.0], [1.0, 0.8, 1.0]]);
    let mut front = perspective_renderer();
    polyline(&mut front, 2.0, &[[-0.5, -0.4, -3.0], [0.25, 0.2, -1.0]]);
    let (a, b) = (support::render(&clipped, 2), support::render(&front, 2));
    let covered = |f: &primflow::runtime::Frame| f.write_count_values().unwrap();
    assert!(covered(&b).iter().filter(|&&c| c > 0).count() > 20);
    assert_eq!(covered(&a), covered(&b));
}

#[test]
fn a_polyline_leaving_the_view_and_the_eye_covers_each_pixel_at_most_once() {
    // A closed loop in front of the camera whose third point is far off to the side and
    // whose fifth is behind the eye: its segments are dropped, clipped by the guard band and
    // by the near plane, and the joints between unclipped segments stay mitered. Source of
    // truth: write counts (no pixel twice; D3D11 3.4.4's rectangles with shared miters), and
    // finite planes; the explain line names the line pipeline and the runtime's clipping.
    let mut r = perspective_renderer();
    let loop_points = [
        [-1.0, -0.5, -3.0],
        [1.0, -0.6, -3.5],
        [1e6, 0.0, -3.0],
        [0.8, 0.7, -2.5],
        [0.0, 0.9, 2.0],
        [-1.2, 0.4, -4.0],
        [-1.0, -0.5, -3.0],
    ];
    polyline(&mut r, 1.5, &loop_points);
    let frame = support::render(&r, 2);
    let counts = frame.write_count_values().unwrap();
    assert!(counts.iter().all(|&c| c <= 1), "a pixel written twice");
    assert!(counts.iter().filter(|&&c| c > 0).count() > 40);
    for plane in frame.all_plane_values() {
        assert!(plane.iter().all(|v| v.is_finite()));
    }
    let explain = r.explain_lines().join("\n");
    assert!(
        explain.contains("polyline") && explain.contains("CC line pipeline"),
        "{explain}"
    );
    assert!(explain.contains("clipped by the runtime"), "{explain}");
}
