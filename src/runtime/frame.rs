//! The frame's buffers: depth, G-buffer planes, depth-write counts and colours, their
//! layout, the deferred shading pass over them and the images made from them.
//!
//! Invariants the kernels and the render loop ([`super::render`]) rely on: every buffer is
//! row-major from the top-left pixel with a row stride of whole pixel groups
//! ([`row_stride`]), so a group never straddles a row; pixel (x, y) is element
//! `y * stride + x` of each buffer and of each plane (`Frame::index`, the one place that says
//! so), and the planes lie [`plane_pitch`] elements apart in one buffer. Depth is u32 with
//! 0 = farthest. Tiles start on group boundaries ([`tile_side`]) and their rectangles, the
//! padding columns the rightmost tiles' last groups reach into included, cut the padded frame
//! into disjoint parts, so tile tasks write disjoint memory (`FrameTarget`). The buffers'
//! earlier contents never matter: `Frame::reset` shapes a frame without clearing it (nothing
//! allocated when it has room) and every tile zeroes its own rectangle before its draws.
//!
//! The deferred shading pass (`Frame::shade`, [`super::shading`]) runs when the scene turns
//! an effect on, bands of rows in parallel. Without one, a pixel whose depth was written
//! (depth != 0; a write of exactly the far value 0 is indistinguishable from none, and a
//! `Z > depth` test never passes there anyway) shows the `Cs` shading parameter clamped to
//! [0, 1] (white without one, as OpenGL's default colour), other pixels the background.

use image::{ImageBuffer, Luma, RgbImage};
use rayon::prelude::*;

use crate::abi::GROUP;

use super::api::{RenderOptions, MAX_TILE_SIDE};
use super::samples::Filter;
use super::shading::{PixelInputs, RowInputs, Shader, ShadingKernel};

/// Rows per parallel task of the shading pass: enough work per task (~4k pixels at 512
/// wide) that rayon's scheduling is noise, and still dozens of tasks per frame for two cores.
const SHADE_BAND_ROWS: usize = 8;

/// Row stride, in pixels, of buffers `width` pixels wide: whole pixel groups. The frame's
/// buffers use it (a tile's last group may run past the viewport's right edge, into the
/// padding), and so does a tile's column range (its groups from `x0`).
pub fn row_stride(width: u32) -> u32 {
    width.div_ceil(GROUP) * GROUP
}

/// Elements from one G-buffer plane's start to the next for planes of `plane_len` elements:
/// `plane_len` rounded up to whole 64-byte cache lines, then up to a line count of 17 modulo
/// 64.
///
/// Why: a kernel's pixel group stores to the same pixel of every plane, and on a frame
/// whose `stride * height * 4` is a multiple of 4 KiB (any 512 x 512 one: planes exactly
/// 1 MiB apart) those stores all fall in one set of the L1 and L2 caches (sets are indexed
/// by address bits below 4 KiB and 128 KiB). Sixteen planes plus the depth buffer are more
/// lines than a set has ways, so every group evicted the lines the next group of the row
/// writes: 2.7x the frame time at K = 16 (docs/performance.md, "G-buffer plane stride"). An odd line count
/// between planes puts plane `p`'s lines `17 p` sets further on in any power-of-two set
/// count, so up to 64 planes' row segments (4 lines each at the default tile side) sit in
/// different L1 sets; at most 63 lines (~4 KiB) of padding per plane.
pub fn plane_pitch(plane_len: usize) -> usize {
    const LINE: usize = 16; // f32 elements per 64-byte line
    let lines = plane_len.div_ceil(LINE);
    let lines = lines + (17 + 64 - lines % 64) % 64;
    lines * LINE
}

/// The tile side a render uses for a requested `tile_size`: clamped to `1..=MAX_TILE_SIDE`
/// and rounded up to whole pixel groups, so that every tile starts on a group of the
/// frame's rows (its kernels write whole groups) and no two tiles share a group.
pub fn tile_side(tile_size: u32) -> u32 {
    row_stride(tile_size.clamp(1, MAX_TILE_SIDE))
}

/// A shading parameter's place in the frame's planes.
#[derive(Clone, Debug, PartialEq)]
pub struct ParamPlanes {
    pub name: String,
    pub first_plane: u32,
    pub components: u32,
}

/// The colour of a pixel whose language shading gave a NaN or infinite channel (magenta,
/// with warning W1004).
pub const NON_FINITE_COLOR: [f32; 3] = [1.0, 0.0, 1.0];

