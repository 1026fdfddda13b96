//! Multisampling (`runtime::samples`): resolved pixel values against hand-counted samples,
//! the image the same for any thread count and tile size with samples on, and the errors
//! for sample counts outside the allowed set and frames too large for their samples.

use crate::support::*;

use primflow::diag::{Diagnostics, SourceMap};
use primflow::jit::Jit;
use primflow::runtime::samples::{Filter, ALLOWED_SAMPLES};
use primflow::runtime::{Renderer, MAX_IMAGE_SIDE};

/// A white triangle covering every pixel of a 24 x 8 image left of x = 10.5 (its right
/// edge vertical there, through the centres of column 10).
fn left_of_ten_and_a_half(samples: u32, filter: Filter) -> Renderer {
    let program = library();
    let mut r = renderer(&program, 24, 8, false);
    r.set_samples(samples).unwrap();
    r.set_filter(filter);
    screen_triangle(
        &mut r,
        [
            [-40.0, -40.0, 0.5, 1.0],
            [10.5, -40.0, 0.5, 1.0],
            [10.5, 60.0, 0.5, 1.0],
        ],
        &[],
    );
    r
}

/// Column 10's pixels have their centre on the edge: of the standard patterns' samples, the
/// ones left of the centre are covered (2 of 4 at 4x: x offsets -2/16 and -6/16; 8 of 16 at
/// 16x, whose sample at offset 0 lies on the edge, a right edge, so outside by the top-left
/// rule), exactly half at every count but 1, where the centre itself is outside. The box
/// resolve shows 0.5 there, 1 left of it and 0 right of it, exactly; byte 128 in the image.
#[test]
fn a_pixel_half_covered_by_samples_resolves_to_half() {
    let mut jit = Jit::new(library()).unwrap();
    for samples in ALLOWED_SAMPLES {
        let frame = render_with(&left_of_ten_and_a_half(samples, Filter::Box), &mut jit, 2);
        assert_eq!(frame.sample_count(), samples as usize);
        let want_10 = if samples == 1 { 0.0 } else { 0.5 };
        let image = frame.to_rgb8();
        for y in 0..8 {
            assert_eq!(frame.color_at(9, y), [1.0; 3], "{samples} samples");
            assert_eq!(frame.color_at(10, y), [want_10; 3], "{samples} samples");
            assert_eq!(frame.color_at(11, y), [0.0; 3], "{samples} samples");
            assert_eq!(image.get_pixel(10, y).0, [if samples == 1 { 0 } else { 128 }; 3]);
        }
        let coverage = frame.coverage_values();
        assert_eq!(coverage[10], want_10);
        assert_eq!(coverage.iter().filter(|&&c| c == 1.0).count(), 10 * 8);
    }
}

/// The Gaussian resolve (pbrt's, radius 1.5 px) spreads the edge over the columns within
/// its reach and keeps a flat region flat: 1 (to f32 rounding) two columns left of the
/// edge, 0 two right of it, and in between values falling from left to right, column 10
/// near one half (the filter is symmetric and so is the 16x pattern, almost).
#[test]
fn the_gaussian_resolve_blurs_the_edge_over_its_radius_only() {
    let mut jit = Jit::new(library()).unwrap();
    let frame = render_with(&left_of_ten_and_a_half(16, Filter::Gaussian), &mut jit, 2);
    let level = |x: u32| frame.color_at(x, 4)[0];
    for x in 0..=7 {
        assert!((level(x) - 1.0).abs() < 1e-6, "column {x}: {}", level(x));
    }
    for x in 13..24 {
        assert_eq!(level(x), 0.0, "column {x}");
    }
    let falling: Vec<f32> = (8..=12).map(level).collect();
    assert!(falling.windows(2).all(|w| w[1] < w[0]), "{falling:?}");
    assert!((level(10) - 0.5).abs() < 0.1, "{}", level(10));
}

