//! `screen_segment` (prims/screen_segment.prim), the line twin of screen_triangle, called
//! directly with explicit rows, against an f64 reference of its rule written here: D3D11's
//! rectangle lines (functional spec 3.4.4) with butt ends, miter cuts at joints (a pixel
//! centre on a miter belongs to the segment starting there), the top-left rule on long sides
//! and butt ends, and the bound's miter limit of 2 widths.
//!
//! Coordinates are on the 1/16 pixel grid and every case is checked for near-ties: the
//! reference records any pixel centre within [`NEAR_TIE`] px of an edge, miter or bound
//! without being exactly on it, and a case with one is rejected (the fixed cases assert none,
//! the random ones are drawn again). The f32 kernel's distances are off by at most ~2e-5 px
//! at the sizes used (a unit vector's ~3 ulp times 90 px, plus the sum's rounding), so away
//! from near-ties f32 and f64 must agree; exact ties (axis-aligned and 45-degree edges and
//! miters through pixel centres) are computed exactly by both, as the differences of 1/16-grid
//! values are exact.

use crate::support::*;

use std::sync::Arc;

use primflow::ir::Program;
use primflow::jit::Jit;
use primflow::runtime::{Frame, Renderer, Value};

/// Distance (px) under which a pixel centre that is not exactly on an edge counts as a
/// near-tie: five times the kernel's worst f32 distance error at these sizes.
const NEAR_TIE: f64 = 1e-4;

/// The image of every case.
const SIZE: u32 = 96;

/// The rows of a segment: [point before, start, end, point after], x y z w each.
type Rows = [[f32; 4]; 4];

/// On the 1/16 grid.
fn snap(v: f64) -> f64 {
    (v * 16.0).round() / 16.0
}

/// Submit one `screen_segment` with `rows`, `width` and per-parameter values at start and end.
fn segment(r: &mut Renderer, rows: Rows, width: f32, params: &[(&str, [Vec<f32>; 2])]) {
    r.begin("screen_segment").unwrap();
    r.rast_param("screen_vertex", &Value(rows.iter().flatten().copied().collect()))
        .unwrap();
    r.rast_param("width", &Value(vec![width])).unwrap();
    for i in 0..2 {
        for (name, values) in params {
            r.material(name, &Value(values[i].clone())).unwrap();
        }
        r.sequence_point().unwrap();
    }
    r.end().unwrap();
    assert!(r.take_warnings().is_empty());
}

/// The segments of the polyline through `points` (x, y; depth 0.5, w 1): each segment's rows
/// name its neighbours, or repeat its own endpoint at the polyline's ends (non-joints).
fn polyline_rows(points: &[[f64; 2]]) -> Vec<Rows> {
    let row = |p: [f64; 2]| [p[0] as f32, p[1] as f32, 0.5, 1.0];
    let n = points.len();
    (0..n - 1)
        .map(|i| {
            let before = if i == 0 { points[i] } else { points[i - 1] };
            let after = if i + 2 < n { points[i + 2] } else { points[i + 1] };
            [row(before), row(points[i]), row(points[i + 1]), row(after)]
        })
        .collect()
}

/// The library and one JIT for a test's many small renders (each kernel compiled once).
struct Lines {
    program: Arc<Program>,
    jit: Jit,
}

impl Lines {
    fn new() -> Lines {
        let program = library();
        let jit = Jit::new(program.clone()).unwrap();
        Lines { program, jit }
    }

    /// Render `segments` (all of width `width`) with write counting; the frame.
    fn render(&mut self, segments: &[Rows], width: f32) -> Frame {
        let mut r = renderer(&self.program, SIZE, SIZE, true);
        for rows in segments {
            segment(&mut r, *rows, width, &[]);
        }
        render_with(&r, &mut self.jit, 2)
    }
}

fn counts(frame: &Frame) -> Vec<u32> {
    frame.write_count_values().unwrap()
}

// ---- The f64 reference -------------------------------------------------------------------

/// screen_triangle's (and the prim's) top-left predicate for an inside-pointing normal.
fn top_left(a: f64, b: f64) -> bool {
    a > 0.0 || (a == 0.0 && b < 0.0)
}

