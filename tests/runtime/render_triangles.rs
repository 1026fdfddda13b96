//! End-to-end tests of screen_triangle through the whole stack (parse, check, JIT, runtime):
//! exact coverage, shared edges, interpolation against analytic values, determinism.

use crate::support;
use support::*;

/// Every pixel of a covered area has exactly the write count the reference gives it.
fn assert_counts(frame: &primflow::runtime::Frame, expected: &[u32]) {
    let (w, h) = (frame.width, frame.height);
    let mut bad = vec![];
    for y in 0..h {
        for x in 0..w {
            let got = frame.write_count_at(x, y).unwrap();
            let want = expected[(y * w + x) as usize];
            if got != want {
                bad.push((x, y, got, want));
            }
        }
    }
    assert!(
        bad.is_empty(),
        "{} pixels with wrong write counts (x, y, got, want): {:?}",
        bad.len(),
        &bad[..bad.len().min(20)]
    );
}

#[test]
fn two_triangles_sharing_an_edge_write_each_pixel_once() {
    let program = library();
    // A quad split along a diagonal with fractional, off-grid-centre coordinates, so the shared
    // edge passes exactly through some pixel centres and near many others.
    let quads: [[[f32; 2]; 4]; 3] = [
        [[3.0, 2.0], [60.5, 5.25], [58.0, 44.0], [4.5, 40.0]],
        [[0.5, 0.5], [63.5, 0.5], [63.5, 47.5], [0.5, 47.5]], // diagonal through pixel centres
        [[10.0, 3.0], [50.0, 11.0], [42.0, 45.0], [2.0, 37.0]],
    ];
    for q in quads {
        let mut r = renderer(&program, 64, 48, true);
        let v = |i: usize| [q[i][0], q[i][1], 0.5, 1.0];
        screen_triangle(&mut r, [v(0), v(1), v(2)], &[]);
        screen_triangle(&mut r, [v(0), v(2), v(3)], &[]);
        let frame = render(&r, 2);
        let d = |i: usize| [q[i][0] as f64, q[i][1] as f64];
        let a = reference_coverage([d(0), d(1), d(2)], 64, 48);
        let b = reference_coverage([d(0), d(2), d(3)], 64, 48);
        assert!(a.iter().zip(&b).all(|(a, b)| !(a & b)), "the reference itself overlaps");
        let expected: Vec<u32> = a.iter().zip(&b).map(|(a, b)| (*a || *b) as u32).collect();
        assert!(expected.iter().sum::<u32>() > 1000);
        assert_counts(&frame, &expected);
    }
}

#[test]
fn fan_of_32_slivers_covers_every_pixel_once() {
    let program = library();
    let mut r = renderer(&program, 96, 96, true);
    let (cx, cy, radius) = (47.3125f64, 48.6875f64, 44.0f64);
    let ring: Vec<[f64; 2]> = (0..32)
        .map(|k| {
            let t = k as f64 / 32.0 * std::f64::consts::TAU;
            // On the 1/16 grid so the reference and the kernel see the same vertices.
            [
                ((cx + radius * t.cos()) * 16.0).round() / 16.0,
                ((cy + radius * t.sin()) * 16.0).round() / 16.0,
            ]
        })
        .collect();
    let mut expected = vec![0u32; 96 * 96];
    for k in 0..32 {
        let (p, q) = (ring[k], ring[(k + 1) % 32]);
        let f = |a: [f64; 2]| [a[0] as f32, a[1] as f32, 0.5, 1.0];
        screen_triangle(&mut r, [f([cx, cy]), f(p), f(q)], &[]);
        for (e, c) in expected.iter_mut().zip(reference_coverage([[cx, cy], p, q], 96, 96)) {
            *e += c as u32;
        }
    }
    assert!(expected.iter().all(|&c| c <= 1), "reference fan overlaps");
    assert!(expected.iter().sum::<u32>() > 5000);
    let frame = render(&r, 2);
    assert_counts(&frame, &expected);
}

