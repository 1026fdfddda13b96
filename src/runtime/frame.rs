//! Rendering a frame: compile, bound, bin, render tiles in parallel, shade, write images.
//!
//! 1. Every (primitive, key) the instances need is compiled once through the [`KernelSource`],
//!    in first-use order. The renderer interns each instance's key as the instance is added,
//!    so a frame finds an instance's kernel by index (no key compared, hashed or cloned per
//!    instance).
//! 2. Instances become *draws*: an instance of a primitive that only calls primitives
//!    (`abi::expands`) runs once in `MODE_EXPAND` and is replaced by the calls it makes, in
//!    call order ([`super::expand`]; off with `RenderOptions::expand_calls`); any other
//!    instance is one draw. Each draw's kernel runs once in `MODE_BOUND` on an empty tile
//!    with no buffers (instances expand and bound in parallel, draws are binned afterwards
//!    in submission order); its recorded screen bound (conservative) bins it into the tiles
//!    it overlaps. A NaN bound, or no bound at all, puts it in no tile. The bins are one flat
//!    list of draw copies grouped by tile (a counting sort, in parallel chunks of instances),
//!    so a tile task reads its draws front to back and prefetches a coming draw's arguments
//!    while a kernel runs.
//! 3. Tiles render in parallel with rayon, one job per tile (so that the tiles spread evenly
//!    over the threads), straight into the frame: the frame's buffers (depth u32 with 0 =
//!    farthest, G-buffer planes f32 in one buffer, write counts) have a row stride of whole
//!    pixel groups ([`row_stride`]), tiles start on group boundaries (the tile side is
//!    rounded up to whole groups), and a tile's kernels get a context whose buffer pointers
//!    point into the frame at the tile's origin, with the frame's row and plane strides. A
//!    tile task first zeroes its own rectangle of every buffer (cache-hot for its draws),
//!    then runs its draws in order in `MODE_RENDER` with fresh fuel each; a tile no draw
//!    touches is zeroed only. Tiles are disjoint, including the padding columns the rightmost
//!    tiles' last groups reach into, so tasks write disjoint memory (`FrameTarget`). Every
//!    pixel is computed by one tile from the same zeroed start whatever the schedule, so the
//!    result is bit-identical whatever the number of threads, no serial pass gathers the
//!    tiles, and the frame's earlier contents never matter: [`Renderer::render_into`] reuses
//!    a caller's [`Frame`] (no allocation, no page faults on fresh buffers) and
//!    [`Renderer::render`] is it on an empty frame.
//! 4. Kernel run-time errors become warnings at the failing site of the primitive source,
//!    once per (site, error), in tile order.
//!
//! With a kernel source that upgrades its kernels in the background (a tiered JIT,
//! `KernelSource::tier_up`), the frame holds that compiler from before step 1 until a grace
//! period after it (in proportion to the step's compile time), and from then on, while a
//! compile is running, step 2's jobs and step 3's tiles run on one thread fewer than the
//! pool has (`super::tiergate`): a short frame keeps every core, a long one gets the
//! faster kernels sooner. Which thread runs a job never changes what it computes, so the
//! frame is the same bit for bit; `RenderStats::gated_jobs` counts the jobs run that way.
//!
//! Then the deferred shading pass ([`super::shading`]) when the scene turns an effect on,
//! bands of rows in parallel. Without one, a pixel whose depth was written (depth != 0; a write of
//! exactly the far value 0 is indistinguishable from none, and a `Z > depth` test never
//! passes there anyway) shows the `Cs` shading parameter clamped to [0, 1] (white without
//! one, as OpenGL's default colour), other pixels the background.

use std::collections::BTreeSet;
use std::sync::Arc;
use std::time::Instant;

use image::{ImageBuffer, Luma, RgbImage};
use rayon::prelude::*;

use crate::abi::{Kernel, TileCtx, VariantKey, ERR_CALL_DEPTH, ERR_FUEL, ERR_INDEX, ERR_STACK, GROUP, MODE_RENDER};
use crate::diag::{Diagnostic, Diagnostics};
use crate::ir::{FuncId, Program};

use super::api::{Instance, RenderOptions, Renderer, MAX_FRAME_BYTES, MAX_IMAGE_SIDE, MAX_TILE_SIDE};
use super::expand::{expand_instance, Budget, Draw, Expanded, TileRect};
use super::kernels::KernelSource;
use super::shading::{Effects, PixelInputs, RowInputs, Shader, ShadingKernel, ShadingSpaces};
use super::tiergate::{self, Compiler, GateStats};

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
/// writes: 2.7x the frame time at K = 16 (docs/performance.md, `k16`). An odd line count
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
    depth: Vec<u32>,
    /// `num_planes` planes of `stride * height`, [`plane_pitch`] elements apart.
    planes: Vec<f32>,
    write_counts: Option<Vec<u32>>,
    /// The deferred shading pass's colours, `stride * height` (`None` when the scene turns
    /// no effect on and covered pixels show `Cs`).
    colors: Option<Vec<[f32; 3]>>,
}

/// What a render measured.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RenderStats {
    pub instances: usize,
    pub kernels_compiled: usize,
    /// The kernels' own compile times (`Kernel::compile_micros`, callees excluded), summed
    /// over the frame's variants: a kernel a source had compiled for an earlier frame counts
    /// its compile again.
    pub compile_micros: u64,
    pub render_micros: u64,
    /// Of `render_micros`: compiling (or looking up) kernels, the bound pass and binning
    /// (serial).
    pub setup_micros: u64,
    /// Of `setup_micros`: getting the frame's kernels from the source, wall time (compiling
    /// the ones it has not compiled yet, their callees included; else only looking them up).
    pub kernels_micros: u64,
    /// Of `render_micros`: shaping the frame (allocating only buffers it has no room for)
    /// and rendering the tiles into it (parallel).
    pub tiles_micros: u64,
    /// Of `render_micros`: the deferred shading pass (0 when the scene turns no effect on).
    pub shade_micros: u64,
    /// Draw-tile pairs rendered (a draw — an instance, or a call an expanded instance made —
    /// counts once per tile it was binned into).
    pub tile_invocations: usize,
    /// Instances replaced by the calls they make (`RenderOptions::expand_calls`).
    pub expanded_instances: usize,
    /// Draws those instances produced.
    pub expanded_calls: usize,
    /// Instances whose expansion exceeded `RenderOptions::expand_budget_words` (rendered
    /// per tile instead).
    pub expand_over_budget: usize,
    /// Jobs of the expansion and bound pass (up to `BOUND_JOB` instances each), of the
    /// binning (its chunks, when it has more than one) and tiles started while the kernel
    /// source's background compiler had a compile pending, on one thread fewer than the pool
    /// has (`super::tiergate`; 0 for a source without one, a one-thread pool, or once the
    /// compile has landed).
    pub gated_jobs: usize,
    /// Most threads that ran those jobs at once (at most the pool's threads less one).
    pub gated_peak_threads: usize,
}