/// The miter normal at `joint` between the segments from `prev` and to `next`, if any: the
/// sum of their unit directions, none for a zero-length neighbour or a fold-back (|m| <= 1e-3).
fn miter(prev: [f64; 2], joint: [f64; 2], next: [f64; 2]) -> Option<[f64; 2]> {
    let (ix, iy) = (joint[0] - prev[0], joint[1] - prev[1]);
    let (ox, oy) = (next[0] - joint[0], next[1] - joint[1]);
    let (li, lo) = (ix.hypot(iy), ox.hypot(oy));
    if li == 0.0 || lo == 0.0 {
        return None;
    }
    let m = [ix / li + ox / lo, iy / li + oy / lo];
    (m[0] * m[0] + m[1] * m[1] > 1e-6).then_some(m)
}

/// The rule of screen_segment in f64, for one segment.
struct Reference {
    p: [[f64; 2]; 4],
    width: f64,
    /// Pixel centres seen within NEAR_TIE of an edge without being on it.
    near_ties: usize,
    /// Pixel centres exactly on a miter line (the partition's tie-break exercised).
    miter_ties: usize,
}

impl Reference {
    fn new(rows: &Rows, width: f32) -> Reference {
        Reference {
            p: rows.map(|r| [f64::from(r[0]), f64::from(r[1])]),
            width: f64::from(width),
            near_ties: 0,
            miter_ties: 0,
        }
    }

    /// Whether the segment covers pixel centre (x, y).
    fn covers(&mut self, x: f64, y: f64) -> bool {
        // Every test as (value, a distance in px positive inside; whether a tie is inside;
        // whether it is a miter).
        let tests = self.tests(x, y);
        let pass = |&(e, tie, _): &(f64, bool, bool)| e > 0.0 || (e == 0.0 && tie);
        let inside = tests.iter().all(pass);
        // A near-tie matters where it alone could decide: every other test passes.
        for (i, &(e, _, is_miter)) in tests.iter().enumerate() {
            let others = tests.iter().enumerate().all(|(j, t)| j == i || pass(t));
            if e != 0.0 && e.abs() < NEAR_TIE && others {
                self.near_ties += 1;
            }
            if e == 0.0 && is_miter && others {
                self.miter_ties += 1;
            }
        }
        inside
    }

    fn tests(&self, x: f64, y: f64) -> Vec<(f64, bool, bool)> {
        let [_, s, e, _] = self.p;
        let (dx, dy) = (e[0] - s[0], e[1] - s[1]);
        let len = dx.hypot(dy);
        if len == 0.0 {
            return vec![(-1.0, false, false)];
        }
        let (tx, ty) = (dx / len, dy / len);
        let (nx, ny) = (-ty, tx);
        let hw = self.width / 2.0;
        // The bound: the endpoints' box grown by the reach (width/2, a miter's tip up to
        // 2 width) and 1/16 px; pixel centres on it are inside.
        let start_miter = miter(self.p[0], s, e);
        let end_miter = miter(s, e, self.p[3]);
        let mut reach = hw;
        for m in [start_miter, end_miter].into_iter().flatten() {
            reach = reach.max((self.width / m[0].hypot(m[1])).min(2.0 * self.width));
        }
        let pad = reach + 0.0625;
        let mut tests = vec![
            (x - (s[0].min(e[0]) - pad), true, false),
            (y - (s[1].min(e[1]) - pad), true, false),
            (s[0].max(e[0]) + pad - x, true, false),
            (s[1].max(e[1]) + pad - y, true, false),
        ];
        // The long sides, top-left by their inside-pointing normals.
        let (rx, ry) = (x - s[0], y - s[1]);
        let across = nx * rx + ny * ry;
        tests.push((hw - across, top_left(-nx, -ny), false));
        tests.push((hw + across, top_left(nx, ny), false));
        // The start: a miter (pixel centres on it belong here) or a butt end.
        tests.push(match start_miter {
            Some(m) => {
                let f = (m[0] * (x - s[0]) + m[1] * (y - s[1])) / m[0].hypot(m[1]);
                (f, true, true)
            }
            None => (tx * rx + ty * ry, top_left(tx, ty), false),
        });
        // The end: the negated miter (pixel centres on it belong to the next segment) or a
        // butt end.
        tests.push(match end_miter {
            Some(m) => {
                let f = (m[0] * (x - e[0]) + m[1] * (y - e[1])) / m[0].hypot(m[1]);
                (-f, false, true)
            }
            None => (-(tx * (x - e[0]) + ty * (y - e[1])), top_left(-tx, -ty), false),
        });
        tests
    }
}

