//! `points` (prims/points.prim): square and round points through the runtime's `point`
//! geometry, against an f64 statement of the rule written here (square: the box of side
//! `size` with screen_triangle's edge rule, left and lower edges in; round: centres strictly
//! inside the circle), plus tiling, shading, depth and clipping by the centre.

use crate::support::*;

use primflow::jit::Jit;
use primflow::runtime::{Frame, Renderer, Value};

const SIZE: u32 = 48;

/// Submit one `points` primitive of `size` (round or square) at `centres` (x, y, depth),
/// each with its own value of the shading parameter `Cs`.
fn points(r: &mut Renderer, size: f32, round: bool, centres: &[[f32; 3]]) {
    r.material_interp("Cs", "linear", &[]).unwrap();
    r.begin("points").unwrap();
    r.rast_param("size", &Value(vec![size])).unwrap();
    r.rast_param("round", &Value(vec![if round { 1.0 } else { 0.0 }]))
        .unwrap();
    for (i, c) in centres.iter().enumerate() {
        r.material("Cs", &Value(vec![i as f32, 0.5, 0.25])).unwrap();
        r.vertex(c[0], c[1], c[2], 1.0).unwrap();
    }
    r.end().unwrap();
    assert!(r.take_warnings().is_empty());
}

/// Whether the pixel centre (px, py) is covered by the point at (cx, cy), in f64.
fn reference(cx: f64, cy: f64, size: f64, round: bool, px: f64, py: f64) -> bool {
    let (h, dx, dy) = (size / 2.0, px - cx, py - cy);
    if round {
        dx * dx + dy * dy < h * h
    } else {
        dx >= -h && dx < h && dy > -h && dy <= h
    }
}

fn render(r: &Renderer, jit: &mut Jit) -> Frame {
    render_with(r, jit, 2)
}

#[test]
fn square_and_round_points_cover_the_pixels_of_the_f64_rule() {
    // Centres on the 1/16 grid and sizes that are multiples of 1/8, so every edge test in
    // f32 is exact (differences of grid values); round points are kept clear of ties by at
    // least 1e-3 px^2 (asserted). Source of truth: the rule in f64; tolerance 0 pixels.
    let program = library();
    let mut jit = Jit::new(program.clone()).unwrap();
    let mut rng = SplitMix(5);
    let mut checked = 0;
    for case in 0..40 {
        let round = case % 2 == 1;
        let size = [1.0, 2.0, 3.0, 4.5, 7.25][case % 5] as f32;
        let c = [
            (rng.range(8.0, 40.0) * 16.0).round() / 16.0,
            (rng.range(8.0, 40.0) * 16.0).round() / 16.0,
        ];
        let near_tie = (0..SIZE * SIZE).any(|i| {
            let (dx, dy) = (f64::from(i % SIZE) + 0.5 - c[0], f64::from(i / SIZE) + 0.5 - c[1]);
            let h = f64::from(size) / 2.0;
            round && (dx * dx + dy * dy - h * h).abs() < 1e-3 && dx * dx + dy * dy != h * h
        });
        if near_tie {
            continue;
        }
        let mut r = renderer(&program, SIZE, SIZE, true);
        points(&mut r, size, round, &[[c[0] as f32, c[1] as f32, 0.5]]);
        let frame = render(&r, &mut jit);
        for y in 0..SIZE {
            for x in 0..SIZE {
                let want = reference(
                    c[0],
                    c[1],
                    f64::from(size),
                    round,
                    f64::from(x) + 0.5,
                    f64::from(y) + 0.5,
                );
                assert_eq!(
                    frame.written(x, y),
                    want,
                    "size {size} round {round} at {c:?}: pixel {x},{y}"
                );
            }
        }
        checked += 1;
    }
    assert!(checked >= 35, "{checked} cases checked");
}

#[test]
fn square_points_size_apart_tile_without_gap_or_double_pixel() {
    // A 6 x 6 grid of 2.5 px points 2.5 px apart, their centres on the 1/16 grid: the squares
    // tile the plane, so by the edge rule each pixel centre of the covered area is written
    // exactly once. Source of truth: the tiling (write counts); tolerance 0.
    let program = library();
    let mut r = renderer(&program, SIZE, SIZE, true);
    let centres: Vec<[f32; 3]> = (0..36)
        .map(|i| [10.0 + 2.5 * (i % 6) as f32, 10.0 + 2.5 * (i / 6) as f32, 0.5])
        .collect();
    points(&mut r, 2.5, false, &centres);
    let frame = render(&r, &mut Jit::new(program.clone()).unwrap());
    let counts = frame.write_count_values().unwrap();
    for y in 0..SIZE {
        for x in 0..SIZE {
            let (px, py) = (f64::from(x) + 0.5, f64::from(y) + 0.5);
            // The union of the squares: [8.75, 23.75) in x, (8.75, 23.75] in y.
            let inside = (8.75..23.75).contains(&px) && py > 8.75 && py <= 23.75;
            assert_eq!(counts[(y * SIZE + x) as usize], u32::from(inside), "pixel {x},{y}");
        }
    }
}

#[test]
fn a_point_shades_with_its_own_values_and_depth() {
    // Two overlapping points at depths 0.25 and 0.75: the nearer (larger) wins where they
    // overlap, each pixel carries its own point's Cs, and the depth is the point's. Source
    // of truth: the values given; tolerance: the depth buffer's step.
    let program = library();
    let mut r = renderer(&program, SIZE, SIZE, false);
    points(&mut r, 6.0, false, &[[20.0, 20.0, 0.25], [22.0, 22.0, 0.75]]);
    let frame = render(&r, &mut Jit::new(program.clone()).unwrap());
    assert_eq!(frame.param_at("Cs", 18, 18).unwrap(), vec![0.0, 0.5, 0.25]);
    assert_eq!(frame.param_at("Cs", 21, 21).unwrap(), vec![1.0, 0.5, 0.25]);
    assert_eq!(frame.depth_at(21, 21), Some(raw_depth(0.75)));
    assert_eq!(frame.depth_at(18, 18), Some(raw_depth(0.25)));
}

#[test]
fn points_are_clipped_by_their_centre() {
    // Under a camera: a point behind the eye and one far outside the guard band draw
    // nothing; one whose centre is just off the image (inside the guard band) draws its
    // visible part; a NaN point is dropped. Source of truth: the clip rule (docs/pipeline.md,
    // "Points"); pixel counts exact.
    let program = library();
    let mut r = renderer(&program, SIZE, SIZE, true);
    r.perspective_checked(90.0, 1.0, 100.0).unwrap();
    r.begin("points").unwrap();
    r.rast_param("size", &Value(vec![8.0])).unwrap();
    // Camera space x = 1.125 at z = -1.125 is device x = 24 + 24 = 48: the right edge.
    r.vertex(1.125, 0.0, -1.125, 1.0).unwrap();
    r.vertex(0.0, 0.0, 3.0, 1.0).unwrap();
    r.vertex(500.0, 0.0, -2.0, 1.0).unwrap();
    r.vertex(f32::NAN, 0.0, -2.0, 1.0).unwrap();
    r.end().unwrap();
    let frame = render(&r, &mut Jit::new(program.clone()).unwrap());
    let counts = frame.write_count_values().unwrap();
    // Half of the 8 x 8 square is on the image: 4 columns x 8 rows.
    assert_eq!(counts.iter().filter(|&&c| c == 1).count(), 32);
    assert!(counts.iter().all(|&c| c <= 1));
    assert!(r.explain_lines().join("\n").contains("CC point pipeline"));
}
