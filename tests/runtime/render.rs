//! The renderer with hand-written ABI kernels: depth order, tiling and binning, thread-count
//! independence, write counts, hostile bounds, run-time error reports, images.

use crate::support::kernels::*;
use crate::support::raw_depth;
use primflow::diag::SourceMap;
use primflow::runtime::{RenderOutput, Renderer};

fn setup(width: u32, height: u32, tile: u32) -> (SourceMap, Renderer) {
    let mut sources = SourceMap::new();
    let mut r = Renderer::new(program(&mut sources));
    r.set_image_size(width, height).unwrap();
    r.set_tile_size(tile).unwrap();
    r.set_background([0.0, 0.0, 1.0]);
    // The rect kernel writes its colour into the first binding's planes.
    r.material("Cs", &[0.0, 0.0, 0.0].into()).unwrap();
    (sources, r)
}

fn render(r: &Renderer) -> RenderOutput {
    let mut kernels = TestKernels::new(r.program().clone());
    r.render(&mut kernels)
}

#[test]
fn nearer_rect_wins_whatever_the_submission_order() {
    for near_first in [false, true] {
        let (_s, mut r) = setup(40, 30, 16);
        let far = ([5.0, 5.0, 25.0, 25.0], 0.3, [1.0, 0.0, 0.0]);
        let near = ([15.0, 10.0, 35.0, 20.0], 0.7, [0.0, 1.0, 0.0]);
        let order = if near_first { [near, far] } else { [far, near] };
        for (xy, d, c) in order {
            rect(&mut r, xy, d, c);
        }
        let out = render(&r);
        assert!(out.diags.items.is_empty(), "{:?}", out.diags.items);
        let f = &out.frame;
        assert_eq!(f.color_at(7, 7), [1.0, 0.0, 0.0], "far only");
        assert_eq!(f.color_at(20, 15), [0.0, 1.0, 0.0], "overlap: near");
        assert_eq!(f.color_at(30, 15), [0.0, 1.0, 0.0], "near only");
        assert_eq!(f.color_at(38, 28), [0.0, 0.0, 1.0], "background");
        assert_eq!(f.depth_at(20, 15), Some(raw_depth(f64::from(0.7f32))));
        assert_eq!(f.depth_at(7, 7), Some(raw_depth(f64::from(0.3f32))));
        assert_eq!(f.depth_at(38, 28), Some(0));
        assert_eq!(f.param_at("Cs", 20, 15), Some(vec![0.0, 1.0, 0.0]));
        assert_eq!(out.stats.instances, 2);
        assert_eq!(out.stats.kernels_compiled, 1, "one (rect, key) kernel, reused");
    }
}

#[test]
fn a_rect_across_tiles_covers_exactly_its_pixels() {
    // Tile 5 is not a multiple of the group width: the renderer rounds it up to 8 (tiles
    // start on pixel groups of the frame's rows); 43 is not one either: the right edge tiles
    // are cut, their last group reaching into the frame's padding.
    let (_s, mut r) = setup(43, 32, 5);
    rect(&mut r, [7.0, 8.0, 23.0, 19.0], 0.5, [1.0, 1.0, 1.0]);
    let out = render(&r);
    let f = &out.frame;
    let mut covered = 0;
    for y in 0..32 {
        for x in 0..43 {
            let inside = (7..23).contains(&x) && (8..19).contains(&y);
            assert_eq!(f.written(x, y), inside, "pixel {x},{y}");
            covered += u32::from(f.written(x, y));
        }
    }
    assert_eq!(covered, 16 * 11);
    // Binned into the 3x2 tiles its pixels (x 7..=22, y 8..=18) touch, of the 6x4 8-pixel
    // tiles: no call for a tile that holds none of them.
    assert_eq!(out.stats.tile_invocations, 6);
}