/// The reference's write counts of `segments` over the image, and its near-ties and miter
/// ties in all.
fn reference_counts(segments: &[Rows], width: f32) -> (Vec<u32>, usize, usize) {
    let mut out = vec![0u32; (SIZE * SIZE) as usize];
    let (mut near, mut miter_ties) = (0, 0);
    for rows in segments {
        let mut r = Reference::new(rows, width);
        // Only pixels near the segment: farther than its reach plus a pixel, its bound
        // leaves them out by a wide margin.
        let margin = 2.0 * f64::from(width) + 1.0;
        let span = |a: f32, b: f32| {
            let lo = (f64::from(a.min(b)) - margin).floor().clamp(0.0, f64::from(SIZE)) as u32;
            let hi = (f64::from(a.max(b)) + margin).ceil().clamp(0.0, f64::from(SIZE)) as u32;
            lo..hi
        };
        for py in span(rows[1][1], rows[2][1]) {
            for px in span(rows[1][0], rows[2][0]) {
                if r.covers(f64::from(px) + 0.5, f64::from(py) + 0.5) {
                    out[(py * SIZE + px) as usize] += 1;
                }
            }
        }
        near += r.near_ties;
        miter_ties += r.miter_ties;
    }
    (out, near, miter_ties)
}

/// Pixels where two count vectors differ, as (x, y, got, want), at most 8.
fn differences(got: &[u32], want: &[u32]) -> Vec<(u32, u32, u32, u32)> {
    (0..SIZE * SIZE)
        .filter(|&i| got[i as usize] != want[i as usize])
        .take(8)
        .map(|i| (i % SIZE, i / SIZE, got[i as usize], want[i as usize]))
        .collect()
}

// ---- Single segments ---------------------------------------------------------------------

/// A lone segment (no joints: rows [0] and [3] repeat its ends).
fn lone(s: [f64; 2], e: [f64; 2]) -> Rows {
    polyline_rows(&[s, e])[0]
}

/// Single segments at axis-aligned, 45-degree and arbitrary angles, widths 1, 2.5 and 7,
/// some with endpoints and long sides exactly on pixel centres. Source of truth: the rule in
/// f64 ([`Reference`]); tolerance 0 pixels (no near-ties, asserted, so f32 and f64 decide
/// alike; exact ties are exact in both).
#[test]
fn single_segments_cover_the_pixels_of_the_f64_rule() {
    let mut lines = Lines::new();
    let c = [48.0, 48.0];
    let mut cases: Vec<(Rows, &str)> = vec![
        (
            lone([10.5, 20.5], [80.5, 20.5]),
            "horizontal, ends and centre line on pixel centres",
        ),
        (
            lone([80.5, 30.0], [10.5, 30.0]),
            "horizontal, right to left, sides on pixel centres",
        ),
        (lone([40.0, 8.5], [40.0, 88.5]), "vertical, sides on pixel centres"),
        (lone([60.5, 88.5], [60.5, 8.5]), "vertical, upwards"),
        (lone([10.5, 10.5], [70.5, 70.5]), "45 degrees through pixel centres"),
        (lone([70.25, 12.5], [14.25, 68.5]), "135 degrees"),
    ];
    let mut rng = SplitMix(5);
    for k in 0..12 {
        let angle = rng.range(0.0, std::f64::consts::TAU);
        let half = rng.range(3.0, 40.0);
        let (dx, dy) = (half * angle.cos(), half * angle.sin());
        let rows = lone([snap(c[0] - dx), snap(c[1] - dy)], [snap(c[0] + dx), snap(c[1] + dy)]);
        cases.push((rows, ["random angle a", "random angle b", "random angle c"][k % 3]));
    }
    let mut total = 0;
    for (rows, what) in &cases {
        for width in [1.0f32, 2.5, 7.0] {
            let (want, near, _) = reference_counts(&[*rows], width);
            assert_eq!(near, 0, "{what}, width {width}: a near-tie, choose other coordinates");
            let got = counts(&lines.render(&[*rows], width));
            assert_eq!(
                differences(&got, &want),
                vec![],
                "{what}, width {width}, rows {rows:?}: (x, y, kernel, reference)"
            );
            let covered = want.iter().filter(|&&c| c > 0).count();
            assert!(covered > 0, "{what}: the case covers nothing");
            total += covered;
        }
    }
    println!(
        "single segments: {} cases, {total} pixels, all equal to the f64 rule",
        cases.len() * 3
    );
}

