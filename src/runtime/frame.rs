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
//!    list of draw copies grouped by tile (a counting sort), so a tile task reads its draws
//!    front to back and prefetches the next draw's arguments while a kernel runs.
//! 3. Tiles render in parallel with rayon, one job per tile (so that the tiles spread evenly
//!    over the threads). A tile task renders into its thread's scratch buffers (depth u32
//!    with 0 = farthest, G-buffer planes f32, write counts; zeroed per tile, reused from tile
//!    to tile and frame to frame), running its draws in order in `MODE_RENDER` with fresh
//!    fuel each, then copies the tile into the frame through row slices it alone owns
//!    (tiles are disjoint); a tile no draw touches zeroes its part of the frame instead,
//!    which is what it would copy. Every pixel is computed by one tile from the same zeroed
//!    start whatever the schedule, so the result is bit-identical whatever the number of
//!    threads, no serial pass gathers the tiles, and the frame's earlier contents never
//!    matter: [`Renderer::render_into`] reuses a caller's [`Frame`] (no allocation, no page
//!    faults on fresh buffers) and [`Renderer::render`] is it on an empty frame.
//! 4. Kernel run-time errors become warnings at the failing site of the primitive source,
//!    once per (site, error), in tile order.
//!
//! Then the deferred shading pass ([`super::shading`]) when the scene turns an effect on,
//! bands of rows in parallel. Without one, a pixel whose depth was written (depth != 0; a write of
//! exactly the far value 0 is indistinguishable from none, and a `Z > depth` test never
//! passes there anyway) shows the `Cs` shading parameter clamped to [0, 1] (white without
//! one, as OpenGL's default colour), other pixels the background.

use std::collections::BTreeSet;
use std::sync::Arc;
use std::time::Instant;

use image::{ImageBuffer, Luma, Rgb, RgbImage};
use rayon::prelude::*;

use crate::abi::{TileCtx, VariantKey, ERR_CALL_DEPTH, ERR_FUEL, ERR_INDEX, GROUP, MODE_BOUND, MODE_RENDER};
use crate::diag::{Diagnostic, Diagnostics};
use crate::ir::{FuncId, Program};
use crate::jit::Kernel;

use super::api::{Instance, RenderOptions, Renderer, MAX_IMAGE_SIDE, MAX_TILE_SIDE};
use super::expand::{expand_instance, Budget, Draw, Expanded};
use super::kernels::KernelSource;
use super::shading::{Effects, PixelInputs, RowInputs, Shader, ShadingKernel, ShadingSpaces};

/// Rows per parallel task of the shading pass: enough work per task (~4k pixels at 512
/// wide) that rayon's scheduling is noise, and still dozens of tasks per frame for two cores.
const SHADE_BAND_ROWS: usize = 8;

/// Tile buffer row stride for a tile `width` pixels wide: whole pixel groups.
pub fn tile_stride(width: u32) -> u32 {
    width.div_ceil(GROUP) * GROUP
}

/// A shading parameter's place in the frame's planes.
#[derive(Clone, Debug, PartialEq)]
pub struct ParamPlanes {
    pub name: String,
    pub first_plane: u32,
    pub components: u32,
}

/// The rendered frame: depth, G-buffer planes and (when counted) depth-write counts, each
/// `width * height`, row-major from the top-left pixel.
#[derive(Clone, Debug)]
pub struct Frame {
    pub width: u32,
    pub height: u32,
    pub background: [f32; 3],
    pub depth: Vec<u32>,
    pub planes: Vec<Vec<f32>>,
    pub write_counts: Option<Vec<u32>>,
    pub params: Vec<ParamPlanes>,
    /// The deferred shading pass's colours (`None` when the scene turns no effect on and
    /// covered pixels show `Cs`).
    pub colors: Option<Vec<[f32; 3]>>,
}

/// What a render measured.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RenderStats {
    pub instances: usize,
    pub kernels_compiled: usize,
    pub compile_micros: u64,
    pub render_micros: u64,
    /// Of `render_micros`: compiling (or looking up) kernels, the bound pass and binning
    /// (serial).
    pub setup_micros: u64,
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