#[test]
fn output_is_bit_identical_for_one_and_two_threads() {
    let (_s, mut r) = setup(97, 61, 16);
    // Deterministic pseudo-random overlapping rects, some equal depths (first one wins).
    let mut seed = 12345u32;
    let mut next = || {
        seed = seed.wrapping_mul(1664525).wrapping_add(1013904223);
        (seed >> 8) as f32 / (1u32 << 24) as f32
    };
    for _ in 0..60 {
        let (x, y) = (next() * 100.0 - 5.0, next() * 64.0 - 3.0);
        let (w, h) = (next() * 40.0, next() * 30.0);
        let depth = (next() * 8.0).floor() / 8.0 + 0.01;
        rect(&mut r, [x, y, x + w, y + h], depth, [next(), next(), next()]);
    }
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| render(&r)).frame
    };
    let (one, two) = (run(1), run(2));
    assert_eq!(one.depth_values(), two.depth_values());
    let bits = |f: &primflow::runtime::Frame| -> Vec<Vec<u32>> {
        f.all_plane_values()
            .iter()
            .map(|p| p.iter().map(|v| v.to_bits()).collect())
            .collect()
    };
    assert_eq!(bits(&one), bits(&two));
    assert_eq!(one.to_rgb8().into_raw(), two.to_rgb8().into_raw());
    assert!(
        one.depth_values().iter().filter(|&&d| d != 0).count() > 1000,
        "the scene covers pixels"
    );
}

#[test]
fn write_counts_count_every_depth_write() {
    let (_s, mut r) = setup(20, 10, 8);
    r.options.count_writes = true;
    rect(&mut r, [0.0, 0.0, 10.0, 10.0], 0.2, [1.0, 0.0, 0.0]);
    rect(&mut r, [5.0, 0.0, 15.0, 10.0], 0.6, [0.0, 1.0, 0.0]); // nearer, drawn later: rewrites
    rect(&mut r, [0.0, 0.0, 20.0, 10.0], 0.1, [0.0, 0.0, 0.0]); // farthest, drawn last
    let out = render(&r);
    let f = &out.frame;
    assert_eq!(f.write_count_at(2, 5), Some(1));
    assert_eq!(f.write_count_at(7, 5), Some(2));
    assert_eq!(f.write_count_at(12, 5), Some(1));
    assert_eq!(f.write_count_at(17, 5), Some(1));
    let mut kernels = TestKernels::new(r.program().clone());
    r.render(&mut kernels);
    assert!(kernels.requests.iter().all(|(_, key)| key.count_writes));

    let (_s, mut r) = setup(20, 10, 8);
    rect(&mut r, [0.0, 0.0, 10.0, 10.0], 0.2, [1.0, 0.0, 0.0]);
    assert_eq!(render(&r).frame.write_count_at(2, 5), None, "not counted unless asked");
}

#[test]
fn nan_and_infinite_bounds_never_panic() {
    let (_s, mut r) = setup(30, 20, 8);
    rect(&mut r, [f32::NAN, 0.0, 10.0, 10.0], 0.9, [1.0, 0.0, 0.0]);
    rect(
        &mut r,
        [-1e38, f32::NEG_INFINITY, 1e38, f32::INFINITY],
        0.5,
        [0.0, 1.0, 0.0],
    );
    rect(&mut r, [1000.0, 1000.0, 2000.0, 2000.0], 0.9, [1.0, 1.0, 1.0]);
    let out = render(&r);
    let f = &out.frame;
    // The NaN rect is in no tile; the infinite one covers everything; the off-screen one nothing.
    assert!((0..20).all(|y| (0..30).all(|x| f.color_at(x, y) == [0.0, 1.0, 0.0])));
    assert_eq!(out.stats.tile_invocations, 4 * 3);
}

#[test]
fn kernel_runtime_errors_are_reported_once_per_site_with_the_prim_location() {
    let mut sources = SourceMap::new();
    let mut r = Renderer::new(program(&mut sources));
    r.set_image_size(64, 64).unwrap();
    r.set_tile_size(16).unwrap();
    for _ in 0..3 {
        r.begin("faulty").unwrap();
        r.end().unwrap();
    }
    let out = render(&r);
    assert_eq!(out.diags.codes_at(&sources), vec!["W0801@3:9"]);
    let text = out.diags.render(&sources);
    assert!(text.contains("faulty.prim:3:9"), "{text}");
    assert!(text.contains("out of range"), "{text}");
}