#[test]
fn random_triangles_match_the_exact_rasterizer() {
    let program = library();
    let mut jit = primflow::jit::Jit::new(program.clone()).unwrap();
    let mut rng = Lcg(7);
    let (w, h) = (48u32, 40u32);
    let mut covered_total = 0;
    for case in 0..150 {
        // Some triangles poke outside the viewport, some are slivers, some tiny.
        let scale = [4.0, 20.0, 70.0][case % 3];
        let (cx, cy) = (rng.range(-5.0, w as f64 + 5.0), rng.range(-5.0, h as f64 + 5.0));
        let v: Vec<[f64; 2]> = (0..3)
            .map(|_| {
                [
                    grid(&mut rng, cx - scale, cx + scale),
                    grid(&mut rng, cy - scale, cy + scale),
                ]
            })
            .collect();
        let v = [v[0], v[1], v[2]];
        let mut r = renderer(&program, w, h, false);
        let f = |a: [f64; 2]| [a[0] as f32, a[1] as f32, 0.5, 1.0];
        screen_triangle(&mut r, [f(v[0]), f(v[1]), f(v[2])], &[]);
        let frame = render_with(&r, &mut jit, 1);
        let expected = reference_coverage(v, w, h);
        let mut differing = vec![];
        for y in 0..h {
            for x in 0..w {
                if frame.written(x, y) != expected[(y * w + x) as usize] {
                    differing.push((x, y));
                }
            }
        }
        assert!(
            differing.is_empty(),
            "triangle {v:?}: {} pixels differ: {differing:?}",
            differing.len()
        );
        covered_total += expected.iter().filter(|&&c| c).count();
    }
    assert!(
        covered_total > 10_000,
        "too few covered pixels to mean anything: {covered_total}"
    );
}

/// Perspective-correct interpolation (w in [0.2, 4]) against the analytic
/// f = sum(a_i f_i / w_i) / sum(a_i / w_i); linear against screen-space barycentrics.
#[test]
fn perspective_and_linear_interpolation_match_analytic() {
    let program = library();
    let mut r = renderer(&program, 64, 64, false);
    r.material_interp("persp", "perspective_linear", &[]).unwrap();
    r.material_interp("lin", "linear", &[]).unwrap();
    let v2 = [[2.0, 3.0], [61.0, 9.0], [20.0, 62.0]];
    let w = [0.2, 1.7, 4.0];
    let f = [[1.0, -2.0, 0.25], [3.0, 0.5, -1.0], [-0.5, 4.0, 2.0]]; // per vertex, 3 components
    let v = |i: usize| [v2[i][0] as f32, v2[i][1] as f32, 0.5, w[i] as f32];
    let vals = |i: usize| f[i].iter().map(|&x| x as f32).collect::<Vec<_>>();
    let per_vertex = [vals(0), vals(1), vals(2)];
    screen_triangle(
        &mut r,
        [v(0), v(1), v(2)],
        &[("persp", per_vertex.clone()), ("lin", per_vertex)],
    );
    let frame = render(&r, 1);
    let mut checked = 0;
    let (mut max_persp, mut max_lin, mut max_gap) = (0f64, 0f64, 0f64);
    for y in 0..64 {
        for x in 0..64 {
            if !frame.written(x, y) {
                continue;
            }
            let a = barycentric(v2, x as f64 + 0.5, y as f64 + 0.5);
            let persp = frame.param_at("persp", x, y).unwrap();
            let lin = frame.param_at("lin", x, y).unwrap();
            for c in 0..3 {
                let num: f64 = (0..3).map(|i| a[i] * f[i][c] / w[i]).sum();
                let den: f64 = (0..3).map(|i| a[i] / w[i]).sum();
                let want_lin: f64 = (0..3).map(|i| a[i] * f[i][c]).sum();
                max_persp = max_persp.max((persp[c] as f64 - num / den).abs());
                max_lin = max_lin.max((lin[c] as f64 - want_lin).abs());
                max_gap = max_gap.max((num / den - want_lin).abs());
            }
            checked += 1;
        }
    }
    assert!(checked > 1000, "only {checked} pixels covered");
    assert!(max_persp < 1e-4, "perspective error {max_persp}");
    assert!(max_lin < 1e-4, "linear error {max_lin}");
    // The two really differ on this triangle (otherwise the test proves nothing).
    assert!(max_gap > 0.5, "perspective and linear nearly agree: {max_gap}");
}