// ---- Polylines -----------------------------------------------------------------------------

/// A random polyline of `joints` joints from SplitMix `rng`: segments 6 to 24 px, each turn
/// up to `max_turn` degrees, on the 1/16 grid, inside the image.
fn random_polyline(rng: &mut SplitMix, joints: usize, max_turn: f64) -> Vec<[f64; 2]> {
    loop {
        let mut p = [snap(rng.range(20.0, 76.0)), snap(rng.range(20.0, 76.0))];
        let mut heading = rng.range(0.0, std::f64::consts::TAU);
        let mut points = vec![p];
        for _ in 0..=joints {
            let step = rng.range(6.0, 24.0);
            p = [snap(p[0] + step * heading.cos()), snap(p[1] + step * heading.sin())];
            points.push(p);
            heading += rng.range(-max_turn, max_turn).to_radians();
        }
        if points.iter().all(|q| q.iter().all(|&v| (8.0..88.0).contains(&v))) {
            return points;
        }
    }
}

/// Random polylines (SplitMix seed 17), 5 to 20 joints, turns up to 150 degrees, widths
/// 1, 2.5 and 7: every pixel is written at most once and the written pixels are the
/// reference's union. Source of truth: the f64 rule; tolerance 0 pixels. Polylines whose
/// reference itself covers a pixel twice (the path crossing itself) or has a near-tie are
/// drawn again: neither says anything about the joints.
#[test]
fn random_polylines_cover_each_pixel_at_most_once() {
    let mut lines = Lines::new();
    let mut rng = SplitMix(17);
    let (mut done, mut pixels, mut rejected) = (0, 0, 0);
    while done < 24 {
        let width = [1.0f32, 2.5, 7.0][done % 3];
        let joints = 5 + (rng.next() % 16) as usize;
        let points = random_polyline(&mut rng, joints, 150.0);
        let segments = polyline_rows(&points);
        let (want, near, _) = reference_counts(&segments, width);
        if near > 0 || want.iter().any(|&c| c > 1) {
            rejected += 1;
            continue;
        }
        let got = counts(&lines.render(&segments, width));
        assert!(
            got.iter().all(|&c| c <= 1),
            "width {width}, {points:?}: a pixel written twice"
        );
        assert_eq!(
            differences(&got, &want),
            vec![],
            "width {width}, {points:?}: (x, y, kernel, reference)"
        );
        pixels += want.iter().filter(|&&c| c > 0).count();
        done += 1;
    }
    println!("random polylines: {done} drawn ({rejected} redrawn), {pixels} pixels, each once");
}

/// Joints whose miter lines pass exactly through pixel centres: a straight horizontal line
/// split at pixel centres (vertical miters), a staircase of 90-degree turns (diagonal miters
/// x + y = const through pixel centres), a zigzag of diagonal segments (vertical miters at
/// pixel-centre x), and 45-degree turns at pixel centres. Source of truth: the f64 rule, in
/// which these pixel centres lie exactly on the miter (asserted: ties are exercised);
/// tolerance 0: each such pixel written exactly once, by the segment starting at the joint,
/// and the union equals the reference's.
#[test]
fn joints_with_pixel_centres_on_the_miter_cover_them_once() {
    let mut lines = Lines::new();
    let cases: Vec<(&str, Vec<[f64; 2]>)> = vec![
        (
            "straight line split at pixel centres",
            vec![[8.5, 40.5], [20.5, 40.5], [33.5, 40.5], [60.5, 40.5], [88.5, 40.5]],
        ),
        (
            "staircase of 90-degree turns",
            vec![
                [10.5, 10.5],
                [30.5, 10.5],
                [30.5, 30.5],
                [50.5, 30.5],
                [50.5, 50.5],
                [70.5, 50.5],
                [70.5, 80.5],
            ],
        ),
        (
            "zigzag of diagonal segments",
            vec![
                [8.5, 40.5],
                [22.5, 26.5],
                [36.5, 40.5],
                [50.5, 26.5],
                [64.5, 40.5],
                [78.5, 26.5],
            ],
        ),
        (
            "45-degree turns at pixel centres",
            vec![[10.5, 20.5], [40.5, 20.5], [60.5, 40.5], [60.5, 70.5], [40.5, 90.5]],
        ),
    ];
    for (what, points) in cases {
        let segments = polyline_rows(&points);
        for width in [1.0f32, 2.5, 7.0] {
            let (want, near, miter_ties) = reference_counts(&segments, width);
            assert_eq!(near, 0, "{what}, width {width}: a near-tie");
            assert!(miter_ties > 0, "{what}, width {width}: no pixel centre on a miter");
            assert!(want.iter().all(|&c| c <= 1), "{what}: the reference overlaps");
            let got = counts(&lines.render(&segments, width));
            assert_eq!(
                differences(&got, &want),
                vec![],
                "{what}, width {width}: (x, y, kernel, reference)"
            );
        }
    }
}