/// A rayon worker's tile buffers, reused from tile to tile (cleared, not reallocated):
/// depth (u32, 0 = farthest), G-buffer planes and write counts, each `stride * rows`.
#[derive(Default)]
struct TileScratch {
    depth: Vec<u32>,
    gbuf: Vec<f32>,
    counts: Vec<u32>,
}

thread_local! {
    /// This thread's tile buffers. Rayon's worker threads live as long as their pool, so a
    /// worker reuses its buffers for every tile of every frame it renders: no allocation and
    /// no fresh (page-faulting) memory per tile or per frame, and the buffers stay in the
    /// core's cache. (`map_init` would not do this: with one job per tile it builds a new
    /// scratch per tile.) A tile task borrows it for the whole tile and makes no rayon call
    /// meanwhile, so no other task can run on this thread while it is borrowed.
    static TILE_SCRATCH: std::cell::RefCell<TileScratch> = std::cell::RefCell::default();
}

/// Scratch capacity (elements per buffer) a thread keeps after a tile: a huge tile's buffers
/// are given back rather than held for the thread's lifetime. 64 planes of a 128 x 128 tile.
const SCRATCH_KEEP: usize = 128 * 128 * 64;

/// Where one tile's pixels go in the frame: for every frame buffer, one mutable slice per
/// tile row (`tile.x1 - tile.x0` long). Tiles are disjoint, so every tile task owns its
/// slices and writes them while the others run.
struct TileTarget<'f> {
    depth: Vec<&'f mut [u32]>,
    /// `[plane][row]`.
    planes: Vec<Vec<&'f mut [f32]>>,
    /// Empty when writes are not counted.
    counts: Vec<&'f mut [u32]>,
}

/// Cut a `width`-wide row-major buffer into each tile's row slices, tiles in
/// [`tile_grid`] order (row-major, `tile_size` square, cut at the right and bottom edges).
fn tile_rows<T>(buf: &mut [T], width: usize, tile_size: usize, tiles: usize) -> Vec<Vec<&mut [T]>> {
    let mut out: Vec<Vec<&mut [T]>> = (0..tiles).map(|_| Vec::with_capacity(tile_size)).collect();
    if width == 0 || tile_size == 0 {
        return out;
    }
    let tiles_x = width.div_ceil(tile_size);
    for (y, mut row) in buf.chunks_mut(width).enumerate() {
        let first = (y / tile_size) * tiles_x;
        for slot in out.iter_mut().skip(first).take(tiles_x) {
            let len = tile_size.min(row.len());
            let (piece, rest) = std::mem::take(&mut row).split_at_mut(len);
            slot.push(piece);
            row = rest;
        }
    }
    out
}