/// Triangles with colours, overlapping at several depths: with samples on (4 and 16, both
/// filters) the image and every sample's buffers are the same bit for bit on 1 and 2
/// threads and with tiles of 8, 16 and 64 pixels.
#[test]
fn samples_give_the_same_image_for_any_thread_count_and_tile_size() {
    let program = library();
    let mut jit = Jit::new(program.clone()).unwrap();
    let mut rng = Lcg(38);
    let tris: Vec<[[f32; 4]; 3]> = (0..40)
        .map(|_| {
            std::array::from_fn(|_| {
                [
                    rng.range(-5.0, 70.0) as f32,
                    rng.range(-5.0, 50.0) as f32,
                    rng.range(0.1, 0.9) as f32,
                    1.0,
                ]
            })
        })
        .collect();
    for (samples, filter) in [(4, Filter::Box), (16, Filter::Gaussian), (8, Filter::Box)] {
        let mut frames = vec![];
        for tile in [8, 16, 64] {
            for threads in [1, 2] {
                let mut r = renderer(&program, 67, 45, true);
                r.set_samples(samples).unwrap();
                r.set_filter(filter);
                r.set_tile_size(tile).unwrap();
                r.material_interp("Cs", "linear", &[]).unwrap();
                for (k, t) in tris.iter().enumerate() {
                    let c = |v: usize| vec![(k % 3) as f32 / 2.0, v as f32 / 2.0, ((k + v) % 5) as f32 / 4.0];
                    screen_triangle(&mut r, *t, &[("Cs", [c(0), c(1), c(2)])]);
                }
                frames.push(render_with(&r, &mut jit, threads));
            }
        }
        let first = &frames[0];
        let image = first.to_rgb8();
        // Not vacuous: the edges are antialiased (levels other than the triangles' own).
        let levels: std::collections::HashSet<[u8; 3]> = image.pixels().map(|p| p.0).collect();
        assert!(levels.len() > 200, "{} colours", levels.len());
        for f in &frames[1..] {
            assert!(first.same_buffers(f), "{samples} samples: buffers differ");
            assert_eq!(f.to_rgb8(), image, "{samples} samples: images differ");
            assert_eq!(f.write_count_values(), first.write_count_values());
        }
    }
}

/// A sample count outside 1, 2, 4, 8, 16 is refused, naming the allowed ones: by the API, by
/// the scene's `samples` line (with its place), and a filter name it does not know too.
#[test]
fn sample_counts_outside_the_allowed_set_are_errors_naming_them() {
    let program = library();
    let mut r = Renderer::new(program.clone());
    let e = r.set_samples(3).unwrap_err();
    assert_eq!(e.code, "E0708");
    assert!(e.message.contains("use 1, 2, 4, 8 or 16"), "{}", e.message);
    assert_eq!(r.options.samples, 1);
    let mut sources = SourceMap::new();
    let file = sources.add(
        "aa.scene",
        "image 8 8\nsamples 3\nsamples 4 blurry\nsamples 0\nsamples 16 gaussian\n",
    );
    let mut r = Renderer::new(program);
    let mut diags = Diagnostics::new();
    primflow::scene::load_into(&sources, file, &mut r, &mut diags);
    assert_eq!(diags.codes_at(&sources), ["E0604@3:11", "E0604@4:9", "E0708@2:9"]);
    let rendered = diags.render(&sources);
    assert!(rendered.contains("use box or gaussian"), "{rendered}");
    assert_eq!((r.options.samples, r.options.filter), (16, Filter::Gaussian));
}

/// The frame's bytes count every sample: a 16384 x 16384 frame of three planes takes 7.5 GiB
/// a sample, under the 16 GiB limit with one and far over it with 16, which is refused with
/// E0803 naming the samples, before anything is allocated.
#[test]
fn a_frame_too_large_for_its_samples_is_refused() {
    let program = library();
    let mut r = renderer(&program, MAX_IMAGE_SIDE, MAX_IMAGE_SIDE, false);
    r.set_samples(16).unwrap();
    r.material_interp("Cs", "linear", &[]).unwrap();
    screen_triangle(
        &mut r,
        [[1.0, 1.0, 0.5, 1.0], [9.0, 1.0, 0.5, 1.0], [1.0, 9.0, 0.5, 1.0]],
        &[("Cs", [vec![1.0, 0.0, 0.0], vec![0.0, 1.0, 0.0], vec![0.0, 0.0, 1.0]])],
    );
    let mut jit = Jit::new(r.program().clone()).unwrap();
    let out = r.render(&mut jit);
    let codes: Vec<&str> = out.diags.items.iter().map(|d| d.code).collect();
    assert_eq!(codes, ["E0803"], "{:?}", out.diags.items);
    assert!(
        out.diags.items[0].message.contains("16 sample(s)"),
        "{}",
        out.diags.items[0].message
    );
    assert_eq!(out.frame.width, 0);
}
