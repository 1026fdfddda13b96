//! Multisampling: where in a pixel each of a frame's samples lies, and how the samples'
//! colours resolve to the pixel's.
//!
//! A frame of N samples is N frames of buffers (`Frame::samples`), sample `s` rendered with
//! every kernel evaluating at `(x + offset_s.x, y + offset_s.y)` instead of the pixel
//! centre (`TileCtx::sample_x`, `sample_y`): the primitive sees the sample's position as
//! its `X` and `Y`, and its edge rule decides per sample, so two triangles sharing an
//! edge cover each sample once at every N exactly as they cover each pixel centre once at
//! N = 1. Setup runs once per draw per tile per sample; shading runs per sample
//! (supersampling).
//!
//! Invariants:
//! - The patterns are the standard ones of Direct3D 11 and Vulkan
//!   (`standardSampleLocations`) for 1, 2, 4, 8 and 16 samples: offsets from the pixel
//!   centre in 1/16 pixel, y down (our screen's rows run down too). Every offset is a
//!   multiple of 1/16 in `[0, 1)` from the pixel's top-left corner, so a pixel's sample
//!   coordinates are exact in f32 (the JIT's carried row and group coordinates rely on
//!   it); N = 1 is the centre, so a one-sample frame is the frame without multisampling,
//!   bit for bit.
//! - The resolve is per pixel from its own and (Gaussian) its neighbours' samples with
//!   fixed weights, each pixel independently, so the image is the same for any thread
//!   count and tile size.

use rayon::prelude::*;

/// The sample counts a frame may have.
pub const ALLOWED_SAMPLES: [u32; 5] = [1, 2, 4, 8, 16];

/// The standard pattern of `n` samples (one of [`ALLOWED_SAMPLES`]), in 1/16 pixel from
/// the centre.
fn pattern_sixteenths(n: u32) -> Option<&'static [[i8; 2]]> {
    Some(match n {
        1 => &[[0, 0]],
        2 => &[[4, 4], [-4, -4]],
        4 => &[[-2, -6], [6, -2], [-6, 2], [2, 6]],
        8 => &[[1, -3], [-1, 3], [5, 1], [-3, -5], [-5, 5], [-7, -1], [3, 7], [7, -7]],
        16 => &[
            [1, 1],
            [-1, -3],
            [-3, 2],
            [4, -1],
            [-5, -2],
            [2, 5],
            [5, 3],
            [3, -5],
            [-2, 6],
            [0, -7],
            [-4, -6],
            [-6, 4],
            [-8, 0],
            [7, -4],
            [6, 7],
            [-7, -8],
        ],
        _ => return None,
    })
}

/// The positions of `n` samples within a pixel, from its top-left corner (each in `[0, 1)`),
/// in sample order; `None` unless `n` is one of [`ALLOWED_SAMPLES`].
pub fn sample_positions(n: u32) -> Option<Vec<[f32; 2]>> {
    let at = |d: i8| 0.5 + f32::from(d) / 16.0;
    pattern_sixteenths(n).map(|p| p.iter().map(|&[x, y]| [at(x), at(y)]).collect())
}

/// The least and greatest sample offsets of `n` samples' pattern, `[min x, min y, max x,
/// max y]` from the pixel's top-left corner (the centre's 0.5 for a count not allowed,
/// which a render treats as 1).
pub fn sample_offset_range(n: u32) -> [f64; 4] {
    let pattern = pattern_sixteenths(n).unwrap_or(&[[0, 0]]);
    let at = |d: i8| 0.5 + f64::from(d) / 16.0;
    let mut r = [f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY];
    for &[x, y] in pattern {
        r = [r[0].min(at(x)), r[1].min(at(y)), r[2].max(at(x)), r[3].max(at(y))];
    }
    r
}

/// The error for a sample count not in [`ALLOWED_SAMPLES`].
pub fn samples_error(n: u32) -> String {
    format!("{n} samples per pixel is not supported: use 1, 2, 4, 8 or 16")
}

/// How a pixel's colour is made from the samples' colours.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Filter {
    /// The mean of the pixel's own samples.
    #[default]
    Box,
    /// pbrt's Gaussian (σ = 0.5 pixel, radius 1.5 pixels, separable, shifted to 0 at the
    /// radius) over the samples of the pixel and its neighbours, normalised by the weights
    /// of the samples inside the image: softer edges, a little blur.
    Gaussian,
}