#[test]
fn depth_test_keeps_the_nearer_triangle() {
    let program = library();
    let mut r = renderer(&program, 32, 32, false);
    r.material_interp("Cs", "constant", &[]).unwrap();
    let tri = |z: f32| [[1.0, 1.0, z, 1.0], [31.0, 1.0, z, 1.0], [1.0, 31.0, z, 1.0]];
    let red = [vec![1.0, 0.0, 0.0], vec![1.0, 0.0, 0.0], vec![1.0, 0.0, 0.0]];
    let green = [vec![0.0, 1.0, 0.0], vec![0.0, 1.0, 0.0], vec![0.0, 1.0, 0.0]];
    // Near (larger z) first, then far: the far one must lose everywhere.
    screen_triangle(&mut r, tri(0.75), &[("Cs", red)]);
    screen_triangle(&mut r, tri(0.25), &[("Cs", green)]);
    let frame = render(&r, 1);
    assert_eq!(frame.param_at("Cs", 5, 5).unwrap(), vec![1.0, 0.0, 0.0]);
    let depth = frame.depth_f32_at(5, 5).unwrap();
    assert!((depth - 0.75).abs() < 1e-6, "depth {depth}");
    assert!(!frame.written(30, 30));
}

#[test]
fn same_scene_same_bytes_whatever_the_thread_count() {
    let program = library();
    let mut r = renderer(&program, 200, 150, true);
    r.material_interp("Cs", "perspective_linear", &[]).unwrap();
    let mut rng = Lcg(99);
    for _ in 0..300 {
        let mut v = [[0f32; 4]; 3];
        for p in &mut v {
            *p = [
                rng.range(-20.0, 220.0) as f32,
                rng.range(-20.0, 170.0) as f32,
                rng.range(0.0, 1.0) as f32,
                rng.range(0.5, 3.0) as f32,
            ];
        }
        let c = |rng: &mut Lcg| vec![rng.next() as f32, rng.next() as f32, rng.next() as f32];
        let colours = [c(&mut rng), c(&mut rng), c(&mut rng)];
        screen_triangle(&mut r, v, &[("Cs", colours)]);
    }
    let one = render(&r, 1);
    let two = render(&r, 2);
    let four = render(&r, 4);
    assert!(one.depth_values().iter().filter(|&&d| d != 0).count() > 10_000);
    for other in [&two, &four] {
        assert_eq!(one.depth_values(), other.depth_values());
        assert_eq!(one.all_plane_values(), other.all_plane_values());
        assert_eq!(one.write_count_values(), other.write_count_values());
        assert_eq!(one.to_rgb8().into_raw(), other.to_rgb8().into_raw());
    }
}

#[test]
fn non_finite_and_degenerate_triangles_draw_nothing() {
    let program = library();
    let mut r = renderer(&program, 32, 32, true);
    let bad = [
        [[f32::NAN, 1.0, 0.5, 1.0], [30.0, 1.0, 0.5, 1.0], [1.0, 30.0, 0.5, 1.0]],
        [
            [f32::INFINITY, 1.0, 0.5, 1.0],
            [30.0, 1.0, 0.5, 1.0],
            [1.0, 30.0, 0.5, 1.0],
        ],
        [[1.0, 1.0, 0.5, 1.0], [10.0, 10.0, 0.5, 1.0], [20.0, 20.0, 0.5, 1.0]], // collinear
        [[5.0, 5.0, 0.5, 1.0], [5.0, 5.0, 0.5, 1.0], [5.0, 5.0, 0.5, 1.0]],     // a point
        [[1.0, 1.0, 2.0, 1.0], [30.0, 1.0, 2.0, 1.0], [1.0, 30.0, 2.0, 1.0]],   // beyond the near plane
        [[1.0, 1.0, -1.0, 1.0], [30.0, 1.0, -1.0, 1.0], [1.0, 30.0, -1.0, 1.0]], // beyond the far plane
        [[-1e30, -1e30, 0.5, 1.0], [1e30, -1e30, 0.5, 1.0], [0.0, 1e30, 0.5, 1.0]],
    ];
    for v in bad {
        screen_triangle(&mut r, v, &[]);
    }
    let frame = render(&r, 2);
    let total: u32 = (0..32)
        .flat_map(|y| (0..32).map(move |x| (x, y)))
        .map(|(x, y)| frame.write_count_at(x, y).unwrap())
        .sum();
    assert_eq!(total, 0, "degenerate or non-finite triangles wrote pixels");
}