/// A fold-back (the path turns straight back on itself) has no miter: both segments take
/// butt ends there and overlap where they retrace each other, as documented. A 162-degree
/// turn keeps its miter, whose spike past 2 widths is cut off by the bound, and no pixel is
/// written twice. Source of truth: the f64
/// rule (which includes the bound); tolerance 0 pixels, with multiplicity.
#[test]
fn fold_backs_overlap_and_sharp_spikes_are_cut() {
    let mut lines = Lines::new();
    let fold = polyline_rows(&[[10.5, 40.25], [60.5, 40.25], [20.5, 40.25]]);
    let sharp = polyline_rows(&[[10.25, 30.5], [60.25, 40.5], [12.25, 46.5]]);
    for width in [2.5f32, 7.0] {
        let (want, near, _) = reference_counts(&fold, width);
        assert_eq!(near, 0);
        assert!(want.iter().any(|&c| c == 2), "the fold-back overlaps in the reference");
        assert_eq!(differences(&counts(&lines.render(&fold, width)), &want), vec![]);

        let (want, near, _) = reference_counts(&sharp, width);
        assert_eq!(near, 0);
        assert!(want.iter().all(|&c| c <= 1));
        assert_eq!(differences(&counts(&lines.render(&sharp, width)), &want), vec![]);
    }
}

// ---- Depth and interpolation -------------------------------------------------------------