#[test]
fn a_kernel_that_fails_to_compile_is_an_error_and_its_instances_are_skipped() {
    let (_s, mut r) = setup(16, 16, 8);
    r.begin("spacey").unwrap();
    r.rast_param("k", &1.0.into()).unwrap();
    r.end().unwrap();
    rect(&mut r, [0.0, 0.0, 4.0, 4.0], 0.5, [1.0, 0.0, 0.0]);
    let out = render(&r);
    assert_eq!(out.diags.error_count(), 1);
    assert_eq!(out.diags.items[0].code, "E0801");
    assert!(out.diags.items[0].message.contains("spacey"));
    assert_eq!(
        out.frame.color_at(1, 1),
        [1.0, 0.0, 0.0],
        "the other instance still renders"
    );
}

#[test]
fn depth_and_parameter_images() {
    let (_s, mut r) = setup(8, 4, 4);
    r.material("rough", &0.0.into()).unwrap();
    rect(&mut r, [0.0, 0.0, 4.0, 4.0], 0.25, [2.0, -1.0, 0.5]);
    rect(&mut r, [4.0, 0.0, 6.0, 4.0], 0.75, [0.0, 0.0, 0.0]);
    let out = render(&r);
    let f = &out.frame;
    let depth = f.depth_image();
    assert_eq!(depth.get_pixel(1, 1).0[0], (raw_depth(f64::from(0.25f32)) >> 16) as u16);
    assert!(
        depth.get_pixel(5, 1).0[0] > depth.get_pixel(1, 1).0[0],
        "nearer is brighter"
    );
    assert_eq!(depth.get_pixel(7, 1).0[0], 0);
    let rgb = f.to_rgb8();
    assert_eq!(rgb.get_pixel(1, 1).0, [255, 0, 128], "Cs clamped");
    assert_eq!(rgb.get_pixel(7, 1).0, [0, 0, 255], "background");
    assert_eq!(f.param_image("Cs").unwrap().get_pixel(1, 1).0, [255, 0, 128]);
    // `rough` (plane 3) is never written by the rect kernel: all written pixels read 0,
    // a zero range maps to mid-gray; unwritten pixels are black.
    let rough = f.param_image("rough").unwrap();
    assert_eq!(rough.get_pixel(1, 1).0, [128; 3]);
    assert_eq!(rough.get_pixel(7, 1).0, [0; 3]);
    assert!(f.param_image("nosuch").is_err());
}

#[test]
fn out_of_range_options_set_directly_are_clamped_not_panics() {
    let (_s, mut r) = setup(8, 8, 4);
    rect(&mut r, [0.0, 0.0, 8.0, 8.0], 0.5, [1.0, 0.0, 0.0]);
    r.options.tile_size = 0;
    r.options.width = 0;
    let out = render(&r);
    assert_eq!((out.frame.width, out.frame.depth_values().len()), (0, 0));
    r.options.width = 8;
    let out = render(&r);
    assert_eq!(out.frame.color_at(3, 3), [1.0, 0.0, 0.0], "tile side 0 is taken as 1");
}

#[test]
fn without_cs_covered_pixels_are_white_and_a_gray_cs_is_broadcast() {
    let mut sources = SourceMap::new();
    let mut r = Renderer::new(program(&mut sources));
    r.set_image_size(8, 4).unwrap();
    rect(&mut r, [0.0, 0.0, 4.0, 4.0], 0.5, [0.2, 0.4, 0.6]);
    let f = render(&r).frame;
    assert_eq!(f.color_at(1, 1), [1.0; 3]);
    assert_eq!(f.color_at(6, 1), [0.0; 3], "default background is black");

    let mut r = Renderer::new(program(&mut sources));
    r.set_image_size(8, 4).unwrap();
    r.material("Cs", &0.0.into()).unwrap();
    // The test kernel writes all three colour components through the first three words
    // after the plane table's start; with a 1-component Cs the later two words are other
    // data that happen to name plane 0 as well, so give all three the same value.
    rect(&mut r, [0.0, 0.0, 4.0, 4.0], 0.5, [0.25; 3]);
    assert_eq!(render(&r).frame.color_at(1, 1), [0.25; 3]);
}