/// Binning sends a primitive only to the tiles holding a pixel centre of its bound (no
/// margin): small triangles, some with corners on pixel centres and tile edges, render to
/// the same bits in 8, 16 and 24 px tiles as in one tile covering the whole image.
#[test]
fn small_triangles_render_the_same_whatever_the_tile_size() {
    let program = library();
    let mut r = primflow::workload::small_scene(&program, 96, 2000, 4);
    // Corners on pixel centres and on tile edges (8 and 16 divide 32, 64; 24 divides 48).
    for (i, x) in [31.5f32, 32.0, 32.5, 47.5, 48.0, 63.5, 64.0, 64.5]
        .into_iter()
        .enumerate()
    {
        let y = 16.0 + 8.0 * i as f32;
        screen_triangle(
            &mut r,
            [
                [x, y, 0.99, 1.0],
                [x + 3.0, y + 0.5, 0.99, 1.0],
                [x + 0.5, y + 7.5, 0.99, 1.0],
            ],
            &[],
        );
        screen_triangle(
            &mut r,
            [
                [x, y, 0.99, 1.0],
                [x - 0.5, y + 7.5, 0.99, 1.0],
                [x - 3.0, y + 0.5, 0.99, 1.0],
            ],
            &[],
        );
    }
    r.set_tile_size(96).unwrap();
    let whole = render(&r, 1);
    assert!(whole.depth_values().iter().filter(|&&d| d != 0).count() > 4000);
    for tile in [8, 16, 24] {
        r.set_tile_size(tile).unwrap();
        let tiled = render(&r, 2);
        assert!(primflow::workload::same_frame(&tiled, &whole), "{tile} px tiles");
    }
}

/// screen_triangle's bound is its extremes padded by a 1/16 grid step, not the pixel corner
/// below-left of it: a triangle whose leftmost corner (63.6) lies right of pixel 63's centre
/// is binned into tile 1 only (its old bound from x = 63 also sent it to tile 0 for no
/// pixel), and still covers exactly the reference's pixels, the ones on its left edge too.
#[test]
fn a_triangle_is_binned_by_its_extremes_not_its_grid_origin() {
    let program = library();
    for (x0, tiles) in [(63.6f32, 1), (63.45, 2)] {
        let mut r = renderer(&program, 128, 64, true);
        r.set_tile_size(64).unwrap();
        let v = [
            [x0, 10.2, 0.5, 1.0],
            [x0 + 6.0, 30.7, 0.5, 1.0],
            [x0 + 1.0, 40.3, 0.5, 1.0],
        ];
        screen_triangle(&mut r, v, &[]);
        let mut jit = primflow::jit::Jit::new(program.clone()).unwrap();
        let out = r.render(&mut jit);
        assert!(out.diags.items.is_empty(), "{:?}", out.diags.items);
        assert_eq!(out.stats.tile_invocations, tiles, "corner at {x0}");
        let exact = reference_coverage(v.map(|p| [f64::from(p[0]), f64::from(p[1])]), 128, 64);
        let want: Vec<u32> = exact.iter().map(|&c| u32::from(c)).collect();
        assert_counts(&out.frame, &want);
        let left_column = (0..64).any(|y| out.frame.write_count_at(x0.round() as u32, y) == Some(1));
        assert!(left_column, "corner at {x0}: its leftmost pixel column is covered");
    }
}