/// The rendered frame: depth, G-buffer planes, (when counted) depth-write counts and (when
/// shaded) colours, read through the accessors (`depth_at`, `plane_at`, `param_at`,
/// `write_count_at`, `color_at`, the `*_values` copies and the images).
///
/// Layout (private; the kernels render into it): every buffer is row-major from the
/// top-left pixel with a row stride of [`row_stride`]`(width)` pixels, so a pixel group never
/// straddles a row; pixel (x, y) is element `y * stride + x` (`Frame::index`, the one place
/// that says so) of the depth, write-count and colour buffers and of each plane, and the
/// planes follow each other [`plane_pitch`]`(stride * height)` elements apart in one buffer
/// (a few cache lines more than a plane, so that the planes' pixels do not share cache
/// sets). The padding columns (`width..stride`) and the gaps between planes hold nothing
/// anyone reads.
#[derive(Clone, Debug)]
pub struct Frame {
    pub width: u32,
    pub height: u32,
    pub background: [f32; 3],
    pub params: Vec<ParamPlanes>,
    /// Row stride of every buffer, in pixels (`row_stride(width)`).
    stride: u32,
    num_planes: u32,
    /// `stride * height`.
    #[doc(hidden)]
    pub depth: Vec<u32>,
    /// `num_planes` planes of `stride * height`, [`plane_pitch`] elements apart.
    #[doc(hidden)]
    pub planes: Vec<f32>,
    write_counts: Option<Vec<u32>>,
    /// The deferred shading pass's colours, `stride * height` (`None` when the scene turns
    /// no effect on and covered pixels show `Cs`).
    #[doc(hidden)]
    pub colors: Option<Vec<[f32; 3]>>,
    /// Where in each pixel this frame's buffers were evaluated, from the pixel's top-left
    /// corner ([0.5, 0.5], the centre, without multisampling).
    sample: [f32; 2],
    /// A multisampled frame's other samples (`1..N`; this frame is sample 0), each a frame
    /// of this size, planes and options rendered at its own sample position
    /// ([`super::samples`]); empty without multisampling.
    samples: Vec<Frame>,
    /// A multisampled frame's pixel colours, resolved from every sample's ([`Frame::resolve`]):
    /// `width * height`, row-major, clamped to [0, 1], background included.
    resolved: Option<Vec<[f32; 3]>>,
}

/// One tile of the grid: pixels `x0..x1` by `y0..y1`.
#[doc(hidden)]
pub struct Tile {
    pub x0: u32,
    pub y0: u32,
    pub x1: u32,
    pub y1: u32,
}

impl Tile {
    /// Columns of the tile's rectangle in every buffer, from `x0`: its pixels rounded up to
    /// whole groups, which is what its kernels address. `x1 - x0` is a multiple of `GROUP`
    /// except at the viewport's right edge, where the rounding reaches into the padding.
    pub fn group_columns(&self) -> u32 {
        row_stride(self.x1 - self.x0)
    }
}

/// The frame's buffers as the tile tasks write them: raw pointers taken from one `&mut`
/// borrow of the frame (`'f`), held by no one else while the tiles render.
///
/// Invariant that makes the parallel writes sound: the task of tile `t` reads and writes
/// only `t`'s rectangle of each buffer, rows `y0..y1` and columns `x0..x0 +
/// group_columns()`; the tile grid cuts the padded frame into disjoint such rectangles
/// (`x0` is a multiple of the tile side, itself a multiple of `GROUP`; only the rightmost
/// tiles are rounded up, into padding no other tile has), so no element is touched by two
/// tasks, and no `&mut` slice of a buffer exists while the tiles render. Every rectangle
/// lies inside its buffer: `(y1 - 1) * stride + x0 + group_columns() <= height * stride`.
#[derive(Clone, Copy)]
pub(crate) struct FrameTarget<'f> {
    pub(crate) depth: *mut u32,
    pub(crate) planes: *mut f32,
    /// Null when writes are not counted.
    pub(crate) counts: *mut u32,
    pub(crate) stride: usize,
    /// Elements from one plane's start to the next ([`plane_pitch`]).
    pub(crate) plane_pitch: usize,
    pub(crate) num_planes: usize,
    /// Where in each pixel the kernels evaluate for these buffers (`TileCtx::sample_x`,
    /// `sample_y`): the frame's sample position ([`Frame::sample`]).
    pub(crate) sample: [f32; 2],
    _frame: std::marker::PhantomData<&'f mut Frame>,
}

// SAFETY: the pointers are only dereferenced by tile tasks, each within its own tile's
// rectangle (the invariant above), while the `&mut Frame` they come from is borrowed.
unsafe impl Send for FrameTarget<'_> {}
// SAFETY: as above: sharing the target between tasks shares no element.
unsafe impl Sync for FrameTarget<'_> {}

impl FrameTarget<'_> {
    /// Zero `tile`'s rectangle of every buffer: what the tile's draws start from.
    ///
    /// # Safety
    /// The caller is the task that owns `tile` (see the type's invariant).
    pub(super) unsafe fn clear(&self, tile: &Tile) {
        let cols = tile.group_columns() as usize;
        for y in tile.y0 as usize..tile.y1 as usize {
            let at = y * self.stride + tile.x0 as usize;
            // SAFETY: `at .. at + cols` is one row of the tile's rectangle, inside every
            // buffer and owned by this task; all-zero bytes are 0 and +0.0.
            unsafe {
                std::ptr::write_bytes(self.depth.add(at), 0, cols);
                if !self.counts.is_null() {
                    std::ptr::write_bytes(self.counts.add(at), 0, cols);
                }
                for p in 0..self.num_planes {
                    std::ptr::write_bytes(self.planes.add(p * self.plane_pitch + at), 0, cols);
                }
            }
        }
    }
}