/// A render's frame, statistics and diagnostics (compile failures are errors, kernel warnings
/// and run-time errors warnings).
pub struct RenderOutput {
    pub frame: Frame,
    pub stats: RenderStats,
    pub diags: Diagnostics,
    /// Every kernel variant compiled for the frame, in first-use order.
    pub kernels: Vec<KernelReport>,
    /// The effects the shading pass was compiled for.
    pub effects: Effects,
}

/// What [`Renderer::render_into`] returns besides the frame it filled: the same as a
/// [`RenderOutput`] without the frame.
pub struct RenderReport {
    pub stats: RenderStats,
    pub diags: Diagnostics,
    /// Every kernel variant compiled for the frame, in first-use order.
    pub kernels: Vec<KernelReport>,
    /// The effects the shading pass was compiled for.
    pub effects: Effects,
}

/// One compiled kernel variant (`render --explain`).
#[derive(Clone, Debug, PartialEq)]
pub struct KernelReport {
    pub primitive: String,
    pub key: String,
    pub trivial_accept: bool,
    pub compile_micros: u64,
}

struct Tile {
    x0: u32,
    y0: u32,
    x1: u32,
    y1: u32,
}

impl Tile {
    /// Columns of the tile's rectangle in every buffer, from `x0`: its pixels rounded up to
    /// whole groups, which is what its kernels address. `x1 - x0` is a multiple of `GROUP`
    /// except at the viewport's right edge, where the rounding reaches into the padding.
    fn group_columns(&self) -> u32 {
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
struct FrameTarget<'f> {
    depth: *mut u32,
    planes: *mut f32,
    /// Null when writes are not counted.
    counts: *mut u32,
    stride: usize,
    /// Elements from one plane's start to the next ([`plane_pitch`]).
    plane_pitch: usize,
    num_planes: usize,
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
    unsafe fn clear(&self, tile: &Tile) {
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

impl Renderer {
    /// Render every instance submitted so far into a new [`Frame`]. Uses the current rayon
    /// thread pool: wrap the call in `ThreadPool::install` on a
    /// [`render_pool`](super::render_pool), whose threads each keep to a core (a plain pool's
    /// threads, woken after an idle gap, may share one core for the whole frame).
    /// Equivalent to [`Renderer::render_into`] on [`Frame::empty`].
    pub fn render(&self, source: &mut dyn KernelSource) -> RenderOutput {
        let mut frame = Frame::empty();
        let RenderReport {
            stats,
            diags,
            kernels,
            effects,
        } = self.render_into(source, &mut frame);
        RenderOutput {
            frame,
            stats,
            diags,
            kernels,
            effects,
        }
    }

    /// Render every instance submitted so far into `frame`, reusing its buffers: an
    /// application that renders frame after frame into the same `Frame` pays for no
    /// allocation, no page fault and no clearing of the whole frame (every tile zeroes its
    /// own part of the frame right before its draws render into it). Whatever `frame` held before (another size, other planes, colours), the result
    /// is bit for bit the frame [`Renderer::render`] returns.
    pub fn render_into(&self, source: &mut dyn KernelSource, frame: &mut Frame) -> RenderReport {
        let started = Instant::now();
        // The options are public fields: clamp them here so that no setting can panic or
        // overflow the frame size (the setters already reject these values).
        let opts = &RenderOptions {
            width: self.options.width.min(MAX_IMAGE_SIDE),
            height: self.options.height.min(MAX_IMAGE_SIDE),
            tile_size: tile_side(self.options.tile_size),
            ..self.options.clone()
        };
        let program = self.program().clone();
        let mut diags = Diagnostics::new();
        let mut stats = RenderStats {
            instances: self.instances().len(),
            ..RenderStats::default()
        };
        // Refused before any work: a frame this large would abort the process when its
        // allocation fails.
        let num_planes = self.num_planes();
        let frame_bytes = frame_bytes(opts, num_planes);
        if frame_bytes > MAX_FRAME_BYTES {
            diags.push(Diagnostic::error(
                "E0803",
                format!(
                    "a {}x{} frame with {num_planes} shading-parameter planes needs {:.1} GiB, more than the {} GiB a frame may take; nothing is rendered",
                    opts.width,
                    opts.height,
                    frame_bytes as f64 / (1u64 << 30) as f64,
                    MAX_FRAME_BYTES >> 30
                ),
            ));
            *frame = Frame::empty();
            stats.render_micros = started.elapsed().as_micros() as u64;
            return RenderReport {
                stats,
                diags,
                kernels: vec![],
                effects: self.shading_setup.effects(),
            };
        }

        // A background compiler (a tiered JIT's tier 1) starts nothing before the frame has
        // run for a grace period (`tiergate`): a short frame keeps every core, a long one
        // gets tier-1 code soon after. Taken before the compiles, which queue its work.
        let compiler = source.tier_up();
        let mut held_compiler = compiler.as_ref().map(|w| w.hold());

        // 1. Compile each (func, key) once, in first-use order.
        let (variants, variant_of) = self.variants();
        let mut reports: Vec<KernelReport> = vec![];
        let kernels: Vec<Option<Arc<Kernel>>> = variants
            .iter()
            .map(|(func, key)| {
                let key = VariantKey {
                    count_writes: opts.count_writes,
                    ..key.clone()
                };
                let kernel = compile_one(&program, source, *func, &key, &mut diags);
                if let Some(k) = &kernel {
                    stats.kernels_compiled += 1;
                    stats.compile_micros += k.compile_micros;
                    reports.push(KernelReport {
                        primitive: program.func(*func).name.clone(),
                        key: describe_key(&key),
                        trivial_accept: key.trivial_accept,
                        compile_micros: k.compile_micros,
                    });
                }
                kernel
            })
            .collect();
        let compiled = Instant::now();
        stats.kernels_micros = micros_between(started, compiled);
        if let (Some(hold), Some(watch)) = (&mut held_compiler, &compiler) {
            hold.release_at(compiled + watch.grace(compiled.duration_since(started)));
        }
        // Never hand a kernel an argument block shorter than its layout reads.
        let ready: Vec<Option<&Kernel>> = self
            .instances()
            .iter()
            .zip(variant_of)
            .map(|(inst, &v)| {
                kernels[v]
                    .as_deref()
                    .filter(|k| k.layout.words(inst.n_seq) <= inst.args.len())
            })
            .collect();

        // 2. Expansion and bound pass in parallel: an instance that only calls primitives is
        // replaced by the calls it makes (see `expand`), and every draw is bound and its bound
        // turned into the tiles it overlaps. Then binning, in instance order.
        let tiles = tile_grid(opts);
        let tiles_x = opts.width.div_ceil(opts.tile_size) as usize;
        let mut errors: Vec<(usize, u32, u32)> = vec![];
        let instances = self.instances();
        let budget = Budget::new(opts.expand_budget_words);
        // While the source's background compiler (a tiered JIT's tier 1) has a compile
        // pending, the parallel passes leave it a core (`tiergate`); checked per pass.
        let compiler = compiler.as_ref().map(|w| w as &dyn Compiler);
        let expand_one = |i: usize| -> Option<Expanded> {
            if let Some(next) = instances.get(i + 1) {
                prefetch(&next.args);
            }
            let kernel = ready[i]?;
            let tiles_of = |bound| tiles_overlapped(bound, opts);
            Some(expand_instance(
                &program,
                opts,
                &budget,
                &instances[i],
                kernel,
                compiler,
                tiles_of,
            ))
        };
        let (expanded, gated) = tiergate::run_items(compiler, instances.len(), BOUND_JOB, expand_one);
        stats.add_gated(gated);
        drop(ready);
        let mut draws = 0;
        for (i, e) in expanded.iter().enumerate() {
            let Some(e) = e else { continue };
            draws += e.len();
            stats.expanded_instances += usize::from(e.expanded());
            stats.expanded_calls += if e.expanded() { e.len() } else { 0 };
            stats.expand_over_budget += usize::from(e.over_budget());
            errors.extend(e.errors().iter().map(|&(code, site)| (i, code, site)));
        }
        // A few chunks per thread, so that a thread slowed by other work is helped out.
        let chunks = match rayon::current_num_threads() {
            1 => 1,
            n => 4 * n,
        };
        let ranges = chunk_ranges(&expanded, draws, chunks, tiles.len());
        let (bins, gated) = Bins::new(&expanded, instances, tiles.len(), tiles_x, &ranges, compiler);
        gated.into_iter().for_each(|g| stats.add_gated(g));
        stats.tile_invocations = bins.draws.len();
        let tiles_started = Instant::now();
        stats.setup_micros = micros_between(started, tiles_started);

        // 3. Tiles in parallel, each rendering into its own part of the frame; errors kept in
        // tile order.
        frame.reset(
            opts,
            num_planes,
            self.shading_params().iter().map(|p| ParamPlanes {
                name: p.name.clone(),
                first_plane: p.first_plane,
                components: p.components,
            }),
        );
        let target = frame.target();
        let slices = bins.slices();
        let (tile_errors, gated) = tiergate::run_items(compiler, tiles.len(), 1, |t| {
            // SAFETY: each tile index is run once (`tiles` holds each tile once), and
            // `target` is the frame reset for this grid.
            unsafe { render_tile(&tiles[t], slices[t], opts, target) }
        });
        stats.add_gated(gated);
        errors.extend(tile_errors.into_iter().flatten());
        // The hold ends with the frame but keeps its deadline (`TierUpHold`'s drop): a
        // worker let go right here would compete with the caller's thread waking up.
        drop(held_compiler);

        let shade_started = Instant::now();
        stats.tiles_micros = micros_between(tiles_started, shade_started);

        // Deferred shading over the visible pixels, compiled for the scene's effects.
        let effects = self.shading_setup.effects();
        let spaces = ShadingSpaces {
            device_from_lighting: self.geometry.device_from_lighting(),
            lighting_from_world: self.geometry.lighting_from_world(),
            device_from_clip: self.geometry.device_from_clip(),
        };
        // The previous frame's colour buffer (if any) is reused; without an effect there is
        // none.
        let colors = frame.colors.take();
        if let Some(shader) = Shader::new(&self.shading_setup, &spaces) {
            let mut buf = colors.unwrap_or_default();
            frame.shade(
                &shader,
                self.shading_setup.texture.as_ref().map(|t| t.param.as_str()),
                &mut buf,
            );
            frame.colors = Some(buf);
        }
        stats.shade_micros = shade_started.elapsed().as_micros() as u64;

        // 4. Run-time errors, once per (site, code), in a thread-independent order.
        report_runtime_errors(&program, &errors, instances, &mut diags);
        stats.render_micros = started.elapsed().as_micros() as u64;
        RenderReport {
            stats,
            diags,
            kernels: reports,
            effects,
        }
    }
}

impl RenderStats {
    fn add_gated(&mut self, gated: GateStats) {
        self.gated_jobs += gated.gated_jobs;
        self.gated_peak_threads = self.gated_peak_threads.max(gated.peak_threads);
    }
}

/// Bytes of a frame for `opts` with `num_planes` planes (see [`MAX_FRAME_BYTES`]): depth,
/// write counts when counted, colours, and the planes [`plane_pitch`] apart.
fn frame_bytes(opts: &RenderOptions, num_planes: u32) -> u64 {
    let len = u64::from(row_stride(opts.width)) * u64::from(opts.height);
    let per_pixel = 4 + 12 + if opts.count_writes { 4 } else { 0 };
    len * per_pixel + plane_pitch(len as usize) as u64 * u64::from(num_planes) * 4
}

/// Most instances one job of the parallel expansion and bound pass takes: small enough that
/// the jobs spread evenly over the threads (one preempted thread does not hold back the
/// frame with a large part of the pass), large enough that scheduling them costs nothing
/// next to the bound runs (a small triangle's takes well under a microsecond).
const BOUND_JOB: usize = 512;

fn micros_between(from: Instant, to: Instant) -> u64 {
    to.duration_since(from).as_micros() as u64
}

fn compile_one(
    program: &Program,
    source: &mut dyn KernelSource,
    func: FuncId,
    key: &VariantKey,
    diags: &mut Diagnostics,
) -> Option<Arc<Kernel>> {
    let name = &program.func(func).name;
    match source.kernel(func, key) {
        Ok(kernel) => {
            let expected = crate::abi::ArgLayout::new(program, func, key);
            if kernel.layout != expected {
                diags.push(Diagnostic::error(
                    "E0802",
                    format!("the kernel for `{name}` disagrees with the argument layout; its instances are skipped"),
                ));
                return None;
            }
            for w in &kernel.warnings {
                // Kernel warnings already name their primitive.
                diags.push(Diagnostic::warning("W0802", w.clone()));
            }
            Some(kernel)
        }
        Err(e) => {
            diags.push(Diagnostic::error(
                "E0801",
                format!("cannot compile `{name}` for {}: {e}", describe_key(key)),
            ));
            None
        }
    }
}

/// `linear:3,constant:1` style description of a key (the CLI's `--key` syntax).
pub fn describe_key(key: &VariantKey) -> String {
    let parts: Vec<String> = key
        .bindings
        .iter()
        .map(|b| match &b.kind {
            crate::abi::BindingKind::Kind(k) => format!("{k}:{}", b.components),
            crate::abi::BindingKind::Shared(s) => format!("{s}:{}", b.components),
            crate::abi::BindingKind::Constant => format!("constant:{}", b.components),
        })
        .collect();
    let mut s = if parts.is_empty() {
        "no bindings".to_string()
    } else {
        parts.join(",")
    };
    if key.count_writes {
        s.push_str(" (counting writes)");
    }
    s
}

fn tile_grid(opts: &RenderOptions) -> Vec<Tile> {
    let ts = opts.tile_size;
    let mut tiles = vec![];
    for y0 in (0..opts.height).step_by(ts as usize) {
        for x0 in (0..opts.width).step_by(ts as usize) {
            tiles.push(Tile {
                x0,
                y0,
                x1: (x0 + ts).min(opts.width),
                y1: (y0 + ts).min(opts.height),
            });
        }
    }
    tiles
}

/// The tiles (inclusive tile-index rectangle) holding a pixel whose centre lies in a screen
/// bound, or `None`: exactly the tiles in which a kernel's render call runs a pixel
/// (`pass_range` in the JIT takes the same pixels). In f64 `x - 0.5` and its floor and ceil
/// are exact for every clamped f32 bound, so no margin is needed; a one-pixel margin each way
/// (until session 20) sent a 20-pixel triangle to 1.29 tiles on average where 1.2 hold a
/// pixel of it, each extra call paying the whole setup for no pixel.
fn tiles_overlapped(bound: [f32; 4], opts: &RenderOptions) -> Option<TileRect> {
    if bound.iter().any(|v| v.is_nan()) {
        return None;
    }
    let (w, h) = (f64::from(opts.width), f64::from(opts.height));
    // Clamp in float first: infinities and huge values must not overflow the conversion.
    let xmin = f64::from(bound[0]).clamp(-2.0, w + 2.0);
    let ymin = f64::from(bound[1]).clamp(-2.0, h + 2.0);
    let xmax = f64::from(bound[2]).clamp(-2.0, w + 2.0);
    let ymax = f64::from(bound[3]).clamp(-2.0, h + 2.0);
    let px0 = ceil_clamped(xmin - 0.5).max(0);
    let py0 = ceil_clamped(ymin - 0.5).max(0);
    let px1 = floor_clamped(xmax - 0.5).min(i64::from(opts.width) - 1);
    let py1 = floor_clamped(ymax - 0.5).min(i64::from(opts.height) - 1);
    if px0 > px1 || py0 > py1 {
        return None;
    }
    let ts = i64::from(opts.tile_size);
    Some((
        (px0 / ts) as usize,
        (py0 / ts) as usize,
        (px1 / ts) as usize,
        (py1 / ts) as usize,
    ))
}

/// `x.floor() as i64` for a finite `x` well inside the i64 range (a clamped screen
/// coordinate), without the libm call `floor` is on targets without SSE4.1: truncate, then
/// step down when that rounded a negative fraction up.
fn floor_clamped(x: f64) -> i64 {
    let t = x as i64;
    t - i64::from((t as f64) > x)
}

/// `x.ceil() as i64` under the same conditions as [`floor_clamped`].
fn ceil_clamped(x: f64) -> i64 {
    let t = x as i64;
    t + i64::from((t as f64) < x)
}

/// Every tile's draws, in submission order, as one flat list: tile `t`'s draws are
/// `draws[start[t]..start[t + 1]]`, copied there so that a tile task reads its draws
/// front to back (a counting sort of the draws by the tiles they overlap: two passes, no
/// per-tile vector).
///
/// Both passes run in parallel over chunks of consecutive instances: each chunk counts its
/// draws per tile, the counts give every (tile, chunk) pair its own run of slots (chunks in
/// instance order within a tile), and each chunk then fills its runs. The result is the
/// serial sort's, slot for slot, whatever the number of chunks. (Serial, binning was 5 ms of
/// the 200 000-triangle `small` frame's 13 ms setup on two threads.)
struct Bins<'a> {
    start: Vec<usize>,
    draws: Vec<Draw<'a>>,
}

/// Fewest draws per chunk worth a parallel job of the binning.
const BIN_CHUNK_DRAWS: usize = 4096;

impl<'a> Bins<'a> {
    /// Bin every draw of `expanded` (instance `i`'s at index `i`, `None` for an instance
    /// without a usable kernel) into the tiles it overlaps, for a grid of `tiles` tiles,
    /// `tiles_x` per row, in up to `chunks` parallel chunks on the current pool (under the
    /// tier-up gate when `compiler` has a compile pending).
    fn new(
        expanded: &'a [Option<Expanded>],
        instances: &'a [Instance],
        tiles: usize,
        tiles_x: usize,
        ranges: &[std::ops::Range<usize>],
        compiler: Option<&dyn Compiler>,
    ) -> (Bins<'a>, [GateStats; 2]) {
        // Draw `d` of instance `i` in each tile of its rectangle, for the instances of `range`.
        let each = |range: std::ops::Range<usize>, visit: &mut dyn FnMut(usize, &'a Expanded, usize, usize)| {
            for (i, e) in expanded[range.clone()].iter().enumerate() {
                let Some(e) = e else { continue };
                for d in 0..e.len() {
                    let Some((tx0, ty0, tx1, ty1)) = e.tiles(d) else {
                        continue;
                    };
                    for ty in ty0..=ty1 {
                        for tx in tx0..=tx1 {
                            visit(ty * tiles_x + tx, e, d, range.start + i);
                        }
                    }
                }
            }
        };
        // One chunk runs on the calling thread: no jobs (and none counted as gated).
        let serial = ranges.len() == 1;
        let count = |c: usize| {
            let mut n = vec![0usize; tiles];
            each(ranges[c].clone(), &mut |t, _, _, _| n[t] += 1);
            n
        };
        let (counts, counted) = if serial {
            (vec![count(0)], GateStats::default())
        } else {
            tiergate::run_items(compiler, ranges.len(), 1, count)
        };
        let mut start = vec![0usize; tiles + 1];
        for t in 0..tiles {
            start[t + 1] = start[t] + counts.iter().map(|n| n[t]).sum::<usize>();
        }
        // Every slot is overwritten below (the counts are exact); the filler is never run.
        let mut draws = vec![Draw::NONE; start[tiles]];
        // Hand each chunk its run of slots in every tile: tile-major, chunks in order.
        let mut runs: Vec<Vec<&mut [Draw<'a>]>> = ranges.iter().map(|_| Vec::with_capacity(tiles)).collect();
        let mut rest: &mut [Draw<'a>] = &mut draws;
        for t in 0..tiles {
            for (c, n) in counts.iter().enumerate() {
                let (run, after) = std::mem::take(&mut rest).split_at_mut(n[t]);
                runs[c].push(run);
                rest = after;
            }
        }
        let runs: Vec<std::sync::Mutex<Vec<&mut [Draw<'a>]>>> = runs.into_iter().map(std::sync::Mutex::new).collect();
        let place = |c: usize| {
            // Each chunk's job is the only one to lock its runs.
            let mut runs = runs[c].lock().unwrap_or_else(|e| e.into_inner());
            let mut filled = vec![0usize; tiles];
            each(ranges[c].clone(), &mut |t, e, d, i| {
                runs[t][filled[t]] = e.draw(d, &instances[i], i);
                filled[t] += 1;
            });
        };
        let placed = if serial {
            place(0);
            GateStats::default()
        } else {
            tiergate::run_items(compiler, ranges.len(), 1, place).1
        };
        drop(runs);
        (Bins { start, draws }, [counted, placed])
    }

    /// Each tile's draws, in tile order.
    fn slices(&self) -> Vec<&[Draw<'a>]> {
        self.start.windows(2).map(|w| &self.draws[w[0]..w[1]]).collect()
    }
}

/// Up to `chunks` ranges of consecutive instances with about the same number of draws each
/// (`total` draws in all), covering every instance: at least [`BIN_CHUNK_DRAWS`] draws
/// apiece, and at least `tiles` (a chunk's per-tile counts and runs must not outweigh its
/// draws: a 16384-pixel frame of 4-pixel tiles has 16 M tiles). One range for a small frame.
fn chunk_ranges(
    expanded: &[Option<Expanded>],
    total: usize,
    chunks: usize,
    tiles: usize,
) -> Vec<std::ops::Range<usize>> {
    let chunks = chunks.min(total / BIN_CHUNK_DRAWS).min(total / tiles.max(1)).max(1);
    if chunks == 1 {
        return vec![0..expanded.len()];
    }
    let per_chunk = total.div_ceil(chunks).max(1);
    let mut ranges = vec![];
    let (mut first, mut draws) = (0, 0);
    for (i, e) in expanded.iter().enumerate() {
        draws += e.as_ref().map_or(0, Expanded::len);
        if draws >= per_chunk && ranges.len() + 1 < chunks {
            ranges.push(first..i + 1);
            (first, draws) = (i + 1, 0);
        }
    }
    if first < expanded.len() || ranges.is_empty() {
        ranges.push(first..expanded.len());
    }
    ranges
}

/// Zero `tile`'s part of the frame and render its draws into it; returns the tile's run-time
/// errors (instance, code, site) in order.
///
/// # Safety
/// `target` names the buffers of a frame reset for `opts`'s tile grid, `tile` is a tile of
/// that grid, and no other task renders `tile` meanwhile ([`FrameTarget`]'s invariant).
unsafe fn render_tile(
    tile: &Tile,
    bin: &[Draw],
    opts: &RenderOptions,
    target: FrameTarget<'_>,
) -> Vec<(usize, u32, u32)> {
    // Every tile starts from zeroed buffers, exactly as if freshly allocated; a tile no draw
    // touches is just that. Cleared here, right before the draws, the rectangle is in cache
    // when they run.
    // SAFETY: the caller's contract.
    unsafe { target.clear(tile) };
    if bin.is_empty() {
        return vec![];
    }
    let origin = tile.y0 as usize * target.stride + tile.x0 as usize;
    let mut errors = vec![];
    // Every draw starts from this context (a copy: a kernel may change any field of its
    // own, e.g. fuel, the error or the call depth). The buffer pointers are the frame's at
    // the tile's origin (`wrapping_add`: a frame without planes or counts has empty
    // buffers, and the kernel never dereferences those).
    let mut start = TileCtx::new(MODE_RENDER, opts.width, opts.height);
    start.x0 = tile.x0 as i32;
    start.y0 = tile.y0 as i32;
    start.x1 = tile.x1 as i32;
    start.y1 = tile.y1 as i32;
    start.stride = target.stride as u32;
    start.depth = target.depth.wrapping_add(origin);
    start.gbuf = target.planes.wrapping_add(origin);
    start.plane_stride = target.plane_pitch as u32;
    start.num_planes = target.num_planes as u32;
    start.write_count = target.counts.wrapping_add(origin);
    // Draw j + PREFETCH_AHEAD's arguments are asked for while draw j runs; draw 1's now.
    if let Some(second) = bin.get(1).filter(|_| PREFETCH_AHEAD > 1) {
        prefetch(second.args);
    }
    for (j, draw) in bin.iter().enumerate() {
        if let Some(ahead) = bin.get(j + PREFETCH_AHEAD) {
            prefetch(ahead.args);
        }
        let mut ctx = TileCtx {
            call_depth: draw.call_depth,
            ..start
        };
        // SAFETY: the context names the tile's rectangle of the frame's buffers, which this
        // task alone owns ([`FrameTarget`]): the kernel addresses `(y - y0) * stride + (x -
        // x0)` for y in `y0..y1` and x in whole groups from `x0` up to `x1`, i.e. inside the
        // rectangle, in the depth buffer, in each of the `num_planes` planes `plane_stride`
        // apart, and (only when compiled with count_writes == opts.count_writes, i.e. when
        // the frame has them) in the write counts. The argument block is long enough for the
        // kernel's layout (checked in `render_into` and when calls were recorded).
        unsafe { (draw.entry)(&mut ctx, draw.args.as_ptr()) };
        if ctx.error != 0 {
            errors.push((draw.instance, ctx.error, ctx.error_site));
        }
    }
    errors
}

/// How many draws ahead of the one running a tile asks for arguments ([`prefetch`]). One
/// draw ahead left part of the wait: a 20-pixel triangle's kernel is shorter than a load
/// that misses the caches and the TLB (the 200 000-triangle `small` frame's arguments span
/// 26 MB). Measured (a scratch probe, one thread, distances interleaved frame by frame,
/// medians of 15): tiles 64.5-64.7 ms one ahead, 60.5-61.4 ms two, three, four or six ahead;
/// the 20 000-triangle frame, whose arguments stay in the caches, the same at every distance.
const PREFETCH_AHEAD: usize = 2;

/// Ask the CPU to start loading the argument block a coming kernel will read: a tile's
/// draws come from anywhere in the submission, so their blocks are scattered in memory, and
/// the kernel running meanwhile hides the wait. Every line the block touches, up to four:
/// blocks are not line-aligned, and a K=4 screen triangle's ~130 bytes mostly span three
/// lines (with only the first two fetched, perf put ~15 % of small triangles' setup time on
/// the loads from the third). A hint only: it never faults and changes no value.
#[inline]
fn prefetch(args: &[u32]) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        let p = args.as_ptr().cast::<i8>();
        let lines = (p as usize % 64 + args.len() * 4).div_ceil(64);
        for line in 0..lines.min(4) {
            // SAFETY: prefetching is a hint that never faults, whatever the address; SSE (which
            // `prefetcht0` belongs to) is part of the x86_64 baseline.
            unsafe { _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(64 * line)) };
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = args;
}

fn report_runtime_errors(
    program: &Program,
    errors: &[(usize, u32, u32)],
    instances: &[Instance],
    diags: &mut Diagnostics,
) {
    let mut seen = BTreeSet::new();
    for &(i, code, site) in errors {
        if !seen.insert((site, code)) {
            continue;
        }
        let what = match code {
            ERR_INDEX => "an index was out of range (clamped)",
            ERR_FUEL => "a loop ran out of fuel (left early)",
            ERR_CALL_DEPTH => "primitive calls nested too deep (call skipped)",
            ERR_STACK => "its stack frame (local arrays) did not fit in the rendering thread's stack (not run)",
            _ => "an unknown run-time error",
        };
        let name = &program.func(instances[i].func).name;
        let mut d = Diagnostic::warning("W0801", format!("in `{name}` at run time: {what}"));
        // A stack error's site is the primitive whose frame did not fit (a caller's
        // instance may have called it).
        let span = match code {
            ERR_STACK => program.functions.get(site as usize).map(|f| f.span),
            _ => program.sites.get(site as usize).copied(),
        };
        if let Some(span) = span {
            d = d.primary(span, what);
        }
        diags.push(d);
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
        }
    }

    /// Shape the frame for a render with `opts` and `num_planes` planes, keeping the buffers
    /// it already has (room enough: nothing allocated). Contents are left as they are: the
    /// tile tasks zero and write every tile's part, padding included.
    fn reset(&mut self, opts: &RenderOptions, num_planes: u32, params: impl Iterator<Item = ParamPlanes>) {
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
    fn target(&mut self) -> FrameTarget<'_> {
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

    /// Whether `self` and `other` have the same size and bit for bit the same depth and
    /// shading-parameter planes at every pixel (write counts and colours not compared).
    pub fn same_buffers(&self, other: &Frame) -> bool {
        let bits = |v: Vec<f32>| v.into_iter().map(f32::to_bits).collect::<Vec<_>>();
        (self.width, self.height, self.num_planes) == (other.width, other.height, other.num_planes)
            && self.depth_values() == other.depth_values()
            && (0..self.num_planes).all(|p| self.plane_values(p).map(bits) == other.plane_values(p).map(bits))
    }

    pub fn param(&self, name: &str) -> Option<&ParamPlanes> {
        self.params.iter().find(|p| p.name == name)
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
    fn shade(&self, shader: &Shader, texture_param: Option<&str>, colors: &mut Vec<[f32; 3]>) {
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
        let width = self.width as usize;
        let background = self.background.map(to_u8);
        // Without shaded colours a pixel is Cs: 3 planes, or one as gray; a plane the frame
        // lacks reads 0 (as in `plane_at`); no Cs (or one of 2 components) is white.
        let cs = self.param("Cs").filter(|cs| cs.components == 1 || cs.components >= 3);
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
            if let Some(colors) = self.colors.as_ref().and_then(|c| self.row_of(c, y)) {
                to_u8_row(colors.as_flattened(), &mut bytes);
                put(&mut bytes.chunks_exact(3).map(|c| [c[0], c[1], c[2]]));
                return;
            }
            let plane_row = |k: u32| -> &[f32] {
                let Some(cs) = cs else { return &ones };
                let plane = cs.first_plane + if cs.components == 1 { 0 } else { k };
                self.plane_row(plane, y, &zeros)
            };
            let [r, g, b] = rows_to_u8([plane_row(0), plane_row(1), plane_row(2)], &mut bytes);
            put(&mut r.iter().zip(g).zip(b).map(|((&r, &g), &b)| [r, g, b]));
        })
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
        let p = self
            .param(name)
            .ok_or_else(|| format!("the scene has no shading parameter `{name}`"))?;
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
fn to_u8(v: f32) -> u8 {
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

#[cfg(test)]
mod tests {
    use super::*;

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

    fn opts(w: u32, h: u32, ts: u32) -> RenderOptions {
        RenderOptions {
            width: w,
            height: h,
            tile_size: ts,
            ..RenderOptions::default()
        }
    }

    #[test]
    fn strides_and_tile_sides_are_whole_groups() {
        assert_eq!(row_stride(64), 64);
        assert_eq!(row_stride(13), 16);
        assert_eq!(row_stride(1), 4);
        assert_eq!(row_stride(0), 0);
        assert_eq!(
            [0, 1, 4, 5, 16, 63, 4096, 5000].map(tile_side),
            [4, 4, 4, 8, 16, 64, 4096, 4096]
        );
    }

    /// Planes are whole lines apart, 17 lines modulo 64 (so plane `p` starts `17 p` cache
    /// sets after plane 0 in any power-of-two set count up to 64 sets per 4 KiB), with
    /// less than 64 lines of padding.
    #[test]
    fn plane_pitch_spreads_planes_over_cache_sets() {
        for len in [
            0usize,
            1,
            15,
            16,
            17,
            4096,
            64 * 64,
            500 * 500,
            512 * 512,
            520 * 517,
            16384 * 16384,
        ] {
            let pitch = plane_pitch(len);
            assert!(pitch >= len, "{len}");
            assert_eq!(pitch % 16, 0, "{len}");
            assert_eq!((pitch / 16) % 64, 17, "{len}");
            assert!(pitch - len < 64 * 16, "{len}");
            // The first 64 planes' starts fall in 64 different 4 KiB-cache sets.
            let mut sets: Vec<usize> = (0..64).map(|p| (p * pitch * 4 / 64) % 64).collect();
            sets.sort_unstable();
            sets.dedup();
            assert_eq!(sets.len(), 64, "{len}");
        }
        assert_eq!(plane_pitch(512 * 512), 512 * 512 + 17 * 16);
    }

    #[test]
    fn grid_cuts_edge_tiles() {
        let tiles = tile_grid(&opts(100, 70, 64));
        let rects: Vec<_> = tiles.iter().map(|t| (t.x0, t.y0, t.x1, t.y1)).collect();
        assert_eq!(
            rects,
            vec![(0, 0, 64, 64), (64, 0, 100, 64), (0, 64, 64, 70), (64, 64, 100, 70)]
        );
    }

    /// [`FrameTarget`]'s invariant: the tiles' rectangles (rows `y0..y1`, columns `x0 ..
    /// x0 + group_columns()`) start on groups, lie inside the padded buffer and cover each
    /// of its elements exactly once.
    #[test]
    fn tile_rectangles_cut_the_padded_frame_into_disjoint_groups() {
        for (w, h, requested) in [
            (100, 70, 64),
            (9, 7, 5),
            (64, 64, 64),
            (5, 3, 8),
            (37, 23, 16),
            (130, 67, 16),
            (1, 1, 1),
        ] {
            let o = opts(w, h, tile_side(requested));
            let stride = row_stride(w) as usize;
            let mut owners = vec![0u32; stride * h as usize];
            for tile in tile_grid(&o) {
                assert_eq!(tile.x0 % GROUP, 0, "{w}x{h}/{requested}");
                let cols = tile.group_columns() as usize;
                assert_eq!(cols % GROUP as usize, 0);
                for y in tile.y0 as usize..tile.y1 as usize {
                    let at = y * stride + tile.x0 as usize;
                    assert!(
                        at + cols <= owners.len(),
                        "{w}x{h}/{requested}: row {y} leaves the buffer"
                    );
                    // A group never straddles two rows.
                    assert!(tile.x0 as usize + cols <= stride);
                    owners[at..at + cols].iter_mut().for_each(|n| *n += 1);
                }
            }
            assert!(owners.iter().all(|&n| n == 1), "{w}x{h}/{requested}: {owners:?}");
        }
    }

    /// Against brute force: the tiles holding a pixel whose centre lies in the bound, for
    /// bounds on, just off and between pixel centres and tile edges.
    #[test]
    fn binning_takes_exactly_the_tiles_with_a_covered_centre() {
        for (w, h, ts) in [(40, 24, 8), (37, 23, 12), (41, 19, 4)] {
            tiles_with_a_covered_centre(&opts(w, h, ts));
        }
    }

    fn tiles_with_a_covered_centre(o: &RenderOptions) {
        let ts = o.tile_size;
        let mut edges: Vec<f32> = (-2..=44)
            .flat_map(|i| {
                let x = i as f32;
                [x, x + 0.5, x + 0.5 - 1e-4, x + 0.5 + 1e-4, x + 0.25]
            })
            .collect();
        edges.extend([f32::NEG_INFINITY, -1e30, 1e30, f32::INFINITY]);
        let mut seed = 7u32;
        let mut pick = || {
            seed = seed.wrapping_mul(1664525).wrapping_add(1013904223);
            edges[(seed >> 8) as usize % edges.len()]
        };
        for _ in 0..20_000 {
            let b = [pick(), pick() * 0.6, pick(), pick() * 0.6];
            let mut want: Option<TileRect> = None;
            for py in 0..o.height {
                for px in 0..o.width {
                    let (cx, cy) = (px as f32 + 0.5, py as f32 + 0.5);
                    if cx >= b[0] && cx <= b[2] && cy >= b[1] && cy <= b[3] {
                        let (tx, ty) = ((px / ts) as usize, (py / ts) as usize);
                        want = Some(match want {
                            None => (tx, ty, tx, ty),
                            Some((a, b, c, d)) => (a.min(tx), b.min(ty), c.max(tx), d.max(ty)),
                        });
                    }
                }
            }
            assert_eq!(tiles_overlapped(b, o), want, "bound {b:?} in {ts} px tiles");
        }
    }

    #[test]
    fn clamped_floor_and_ceil_match_the_library_ones() {
        let mut values = vec![-0.0, 0.0, -2.5, -2.0, -1.5, -1.0, -0.5, -1e-9, 1e-9, 0.5, 16386.5];
        // Every quarter pixel, and values just around integers, over a clamped range.
        for i in -12..=65_560 {
            let x = f64::from(i) / 4.0;
            values.extend([x, x - 1e-7, x + 1e-7]);
        }
        for x in values {
            assert_eq!(floor_clamped(x), x.floor() as i64, "floor {x}");
            assert_eq!(ceil_clamped(x), x.ceil() as i64, "ceil {x}");
        }
    }

    /// Binning in parallel chunks gives the serial counting sort's list, slot for slot:
    /// every tile's draws in submission order, whatever the chunks and threads.
    #[test]
    fn parallel_binning_matches_the_serial_order() {
        unsafe extern "C" fn kernel(_ctx: *mut TileCtx, _args: *const u32) {}
        let (tiles_x, tiles_y) = (5usize, 4usize);
        // 30 000 draws: rectangles of 1..=3 x 1..=2 tiles (some clipped to the grid), every
        // 7th without a tile, every 11th instance without a kernel.
        let mut seed = 12345u64;
        let mut next = |n: usize| {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 33) as usize % n
        };
        let instances: Vec<Instance> = (0..30_000u32)
            .map(|i| Instance {
                func: FuncId(0),
                key: VariantKey::default(),
                n_seq: 0,
                args: vec![i],
            })
            .collect();
        let expanded: Vec<Option<Expanded>> = (0..instances.len())
            .map(|i| {
                (i % 11 != 0).then(|| {
                    let (x0, y0) = (next(tiles_x), next(tiles_y));
                    let rect = (x0, y0, (x0 + next(3)).min(tiles_x - 1), (y0 + next(2)).min(tiles_y - 1));
                    Expanded::Itself {
                        entry: kernel,
                        tiles: (i % 7 != 0).then_some(rect),
                        error: None,
                        over_budget: false,
                    }
                })
            })
            .collect();
        let tiles = tiles_x * tiles_y;
        let key = |b: &Bins<'_>| {
            let draws: Vec<(usize, u32)> = b.draws.iter().map(|d| (d.instance, d.args[0])).collect();
            (b.start.clone(), draws)
        };
        let total: usize = expanded.iter().flatten().map(Expanded::len).sum();
        let (serial, _) = Bins::new(&expanded, &instances, tiles, tiles_x, &[0..instances.len()], None);
        let want = key(&serial);
        // Every tile's list is in instance order and names each draw's own arguments.
        for t in 0..tiles {
            let list = &want.1[want.0[t]..want.0[t + 1]];
            assert!(list.windows(2).all(|w| w[0].0 < w[1].0), "tile {t}");
            assert!(list.iter().all(|&(i, a)| i as u32 == a));
        }
        assert!(want.1.len() > 30_000, "draws span several tiles");
        let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
        for chunks in [2, 3, 5, 6] {
            let ranges = chunk_ranges(&expanded, total, chunks, tiles);
            assert!(ranges.len() == chunks, "{chunks} chunks used");
            let (parallel, _) = pool.install(|| Bins::new(&expanded, &instances, tiles, tiles_x, &ranges, None));
            assert!(key(&parallel) == want, "{chunks} chunks");
        }
    }

    #[test]
    fn chunk_ranges_cover_every_instance_in_order() {
        unsafe extern "C" fn kernel(_ctx: *mut TileCtx, _args: *const u32) {}
        let itself = || Expanded::Itself {
            entry: kernel,
            tiles: None,
            error: None,
            over_budget: false,
        };
        // (instances, chunks asked for, tiles, ranges): 4/5 of the instances have a draw.
        for (n, chunks, tiles, want) in [
            (0, 4, 64, 1),
            (10, 4, 64, 1),
            (5 * BIN_CHUNK_DRAWS, 8, 64, 4),
            (20_000, 2, 64, 2),
            // Far more tiles than draws: one range, not per-tile arrays per chunk.
            (100_000, 8, 1 << 24, 1),
            (100_000, 8, 30_000, 2),
        ] {
            let expanded: Vec<Option<Expanded>> = (0..n).map(|i| (i % 5 != 0).then(itself)).collect();
            let total: usize = expanded.iter().flatten().map(Expanded::len).sum();
            let ranges = chunk_ranges(&expanded, total, chunks, tiles);
            assert_eq!(ranges.len(), want, "{n} instances, {chunks} chunks, {tiles} tiles");
            assert_eq!(ranges.first().map(|r| r.start), Some(0));
            assert_eq!(ranges.last().map(|r| r.end), Some(n));
            assert!(ranges
                .windows(2)
                .all(|w| w[0].end == w[1].start && w[0].start < w[0].end));
        }
    }

    #[test]
    fn binning_is_conservative_and_clamped() {
        let o = opts(256, 128, 64);
        assert_eq!(tiles_overlapped([10.0, 10.0, 20.0, 20.0], &o), Some((0, 0, 0, 0)));
        // Pixel 64's centre is 64.5: a bound ending at 64 holds no pixel of tile 1, one
        // ending at 64.5 does (and one starting at 63.5 holds pixel 63 of tile 0).
        assert_eq!(tiles_overlapped([10.0, 10.0, 64.0, 20.0], &o), Some((0, 0, 0, 0)));
        assert_eq!(tiles_overlapped([10.0, 10.0, 64.5, 20.0], &o), Some((0, 0, 1, 0)));
        assert_eq!(tiles_overlapped([63.5, 10.0, 70.0, 20.0], &o), Some((0, 0, 1, 0)));
        assert_eq!(tiles_overlapped([63.51, 10.0, 70.0, 20.0], &o), Some((1, 0, 1, 0)));
        // A bound between two centres holds no pixel.
        assert_eq!(tiles_overlapped([10.6, 10.0, 11.4, 20.0], &o), None);
        assert_eq!(
            tiles_overlapped([f32::NEG_INFINITY, -1e30, f32::INFINITY, 1e30], &o),
            Some((0, 0, 3, 1))
        );
        assert_eq!(tiles_overlapped([f32::NAN, 0.0, 10.0, 10.0], &o), None);
        assert_eq!(tiles_overlapped([300.0, 0.0, 400.0, 10.0], &o), None);
        assert_eq!(tiles_overlapped([-50.0, -50.0, -10.0, -10.0], &o), None);
        // Inverted (empty) bound.
        assert_eq!(tiles_overlapped([50.0, 50.0, 10.0, 10.0], &o), None);
    }
}
