//! A frame larger than `MAX_FRAME_BYTES` is refused with E0803 before anything is allocated
//! (at 16384 x 16384 each G-buffer plane is 1 GiB: wide shading parameters would otherwise
//! abort the process when the allocation fails), and the same scene at a small size renders.

use crate::support;

use primflow::jit::Jit;
use primflow::runtime::{Frame, MAX_FRAME_BYTES, MAX_IMAGE_SIDE};

/// One triangle carrying eight 64-component shading parameters (512 planes).
fn wide_scene(side: u32) -> primflow::runtime::Renderer {
    let program = support::library();
    let mut r = support::renderer(&program, side, side, false);
    let wide: Vec<(String, [Vec<f32>; 3])> = (0..8)
        .map(|p| (format!("P{p}"), std::array::from_fn(|v| vec![0.25 * v as f32; 64])))
        .collect();
    let params: Vec<(&str, [Vec<f32>; 3])> = wide.iter().map(|(n, v)| (n.as_str(), v.clone())).collect();
    support::screen_triangle(
        &mut r,
        [[1.0, 1.0, 0.5, 1.0], [60.0, 4.0, 0.5, 1.0], [20.0, 50.0, 0.5, 1.0]],
        &params,
    );
    r
}

#[test]
fn a_frame_over_the_byte_limit_is_refused_with_e0803() {
    let r = wide_scene(MAX_IMAGE_SIDE);
    assert_eq!(r.num_planes(), 512);
    // 512 planes of 16384^2 f32 are 512 GiB.
    assert!(512u64 << 30 > MAX_FRAME_BYTES);
    let mut jit = Jit::new(r.program().clone()).unwrap();
    // A reused frame that held an earlier render is emptied, not left stale.
    let mut frame = wide_scene(64).render(&mut jit).frame;
    assert_eq!(frame.width, 64);
    let report = r.render_into(&mut jit, &mut frame);
    let codes: Vec<&str> = report.diags.items.iter().map(|d| d.code).collect();
    assert_eq!(codes, ["E0803"], "{:?}", report.diags.items);
    assert!(report.diags.items[0].message.contains("16384x16384"));
    assert_eq!((frame.width, frame.height, frame.num_planes()), (0, 0, 0));
    assert_eq!(report.stats.kernels_compiled, 0);
    assert!(Frame::empty().same_buffers(&frame));
}

#[test]
fn the_same_scene_at_a_small_size_renders_every_plane() {
    let r = wide_scene(64);
    let frame = support::render(&r, 2);
    assert_eq!(frame.num_planes(), 512);
    // `constant` by default: the value current at `end`, vertex 2's (0.5), in every plane.
    for p in 0..8 {
        let name = format!("P{p}");
        let inside = frame.param_at(&name, 20, 20).expect("the parameter exists");
        assert_eq!(inside, vec![0.5; 64], "{name}");
        // Outside the triangle nothing is written: every plane reads zero.
        assert!(!frame.written(62, 62));
        assert_eq!(frame.param_at(&name, 62, 62), Some(vec![0.0; 64]), "{name}");
    }
}
