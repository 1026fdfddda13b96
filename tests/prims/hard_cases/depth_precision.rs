//! Depth precision. The depth buffer is `fixed<32,32>` (docs/language.md: an unsigned
//! fraction in [0, 1), raw = depth * 2^32, larger is nearer, 0 = nothing written); a float
//! depth converts to it rounding to the nearest raw value and clamping (docs/language.md,
//! section 5). screen_triangle evaluates its depth plane in f32, converts, and keeps the
//! pixel unless the buffer holds a nearer value (`triangle_z < Z` returns), so equal depths
//! let the later primitive through.

use crate::support::*;

use std::sync::Arc;

use primflow::ir::Program;
use primflow::jit::Jit;
use primflow::runtime::Frame;

const W: u32 = 32;
const H: u32 = 32;

/// Screen triangles with an `id` shading parameter (linear, the same at every vertex), in
/// the order given; the frame.
fn draw(program: &Arc<Program>, jit: &mut Jit, triangles: &[([[f32; 3]; 3], f32)]) -> Frame {
    let mut r = renderer(program, W, H, false);
    r.material_interp("id", "linear", &[]).unwrap();
    for (t, id) in triangles {
        let v = |i: usize| [t[i][0], t[i][1], t[i][2], 1.0];
        let ids: [Vec<f32>; 3] = std::array::from_fn(|_| vec![*id]);
        screen_triangle(&mut r, [v(0), v(1), v(2)], &[("id", ids)]);
    }
    render_with(&r, jit, 2)
}

/// A triangle covering the whole 32 x 32 view (inside the 1,024 px exact path), its three
/// vertices at the depths given.
fn covering(z: [f32; 3]) -> [[f32; 3]; 3] {
    [[-8.0, -8.0, z[0]], [88.0, -8.0, z[1]], [-8.0, 88.0, z[2]]]
}

/// The smallest f32 depth whose raw value is the next one above `z`'s, kept clear of a
/// rounding tie (so the conversion's tie rule does not matter).
fn next_resolved(z: f32) -> f32 {
    let raw = raw_depth(z.into());
    let mut next = ((f64::from(raw) + 0.5) / 4294967296.0) as f32;
    while f64::from(next) * 4294967296.0 <= f64::from(raw) + 0.5 {
        next = next.next_up();
    }
    next
}

/// Two constant-depth triangles covering the view, one raw depth step apart (at and above
/// depth 2^-9 that is one f32 ulp of the depth, 2^8 raw steps at depth 0.5; below it one raw
/// step, 2^-32), drawn in both orders: the nearer wins at every pixel, and the buffer holds
/// exactly its rounded depth. Equal depths: the later triangle wins everywhere. Source:
/// docs/language.md's conversion (round to nearest, clamp) with raw = round(z 2^32) computed
/// in f64 (`raw_depth`), and dEQP's `fragment_ops.depth.cmp_greater_or_equal` (equal depths
/// pass a GEQUAL test, which is what a reversed buffer's `triangle_z < Z` return is);
/// tolerance 0 raw units, 0 pixels.
#[test]
fn one_depth_step_apart_the_nearer_triangle_wins_everywhere() {
    let program = library();
    let mut jit = Jit::new(program.clone()).unwrap();
    let pixels = || (0..H).flat_map(|y| (0..W).map(move |x| (x, y)));
    for far in [0.999_999_9f32, 0.75, 0.5, 0.1, 1e-3, 0.001_953_125, 1e-5, 3e-9] {
        let near = next_resolved(far);
        let (raw_far, raw_near) = (raw_depth(far.into()), raw_depth(near.into()));
        // One step: one f32 ulp where the f32 grid is coarser than the raw one, else one raw
        // value.
        assert!(
            raw_near > raw_far && (near == far.next_up() || raw_near == raw_far + 1),
            "setup: {far:e} {near:e}"
        );
        for (order, tris) in [
            ("far first", [(covering([far; 3]), 1.0), (covering([near; 3]), 2.0)]),
            ("near first", [(covering([near; 3]), 2.0), (covering([far; 3]), 1.0)]),
        ] {
            let frame = draw(&program, &mut jit, &tris);
            let wrong: Vec<_> = pixels()
                .filter(|&(x, y)| {
                    frame.depth_at(x, y) != Some(raw_near) || frame.param_at("id", x, y) != Some(vec![2.0])
                })
                .collect();
            assert!(
                wrong.is_empty(),
                "depth {far:e} vs {near:e} ({order}): {} pixels not the nearer's, e.g. {:?} holds {:?}",
                wrong.len(),
                wrong[0],
                frame.depth_at(wrong[0].0, wrong[0].1)
            );
        }
        // A tie: the later of two equal depths is kept.
        let frame = draw(
            &program,
            &mut jit,
            &[(covering([far; 3]), 1.0), (covering([far; 3]), 2.0)],
        );
        assert!(
            pixels()
                .all(|(x, y)| frame.depth_at(x, y) == Some(raw_far) && frame.param_at("id", x, y) == Some(vec![2.0])),
            "depth {far:e}: equal depths do not let the later triangle through"
        );
    }
}

