//! `Renderer::render_into`: rendering into a caller's `Frame`, reusing its buffers, gives
//! bit for bit the frame `Renderer::render` returns, whatever the frame held before (another
//! scene, another size, more planes, write counts, shaded colours) and whatever the thread
//! count.

use crate::support;

use std::sync::Arc;

use primflow::ir::Program;
use primflow::jit::Jit;
use primflow::runtime::shading::ShadingKernel;
use primflow::runtime::{Frame, Renderer};
use primflow::workload::{effects_scene, EffectSet};
use support::*;

/// Every field of two frames, floats compared by their bits.
fn assert_same(a: &Frame, b: &Frame, what: &str) {
    assert_eq!((a.width, a.height), (b.width, b.height), "{what}: size");
    assert_eq!(a.background, b.background, "{what}: background");
    assert_eq!(a.depth_values(), b.depth_values(), "{what}: depth");
    assert_eq!(a.num_planes(), b.num_planes(), "{what}: plane count");
    for (p, (x, y)) in a.all_plane_values().iter().zip(&b.all_plane_values()).enumerate() {
        let bits = |v: &Vec<f32>| v.iter().map(|f| f.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(x), bits(y), "{what}: plane {p}");
    }
    assert_eq!(a.write_count_values(), b.write_count_values(), "{what}: write counts");
    assert_eq!(a.params, b.params, "{what}: parameters");
    let bits = |c: &Option<Vec<[f32; 3]>>| {
        c.as_ref()
            .map(|c| c.iter().map(|p| p.map(f32::to_bits)).collect::<Vec<_>>())
    };
    assert_eq!(bits(&a.color_values()), bits(&b.color_values()), "{what}: colours");
}

/// 100 x 70 in 16 px tiles (edge tiles cut, widths not a multiple of the group), two
/// triangles with 4 perspective-interpolated components that leave most tiles empty.
fn sparse_scene(program: &Arc<Program>) -> Renderer {
    let mut r = renderer(program, 100, 70, false);
    r.set_tile_size(16).unwrap();
    for c in 0..4 {
        r.material_interp(&format!("p{c}"), "perspective_linear", &[]).unwrap();
    }
    let values = |seed: f32| -> [Vec<f32>; 3] { [vec![seed], vec![seed + 0.25], vec![seed + 0.5]] };
    let params: Vec<(String, [Vec<f32>; 3])> = (0..4).map(|c| (format!("p{c}"), values(c as f32))).collect();
    let params: Vec<(&str, [Vec<f32>; 3])> = params.iter().map(|(n, v)| (n.as_str(), v.clone())).collect();
    screen_triangle(
        &mut r,
        [[3.0, 5.0, 0.4, 1.0], [41.5, 9.0, 0.4, 2.0], [12.0, 33.0, 0.4, 1.5]],
        &params,
    );
    screen_triangle(
        &mut r,
        [[20.0, 20.0, 0.6, 1.0], [60.0, 25.0, 0.6, 3.0], [30.0, 50.0, 0.6, 1.0]],
        &params,
    );
    r
}

/// 128 x 96, every pixel covered by 3 layers with `Cs`, `N`, `st` (8 planes), two lights,
/// fog and texture on, write counts on: every buffer of a frame in use.
fn lit_scene(program: &Arc<Program>, kernel: ShadingKernel) -> Renderer {
    let mut r = effects_scene(
        program,
        128,
        3,
        EffectSet {
            lights: 2,
            fog: true,
            texture: true,
        },
    );
    r.set_image_size(128, 96).unwrap();
    r.options.count_writes = true;
    r.shading_setup.kernel = kernel;
    r
}

fn fresh(r: &Renderer, jit: &mut Jit, pool: &rayon::ThreadPool) -> Frame {
    let out = pool.install(|| r.render(jit));
    assert!(!out.diags.has_errors(), "{:?}", out.diags.items);
    out.frame
}