impl Frame {
    /// A 0 x 0 frame with no buffers: the start of [`Renderer::render_into`]'s first frame.
    pub fn empty() -> Frame {
        Frame {
            width: 0,
            height: 0,
            background: [0.0; 3],
            params: vec![],
            stride: 0,
            num_planes: 0,
            depth: vec![],
            planes: vec![],
            write_counts: None,
            colors: None,
            sample: [0.5; 2],
            samples: vec![],
            resolved: None,
        }
    }

    /// Shape the frame for a render with `opts` and `num_planes` planes, keeping the buffers
    /// it already has (room enough: nothing allocated). Contents are left as they are: the
    /// tile tasks zero and write every tile's part, padding included.
    #[doc(hidden)]
    pub fn reset(&mut self, opts: &RenderOptions, num_planes: u32, params: impl Iterator<Item = ParamPlanes>) {
        self.sample = [0.5; 2];
        self.resolved = None;
        self.width = opts.width;
        self.height = opts.height;
        self.stride = row_stride(opts.width);
        self.num_planes = num_planes;
        self.background = opts.background;
        let plane_len = self.plane_len();
        self.depth = fit(std::mem::take(&mut self.depth), plane_len, 0);
        self.planes = fit(
            std::mem::take(&mut self.planes),
            plane_pitch(plane_len) * num_planes as usize,
            0.0,
        );
        if opts.count_writes {
            self.write_counts = Some(fit(self.write_counts.take().unwrap_or_default(), plane_len, 0));
        } else {
            self.write_counts = None;
        }
        self.params.clear();
        self.params.extend(params);
    }

    /// Elements of one buffer (and of each plane): `stride * height`.
    fn plane_len(&self) -> usize {
        self.stride as usize * self.height as usize
    }