/// One segment with w 1 at the start and 4 at the end, depth 0.9 to 0.2, a
/// perspective_linear, a linear and an implicit (3-component) parameter. Source of truth:
/// the f64 formulas with s the pixel's projection onto the segment clamped to [0, 1]:
/// linear a + s (b - a), perspective (a/w0 (1 - s) + b/w1 s) / ((1 - s)/w0 + s/w1), depth
/// z0 + s (z1 - z0). Tolerance: 3e-6 absolute on values in [0, 5] (s carries ~3e-7 from the
/// unit direction and the 80 px projection, times the value's range 3, plus a few ulp of 5;
/// measured 1.0e-6), and on depth 2e-6 plus the fixed<32,32> step (measured 1.1e-7).
#[test]
fn depth_and_shading_along_the_segment() {
    let program = library();
    let mut r = renderer(&program, SIZE, SIZE, true);
    r.material_interp("p", "perspective_linear", &[]).unwrap();
    r.material_interp("l", "linear", &[]).unwrap();
    r.material_interp("n", "implicit", &[]).unwrap();
    let (s0, s1) = ([8.5f32, 20.25], [86.75f32, 70.5]);
    let (w0, w1, z0, z1) = (1.0f32, 4.0, 0.9f32, 0.2f32);
    let rows = [
        [s0[0], s0[1], z0, w0],
        [s0[0], s0[1], z0, w0],
        [s1[0], s1[1], z1, w1],
        [s1[0], s1[1], z1, w1],
    ];
    segment(
        &mut r,
        rows,
        5.0,
        &[
            ("p", [vec![0.0], vec![1.0]]),
            ("l", [vec![2.0], vec![5.0]]),
            ("n", [vec![1.0, 0.0, -1.0], vec![0.0, 3.0, 1.0]]),
        ],
    );
    let frame = render(&r, 2);
    let (ax, ay) = (f64::from(s0[0]), f64::from(s0[1]));
    let (dx, dy) = (f64::from(s1[0]) - ax, f64::from(s1[1]) - ay);
    let (q0, q1) = (1.0 / f64::from(w0), 1.0 / f64::from(w1));
    let persp = |a: f64, b: f64, s: f64| (a * q0 * (1.0 - s) + b * q1 * s) / (q0 * (1.0 - s) + q1 * s);
    let (mut pixels, mut value_err, mut depth_err) = (0, 0.0f64, 0.0f64);
    for py in 0..SIZE {
        for px in 0..SIZE {
            if !frame.written(px, py) {
                continue;
            }
            pixels += 1;
            let (x, y) = (f64::from(px) + 0.5, f64::from(py) + 0.5);
            let s = (((x - ax) * dx + (y - ay) * dy) / (dx * dx + dy * dy)).clamp(0.0, 1.0);
            let want = [
                ("p", vec![persp(0.0, 1.0, s)]),
                ("l", vec![2.0 + 3.0 * s]),
                ("n", vec![persp(1.0, 0.0, s), persp(0.0, 3.0, s), persp(-1.0, 1.0, s)]),
            ];
            for (name, values) in want {
                let got = frame.param_at(name, px, py).unwrap();
                for (g, w) in got.iter().zip(&values) {
                    value_err = value_err.max((f64::from(*g) - w).abs());
                }
            }
            let depth = f64::from(z0) + s * (f64::from(z1) - f64::from(z0));
            let got = f64::from(frame.depth_at(px, py).unwrap()) / 4294967296.0;
            depth_err = depth_err.max((got - depth).abs());
        }
    }
    println!("interpolation: {pixels} pixels, value error {value_err:.2e}, depth error {depth_err:.2e}");
    assert!(pixels > 300, "only {pixels} pixels");
    assert!(value_err < 3e-6, "value error {value_err:e}");
    assert!(depth_err < 2e-6 + 1.0 / 4294967296.0, "depth error {depth_err:e}");
}

/// Depth test as screen_triangle: of two crossing segments the nearer wins at the crossing,
/// and a segment outside [0, 1] in depth draws nothing. Source of truth: the depths given
/// (0.25 and 0.75 flat); exact.
#[test]
fn depth_test_keeps_the_nearer_segment() {
    let program = library();
    let mut r = renderer(&program, SIZE, SIZE, false);
    let flat = |s: [f32; 2], e: [f32; 2], z: f32| {
        let (a, b) = ([s[0], s[1], z, 1.0], [e[0], e[1], z, 1.0]);
        [a, a, b, b]
    };
    segment(&mut r, flat([10.5, 48.5], [86.5, 48.5], 0.75), 5.0, &[]);
    segment(&mut r, flat([48.5, 10.5], [48.5, 86.5], 0.25), 5.0, &[]);
    segment(&mut r, flat([10.5, 20.5], [86.5, 20.5], 1.5), 5.0, &[]);
    let frame = render(&r, 2);
    assert_eq!(frame.depth_at(48, 48), Some(raw_depth(0.75)));
    assert_eq!(frame.depth_at(48, 30), Some(raw_depth(0.25)));
    assert_eq!(frame.depth_at(30, 48), Some(raw_depth(0.75)));
    assert!(!frame.written(30, 20), "a segment at depth 1.5 drew");
}

// ---- Degenerate inputs --------------------------------------------------------------------

/// Zero-length segments, NaN, infinite and 1e30 coordinates in any row, and widths that are
/// zero, negative, NaN, infinite or 1e30 draw nothing, with no diagnostic and no panic.
/// Source of truth: the rule's rejections; exact (no pixel written).
#[test]
fn degenerate_segments_draw_nothing() {
    let mut lines = Lines::new();
    let good = lone([10.5, 20.25], [70.75, 60.5]);
    let mut cases: Vec<(Rows, f32, String)> = vec![
        (lone([30.5, 30.5], [30.5, 30.5]), 3.0, "zero length".into()),
        (
            polyline_rows(&[[10.5, 30.5], [30.5, 30.5], [30.5, 30.5], [50.5, 30.5]])[1],
            3.0,
            "zero length joint".into(),
        ),
    ];
    for bad in [f32::NAN, f32::INFINITY, -f32::INFINITY, 1e30, -1e30] {
        for row in 0..4 {
            for comp in 0..2 {
                let mut rows = good;
                rows[row][comp] = bad;
                cases.push((rows, 3.0, format!("{bad} at row {row}, component {comp}")));
            }
        }
        cases.push((good, bad, format!("width {bad}")));
    }
    cases.push((good, 0.0, "width 0".into()));
    cases.push((good, -2.0, "width -2".into()));
    for (rows, width, what) in cases {
        let frame = lines.render(&[rows], width);
        assert_eq!(frame.covered_pixels(), 0, "{what}: drew");
    }
    // The good segment itself draws.
    assert!(lines.render(&[good], 3.0).covered_pixels() > 100);
}