fn into(r: &Renderer, jit: &mut Jit, pool: &rayon::ThreadPool, frame: &mut Frame) {
    let report = pool.install(|| r.render_into(jit, frame));
    assert!(!report.diags.has_errors(), "{:?}", report.diags.items);
    assert_eq!(report.stats.instances, r.instances().len());
}

fn pool(threads: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap()
}

#[test]
fn rendering_twice_into_one_frame_gives_the_fresh_frame() {
    let program = library();
    let mut jit = Jit::new(program.clone()).unwrap();
    let one = pool(1);
    let r = sparse_scene(&program);
    let reference = fresh(&r, &mut jit, &one);
    assert!(
        reference.written(10, 10) && !reference.written(90, 60),
        "the scene leaves tiles empty"
    );
    let mut frame = Frame::empty();
    into(&r, &mut jit, &one, &mut frame);
    assert_same(&frame, &reference, "first render into an empty frame");
    let depth_ptr = frame.depth_buffer().as_ptr();
    into(&r, &mut jit, &one, &mut frame);
    assert_same(&frame, &reference, "second render into the same frame");
    assert_eq!(
        frame.depth_buffer().as_ptr(),
        depth_ptr,
        "the depth buffer was reused, not reallocated"
    );
}

#[test]
fn a_frame_left_by_another_scene_is_reshaped_and_fully_overwritten() {
    let program = library();
    let mut jit = Jit::new(program.clone()).unwrap();
    let one = pool(1);
    for kernel in [ShadingKernel::Simd, ShadingKernel::ReferenceF64] {
        let sparse = sparse_scene(&program);
        let lit = lit_scene(&program, kernel);
        let sparse_ref = fresh(&sparse, &mut jit, &one);
        let lit_ref = fresh(&lit, &mut jit, &one);
        assert!(lit_ref.is_shaded() && lit_ref.write_count_values().is_some());
        assert_eq!(lit_ref.num_planes(), 8);
        assert_eq!(lit_ref.write_count_at(5, 5), Some(3), "three layers over every pixel");
        let mut frame = Frame::empty();
        // Bigger, more planes, counts and colours -> smaller, fewer, none -> back.
        into(&lit, &mut jit, &one, &mut frame);
        assert_same(&frame, &lit_ref, "lit scene first");
        into(&sparse, &mut jit, &one, &mut frame);
        assert_same(&frame, &sparse_ref, "sparse scene after the lit one");
        assert_eq!(
            frame.color_at(90, 60),
            [0.0; 3],
            "an empty tile shows the background again"
        );
        into(&lit, &mut jit, &one, &mut frame);
        assert_same(&frame, &lit_ref, "lit scene after the sparse one");
        // Colours left by the lit frame must not survive where the next lit frame writes
        // nothing (the shading pass skips unwritten pixels).
        let mut sparse_lit = sparse_scene(&program);
        sparse_lit.shading_setup = lit.shading_setup.clone();
        let sparse_lit_ref = fresh(&sparse_lit, &mut jit, &one);
        assert!(sparse_lit_ref.is_shaded());
        into(&sparse_lit, &mut jit, &one, &mut frame);
        assert_same(&frame, &sparse_lit_ref, "sparse lit scene after the lit one");
        assert_eq!(frame.shaded_at(90, 60), Some([0.0; 3]));
    }
}

#[test]
fn one_and_two_threads_fill_a_reused_frame_identically() {
    let program = library();
    let mut jit = Jit::new(program.clone()).unwrap();
    let (one, two) = (pool(1), pool(2));
    let lit = lit_scene(&program, ShadingKernel::Simd);
    let sparse = sparse_scene(&program);
    let reference = fresh(&lit, &mut jit, &one);
    let mut frame = Frame::empty();
    for round in 0..3 {
        for (threads, p) in [(1, &one), (2, &two)] {
            into(&lit, &mut jit, p, &mut frame);
            assert_same(&frame, &reference, &format!("round {round}, {threads} thread(s)"));
        }
        // Another scene in between, on two threads: its pixels must all be replaced.
        into(&sparse, &mut jit, &two, &mut frame);
    }
}