impl Renderer {
    /// Render every instance submitted so far into a new [`Frame`]. Uses the current rayon
    /// thread pool (wrap the call in `ThreadPool::install` to choose the thread count).
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
    /// allocation, no page fault and no clearing of the whole frame (every pixel is written
    /// once, by the tile it lies in: rendered and copied, or zeroed when no draw touches the
    /// tile). Whatever `frame` held before (another size, other planes, colours), the result
    /// is bit for bit the frame [`Renderer::render`] returns.
    pub fn render_into(&self, source: &mut dyn KernelSource, frame: &mut Frame) -> RenderReport {
        let started = Instant::now();
        // The options are public fields: clamp them here so that no setting can panic or
        // overflow the frame size (the setters already reject these values).
        let opts = &RenderOptions {
            width: self.options.width.min(MAX_IMAGE_SIDE),
            height: self.options.height.min(MAX_IMAGE_SIDE),
            tile_size: self.options.tile_size.clamp(1, MAX_TILE_SIDE),
            ..self.options.clone()
        };
        let program = self.program().clone();
        let mut diags = Diagnostics::new();
        let mut stats = RenderStats {
            instances: self.instances().len(),
            ..RenderStats::default()
        };

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
        let expanded: Vec<Option<Expanded>> = instances
            .par_iter()
            .zip(ready.par_iter())
            .enumerate()
            .with_max_len(BOUND_JOB)
            .map(|(i, (inst, kernel))| {
                if let Some(next) = instances.get(i + 1) {
                    prefetch(&next.args);
                }
                let kernel = (*kernel)?;
                let tiles_of = |bound| tiles_overlapped(bound, opts);
                Some(expand_instance(&program, opts, &budget, inst, kernel, tiles_of))
            })
            .collect();
        drop(ready);
        for (i, e) in expanded.iter().enumerate() {
            let Some(e) = e else { continue };
            stats.expanded_instances += usize::from(e.expanded());
            stats.expanded_calls += if e.expanded() { e.len() } else { 0 };
            stats.expand_over_budget += usize::from(e.over_budget());
            errors.extend(e.errors().iter().map(|&(code, site)| (i, code, site)));
        }
        let bins = Bins::new(&expanded, instances, tiles.len(), tiles_x);
        stats.tile_invocations = bins.draws.len();
        let tiles_started = Instant::now();
        stats.setup_micros = micros_between(started, tiles_started);

        // 3. Tiles in parallel, each copying itself into the frame; errors kept in tile order.
        let num_planes = self.num_planes();
        frame.reset(
            opts,
            num_planes,
            self.shading_params().iter().map(|p| ParamPlanes {
                name: p.name.clone(),
                first_plane: p.first_plane,
                components: p.components,
            }),
        );
        let targets = frame.tile_targets(tiles.len(), opts.tile_size);
        let tile_errors: Vec<Vec<(usize, u32, u32)>> = tiles
            .par_iter()
            .zip(bins.slices().into_par_iter())
            .zip(targets.into_par_iter())
            .with_max_len(1)
            .map(|((tile, bin), target)| {
                TILE_SCRATCH.with(|scratch| render_tile(tile, bin, num_planes, opts, &mut scratch.borrow_mut(), target))
            })
            .collect();
        errors.extend(tile_errors.into_iter().flatten());

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

/// Run a draw's kernel in bound mode: its screen bound (if it recorded one) and its
/// run-time error.
pub(super) fn run_bound(draw: &Draw, opts: &RenderOptions) -> (Option<[f32; 4]>, Option<(u32, u32)>) {
    let mut ctx = TileCtx::new(MODE_BOUND, opts.width, opts.height);
    ctx.call_depth = draw.call_depth;
    // Zero-size buffers: bound mode never touches them, and the empty tile rectangle
    // (x0 = x1 = 0) means even a pixel pass would cover no pixel.
    let mut no_depth: Vec<u32> = Vec::new();
    let mut no_planes: Vec<f32> = Vec::new();
    let mut no_counts: Vec<u32> = Vec::new();
    ctx.depth = no_depth.as_mut_ptr();
    ctx.gbuf = no_planes.as_mut_ptr();
    ctx.write_count = no_counts.as_mut_ptr();
    // SAFETY: `ctx` is a valid TileCtx naming (empty) buffers that outlive the call, and
    // `draw.args` holds at least the words the kernel's layout reads (checked when the
    // kernel was made ready, or when the call was recorded), which is all the ABI lets a
    // kernel read.
    unsafe { (draw.entry)(&mut ctx, draw.args.as_ptr()) };
    let bound = (ctx.bound_set != 0).then_some(ctx.bound);
    let error = (ctx.error != 0).then_some((ctx.error, ctx.error_site));
    (bound, error)
}

/// An inclusive rectangle of tile indices: (tx0, ty0, tx1, ty1).
pub(super) type TileRect = (usize, usize, usize, usize);

/// The tiles (inclusive tile-index rectangle) a screen bound overlaps, or `None`. Pixels
/// whose centre lies in the bound are covered; the range is widened by one pixel each way so
/// float rounding can never drop a tile.
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
    let px0 = (floor_clamped(xmin - 0.5) - 1).max(0);
    let py0 = (floor_clamped(ymin - 0.5) - 1).max(0);
    let px1 = (ceil_clamped(xmax - 0.5) + 1).min(i64::from(opts.width) - 1);
    let py1 = (ceil_clamped(ymax - 0.5) + 1).min(i64::from(opts.height) - 1);
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
struct Bins<'a> {
    start: Vec<usize>,
    draws: Vec<Draw<'a>>,
}

impl<'a> Bins<'a> {
    /// Bin every draw of `expanded` (instance `i`'s at index `i`, `None` for an instance
    /// without a usable kernel) into the tiles it overlaps, for a grid of `tiles` tiles,
    /// `tiles_x` per row.
    fn new(expanded: &'a [Option<Expanded>], instances: &'a [Instance], tiles: usize, tiles_x: usize) -> Bins<'a> {
        // Every draw's tile rectangle, with what to do in each of its tiles.
        let each = |visit: &mut dyn FnMut(usize, &'a Expanded, usize, usize)| {
            for (i, e) in expanded.iter().enumerate() {
                let Some(e) = e else { continue };
                for d in 0..e.len() {
                    let Some((tx0, ty0, tx1, ty1)) = e.tiles(d) else {
                        continue;
                    };
                    for ty in ty0..=ty1 {
                        for tx in tx0..=tx1 {
                            visit(ty * tiles_x + tx, e, d, i);
                        }
                    }
                }
            }
        };
        let mut start = vec![0usize; tiles + 1];
        each(&mut |t, _, _, _| start[t + 1] += 1);
        for t in 0..tiles {
            start[t + 1] += start[t];
        }
        let mut next = start.clone();
        // Every slot is overwritten below (the counts are exact); the filler is never run.
        let mut draws = vec![Draw::NONE; start[tiles]];
        each(&mut |t, e, d, i| {
            draws[next[t]] = e.draw(d, &instances[i], i);
            next[t] += 1;
        });
        Bins { start, draws }
    }