    /// The frame's buffers for the tile tasks (see [`FrameTarget`]), borrowing the frame
    /// until the tiles are done.
    pub(crate) fn target(&mut self) -> FrameTarget<'_> {
        FrameTarget {
            depth: self.depth.as_mut_ptr(),
            planes: self.planes.as_mut_ptr(),
            counts: self
                .write_counts
                .as_mut()
                .map_or(std::ptr::null_mut(), |c| c.as_mut_ptr()),
            stride: self.stride as usize,
            plane_pitch: plane_pitch(self.plane_len()),
            num_planes: self.num_planes as usize,
            sample: self.sample,
            _frame: std::marker::PhantomData,
        }
    }

    /// Where pixel (x, y) is in every buffer and plane: `y * stride + x`, `None` outside the
    /// viewport. Every read of a pixel goes through here.
    fn index(&self, x: u32, y: u32) -> Option<usize> {
        (x < self.width && y < self.height).then(|| y as usize * self.stride as usize + x as usize)
    }

    /// Elements `index(0, y) .. index(0, y) + width` of a buffer: row `y`'s pixels.
    fn row<T>(&self, buf: &'_ [T], y: u32) -> Option<std::ops::Range<usize>> {
        let start = self.index(0, y)?;
        let end = start + self.width as usize;
        (end <= buf.len()).then_some(start..end)
    }

    /// Row `y` of `buf`, a per-pixel buffer of the frame (`None` past its end).
    fn row_of<'b, T>(&self, buf: &'b [T], y: usize) -> Option<&'b [T]> {
        let y = u32::try_from(y).ok()?;
        self.row(buf, y).map(|r| &buf[r])
    }

    /// Row `y` of plane `plane`, or `missing` (a row of zeros, as an unwritten plane holds)
    /// for a plane the frame lacks.
    fn plane_row<'b>(&'b self, plane: u32, y: usize, missing: &'b [f32]) -> &'b [f32] {
        self.plane(plane).and_then(|p| self.row_of(p, y)).unwrap_or(missing)
    }

    /// An RGB image of the frame's size, row `y`'s pixels (3 bytes each) written by
    /// `fill_row(y, row)`.
    fn rgb8_image(&self, mut fill_row: impl FnMut(usize, &mut [u8])) -> RgbImage {
        let (width, height) = (self.width as usize, self.height as usize);
        let mut rgb = vec![0u8; width * height * 3];
        // (`max(1)`: a frame without columns has no rows to fill either.)
        for (y, row) in rgb.chunks_exact_mut((width * 3).max(1)).enumerate() {
            fill_row(y, row);
        }
        RgbImage::from_raw(self.width, self.height, rgb).expect("3 bytes per pixel")
    }

    /// Plane `plane`'s elements (`None` for a plane the frame does not have).
    fn plane(&self, plane: u32) -> Option<&[f32]> {
        let len = self.plane_len();
        let start = plane as usize * plane_pitch(len);
        (plane < self.num_planes).then(|| self.planes.get(start..start + len))?
    }

    /// `buf`'s pixels (not its padding) in row-major order, `width * height` of them.
    fn values<T: Copy>(&self, buf: &[T]) -> Vec<T> {
        (0..self.height)
            .filter_map(|y| self.row(buf, y))
            .flat_map(|r| buf[r].iter().copied())
            .collect()
    }

    /// Shading-parameter planes the frame holds.
    pub fn num_planes(&self) -> u32 {
        self.num_planes
    }

    /// Row stride of the buffers, in pixels: [`row_stride`]`(width)`.
    pub fn stride(&self) -> u32 {
        self.stride
    }

    /// The depth buffer as the kernels wrote it: `stride * height` elements, pixel (x, y) at
    /// `y * stride + x`, the padding columns unspecified.
    pub fn depth_buffer(&self) -> &[u32] {
        &self.depth
    }

    /// Raw depth (`fixed<32,32>`, larger is nearer, 0 = nothing written).
    pub fn depth_at(&self, x: u32, y: u32) -> Option<u32> {
        self.index(x, y).and_then(|i| self.depth.get(i).copied())
    }

    /// Depth as a float in [0, 1).
    pub fn depth_f32_at(&self, x: u32, y: u32) -> Option<f32> {
        self.depth_at(x, y).map(|d| (f64::from(d) / 4294967296.0) as f32)
    }

    /// The colours of the language shading pass: planes `first..first + 3` at every pixel
    /// whose depth was written, 0 elsewhere (padding included).
    /// A shaded colour with a NaN or infinite channel becomes [`NON_FINITE_COLOR`]; returns
    /// how many did.
    pub(crate) fn colors_from_planes(&mut self, first: u32) -> usize {
        let len = self.plane_len();
        let mut colors = fit(self.colors.take().unwrap_or_default(), len, [0.0; 3]);
        let planes: Vec<Option<&[f32]>> = (0..3).map(|c| self.plane(first + c)).collect();
        let mut non_finite = 0;
        for (i, c) in colors.iter_mut().enumerate() {
            let written = self.depth.get(i).is_some_and(|&d| d != 0);
            *c = std::array::from_fn(|k| match planes[k] {
                Some(p) if written => p.get(i).copied().unwrap_or(0.0),
                _ => 0.0,
            });
            if c.iter().any(|v| !v.is_finite()) {
                *c = NON_FINITE_COLOR;
                non_finite += 1;
            }
        }
        self.colors = Some(colors);
        non_finite
    }

    /// Whether a primitive wrote the pixel's depth.
    pub fn written(&self, x: u32, y: u32) -> bool {
        self.depth_at(x, y).is_some_and(|d| d != 0)
    }

    pub fn plane_at(&self, plane: u32, x: u32, y: u32) -> Option<f32> {
        let i = self.index(x, y)?;
        self.plane(plane)?.get(i).copied()
    }

    /// Every pixel's raw depth, row-major, `width * height` values.
    pub fn depth_values(&self) -> Vec<u32> {
        self.values(&self.depth)
    }

    /// Every pixel's value of plane `plane`, row-major (`None` for a plane the frame does
    /// not have).
    pub fn plane_values(&self, plane: u32) -> Option<Vec<f32>> {
        self.plane(plane).map(|p| self.values(p))
    }

    /// Every plane's [`Frame::plane_values`], in plane order.
    pub fn all_plane_values(&self) -> Vec<Vec<f32>> {
        (0..self.num_planes).filter_map(|p| self.plane_values(p)).collect()
    }

    /// Every pixel's depth-write count, row-major (when rendered with `count_writes`).
    pub fn write_count_values(&self) -> Option<Vec<u32>> {
        self.write_counts.as_ref().map(|c| self.values(c))
    }

    /// Every pixel's shaded colour before clamping, row-major (when the shading pass ran).
    pub fn color_values(&self) -> Option<Vec<[f32; 3]>> {
        self.colors.as_ref().map(|c| self.values(c))
    }

    /// Whether the deferred shading pass ran (the scene turned an effect on).
    pub fn is_shaded(&self) -> bool {
        self.colors.is_some()
    }

    /// Pixels whose depth was written.
    pub fn covered_pixels(&self) -> usize {
        (0..self.height)
            .filter_map(|y| self.row(&self.depth, y))
            .map(|r| self.depth[r].iter().filter(|&&d| d != 0).count())
            .sum()
    }

    /// Whether `self` and `other` have the same size and samples and bit for bit the same
    /// depth and shading-parameter planes at every pixel of every sample (write counts and
    /// colours not compared).
    pub fn same_buffers(&self, other: &Frame) -> bool {
        let bits = |v: Vec<f32>| v.into_iter().map(f32::to_bits).collect::<Vec<_>>();
        let same = |a: &Frame, b: &Frame| {
            (a.width, a.height, a.num_planes, a.sample) == (b.width, b.height, b.num_planes, b.sample)
                && a.depth_values() == b.depth_values()
                && (0..a.num_planes).all(|p| a.plane_values(p).map(bits) == b.plane_values(p).map(bits))
        };
        self.samples.len() == other.samples.len()
            && same(self, other)
            && self.samples.iter().zip(&other.samples).all(|(a, b)| same(a, b))
    }

    /// Samples per pixel (1 without multisampling).
    pub fn sample_count(&self) -> usize {
        1 + self.samples.len()
    }

    /// Sample `s`'s buffers: the frame itself for sample 0 (what `depth_at`, `param_at` and
    /// the other accessors of a multisampled frame read), `None` past the last sample.
    pub fn sample(&self, s: usize) -> Option<&Frame> {
        match s {
            0 => Some(self),
            s => self.samples.get(s - 1),
        }
    }

    /// Where in its pixels this frame's own buffers were evaluated (from the top-left corner).
    pub fn sample_position(&self) -> [f32; 2] {
        self.sample
    }

    /// Every pixel's coverage: the fraction of its samples whose depth was written,
    /// row-major, `width * height` values (0 or 1 without multisampling).
    pub fn coverage_values(&self) -> Vec<f32> {
        let n = self.sample_count() as f32;
        let mut covered = vec![0u32; self.width as usize * self.height as usize];
        for s in std::iter::once(self).chain(&self.samples) {
            for (c, d) in covered.iter_mut().zip(s.depth_values()) {
                *c += u32::from(d != 0);
            }
        }
        covered.into_iter().map(|c| c as f32 / n).collect()
    }

    /// The frames of samples `1..n`, shaped like this one will be for a render of `n`
    /// samples at `positions` (sample 0's position set on this frame): taken out of the
    /// frame for the render (`put_samples` hands them back), their buffers reused.
    pub(crate) fn take_samples(&mut self, positions: &[[f32; 2]]) -> Vec<Frame> {
        let mut rest = std::mem::take(&mut self.samples);
        rest.resize_with(positions.len().saturating_sub(1), Frame::empty);
        rest
    }

    /// Shape this frame as `reset` does, then set where its buffers are evaluated.
    pub(crate) fn reset_sample(
        &mut self,
        opts: &RenderOptions,
        num_planes: u32,
        params: impl Iterator<Item = ParamPlanes>,
        sample: [f32; 2],
    ) {
        self.reset(opts, num_planes, params);
        self.samples.clear();
        self.sample = sample;
    }

    /// Hand back the sample frames `take_samples` took, and resolve the pixels' colours
    /// from all the samples with `filter` ([`super::samples::resolve`]); `rest` empty: a
    /// single-sample frame, nothing resolved.
    pub(crate) fn put_samples(&mut self, rest: Vec<Frame>, filter: Filter) {
        self.samples = rest;
        if self.samples.is_empty() {
            self.resolved = None;
            return;
        }
        let positions: Vec<[f32; 2]> = std::iter::once(&*self).chain(&self.samples).map(|f| f.sample).collect();
        let colors: Vec<Vec<[f32; 3]>> = std::iter::once(&*self)
            .chain(&self.samples)
            .collect::<Vec<_>>()
            .par_iter()
            .map(|f| f.display_colors())
            .collect();
        self.resolved = Some(super::samples::resolve(
            &colors,
            &positions,
            filter,
            self.width,
            self.height,
        ));
    }

    /// This frame's own colours (sample 0's in a multisampled frame), clamped, row-major:
    /// [`Frame::color_at`]'s rule, row by row from the buffers' rows (per pixel through
    /// `color_at` a 512 x 512 sample took 8 ms).
    fn display_colors(&self) -> Vec<[f32; 3]> {
        let width = self.width as usize;
        let (zeros, ones) = (vec![0.0f32; width], vec![1.0f32; width]);
        let mut out = vec![self.background.map(clamp01); width * self.height as usize];
        for (y, row) in out.chunks_exact_mut(width.max(1)).enumerate() {
            let Some(depth) = self.row_of(&self.depth, y) else {
                continue;
            };
            let colors = self.row_colors(y, &zeros, &ones);
            for (x, (px, &d)) in row.iter_mut().zip(depth).enumerate() {
                if d != 0 {
                    let c = match colors {
                        RowColors::Shaded(c) => c[x],
                        RowColors::Planes([r, g, b]) => [r[x], g[x], b[x]],
                    };
                    *px = c.map(clamp01);
                }
            }
        }
        out
    }

    pub fn param(&self, name: &str) -> Option<&ParamPlanes> {
        self.params.iter().find(|p| p.name == name)
    }

    /// The error for `name`, a shading parameter the frame does not have, with a "did you
    /// mean" for a close one it has.
    pub fn no_param_message(&self, name: &str) -> String {
        let message = format!("the scene has no shading parameter `{name}`");
        match crate::diag::did_you_mean(name, self.params.iter().map(|p| p.name.as_str())) {
            Some(help) => format!("{message}: {help}"),
            None => message,
        }
    }

    /// A shading parameter's components at a pixel.
    pub fn param_at(&self, name: &str, x: u32, y: u32) -> Option<Vec<f32>> {
        let p = self.param(name)?;
        (p.first_plane..p.first_plane + p.components)
            .map(|plane| self.plane_at(plane, x, y))
            .collect()
    }

    /// Depth writes at a pixel (only when the frame was rendered with `count_writes`).
    pub fn write_count_at(&self, x: u32, y: u32) -> Option<u32> {
        let i = self.index(x, y)?;
        self.write_counts.as_ref()?.get(i).copied()
    }

    /// The shaded colour: where depth was written, `Cs` clamped to [0, 1] (a 1-component
    /// `Cs` is gray; with no usable `Cs` the pixel is white, OpenGL's default current colour);
    /// elsewhere the background.
    pub fn color_at(&self, x: u32, y: u32) -> [f32; 3] {
        if let Some(resolved) = &self.resolved {
            if x < self.width && y < self.height {
                return resolved[y as usize * self.width as usize + x as usize];
            }
            return self.background.map(clamp01);
        }
        self.sample_color_at(x, y)
    }

    /// This frame's own colour at (x, y) (sample 0's in a multisampled frame), as
    /// [`Frame::color_at`] describes it.
    fn sample_color_at(&self, x: u32, y: u32) -> [f32; 3] {
        if !self.written(x, y) {
            return self.background.map(clamp01);
        }
        if let Some(c) = self.shaded_at(x, y) {
            return c.map(clamp01);
        }
        let Some(cs) = self.param("Cs") else {
            return [1.0; 3];
        };
        let c = |k: u32| clamp01(self.plane_at(cs.first_plane + k, x, y).unwrap_or(0.0));
        match cs.components {
            1 => [c(0); 3],
            n if n >= 3 => [c(0), c(1), c(2)],
            _ => [1.0; 3],
        }
    }

    /// The shaded colour before clamping (tests compare lighting spaces with it).
    pub fn shaded_at(&self, x: u32, y: u32) -> Option<[f32; 3]> {
        let i = self.index(x, y)?;
        self.colors.as_ref()?.get(i).copied()
    }

    /// Run `shader` over every written pixel into `colors` (resized to the frame; its old
    /// contents do not matter); unwritten pixels get zero. Bands of [`SHADE_BAND_ROWS`] rows
    /// are shaded in parallel (each pixel's colour depends on that pixel's inputs alone, so
    /// the result is the same for any thread count). The fast kernels write every pixel of
    /// a row (zero where nothing was drawn; no clear of the whole buffer first), reading each
    /// row's planes as contiguous slices ([`RowInputs`]) in one fused pass; the f64
    /// reference takes the written pixels one by one.
    pub(super) fn shade(&self, shader: &Shader, texture_param: Option<&str>, colors: &mut Vec<[f32; 3]>) {
        *colors = fit(std::mem::take(colors), self.plane_len(), [0.0; 3]);
        let (width, stride) = (self.width as usize, self.stride as usize);
        if width == 0 || self.height == 0 {
            return;
        }
        if shader.kernel() == ShadingKernel::ReferenceF64 {
            self.shade_reference(shader, texture_param, colors);
            return;
        }
        let get = |name: &str| self.param(name).cloned();
        let cs = get("Cs").filter(|p| p.components == 1 || p.components >= 3);
        // Read only what the frame's effects need.
        let effects = shader.effects();
        let normal = get(super::api::NORMAL_PARAM).filter(|p| effects.lit && p.components == 3);
        let facing = get(super::api::FACING_PARAM).filter(|_| effects.lit);
        let st = texture_param
            .and_then(get)
            .filter(|p| effects.texture && p.components >= 2);
        // Row `y` of a parameter's component `k` (a plane the frame lacks reads as zeros,
        // as an unwritten plane would; `reset` makes every parameter's planes exist).
        let zeros = vec![0.0f32; width];
        let plane = |p: &ParamPlanes, k: u32, y: usize| self.plane_row(p.first_plane + k, y, &zeros);
        colors
            .par_chunks_mut(stride * SHADE_BAND_ROWS)
            .enumerate()
            .for_each(|(band, band_colors)| {
                for (i, row_colors) in band_colors.chunks_mut(stride).enumerate() {
                    // `shade_row` writes the row's pixels; the padding is zeroed too, so
                    // frames compare equal whatever the buffer held.
                    row_colors[width..].fill([0.0; 3]);
                    let y = band * SHADE_BAND_ROWS + i;
                    let at = y * stride;
                    let row = RowInputs {
                        y: y as u32,
                        depth: &self.depth[at..at + width],
                        cs: cs.as_ref().map(|p| {
                            let k = |c: u32| if p.components == 1 { 0 } else { c };
                            [plane(p, k(0), y), plane(p, k(1), y), plane(p, k(2), y)]
                        }),
                        normal: normal
                            .as_ref()
                            .map(|p| [plane(p, 0, y), plane(p, 1, y), plane(p, 2, y)]),
                        facing: facing.as_ref().map(|p| plane(p, 0, y)),
                        st: st.as_ref().map(|p| [plane(p, 0, y), plane(p, 1, y)]),
                    };
                    shader.shade_row(&row, &mut row_colors[..width]);
                }
            });
    }

    /// The f64 reference pass ([`ShadingKernel::ReferenceF64`]): one [`PixelInputs`] per
    /// written pixel, shaded by [`Shader::shade`].
    fn shade_reference(&self, shader: &Shader, texture_param: Option<&str>, colors: &mut [[f32; 3]]) {
        let get = |name: &str| self.param(name).cloned();
        let (cs, normal, facing) = (get("Cs"), get(super::api::NORMAL_PARAM), get(super::api::FACING_PARAM));
        let st = texture_param.and_then(get);
        let (width, stride) = (self.width as usize, self.stride as usize);
        colors.par_chunks_mut(stride).enumerate().for_each(|(y, row)| {
            // Unwritten pixels (and the padding) are zero (the buffer may hold an earlier
            // frame's colours).
            row.fill([0.0; 3]);
            // Per row: bounded memory for the inputs.
            let mut inputs = Vec::with_capacity(width);
            let mut slots = Vec::with_capacity(width);
            for x in 0..width {
                let (x, y) = (x as u32, y as u32);
                let depth = self.depth_at(x, y).unwrap_or(0);
                if depth == 0 {
                    continue;
                }
                let plane = |p: &ParamPlanes, k: u32| f64::from(self.plane_at(p.first_plane + k, x, y).unwrap_or(0.0));
                let cs = match &cs {
                    Some(p) if p.components >= 3 => [plane(p, 0), plane(p, 1), plane(p, 2)],
                    Some(p) if p.components == 1 => [plane(p, 0); 3],
                    _ => [1.0; 3],
                };
                inputs.push(PixelInputs {
                    x,
                    y,
                    depth: f64::from(depth) / 4294967296.0,
                    cs,
                    normal: normal
                        .as_ref()
                        .filter(|p| p.components == 3)
                        .map(|p| [plane(p, 0), plane(p, 1), plane(p, 2)]),
                    facing: facing.as_ref().map(|p| {
                        if plane(p, 0) < 0.0 {
                            crate::pipeline::face::Facing::Back
                        } else {
                            crate::pipeline::face::Facing::Front
                        }
                    }),
                    st: st
                        .as_ref()
                        .filter(|p| p.components >= 2)
                        .map(|p| [plane(p, 0), plane(p, 1)]),
                });
                slots.push(x as usize);
            }
            let mut out = vec![[0f32; 3]; inputs.len()];
            shader.shade(&inputs, &mut out);
            for (x, c) in slots.into_iter().zip(out) {
                row[x] = c;
            }
        });
    }

    /// [`Frame::color_at`] at every pixel, rounded to 8 bits: row by row over the buffers
    /// (whole frames, as `reset` and `shade` make them), each row's colour source converted
    /// to bytes in one vectorisable pass, then picked per pixel by its depth. Per pixel
    /// through `color_at` it was ~8 ns a pixel on drawn pixels (16 ms for 1920 x 1080).
    pub fn to_rgb8(&self) -> RgbImage {
        if let Some(resolved) = &self.resolved {
            let width = self.width as usize;
            return self.rgb8_image(|y, out| to_u8_row(resolved[y * width..][..width].as_flattened(), out));
        }
        let width = self.width as usize;
        let background = self.background.map(to_u8);
        let (zeros, ones) = (vec![0.0f32; width], vec![1.0f32; width]);
        // A row's colours as bytes: interleaved when shaded, else the r, g and b rows.
        let mut bytes = vec![0u8; width * 3];
        self.rgb8_image(|y, out| {
            let pixels = out.chunks_exact_mut(3);
            let Some(depth) = self.row_of(&self.depth, y) else {
                pixels.for_each(|px| px.copy_from_slice(&background));
                return;
            };
            // Each pixel its colour where a primitive wrote it, else the background.
            let put = |colors: &mut dyn Iterator<Item = [u8; 3]>| {
                for ((px, &d), c) in pixels.zip(depth).zip(colors) {
                    let written = d != 0;
                    px[0] = if written { c[0] } else { background[0] };
                    px[1] = if written { c[1] } else { background[1] };
                    px[2] = if written { c[2] } else { background[2] };
                }
            };
            match self.row_colors(y, &zeros, &ones) {
                RowColors::Shaded(colors) => {
                    to_u8_row(colors.as_flattened(), &mut bytes);
                    put(&mut bytes.chunks_exact(3).map(|c| [c[0], c[1], c[2]]));
                }
                RowColors::Planes(rgb) => {
                    let [r, g, b] = rows_to_u8(rgb, &mut bytes);
                    put(&mut r.iter().zip(g).zip(b).map(|((&r, &g), &b)| [r, g, b]));
                }
            }
        })
    }

    /// Where row `y`'s colours come from for a pixel whose depth was written
    /// ([`Frame::color_at`]'s rule, unclamped): the shading pass's colours when it ran, else
    /// `Cs`'s r, g and b plane rows (one plane three times for a 1-component `Cs`; `zeros`
    /// for a plane the frame lacks, as `plane_at` reads it; `ones`, white, without a `Cs`
    /// of 1 or 3+ components). `zeros` and `ones` are a row long.
    fn row_colors<'b>(&'b self, y: usize, zeros: &'b [f32], ones: &'b [f32]) -> RowColors<'b> {
        if let Some(colors) = self.colors.as_ref().and_then(|c| self.row_of(c, y)) {
            return RowColors::Shaded(colors);
        }
        let cs = self.param("Cs").filter(|cs| cs.components == 1 || cs.components >= 3);
        RowColors::Planes([0, 1, 2].map(|k| match cs {
            None => ones,
            Some(cs) => self.plane_row(cs.first_plane + if cs.components == 1 { 0 } else { k }, y, zeros),
        }))
    }

    /// Depth as 16-bit gray, nearer brighter (the top 16 bits of the raw depth).
    pub fn depth_image(&self) -> ImageBuffer<Luma<u16>, Vec<u16>> {
        // Row by row, as `to_rgb8`: a row past the depth buffer's end reads 0.
        let (width, height) = (self.width as usize, self.height as usize);
        let mut gray = vec![0u16; width * height];
        for (y, out) in gray.chunks_exact_mut(width.max(1)).enumerate() {
            if let Some(row) = self.row_of(&self.depth, y) {
                for (o, &d) in out.iter_mut().zip(row) {
                    *o = (d >> 16) as u16;
                }
            }
        }
        ImageBuffer::from_raw(self.width, self.height, gray).expect("one u16 per pixel")
    }

    /// A shading parameter as an image: 1 component as gray normalised to its range over the
    /// written pixels (unwritten pixels black), 3 components as RGB clamped to [0, 1].
    pub fn param_image(&self, name: &str) -> Result<RgbImage, String> {
        let p = self.param(name).ok_or_else(|| self.no_param_message(name))?;
        if p.components != 1 && p.components != 3 {
            return Err(format!(
                "shading parameter `{name}` has {} components; only 1 (gray) or 3 (RGB) can be written as an image",
                p.components
            ));
        }
        // Row by row over whole buffers, as `to_rgb8`; a plane the frame lacks reads 0.
        let width = self.width as usize;
        let zeros = vec![0.0f32; width];
        let row_of = |k: u32, y: usize| self.plane_row(p.first_plane + k, y, &zeros);
        if p.components == 3 {
            let mut bytes = vec![0u8; width * 3];
            return Ok(self.rgb8_image(|y, out| {
                let [r, g, b] = rows_to_u8([row_of(0, y), row_of(1, y), row_of(2, y)], &mut bytes);
                for (px, ((&r, &g), &b)) in out.chunks_exact_mut(3).zip(r.iter().zip(g).zip(b)) {
                    px.copy_from_slice(&[r, g, b]);
                }
            }));
        }
        // Gray over the range of the written, finite values; others black.
        let value = |d: u32, v: f32| (d != 0 && v.is_finite()).then_some(v);
        let values = |y: usize| {
            let depth = self.row_of(&self.depth, y).unwrap_or(&[]);
            depth.iter().zip(row_of(0, y)).map(move |(&d, &v)| value(d, v))
        };
        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
        for v in (0..self.height as usize).flat_map(values).flatten() {
            lo = lo.min(v);
            hi = hi.max(v);
        }
        Ok(self.rgb8_image(|y, out| {
            let mut values = values(y);
            for px in out.chunks_exact_mut(3) {
                let g = match values.next().flatten() {
                    None => 0.0,
                    Some(v) if hi > lo => (v - lo) / (hi - lo),
                    Some(_) => 0.5,
                };
                px.fill(to_u8(g));
            }
        }))
    }
}