impl Filter {
    pub const NAMES: [&'static str; 2] = ["box", "gaussian"];

    pub fn parse(name: &str) -> Option<Filter> {
        match name {
            "box" => Some(Filter::Box),
            "gaussian" => Some(Filter::Gaussian),
            _ => None,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Filter::Box => "box",
            Filter::Gaussian => "gaussian",
        }
    }
}

/// pbrt-v4's Gaussian filter's parameters.
const GAUSSIAN_SIGMA: f64 = 0.5;
const GAUSSIAN_RADIUS: f64 = 1.5;

/// One axis of the Gaussian filter at distance `d` from the pixel centre.
fn gaussian_1d(d: f64) -> f64 {
    let g = |d: f64| (-d * d / (2.0 * GAUSSIAN_SIGMA * GAUSSIAN_SIGMA)).exp();
    (g(d) - g(GAUSSIAN_RADIUS)).max(0.0)
}

/// The weights a pixel gives the samples around it: `(dx, dy, sample, weight)` for the
/// samples of the pixel `dx, dy` away whose weight is not zero (the pixel's own only, each
/// `1 / n`, for the box filter).
fn taps(filter: Filter, positions: &[[f32; 2]]) -> Vec<(i32, i32, usize, f32)> {
    let n = positions.len();
    match filter {
        Filter::Box => (0..n).map(|s| (0, 0, s, 1.0 / n as f32)).collect(),
        Filter::Gaussian => {
            let reach = GAUSSIAN_RADIUS.ceil() as i32;
            let mut taps = vec![];
            for dy in -reach..=reach {
                for dx in -reach..=reach {
                    for (s, p) in positions.iter().enumerate() {
                        let ox = f64::from(dx) + f64::from(p[0]) - 0.5;
                        let oy = f64::from(dy) + f64::from(p[1]) - 0.5;
                        let w = gaussian_1d(ox) * gaussian_1d(oy);
                        if w > 0.0 {
                            taps.push((dx, dy, s, w as f32));
                        }
                    }
                }
            }
            taps
        }
    }
}

/// Resolve `samples` (sample `s`'s display colours, clamped to [0, 1], `width * height`
/// row-major, background where nothing was drawn) into the pixels' colours with `filter`.
/// `positions`: the samples' positions in their pixel.
pub fn resolve(
    samples: &[Vec<[f32; 3]>],
    positions: &[[f32; 2]],
    filter: Filter,
    width: u32,
    height: u32,
) -> Vec<[f32; 3]> {
    let (w, h) = (width as i32, height as i32);
    let taps = taps(filter, positions);
    let mut out = vec![[0.0f32; 3]; width as usize * height as usize];
    out.par_chunks_mut(width.max(1) as usize)
        .enumerate()
        .for_each(|(y, row)| {
            let y = y as i32;
            for (x, px) in row.iter_mut().enumerate() {
                let x = x as i32;
                let (mut sum, mut weight) = ([0.0f32; 3], 0.0f32);
                for &(dx, dy, s, tap) in &taps {
                    let (sx, sy) = (x + dx, y + dy);
                    if sx < 0 || sy < 0 || sx >= w || sy >= h {
                        continue;
                    }
                    let c = samples[s][(sy * w + sx) as usize];
                    for k in 0..3 {
                        sum[k] += tap * c[k];
                    }
                    weight += tap;
                }
                *px = sum.map(|v| (v / weight).clamp(0.0, 1.0));
            }
        });
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn patterns_are_inside_the_pixel_on_the_sixteenth_grid_and_distinct() {
        for n in ALLOWED_SAMPLES {
            let p = sample_positions(n).unwrap();
            assert_eq!(p.len(), n as usize);
            for (i, a) in p.iter().enumerate() {
                for v in a {
                    assert!((0.0..1.0).contains(v), "{n}: {a:?}");
                    assert_eq!((v * 16.0).fract(), 0.0);
                }
                assert!(p[..i].iter().all(|b| b != a), "{n}: {a:?} twice");
            }
        }
        assert_eq!(sample_positions(1).unwrap(), vec![[0.5, 0.5]]);
        assert_eq!(sample_positions(3), None);
    }

    #[test]
    fn box_resolve_is_the_mean_and_gaussian_of_a_flat_image_is_flat() {
        let p = sample_positions(4).unwrap();
        let samples: Vec<Vec<[f32; 3]>> = (0..4).map(|s| vec![[s as f32 / 4.0, 1.0, 0.0]; 6]).collect();
        let out = resolve(&samples, &p, Filter::Box, 3, 2);
        assert!(out.iter().all(|c| *c == [0.375, 1.0, 0.0]));
        let flat: Vec<Vec<[f32; 3]>> = (0..4).map(|_| vec![[0.25, 0.5, 1.0]; 6]).collect();
        for c in resolve(&flat, &p, Filter::Gaussian, 3, 2) {
            for (v, e) in c.iter().zip([0.25, 0.5, 1.0]) {
                assert!((v - e).abs() < 1e-6, "{c:?}");
            }
        }
    }
}
