//! The layout language shading runs on when a shader of the frame takes screen-space
//! derivatives: each 4-lane pixel group is a 2x2 quad of the tile (lanes 0, 1 the upper row,
//! 2, 3 the lower one), so `Dx` and `Dy` are differences between lanes (`jit::derivative`).
//!
//! Kernels address groups as 4 consecutive elements of a row, so the tile's buffers are
//! gathered into a *quad tile* where they are: pixel (x, y) of the tile is element
//! `(y / 2) * stride + 4 * (x / 2) + 2 * (y % 2) + (x % 2)`, `stride = 4 * ceil(w / 2)`, over
//! `ceil(h / 2)` rows. Past the frame's planes come two more, each pixel's sample position x and y
//! in screen pixels (its centre in a single-sample frame) (what `__shade` reads instead of its own `X` and `Y`, `crate::link`). After
//! the kernels, the output planes are scattered back.
//!
//! Invariants: the quads start at the tile's corner, and tiles start at multiples of the
//! tile side (a multiple of `GROUP`, so even): a pixel's quad is the same in every tiling.
//! An element with no pixel (a ragged right or bottom edge) has depth 0, so no kernel
//! shades it. The quad tile's kernels get the same pixel fuel per group as a kernel over the
//! whole viewport would, so what they compute does not depend on the tile size.

use crate::abi::{TileCtx, GROUP};
use crate::runtime::frame::{FrameTarget, Tile};

/// A tile's buffers in quad order (see the module doc).
pub(crate) struct QuadTile {
    width: usize,
    height: usize,
    stride: usize,
    rows: usize,
    depth: Vec<u32>,
    /// The frame's planes, then the sample's x and y.
    planes: Vec<f32>,
    counts: Vec<u32>,
    frame_planes: usize,
}

impl QuadTile {
    /// Gather `tile` of `target`.
    ///
    /// # Safety
    /// The caller is the task that owns `tile` (`FrameTarget`'s invariant).
    pub(crate) unsafe fn gather(tile: &Tile, target: &FrameTarget<'_>) -> QuadTile {
        let width = (tile.x1 - tile.x0) as usize;
        let height = (tile.y1 - tile.y0) as usize;
        let stride = 4 * width.div_ceil(2);
        let rows = height.div_ceil(2);
        let n = stride * rows;
        let frame_planes = target.num_planes;
        let mut q = QuadTile {
            width,
            height,
            stride,
            rows,
            depth: vec![0; n],
            planes: vec![0.0; (frame_planes + 2) * n],
            counts: vec![0; n],
            frame_planes,
        };
        for y in 0..height {
            let row = (tile.y0 as usize + y) * target.stride + tile.x0 as usize;
            for x in 0..width {
                let at = q.element(x, y);
                // SAFETY: (x, y) is a pixel of the tile, inside every buffer and owned by
                // the caller.
                unsafe {
                    q.depth[at] = *target.depth.add(row + x);
                    for p in 0..frame_planes {
                        q.planes[p * n + at] = *target.planes.add(p * target.plane_pitch + row + x);
                    }
                }
                q.planes[frame_planes * n + at] = (tile.x0 as usize + x) as f32 + target.sample[0];
                q.planes[(frame_planes + 1) * n + at] = (tile.y0 as usize + y) as f32 + target.sample[1];
            }
        }
        q
    }

    fn element(&self, x: usize, y: usize) -> usize {
        (y / 2) * self.stride + 4 * (x / 2) + 2 * (y % 2) + (x % 2)
    }

    /// `ctx` (the tile's context) turned into the quad tile's: a tile of its own at the
    /// origin of a viewport its size, its pixel fuel scaled so that every group gets what a
    /// group of `ctx`'s viewport would.
    pub(crate) fn context(&mut self, ctx: TileCtx) -> TileCtx {
        let viewport_groups = (ctx.width.div_ceil(GROUP) as u64 * ctx.height as u64).max(1);
        let groups = (self.stride / GROUP as usize * self.rows).max(1) as u64;
        let n = self.stride * self.rows;
        TileCtx {
            x0: 0,
            y0: 0,
            x1: self.stride as i32,
            y1: self.rows as i32,
            width: self.stride as u32,
            height: self.rows as u32,
            stride: self.stride as u32,
            depth: self.depth.as_mut_ptr(),
            gbuf: self.planes.as_mut_ptr(),
            plane_stride: n as u32,
            num_planes: (self.frame_planes + 2) as u32,
            write_count: self.counts.as_mut_ptr(),
            pixel_fuel: (ctx.pixel_fuel / viewport_groups).saturating_mul(groups),
            ..ctx
        }
    }

    /// Write `planes` (frame plane indices) back into `tile` of `target`.
    ///
    /// # Safety
    /// As [`QuadTile::gather`], for the same tile and target.
    pub(crate) unsafe fn scatter(&self, tile: &Tile, target: &FrameTarget<'_>, planes: std::ops::Range<usize>) {
        let n = self.stride * self.rows;
        for y in 0..self.height {
            let row = (tile.y0 as usize + y) * target.stride + tile.x0 as usize;
            for x in 0..self.width {
                let at = self.element(x, y);
                for p in planes.clone().filter(|&p| p < self.frame_planes) {
                    // SAFETY: as in `gather`.
                    unsafe { *target.planes.add(p * target.plane_pitch + row + x) = self.planes[p * n + at] };
                }
            }
        }
    }
}