    /// Each tile's draws, in tile order.
    fn slices(&self) -> Vec<&[Draw<'a>]> {
        self.start.windows(2).map(|w| &self.draws[w[0]..w[1]]).collect()
    }
}

/// Render one tile's draws into `scratch`, then copy the tile into the frame through
/// `target`; returns the tile's run-time errors (instance, code, site) in order.
fn render_tile(
    tile: &Tile,
    bin: &[Draw],
    num_planes: u32,
    opts: &RenderOptions,
    scratch: &mut TileScratch,
    mut target: TileTarget<'_>,
) -> Vec<(usize, u32, u32)> {
    let stride = tile_stride(tile.x1 - tile.x0);
    let rows = tile.y1 - tile.y0;
    let plane_len = (stride * rows) as usize;
    // Every tile starts from zeroed buffers of its own size, exactly as if freshly allocated.
    fn reset<T: Copy + Default>(buf: &mut Vec<T>, len: usize) {
        buf.clear();
        buf.resize(len, T::default());
    }
    if bin.is_empty() {
        // Nothing draws here: the tile would hold zeros, so its part of the frame (which may
        // hold an earlier frame) is zeroed directly, without the scratch.
        target.depth.iter_mut().for_each(|row| row.fill(0));
        target.counts.iter_mut().for_each(|row| row.fill(0));
        target.planes.iter_mut().flatten().for_each(|row| row.fill(0.0));
        return vec![];
    }
    reset(&mut scratch.depth, plane_len);
    reset(&mut scratch.gbuf, plane_len * num_planes as usize);
    reset(&mut scratch.counts, if opts.count_writes { plane_len } else { 0 });
    let (depth, gbuf, counts) = (&mut scratch.depth, &mut scratch.gbuf, &mut scratch.counts);
    let mut errors = vec![];
    // Every draw starts from this context (a copy: a kernel may change any field of its
    // own, e.g. fuel, the error or the call depth).
    let mut start = TileCtx::new(MODE_RENDER, opts.width, opts.height);
    start.x0 = tile.x0 as i32;
    start.y0 = tile.y0 as i32;
    start.x1 = tile.x1 as i32;
    start.y1 = tile.y1 as i32;
    start.stride = stride;
    start.depth = depth.as_mut_ptr();
    start.gbuf = gbuf.as_mut_ptr();
    start.plane_stride = plane_len as u32;
    start.num_planes = num_planes;
    start.write_count = counts.as_mut_ptr();
    for (j, draw) in bin.iter().enumerate() {
        if let Some(next) = bin.get(j + 1) {
            prefetch(next.args);
        }
        let mut ctx = TileCtx {
            call_depth: draw.call_depth,
            ..start
        };
        // SAFETY: the context names this tile's own buffers: depth and (when counting)
        // write_count are `stride * rows` long, gbuf `num_planes * plane_stride`; the kernel
        // was compiled with count_writes == opts.count_writes, so it touches write_count
        // only when that buffer is full size. The argument block is long enough for the
        // kernel's layout (checked in `render` and when calls were recorded). Nothing else
        // aliases these buffers while the kernel runs: the scratch belongs to this rayon task.
        unsafe { (draw.entry)(&mut ctx, draw.args.as_ptr()) };
        if ctx.error != 0 {
            errors.push((draw.instance, ctx.error, ctx.error_site));
        }
    }
    // Into the frame, row by row (the tile's stride may exceed its width).
    let stride = stride as usize;
    let copy_rows = |dst: &mut [&mut [u32]], src: &[u32]| {
        for (row, d) in dst.iter_mut().enumerate() {
            d.copy_from_slice(&src[row * stride..row * stride + d.len()]);
        }
    };
    copy_rows(&mut target.depth, depth);
    copy_rows(&mut target.counts, counts);
    for (p, dst) in target.planes.iter_mut().enumerate() {
        let plane = &gbuf[p * plane_len..(p + 1) * plane_len];
        for (row, d) in dst.iter_mut().enumerate() {
            d.copy_from_slice(&plane[row * stride..row * stride + d.len()]);
        }
    }
    if scratch.gbuf.capacity() > SCRATCH_KEEP {
        *scratch = TileScratch::default();
    }
    errors
}