/// `buf` at `len` elements, reusing its memory when it has room. A buffer too small is
/// replaced by `vec![zero; len]` rather than grown: for zero that is the allocator's untouched
/// zero pages (no serial clearing pass; the parallel tile tasks touch them first), where
/// `resize` would write every element here, serially.
/// A row's colours, as [`Frame::row_colors`] finds them.
#[derive(Clone, Copy)]
enum RowColors<'b> {
    /// The shading pass's, interleaved.
    Shaded(&'b [[f32; 3]]),
    /// `Cs`'s r, g and b rows.
    Planes([&'b [f32]; 3]),
}

fn fit<T: Clone>(mut buf: Vec<T>, len: usize, zero: T) -> Vec<T> {
    if buf.capacity() < len {
        return vec![zero; len];
    }
    buf.resize(len, zero);
    buf
}

fn clamp01(v: f32) -> f32 {
    if v.is_nan() {
        0.0
    } else {
        v.clamp(0.0, 1.0)
    }
}

/// `(clamp01(v) * 255).round()` (half away from zero) without a libm `roundf` call per
/// component, and without branches (so [`to_u8_row`] vectorises): `max`/`min` send NaN to 0
/// as `clamp01` does, and for `x` in [0, 255] `x - trunc(x)` is exact (checked for every
/// f32 in [0, 1] when written; `to_u8_rounds_half_away_from_zero` tests the ties and their
/// neighbours).
#[allow(clippy::manual_clamp)] // `clamp` keeps NaN
#[doc(hidden)]
pub fn to_u8(v: f32) -> u8 {
    let x = v.max(0.0).min(1.0) * 255.0;
    // SAFETY: `x` is finite and in [0, 255], so it truncates to an i32 exactly.
    let whole = unsafe { x.to_int_unchecked::<i32>() };
    (whole + i32::from(x - whole as f32 >= 0.5)) as u8
}

/// [`to_u8`] of each of `src` into `dst` (as many as the shorter has).
fn to_u8_row(src: &[f32], dst: &mut [u8]) {
    for (d, &v) in dst.iter_mut().zip(src) {
        *d = to_u8(v);
    }
}

/// Three rows of one width as bytes, in the thirds of `bytes`.
fn rows_to_u8<'b>(rows: [&[f32]; 3], bytes: &'b mut [u8]) -> [&'b [u8]; 3] {
    let width = bytes.len() / 3;
    let (r, rest) = bytes.split_at_mut(width);
    let (g, b) = rest.split_at_mut(width);
    to_u8_row(rows[0], r);
    to_u8_row(rows[1], g);
    to_u8_row(rows[2], b);
    [r, g, b]
}
