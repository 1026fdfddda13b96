//! The frame's images (src/runtime/frame.rs): `to_rgb8` row by row is `color_at` at every
//! pixel, `param_image` is its per-pixel definition, `depth_image` the top 16 bits of each
//! depth, and the 8-bit conversion rounds half away from zero.

use crate::support::render_options as opts;

use primflow::runtime::frame::to_u8;
use primflow::runtime::{Frame, ParamPlanes, RenderOptions};

/// The row-wise `to_rgb8` gives `color_at` rounded at every pixel: unwritten pixels (the
/// background, clamped), shaded colours, `Cs` of 3 and 1 components and of a plane the
/// frame lacks, no `Cs`, values outside [0, 1] and NaN, a width that is not a whole
/// stride.
#[test]
fn to_rgb8_is_color_at_at_every_pixel() {
    let (w, h) = (7, 5);
    let values = [0.25, -1.0, 2.0, f32::NAN, 0.5, 1.0 / 255.0, 0.999];
    for case in 0..5 {
        let mut f = Frame::empty();
        let o = RenderOptions {
            background: [0.2, 1.5, -0.3],
            ..opts(w, h, 4)
        };
        let (components, first) = [(3, 1), (1, 2), (3, 2), (0, 0), (3, 1)][case];
        let cs = (components > 0).then(|| ParamPlanes {
            name: "Cs".into(),
            first_plane: first,
            components,
        });
        // Case 2 names planes 2..5 of a 4-plane frame: the last reads as 0.
        f.reset(&o, 4, cs.into_iter());
        for (k, v) in f.planes.iter_mut().enumerate() {
            *v = values[k % values.len()] * (1.0 + k as f32 / 64.0);
        }
        for (i, d) in f.depth.iter_mut().enumerate() {
            *d = if i % 3 == 0 { 0 } else { i as u32 };
        }
        if case == 4 {
            let n = f.depth.len();
            f.colors = Some((0..n).map(|i| [values[i % 7], values[(i + 1) % 7], 0.5]).collect());
        }
        let image = f.to_rgb8();
        for y in 0..h {
            for x in 0..w {
                let want = f.color_at(x, y).map(to_u8);
                assert_eq!(image.get_pixel(x, y).0, want, "case {case} at ({x}, {y})");
            }
        }
        // Both kinds of pixel occur.
        assert!((0..w).any(|x| f.written(x, 0)) && (0..w).any(|x| !f.written(x, 0)));
    }
}

/// `param_image` row by row gives what it gave pixel by pixel through `plane_at` and
/// `written`: 3 components clamped (unwritten pixels included), 1 as gray over the range
/// of the written finite values, a constant one as mid gray, a missing plane as 0.
#[test]
fn param_image_is_its_per_pixel_definition() {
    let (w, h) = (7, 5);
    let values = [0.25, -1.0, 2.0, f32::NAN, 0.5, f32::INFINITY, 0.999];
    let cases = [
        ("c3", 3, 0, false),
        ("g", 1, 3, false),
        ("flat", 1, 1, true),
        ("gone", 1, 4, false),
    ];
    for (name, components, first, flat) in cases {
        let mut f = Frame::empty();
        let param = ParamPlanes {
            name: name.into(),
            first_plane: first,
            components,
        };
        f.reset(&opts(w, h, 4), 4, std::iter::once(param));
        for (k, v) in f.planes.iter_mut().enumerate() {
            *v = if flat {
                0.75
            } else {
                values[k % values.len()] * (1.0 + k as f32 / 64.0)
            };
        }
        for (i, d) in f.depth.iter_mut().enumerate() {
            *d = if i % 3 == 0 { 0 } else { i as u32 };
        }
        let image = f.param_image(name).unwrap();
        let at = |k: u32, x: u32, y: u32| f.plane_at(first + k, x, y).unwrap_or(0.0);
        let gray = |x: u32, y: u32| (f.written(x, y) && at(0, x, y).is_finite()).then(|| at(0, x, y));
        let seen: Vec<f32> = (0..h).flat_map(|y| (0..w).filter_map(move |x| gray(x, y))).collect();
        let lo = seen.iter().copied().fold(f32::INFINITY, f32::min);
        let hi = seen.iter().copied().fold(f32::NEG_INFINITY, f32::max);
        for y in 0..h {
            for x in 0..w {
                let want = if components == 3 {
                    [0, 1, 2].map(|k| to_u8(at(k, x, y)))
                } else {
                    let g = match gray(x, y) {
                        None => 0.0,
                        Some(v) if hi > lo => (v - lo) / (hi - lo),
                        Some(_) => 0.5,
                    };
                    [to_u8(g); 3]
                };
                assert_eq!(image.get_pixel(x, y).0, want, "{name} at ({x}, {y})");
            }
        }
    }
    let mut f = Frame::empty();
    let two = ParamPlanes {
        name: "uv".into(),
        first_plane: 0,
        components: 2,
    };
    f.reset(&opts(4, 4, 4), 2, std::iter::once(two));
    assert!(f.param_image("uv").is_err() && f.param_image("none").is_err());
}

#[test]
fn depth_image_is_the_top_16_bits_of_every_pixels_depth() {
    let (w, h) = (7, 5);
    let mut f = Frame::empty();
    f.reset(&opts(w, h, 4), 0, std::iter::empty());
    for (i, d) in f.depth.iter_mut().enumerate() {
        *d = (i as u32).wrapping_mul(0x9e37_79b9) | u32::from(i % 4 == 0) << 31;
    }
    let image = f.depth_image();
    assert_eq!(image.dimensions(), (w, h));
    for y in 0..h {
        for x in 0..w {
            let want = (f.depth_at(x, y).unwrap() >> 16) as u16;
            assert_eq!(image.get_pixel(x, y).0, [want], "({x}, {y})");
        }
    }
    // A frame never rendered: an empty image, no panic.
    assert_eq!(Frame::empty().depth_image().dimensions(), (0, 0));
}

#[test]
fn to_u8_rounds_half_away_from_zero() {
    // Every tie k + 1/2 of the 8-bit scale and the floats either side of it, the ends,
    // and what clamps: the same as `round()`.
    let clamp01 = |v: f32| if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) };
    let reference = |v: f32| (clamp01(v) * 255.0).round() as u8;
    let mut values = vec![0.0, 1.0, -0.0, -1.0, 2.0, f32::NAN, f32::INFINITY, f32::MIN_POSITIVE];
    for k in 0..256 {
        let tie = (k as f32 + 0.5) / 255.0;
        values.extend([
            tie,
            f32::from_bits(tie.to_bits() - 1),
            f32::from_bits(tie.to_bits() + 1),
        ]);
        values.push(k as f32 / 255.0);
    }
    for v in values {
        assert_eq!(to_u8(v), reference(v), "{v:e}");
    }
}