/// Ask the CPU to start loading the head of an argument block the next kernel will read:
/// a tile's draws come from anywhere in the submission, so their blocks are scattered in
/// memory, and the kernel running meanwhile hides the wait. A hint only: it never faults
/// and changes no value.
#[inline]
fn prefetch(args: &[u32]) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        let p = args.as_ptr().cast::<i8>();
        // SAFETY: prefetching is a hint that never faults, whatever the address; SSE (which
        // `prefetcht0` belongs to) is part of the x86_64 baseline.
        unsafe { _mm_prefetch::<_MM_HINT_T0>(p) };
        if args.len() > 16 {
            // SAFETY: as above; the address is inside the block.
            unsafe { _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(64)) };
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
            _ => "an unknown run-time error",
        };
        let name = &program.func(instances[i].func).name;
        let mut d = Diagnostic::warning("W0801", format!("in `{name}` at run time: {what}"));
        if let Some(&span) = program.sites.get(site as usize) {
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
            depth: vec![],
            planes: vec![],
            write_counts: None,
            params: vec![],
            colors: None,
        }
    }

    /// Shape the frame for a render with `opts` and `num_planes` planes, keeping the buffers
    /// it already has (same size: nothing allocated). Contents are left as they are: the
    /// tile tasks write every pixel.
    fn reset(&mut self, opts: &RenderOptions, num_planes: u32, params: impl Iterator<Item = ParamPlanes>) {
        let pixels = (opts.width * opts.height) as usize;
        self.width = opts.width;
        self.height = opts.height;
        self.background = opts.background;
        self.depth = fit(std::mem::take(&mut self.depth), pixels, 0);
        self.planes.truncate(num_planes as usize);
        self.planes.resize_with(num_planes as usize, Vec::new);
        for plane in &mut self.planes {
            *plane = fit(std::mem::take(plane), pixels, 0.0);
        }
        if opts.count_writes {
            self.write_counts = Some(fit(self.write_counts.take().unwrap_or_default(), pixels, 0));
        } else {
            self.write_counts = None;
        }
        self.params.clear();
        self.params.extend(params);
    }

    /// Every tile's [`TileTarget`] into this frame's buffers, in [`tile_grid`] order.
    fn tile_targets(&mut self, tiles: usize, tile_size: u32) -> Vec<TileTarget<'_>> {
        let (width, ts) = (self.width as usize, tile_size as usize);
        let mut depth = tile_rows(&mut self.depth, width, ts, tiles).into_iter();
        let mut counts = self
            .write_counts
            .as_mut()
            .map(|c| tile_rows(c, width, ts, tiles).into_iter());
        let mut planes: Vec<_> = self
            .planes
            .iter_mut()
            .map(|p| tile_rows(p, width, ts, tiles).into_iter())
            .collect();
        (0..tiles)
            .map(|_| TileTarget {
                depth: depth.next().unwrap_or_default(),
                planes: planes.iter_mut().map(|p| p.next().unwrap_or_default()).collect(),
                counts: counts.as_mut().and_then(|c| c.next()).unwrap_or_default(),
            })
            .collect()
    }

    fn index(&self, x: u32, y: u32) -> Option<usize> {
        (x < self.width && y < self.height).then(|| (y * self.width + x) as usize)
    }

    /// Raw depth (`fixed<32,32>`, larger is nearer, 0 = nothing written).
    pub fn depth_at(&self, x: u32, y: u32) -> Option<u32> {
        self.index(x, y).map(|i| self.depth[i])
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
        self.planes.get(plane as usize).map(|p| p[i])
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
        self.write_counts.as_ref().map(|c| c[i])
    }

    /// The shaded colour: where depth was written, `Cs` clamped to [0, 1] (a 1-component
    /// `Cs` is gray; with no usable `Cs` the pixel is white, OpenGL's default current colour);
    /// elsewhere the background.
    pub fn color_at(&self, x: u32, y: u32) -> [f32; 3] {
        if !self.written(x, y) {
            return self.background.map(clamp01);
        }
        if let (Some(colors), Some(i)) = (&self.colors, self.index(x, y)) {
            return colors[i].map(clamp01);
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
        self.colors.as_ref().map(|c| c[i])
    }

    /// Run `shader` over every written pixel into `colors` (resized to the frame; its old
    /// contents do not matter); unwritten pixels get zero. Bands of [`SHADE_BAND_ROWS`] rows
    /// are shaded in parallel (each pixel's colour depends on that pixel's inputs alone, so
    /// the result is the same for any thread count); each band zeroes its own colours first
    /// (in parallel, cache-hot, instead of a serial clear of the whole buffer). The fast
    /// kernels read each row's planes as contiguous slices ([`RowInputs`]) in one fused pass;
    /// the f64 reference takes the written pixels one by one.
    fn shade(&self, shader: &Shader, texture_param: Option<&str>, colors: &mut Vec<[f32; 3]>) {
        *colors = fit(std::mem::take(colors), self.depth.len(), [0.0; 3]);
        let width = self.width as usize;
        if width == 0 {
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
        let plane = |p: &ParamPlanes, k: u32, row: usize| {
            let start = row * width;
            &self.planes[(p.first_plane + k) as usize][start..start + width]
        };
        colors
            .par_chunks_mut(width * SHADE_BAND_ROWS)
            .enumerate()
            .for_each(|(band, band_colors)| {
                // `shade_row` skips chunks with no written pixel: they must read zero.
                band_colors.fill([0.0; 3]);
                for (i, row_colors) in band_colors.chunks_mut(width).enumerate() {
                    let y = band * SHADE_BAND_ROWS + i;
                    let row = RowInputs {
                        y: y as u32,
                        depth: &self.depth[y * width..(y + 1) * width],
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
                    shader.shade_row(&row, row_colors);
                }
            });
    }

    /// The f64 reference pass ([`ShadingKernel::ReferenceF64`]): one [`PixelInputs`] per
    /// written pixel, shaded by [`Shader::shade`].
    fn shade_reference(&self, shader: &Shader, texture_param: Option<&str>, colors: &mut [[f32; 3]]) {
        let get = |name: &str| self.param(name).cloned();
        let (cs, normal, facing) = (get("Cs"), get(super::api::NORMAL_PARAM), get(super::api::FACING_PARAM));
        let st = texture_param.and_then(get);
        let width = self.width as usize;
        colors.par_chunks_mut(width).enumerate().for_each(|(y, row)| {
            // Unwritten pixels are zero (the buffer may hold an earlier frame's colours).
            row.fill([0.0; 3]);
            // Per row: bounded memory for the inputs.
            let mut inputs = Vec::with_capacity(width);
            let mut slots = Vec::with_capacity(width);
            for (x, _) in row.iter().enumerate() {
                let i = y * width + x;
                if self.depth[i] == 0 {
                    continue;
                }
                let plane = |p: &ParamPlanes, k: u32| f64::from(self.planes[(p.first_plane + k) as usize][i]);
                let cs = match &cs {
                    Some(p) if p.components >= 3 => [plane(p, 0), plane(p, 1), plane(p, 2)],
                    Some(p) if p.components == 1 => [plane(p, 0); 3],
                    _ => [1.0; 3],
                };
                inputs.push(PixelInputs {
                    x: x as u32,
                    y: y as u32,
                    depth: f64::from(self.depth[i]) / 4294967296.0,
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
                slots.push(x);
            }
            let mut out = vec![[0f32; 3]; inputs.len()];
            shader.shade(&inputs, &mut out);
            for (x, c) in slots.into_iter().zip(out) {
                row[x] = c;
            }
        });
    }

    pub fn to_rgb8(&self) -> RgbImage {
        ImageBuffer::from_fn(self.width, self.height, |x, y| Rgb(self.color_at(x, y).map(to_u8)))
    }

    /// Depth as 16-bit gray, nearer brighter (the top 16 bits of the raw depth).
    pub fn depth_image(&self) -> ImageBuffer<Luma<u16>, Vec<u16>> {
        ImageBuffer::from_fn(self.width, self.height, |x, y| {
            Luma([(self.depth_at(x, y).unwrap_or(0) >> 16) as u16])
        })
    }

    /// A shading parameter as an image: 1 component as gray normalised to its range over the
    /// written pixels (unwritten pixels black), 3 components as RGB clamped to [0, 1].
    pub fn param_image(&self, name: &str) -> Result<RgbImage, String> {
        let p = self
            .param(name)
            .ok_or_else(|| format!("the scene has no shading parameter `{name}`"))?;
        match p.components {
            1 => {
                let plane = &self.planes[p.first_plane as usize];
                let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
                for (i, &v) in plane.iter().enumerate() {
                    if self.depth[i] != 0 && v.is_finite() {
                        lo = lo.min(v);
                        hi = hi.max(v);
                    }
                }
                Ok(ImageBuffer::from_fn(self.width, self.height, |x, y| {
                    let i = (y * self.width + x) as usize;
                    let v = plane[i];
                    let g = if self.depth[i] == 0 || !v.is_finite() {
                        0.0
                    } else if hi > lo {
                        (v - lo) / (hi - lo)
                    } else {
                        0.5
                    };
                    Rgb([to_u8(g); 3])
                }))
            }
            3 => Ok(ImageBuffer::from_fn(self.width, self.height, |x, y| {
                let c = |k: u32| clamp01(self.plane_at(p.first_plane + k, x, y).unwrap_or(0.0));
                Rgb([c(0), c(1), c(2)].map(to_u8))
            })),
            n => Err(format!(
                "shading parameter `{name}` has {n} components; only 1 (gray) or 3 (RGB) can be written as an image"
            )),
        }
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

fn to_u8(v: f32) -> u8 {
    (clamp01(v) * 255.0).round() as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    fn opts(w: u32, h: u32, ts: u32) -> RenderOptions {
        RenderOptions {
            width: w,
            height: h,
            tile_size: ts,
            ..RenderOptions::default()
        }
    }

    #[test]
    fn stride_is_whole_groups() {
        assert_eq!(tile_stride(64), 64);
        assert_eq!(tile_stride(13), 16);
        assert_eq!(tile_stride(1), 4);
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

    #[test]
    fn tile_rows_cut_the_frame_like_the_tile_grid() {
        for (w, h, ts) in [(100, 70, 64), (9, 7, 5), (64, 64, 64), (5, 3, 8)] {
            let tiles = tile_grid(&opts(w, h, ts));
            let mut buf: Vec<usize> = (0..(w * h) as usize).collect();
            let rows = tile_rows(&mut buf, w as usize, ts as usize, tiles.len());
            assert_eq!(rows.len(), tiles.len());
            for (tile, rows) in tiles.iter().zip(&rows) {
                assert_eq!(rows.len(), (tile.y1 - tile.y0) as usize, "{w}x{h}/{ts}");
                for (r, row) in rows.iter().enumerate() {
                    let y = tile.y0 as usize + r;
                    let expected: Vec<usize> = (tile.x0..tile.x1).map(|x| y * w as usize + x as usize).collect();
                    assert_eq!(
                        &row[..],
                        &expected[..],
                        "{w}x{h}/{ts} tile at ({}, {})",
                        tile.x0,
                        tile.y0
                    );
                }
            }
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

    #[test]
    fn binning_is_conservative_and_clamped() {
        let o = opts(256, 128, 64);
        assert_eq!(tiles_overlapped([10.0, 10.0, 20.0, 20.0], &o), Some((0, 0, 0, 0)));
        // A bound ending exactly on a tile edge also takes the next tile (one pixel margin).
        assert_eq!(tiles_overlapped([10.0, 10.0, 64.0, 20.0], &o), Some((0, 0, 1, 0)));
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