/// The lit scene's three full-viewport layers (drawn for 192 x 192) plus a near triangle
/// whose edges cross the right and bottom borders of every viewport below diagonally, so
/// the right edge tiles' last groups are partly covered, at a viewport of `width` x
/// `height` in `tile` px tiles, write counts on.
fn cropped_scene(program: &Arc<Program>, width: u32, height: u32, tile: u32) -> Renderer {
    let lights = EffectSet {
        lights: 2,
        fog: true,
        texture: true,
    };
    let mut r = effects_scene(program, 192, 3, lights);
    r.options.count_writes = true;
    let cs = |v: f32| vec![v, 1.0 - v, 0.5];
    screen_triangle(
        &mut r,
        [[2.0, 1.0, 0.9, 1.0], [140.0, 30.0, 0.9, 2.0], [30.0, 121.5, 0.9, 1.5]],
        &[
            ("Cs", [cs(0.1), cs(0.5), cs(0.9)]),
            ("N", [vec![0.0, 0.0, 1.0], vec![0.3, 0.0, 1.0], vec![0.0, 0.3, 1.0]]),
            ("st", [vec![0.0, 0.0], vec![1.0, 0.0], vec![0.0, 1.0]]),
        ],
    );
    r.set_image_size(width, height).unwrap();
    r.set_tile_size(tile).unwrap();
    r
}

/// Viewports whose width is not a multiple of the group (4) or of the tile: every pixel's
/// depth, planes and write count equal the same scene's at 192 x 192 in 64 px tiles,
/// cropped, on one and two threads, fresh and into a frame a bigger render left.
#[test]
fn a_ragged_viewport_renders_every_pixel_as_a_whole_tile_one_cropped() {
    let program = library();
    let mut jit = Jit::new(program.clone()).unwrap();
    let (one, two) = (pool(1), pool(2));
    let wide = fresh(&cropped_scene(&program, 192, 192, 64), &mut jit, &one);
    assert_eq!(wide.num_planes(), 8);
    for (width, height, tile) in [(37, 23, 16), (130, 67, 16), (5, 3, 16), (61, 9, 5)] {
        let r = cropped_scene(&program, width, height, tile);
        let mut reused = wide.clone();
        for (threads, p) in [(1, &one), (2, &two)] {
            let frame = fresh(&r, &mut jit, p);
            into(&r, &mut jit, p, &mut reused);
            let what = format!("{width}x{height}/{tile}, {threads} thread(s)");
            assert_same(&reused, &frame, &format!("{what}: into a 192 x 192 frame"));
            assert_eq!((frame.width, frame.height, frame.num_planes()), (width, height, 8));
            let mut near = 0;
            for y in 0..height {
                for x in 0..width {
                    let at = format!("{what}: pixel ({x}, {y})");
                    assert_eq!(frame.depth_at(x, y), wide.depth_at(x, y), "{at}: depth");
                    assert!(frame.written(x, y), "{at}: three layers cover every pixel");
                    assert_eq!(frame.write_count_at(x, y), wide.write_count_at(x, y), "{at}: count");
                    for plane in 0..8 {
                        let (a, b) = (frame.plane_at(plane, x, y), wide.plane_at(plane, x, y));
                        assert_eq!(a.map(f32::to_bits), b.map(f32::to_bits), "{at}: plane {plane}");
                    }
                    near += usize::from(frame.write_count_at(x, y) == Some(4));
                }
            }
            // The near triangle covers some pixels and not others (its edges cross the
            // viewport), including in the last column when it reaches that far.
            assert!(
                near > 0 && near < (width * height) as usize,
                "{what}: {near} near pixels"
            );
        }
    }
}