// ---- Through the runtime: the `polyline` primitive -----------------------------------------

/// A renderer (write counting) with one `polyline` through `points` (depth 0.5) of `width`.
fn polyline_scene(program: &Arc<Program>, points: &[[f64; 2]], width: f32) -> Renderer {
    let mut r = renderer(program, SIZE, SIZE, true);
    r.begin("polyline").unwrap();
    r.rast_param("width", &Value(vec![width])).unwrap();
    for p in points {
        r.vertex(p[0] as f32, p[1] as f32, 0.5, 1.0).unwrap();
    }
    r.end().unwrap();
    assert!(r.take_warnings().is_empty());
    r
}

/// Random polylines (SplitMix seed 29) drawn as one `polyline` each, through the runtime's
/// `line` geometry (split into segments with their neighbours, docs/pipeline.md "Lines"),
/// under the identity device transform: the write counts equal those of the same segments
/// handed to `screen_segment` directly with the adjacency [`polyline_rows`] states. Source of
/// truth: that adjacency and the f64 rule (the union is also the reference's); tolerance 0.
#[test]
fn polylines_through_the_runtime_match_their_segments_drawn_directly() {
    let mut lines = Lines::new();
    let mut rng = SplitMix(29);
    let mut done = 0;
    while done < 9 {
        let width = [1.0f32, 2.5, 7.0][done % 3];
        let joints = 3 + (rng.next() % 10) as usize;
        let points = random_polyline(&mut rng, joints, 120.0);
        let segments = polyline_rows(&points);
        let (want, near, _) = reference_counts(&segments, width);
        if near > 0 || want.iter().any(|&c| c > 1) {
            continue;
        }
        let r = polyline_scene(&lines.program, &points, width);
        let got = counts(&render_with(&r, &mut lines.jit, 2));
        assert_eq!(
            got,
            counts(&lines.render(&segments, width)),
            "width {width}, {points:?}"
        );
        assert_eq!(differences(&got, &want), vec![], "width {width}, {points:?}");
        done += 1;
    }
}

/// A closed outline (its last point repeats its first) drawn as one `polyline`: the runtime
/// joins the last segment to the first, so the closing corner is mitered like the others.
/// Source of truth: the same segments handed to `screen_segment` with that cyclic adjacency,
/// and the f64 rule; every pixel written at most once; tolerance 0.
#[test]
fn a_closed_polyline_is_mitered_at_its_closing_corner() {
    let mut lines = Lines::new();
    let points = [[20.0, 20.0], [70.25, 24.5], [60.5, 71.0], [18.75, 55.5], [20.0, 20.0]];
    let n = points.len();
    let row = |p: [f64; 2]| [p[0] as f32, p[1] as f32, 0.5, 1.0];
    let segments: Vec<Rows> = (0..n - 1)
        .map(|i| {
            let before = if i == 0 { points[n - 2] } else { points[i - 1] };
            let after = if i + 2 < n { points[i + 2] } else { points[1] };
            [row(before), row(points[i]), row(points[i + 1]), row(after)]
        })
        .collect();
    for width in [1.0f32, 4.0] {
        let (want, near, _) = reference_counts(&segments, width);
        assert_eq!(near, 0, "no near-ties in this case");
        assert!(want.iter().all(|&c| c <= 1));
        let r = polyline_scene(&lines.program, &points, width);
        let got = counts(&render_with(&r, &mut lines.jit, 2));
        assert!(got.iter().all(|&c| c <= 1), "width {width}: a pixel written twice");
        assert_eq!(differences(&got, &want), vec![], "width {width}");
    }
}
