//! A frame's language shading evaluated by the IR evaluator (`ir::eval`) instead of its
//! kernels: the f64 reference `primflow accuracy`'s shading knob measures the f32 kernels
//! against, and, at f32, a second computation of the kernels' own bits.
//!
//! It shades what the kernels shaded: the frame's depth and planes after the render, in
//! one evaluator tile of the whole viewport (in the quad order of `super::quads` when the
//! frame shades on quads, with the pixel centres in the two planes after the outputs), each
//! binding's linked `__shade` run on it with the argument block its kernel ran with, and
//! each group given the pixel fuel a kernel's group gets. The result is the `Ci` planes, as
//! the kernels leave them before `Frame::colors_from_planes` (no clamping, NaN kept).
//!
//! Invariants: the frame must be the last one the compiled shading ran on (its planes are
//! numbered for it); nothing here panics (a program the evaluator refuses is an `Err`).

use crate::abi::GROUP;
use crate::ir::eval::{Budget, Evaluator, Precision, Tile};
use crate::runtime::frame::Frame;
use crate::runtime::RenderOptions;

use super::language::CompiledShading;

/// Per pixel, row-major from the top-left, `width * height`: the shaded `Ci` (0 where no
/// depth was written).
pub type Colours = Vec<[f32; 3]>;

impl CompiledShading {
    /// Evaluate the frame's shading over `frame` at `precision`: `F32` gives the kernels'
    /// bits, `F64` the reference (see the module doc).
    pub fn evaluate(&self, frame: &Frame, opts: &RenderOptions, precision: Precision) -> Result<Colours, String> {
        let runs = &self.pass;
        let (w, h) = (frame.width as usize, frame.height as usize);
        let inputs = runs.out_plane as usize + 3;
        let quads = runs.quads;
        // The element of pixel (x, y) in the evaluator's tile, and the tile's shape.
        let (stride, rows) = if quads {
            (4 * w.div_ceil(2), h.div_ceil(2))
        } else {
            (w.div_ceil(GROUP as usize) * GROUP as usize, h)
        };
        let element = |x: usize, y: usize| {
            if quads {
                (y / 2) * stride + 4 * (x / 2) + 2 * (y % 2) + (x % 2)
            } else {
                y * stride + x
            }
        };
        let planes = inputs + if quads { 2 } else { 0 };
        let mut tile = Tile::new(0, 0, stride, rows, planes, stride as u32, rows as u32);
        if !quads {
            // A tile as wide as the padded row; the viewport is the frame's.
            tile.x1 = w as i32;
            tile.width = frame.width;
            tile.height = frame.height;
        }
        let n = tile.plane_stride;
        for y in 0..h {
            for x in 0..w {
                let (fx, fy) = (x as u32, y as u32);
                let at = element(x, y);
                tile.depth[at] = frame.depth_at(fx, fy).unwrap_or(0);
                for p in 0..runs.out_plane as usize {
                    tile.planes[p * n + at] = frame.plane_at(p as u32, fx, fy).unwrap_or(0.0);
                }
                if quads {
                    tile.planes[inputs * n + at] = x as f32 + 0.5;
                    tile.planes[(inputs + 1) * n + at] = y as f32 + 0.5;
                }
            }
        }
        // Each group's pixel fuel as a kernel's: the viewport's share, on quads scaled to
        // the quad tile (`quads::QuadTile::context`).
        let viewport_groups = (frame.width.div_ceil(GROUP) as u64 * frame.height as u64).max(1);
        let groups = (stride / GROUP as usize * rows).max(1) as u64;
        let budget = Budget {
            setup_fuel: opts.setup_fuel,
            pixel_fuel: if quads {
                (opts.pixel_fuel / viewport_groups).saturating_mul(groups)
            } else {
                opts.pixel_fuel
            },
            group_fuel_floor: opts.group_fuel_floor,
        };
        let key = super::language::out_key();
        for (program, (_, args)) in runs.programs.iter().zip(&runs.runs) {
            let func = program.find(crate::link::SHADE).ok_or("no linked shading primitive")?;
            Evaluator::with_precision(program, true, precision)
                .run(func, &key, args, &mut tile, budget)
                .map_err(|e| e.to_string())?;
        }
        let out = runs.out_plane as usize;
        Ok((0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .map(|(x, y)| {
                let at = element(x, y);
                if tile.depth[at] == 0 {
                    return [0.0; 3];
                }
                std::array::from_fn(|c| tile.planes[(out + c) * n + at])
            })
            .collect())
    }
}