/// At 37 x 23 (stride 40): the accessors see exactly the viewport's pixels, the bulk copies
/// agree with them, everything outside is `None`, and the images (PNG included) are the
/// viewport's size with every pixel from `color_at`.
#[test]
fn accessors_and_images_of_a_ragged_frame_see_exactly_its_pixels() {
    let program = library();
    let mut jit = Jit::new(program.clone()).unwrap();
    let (width, height) = (37u32, 23u32);
    let frame = fresh(&cropped_scene(&program, width, height, 16), &mut jit, &pool(2));
    assert_eq!(frame.stride(), 40);
    assert_eq!(frame.depth_buffer().len(), 40 * 23);
    let pixels = (width * height) as usize;
    let depth = frame.depth_values();
    let counts = frame.write_count_values().unwrap();
    let colors = frame.color_values().unwrap();
    let planes = frame.all_plane_values();
    assert_eq!((depth.len(), counts.len(), colors.len()), (pixels, pixels, pixels));
    assert_eq!(planes.len(), 8);
    assert_eq!(frame.covered_pixels(), depth.iter().filter(|&&d| d != 0).count());
    let rgb = frame.to_rgb8();
    let depth_image = frame.depth_image();
    let cs_image = frame.param_image("Cs").unwrap();
    assert_eq!(rgb.dimensions(), (width, height));
    assert_eq!(depth_image.dimensions(), (width, height));
    assert_eq!(cs_image.dimensions(), (width, height));
    let to_u8 = |v: f32| (v.clamp(0.0, 1.0) * 255.0).round() as u8;
    for y in 0..height {
        for x in 0..width {
            let i = (y * width + x) as usize;
            assert_eq!(frame.depth_at(x, y), Some(depth[i]), "({x}, {y})");
            assert_eq!(frame.write_count_at(x, y), Some(counts[i]));
            assert_eq!(frame.shaded_at(x, y), Some(colors[i]));
            for (p, plane) in planes.iter().enumerate() {
                assert_eq!(
                    frame.plane_at(p as u32, x, y).map(f32::to_bits),
                    Some(plane[i].to_bits())
                );
            }
            assert_eq!(
                frame.param_at("Cs", x, y).unwrap(),
                planes[..3].iter().map(|p| p[i]).collect::<Vec<_>>()
            );
            assert_eq!(frame.color_at(x, y), colors[i].map(|c| c.clamp(0.0, 1.0)));
            assert_eq!(rgb.get_pixel(x, y).0, frame.color_at(x, y).map(to_u8));
            assert_eq!(depth_image.get_pixel(x, y).0, [(depth[i] >> 16) as u16]);
            let cs = frame.param_at("Cs", x, y).unwrap();
            assert_eq!(cs_image.get_pixel(x, y).0, [cs[0], cs[1], cs[2]].map(to_u8));
        }
    }
    // Outside the viewport (the padding columns included) there is nothing.
    for (x, y) in [(width, 0), (38, 5), (39, 22), (0, height), (width, height)] {
        assert_eq!(frame.depth_at(x, y), None, "({x}, {y})");
        assert_eq!(frame.plane_at(0, x, y), None);
        assert_eq!(frame.write_count_at(x, y), None);
        assert_eq!(frame.shaded_at(x, y), None);
        assert!(!frame.written(x, y));
        assert_eq!(frame.color_at(x, y), frame.background);
    }
    assert_eq!(frame.plane_at(8, 0, 0), None);
    assert_eq!(frame.plane_values(8), None);
    // The PNG the CLI writes decodes to the same pixels.
    let mut png = std::io::Cursor::new(vec![]);
    rgb.write_to(&mut png, image::ImageFormat::Png).unwrap();
    let decoded = image::load_from_memory(png.get_ref()).unwrap().to_rgb8();
    assert_eq!(decoded.dimensions(), (width, height));
    assert_eq!(decoded.into_raw(), rgb.into_raw());
}
