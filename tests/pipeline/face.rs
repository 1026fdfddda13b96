//! Face determination in device space (front = counter-clockwise on screen, y down), and
//! its agreement with the divide-free clip-space test.

use glam::DVec4;
use primflow::pipeline::face::*;
use primflow::pipeline::transform::{device_from_clip, Viewport};

#[test]
fn counter_clockwise_on_screen_is_front() {
    // Top-left, bottom-left, top-right: counter-clockwise as seen with y down.
    let ccw = [[0.0f64, 0.0], [0.0, 10.0], [10.0, 0.0]];
    assert_eq!(screen_area(&ccw), 50.0);
    assert_eq!(facing_device(&ccw), Facing::Front);
    let cw = [[0.0f64, 0.0], [10.0, 0.0], [0.0, 10.0]];
    assert_eq!(facing_device(&cw), Facing::Back);
    // Degenerate (collinear) counts as front.
    assert_eq!(facing_device(&[[0.0f32, 0.0], [1.0, 1.0], [2.0, 2.0]]), Facing::Front);
    assert!(CullMode::Back.culls(Facing::Back) && !CullMode::Back.culls(Facing::Front));
    assert!(CullMode::Front.culls(Facing::Front) && !CullMode::None.culls(Facing::Back));
}

#[test]
fn clip_space_test_agrees_with_device_space_area() {
    let d = device_from_clip(Viewport {
        x0: 0.0,
        y0: 0.0,
        width: 640.0,
        height: 480.0,
    });
    let mut state = 12345u64;
    let mut next = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    let mut fronts = 0;
    for _ in 0..10_000 {
        let tri: [[f64; 4]; 3] = std::array::from_fn(|_| {
            let w = next().abs() * 5.0 + 0.1;
            [next() * 2.0 * w, next() * 2.0 * w, 0.5 * w, w]
        });
        let device: Vec<[f64; 2]> = tri
            .iter()
            .map(|c| {
                let h = d.mul_vec4(DVec4::from_array(*c));
                [h.x / h.w, h.y / h.w]
            })
            .collect();
        let expected = facing_device(&device);
        assert_eq!(triangle_facing_clip(tri), expected);
        // Negating one vertex (same projective point, w < 0) does not change the answer.
        let mut flipped = tri;
        flipped[1] = flipped[1].map(|c| -c);
        assert_eq!(triangle_facing_clip(flipped), expected);
        if expected == Facing::Front {
            fronts += 1;
        }
    }
    assert!((3000..7000).contains(&fronts));
    // A triangle counter-clockwise in clip x, y (y up) is front on screen.
    let up = [[0.0, 0.0, 0.5, 1.0], [0.5, 0.0, 0.5, 1.0], [0.0, 0.5, 0.5, 1.0]];
    assert_eq!(triangle_facing_clip(up), Facing::Front);
    assert!(projected_area(up) > 0.0);
}