/// The error of screen_triangle's f32 depth plane (coefficients from three vertex
/// differences, evaluated as a X + b Y + c, each step one rounding of a term at most 1 in
/// size for these triangles, then one conversion to fixed): a few f32 ulps of 1. Asserted:
/// 2^-21 (eight f32 ulps at depth 0.5).
const PLANE_TOLERANCE: f64 = 1.0 / 2_097_152.0;

/// Random sloped triangles covering the view, depths 0.05 to 0.95 at the vertices, against
/// the plane through the same (f32) vertices in f64 at every pixel centre; then each one
/// twice, the copy moved nearer by the smallest separation the tolerance guarantees (twice
/// it, plus a raw step), drawn in both orders: the nearer wins at every pixel. Source: the
/// f64 plane (a planar primitive's depth is affine in screen space: OpenGL ES 3.0 and D3D11
/// interpolate it without perspective correction); tolerance `PLANE_TOLERANCE` in depth
/// units, and 0 pixels for the ordering.
#[test]
fn sloped_depth_is_the_f64_plane_and_the_nearer_of_two_close_planes_wins() {
    let program = library();
    let mut jit = Jit::new(program.clone()).unwrap();
    let mut rng = Lcg(33);
    let mut worst = 0f64;
    let separation = 2.0 * PLANE_TOLERANCE + 1.0 / 4294967296.0;
    for case in 0..40 {
        // Corners far enough out that the triangle covers the view.
        let angle = rng.range(0.0, std::f64::consts::TAU);
        let corner = |k: f64, rng: &mut Lcg| {
            let a = angle + k * std::f64::consts::TAU / 3.0 + rng.range(-0.3, 0.3);
            let d = rng.range(150.0, 400.0);
            [
                (16.0 + d * a.cos()) as f32,
                (16.0 + d * a.sin()) as f32,
                rng.range(0.05, 0.95) as f32,
            ]
        };
        let t = [corner(0.0, &mut rng), corner(1.0, &mut rng), corner(2.0, &mut rng)];
        let frame = draw(&program, &mut jit, &[(t, 1.0)]);
        let t64 = t.map(|p| p.map(f64::from));
        for y in 0..H {
            for x in 0..W {
                let want = super::screen_triangle_depth(&t64, f64::from(x) + 0.5, f64::from(y) + 0.5);
                let Some(want) = want else {
                    panic!("case {case}: the triangle does not cover ({x}, {y})")
                };
                let got = f64::from(frame.depth_at(x, y).unwrap()) / 4294967296.0;
                worst = worst.max((got - want).abs());
            }
        }
        let nearer = t.map(|p| [p[0], p[1], (f64::from(p[2]) + separation) as f32]);
        for tris in [[(t, 1.0), (nearer, 2.0)], [(nearer, 2.0), (t, 1.0)]] {
            let frame = draw(&program, &mut jit, &tris);
            let lost = (0..H)
                .flat_map(|y| (0..W).map(move |x| (x, y)))
                .filter(|&(x, y)| frame.param_at("id", x, y) != Some(vec![2.0]))
                .count();
            assert_eq!(lost, 0, "case {case}: the nearer plane lost {lost} pixels");
        }
    }
    println!("sloped depth planes: worst error {worst:.2e} (tolerance {PLANE_TOLERANCE:.2e})");
    assert!(worst <= PLANE_TOLERANCE, "depth off the f64 plane by {worst:e}");
}

/// The ends of the range: a depth of exactly 1 (the hither plane) saturates to the largest
/// raw value; a depth below half a raw step rounds to 0, which is the cleared buffer's
/// value, so nothing counts as written (docs: 0 = nothing written); the smallest depth that
/// is written is half a step (rounding up to raw 1); depths outside [0, 1] are not drawn.
/// Source: docs/language.md's conversion (saturating) and `Frame::depth_at`'s documented
/// meaning of 0; tolerance 0 raw units.
#[test]
fn depths_at_the_ends_of_the_range_saturate_round_or_are_not_drawn() {
    let program = library();
    let mut jit = Jit::new(program.clone()).unwrap();
    let at_centre = |z: f32, jit: &mut Jit| {
        let frame = draw(&program, jit, &[(covering([z; 3]), 1.0)]);
        (frame.written(16, 16), frame.depth_at(16, 16).unwrap())
    };
    assert_eq!(at_centre(1.0, &mut jit), (true, u32::MAX), "depth 1");
    assert_eq!(
        at_centre(1.0f32.next_down(), &mut jit),
        (true, u32::MAX - 255),
        "just below 1"
    );
    assert_eq!(at_centre(0.6 / 4294967296.0, &mut jit), (true, 1), "0.6 raw steps");
    assert_eq!(at_centre(0.4 / 4294967296.0, &mut jit), (false, 0), "0.4 raw steps");
    assert_eq!(at_centre(0.0, &mut jit), (false, 0), "depth 0");
    assert_eq!(
        at_centre(1.0f32.next_up(), &mut jit),
        (false, 0),
        "past the hither plane"
    );
    assert_eq!(at_centre(-1e-30, &mut jit), (false, 0), "past the yon plane");
}
