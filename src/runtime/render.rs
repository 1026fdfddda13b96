//! The render loop: compile, bound, bin, render tiles in parallel, shade.
//!
//! Invariants: every tile's draws run in submission order (an expanded instance's calls in
//! call order) whatever the number of threads; tile tasks write disjoint parts of the frame
//! (the layout [`super::frame`] keeps); every pixel starts from zero in its own tile. So a
//! frame is bit-identical whatever the schedule. The steps:
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
//!    then runs its draws in order in `MODE_RENDER`, each with fresh setup fuel and the
//!    frame's pixel fuel (`abi::ctx` has the fuel rules); a tile no draw
//!    touches is zeroed only. Tiles are disjoint, including the padding columns the rightmost
//!    tiles' last groups reach into, so tasks write disjoint memory (`FrameTarget`). Every
//!    pixel is computed by one tile from the same zeroed start whatever the schedule, so the
//!    result is bit-identical whatever the number of threads, no serial pass gathers the
//!    tiles, and the frame's earlier contents never matter: [`Renderer::render_into`] reuses
//!    a caller's [`Frame`] (no allocation, no page faults on fresh buffers) and
//!    [`Renderer::render`] is it on an empty frame.
//! 4. Kernel run-time errors become warnings at the failing site of the primitive source,
//!    one per site with the number of times it failed, in site order ([`super::errors`]:
//!    setup errors are counted in the bound and expand runs, pixel errors in the tiles).
//!
//! With a kernel source that upgrades its kernels in the background (a tiered JIT,
//! `KernelSource::tier_up`), the frame holds that compiler from before step 1 until a grace
//! period after it (in proportion to the step's compile time), and from then on, while a
//! compile is running, step 2's jobs and step 3's tiles run on one thread fewer than the
//! pool has (`super::tiergate`): a short frame keeps every core, a long one gets the
//! faster kernels sooner. Which thread runs a job never changes what it computes, so the
//! frame is the same bit for bit; `RenderStats::gated_jobs` counts the jobs run that way.
//!
//! Then the deferred shading pass over the frame (`Frame::shade` in [`super::frame`]) when
//! the scene turns an effect on.

use std::sync::Arc;
use std::time::Instant;

use crate::abi::{Kernel, TileCtx, VariantKey, MODE_RENDER};
use crate::diag::{Diagnostic, Diagnostics};
use crate::ir::{FuncId, Program};

use super::api::{Instance, RenderOptions, Renderer, MAX_FRAME_BYTES, MAX_IMAGE_SIDE};
use super::errors::{CountArrays, Counts};
use super::expand::{context, expand_instance, Budget, Draw, Expanded, TileRect};
use super::frame::{plane_pitch, row_stride, tile_side, Frame, FrameTarget, ParamPlanes, Tile};
use super::kernels::KernelSource;
use super::live::{self, LivePlanes};
use super::samples::{sample_offset_range, sample_positions};
use super::shading::language::LanguageShading;
use super::shading::{Effects, Shader, ShadingSpaces};
use super::tiergate::{self, Compiler, GateStats};

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
    /// Language shaders run inside the tiles (`tiles_micros`); here only their colours are
    /// gathered from the output planes.
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
    /// What the language shading pass compiled, one line per kernel (`render --explain`);
    /// empty when the Rust pass (or nothing) shaded the frame.
    pub language_shading: Vec<String>,
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
    /// What the language shading pass compiled, one line per kernel (`render --explain`);
    /// empty when the Rust pass (or nothing) shaded the frame.
    pub language_shading: Vec<String>,
}

/// One compiled kernel variant (`render --explain`).
#[derive(Clone, Debug, PartialEq)]
pub struct KernelReport {
    pub primitive: String,
    pub key: String,
    pub trivial_accept: bool,
    pub compile_micros: u64,
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
            language_shading,
        } = self.render_into(source, &mut frame);
        RenderOutput {
            frame,
            stats,
            diags,
            kernels,
            effects,
            language_shading,
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
        // Language shading writes its colours into three planes after the parameters'.
        let mapped;
        let language_shading = if self.language.active() {
            if self.shading_setup.effects().any() {
                diags.push(crate::diag::Diagnostic::warning(
                    "W1002",
                    "the scene has language shaders (`shader`, `lightsource`, `atmosphere`): its `light`, `surface`, `fog` and `texture` lines have no effect",
                ));
            }
            Some(&self.language)
        } else if opts.fixed_shading_in_language && self.shading_setup.effects().any() {
            let (shading, notes) = LanguageShading::from_fixed(&self.shading_setup);
            for note in notes {
                diags.push(crate::diag::Diagnostic::warning("W1003", note));
            }
            mapped = shading;
            Some(&mapped)
        } else {
            None
        };
        let language = language_shading.is_some();
        // Language shaders are linked and compiled first: the planes they read are the
        // planes the frame allocates and the primitives fill (`super::live`). They run in
        // each tile's task right after its draws, while its G-buffer is in cache.
        let shading = language_shading.and_then(|l| self.compile_language(l, &opts.keep_params, &mut diags));
        let live = match &shading {
            Some(s) => LivePlanes::only(self.shading_params(), |name| s.planes.iter().any(|p| p.name == name)),
            None => LivePlanes::all(self.shading_params()),
        };
        let num_planes = live.num_planes + if language { 3 } else { 0 };
        if let Some(too_large) = frame_too_large(opts, num_planes) {
            diags.push(too_large);
            *frame = Frame::empty();
            stats.render_micros = started.elapsed().as_micros() as u64;
            return RenderReport {
                stats,
                diags,
                kernels: vec![],
                effects: self.shading_setup.effects(),
                language_shading: vec![],
            };
        }

        // A background compiler (a tiered JIT's tier 1) starts nothing before the frame has
        // run for a grace period (`tiergate`): a short frame keeps every core, a long one
        // gets tier-1 code soon after. Taken before the compiles, which queue its work.
        let compiler = source.tier_up();
        let mut held_compiler = compiler.as_ref().map(|w| w.hold());

        // 1. Compile each (func, key) once, in first-use order, for the bindings the frame
        // keeps.
        let stripped = live.drops_any().then(|| live::strip(&program, self.instances(), &live));
        let (instances, variants) = match &stripped {
            Some(s) => (&s.instances[..], &s.variants),
            None => (self.instances(), self.variants()),
        };
        let variant_of = variants.of_instance();
        // Binding k of a key is the k-th shading parameter the frame keeps (`live`).
        let param_names: Vec<&str> = self
            .shading_params()
            .iter()
            .zip(&live.first_plane)
            .filter(|(_, first)| first.is_some())
            .map(|(p, _)| p.name.as_str())
            .collect();
        let (kernels, reports) = compile_variants(
            &program,
            source,
            variants.list(),
            &param_names,
            opts,
            &mut stats,
            &mut diags,
        );
        let compiled = Instant::now();
        stats.kernels_micros = micros_between(started, compiled);
        if let (Some(hold), Some(watch)) = (&mut held_compiler, &compiler) {
            hold.release_at(compiled + watch.grace(compiled.duration_since(started)));
        }
        // Never hand a kernel an argument block shorter than its layout reads.
        let ready: Vec<Option<&Kernel>> = instances
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
        let mut errors = Counts::new();
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
        report_unbounded(&program, variants.list(), variant_of, &expanded, opts, &mut diags);
        let mut draws = 0;
        for e in &expanded {
            let Some(e) = e else { continue };
            draws += e.len();
            stats.expanded_instances += usize::from(e.expanded());
            stats.expanded_calls += if e.expanded() { e.len() } else { 0 };
            stats.expand_over_budget += usize::from(e.over_budget());
            errors.extend_from_slice(e.errors());
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

        // 3. Tiles in parallel, each rendering into its own part of the frame, each counting
        // its pixel code's run-time errors; then the frame's colours. Once per sample of a
        // multisampled frame, each sample into its own buffers at its own position.
        let positions = sample_positions(opts.samples).unwrap_or_else(|| vec![[0.5; 2]]);
        let params: Vec<ParamPlanes> = live
            .params(self.shading_params())
            .into_iter()
            .chain(language.then(|| ParamPlanes {
                name: "Ci".into(),
                first_plane: live.num_planes,
                components: 3,
            }))
            .collect();
        let mut other_samples = frame.take_samples(&positions);
        let shading_runs = shading.as_ref().map(|s| &s.pass);
        let slices = bins.slices();
        let mut shading_errors = vec![];
        let mut non_finite = 0;
        let mut shade_micros = 0;
        for (s, &position) in positions.iter().enumerate() {
            let sample = match s {
                0 => &mut *frame,
                s => &mut other_samples[s - 1],
            };
            sample.reset_sample(opts, num_planes, params.iter().cloned(), position);
            let target = sample.target();
            let (tile_errors, gated) = tiergate::run_items(compiler, tiles.len(), 1, |t| {
                let (tile, bin) = (&tiles[t], slices[t]);
                // SAFETY: each tile index is run once (`tiles` holds each tile once), and
                // `target` is the frame reset for this grid.
                let errors = unsafe { render_tile(&program, tile, bin, opts, target) };
                // A tile without draws has nothing to shade.
                let shading_errors = match shading_runs.filter(|_| !bin.is_empty()) {
                    // SAFETY: as above: this task owns `tile`.
                    Some(runs) => unsafe { runs.shade_tile(tile, opts, target) },
                    None => vec![],
                };
                (errors, shading_errors)
            });
            stats.add_gated(gated);
            for (e, s) in tile_errors {
                errors.extend(e);
                shading_errors.extend(s);
            }
            let shade_started = Instant::now();
            match &shading {
                Some(compiled) => non_finite += sample.colors_from_planes(compiled.pass.out_plane),
                // Language shading that did not compile (its errors are reported) leaves no
                // colours, not the previous frame's.
                None if language => sample.colors = None,
                None => self.shade(sample),
            }
            shade_micros += shade_started.elapsed().as_micros() as u64;
        }
        // The hold ends with the frame but keeps its deadline (`TierUpHold`'s drop): a
        // worker let go right here would compete with the caller's thread waking up.
        drop(held_compiler);
        let resolve_started = Instant::now();
        frame.put_samples(other_samples, opts.filter);
        stats.shade_micros = shade_micros + resolve_started.elapsed().as_micros() as u64;
        stats.tiles_micros = micros_between(tiles_started, Instant::now()).saturating_sub(stats.shade_micros);
        if let Some(compiled) = &shading {
            compiled.pass.report(&shading_errors, &mut diags);
            if non_finite > 0 {
                let what = if positions.len() > 1 {
                    "pixel sample(s)"
                } else {
                    "pixel(s)"
                };
                diags.push(Diagnostic::warning(
                    "W1004",
                    format!("{non_finite} {what} shaded to a NaN or infinite colour: shown magenta (1, 0, 1)"),
                ));
            }
        }

        // 4. Run-time errors, one warning per site with its count, in site order.
        super::errors::report(&program, &errors, &mut diags);
        stats.render_micros = started.elapsed().as_micros() as u64;
        RenderReport {
            stats,
            diags,
            kernels: reports,
            effects: self.shading_setup.effects(),
            language_shading: shading.as_ref().map(|s| s.explain.clone()).unwrap_or_default(),
        }
    }

    /// Link and compile the scene's language shaders for this frame (`shading::language`).
    fn compile_language(
        &self,
        shading: &LanguageShading,
        keep: &[String],
        diags: &mut Diagnostics,
    ) -> Option<Arc<super::shading::language::CompiledShading>> {
        let planes: Vec<crate::link::PlaneParam> = self
            .shading_params()
            .iter()
            .map(|p| crate::link::PlaneParam {
                name: p.name.clone(),
                first_plane: p.first_plane,
                components: p.components,
            })
            .collect();
        let device_from_lighting = self.geometry.device_from_lighting();
        let lighting_from_device = device_from_lighting.inverse();
        // The eye: clip space's point at infinity along z, mapped back (as `Shader::new`).
        let lighting_from_clip = lighting_from_device * self.geometry.device_from_clip();
        let eye_h = lighting_from_clip * glam::DVec4::new(0.0, 0.0, 1.0, 0.0);
        // Clip z = 1 is the near plane, z = 0 the far one.
        let at = |z: f64| {
            let q = lighting_from_clip * glam::DVec4::new(0.0, 0.0, z, 1.0);
            q.truncate() / q.w
        };
        let near = at(1.0);
        let eye = if eye_h.w.abs() > 1e-12 * eye_h.truncate().length() {
            let e = eye_h.truncate() / eye_h.w;
            [e.x, e.y, e.z, 1.0]
        } else {
            let d = (near - at(0.0)).normalize_or_zero();
            [d.x, d.y, d.z, 0.0]
        };
        let spaces = super::shading::language::Spaces {
            lighting_from_world: self.geometry.lighting_from_world(),
            device_from_lighting,
            eye,
            near: if near.is_finite() { near.to_array() } else { [0.0; 3] },
        };
        super::shading::language::compile_cached(
            &self.shading_cache,
            self.program(),
            shading,
            &planes,
            keep,
            &spaces,
            diags,
        )
    }

    /// The language shading of `frame`, the last frame this renderer rendered, computed
    /// again by the IR evaluator at `precision` (`shading::reference`): `Ci` per pixel,
    /// row-major.
    pub fn evaluate_shading(
        &self,
        frame: &Frame,
        precision: crate::ir::eval::Precision,
    ) -> Result<super::shading::reference::Colours, String> {
        let compiled = self
            .shading_cache
            .last()
            .ok_or("the renderer has not shaded a frame with language shaders")?;
        let out = compiled.pass.out_plane;
        if frame.param("Ci").map(|p| p.first_plane) != Some(out) || frame.num_planes() != out + 3 {
            return Err("the frame is not the last one the renderer shaded with language shaders".into());
        }
        compiled.evaluate(frame, &self.options, precision)
    }

    /// Deferred shading over the visible pixels of `frame`, compiled for the scene's
    /// effects. The previous frame's colour buffer (if any) is reused; without an effect
    /// there is none.
    fn shade(&self, frame: &mut Frame) {
        let spaces = ShadingSpaces {
            device_from_lighting: self.geometry.device_from_lighting(),
            lighting_from_world: self.geometry.lighting_from_world(),
            device_from_clip: self.geometry.device_from_clip(),
        };
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
    }
}

/// E0803 when a `opts`-sized frame with `num_planes` planes needs more than
/// `MAX_FRAME_BYTES`.
fn frame_too_large(opts: &RenderOptions, num_planes: u32) -> Option<Diagnostic> {
    let bytes = frame_bytes(opts, num_planes);
    (bytes > MAX_FRAME_BYTES).then(|| {
        Diagnostic::error(
            "E0803",
            format!(
                "a {}x{} frame with {num_planes} shading-parameter planes and {} sample(s) per pixel needs {:.1} GiB, more than the {} GiB a frame may take; nothing is rendered",
                opts.width,
                opts.height,
                samples_of(opts),
                bytes as f64 / (1u64 << 30) as f64,
                MAX_FRAME_BYTES >> 30
            ),
        )
    })
}

/// Compile every variant (`(func, key)`, in first-use order) through `source`, with the
/// frame's `count_writes`; a variant that fails has `None` and its errors in `diags`.
/// `param_names`: the shading parameter of each binding, in key order (for warnings).
/// Returns the kernels, indexed like `variants`, and a report of each compiled one.
fn compile_variants(
    program: &Program,
    source: &mut dyn KernelSource,
    variants: &[(FuncId, VariantKey)],
    param_names: &[&str],
    opts: &RenderOptions,
    stats: &mut RenderStats,
    diags: &mut Diagnostics,
) -> (Vec<Option<Arc<Kernel>>>, Vec<KernelReport>) {
    let mut reports = vec![];
    let kernels = variants
        .iter()
        .map(|(func, key)| {
            let key = VariantKey {
                count_writes: opts.count_writes,
                ..key.clone()
            };
            let kernel = compile_one(program, source, *func, &key, param_names, diags);
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
    (kernels, reports)
}

impl RenderStats {
    fn add_gated(&mut self, gated: GateStats) {
        self.gated_jobs += gated.gated_jobs;
        self.gated_peak_threads = self.gated_peak_threads.max(gated.peak_threads);
    }
}

/// Bytes of a frame for `opts` with `num_planes` planes (see [`MAX_FRAME_BYTES`]): per
/// sample depth, write counts when counted, colours, and the planes [`plane_pitch`] apart;
/// and a multisampled frame's resolved colours.
fn frame_bytes(opts: &RenderOptions, num_planes: u32) -> u64 {
    let len = u64::from(row_stride(opts.width)) * u64::from(opts.height);
    let per_pixel = 4 + 12 + if opts.count_writes { 4 } else { 0 };
    let sample = len * per_pixel + plane_pitch(len as usize) as u64 * u64::from(num_planes) * 4;
    let samples = samples_of(opts);
    sample * samples + if samples > 1 { len * 12 } else { 0 }
}

/// The samples per pixel a render with `opts` takes (a count not allowed renders as 1).
fn samples_of(opts: &RenderOptions) -> u64 {
    sample_positions(opts.samples).map_or(1, |p| p.len() as u64)
}

/// Most instances one job of the parallel expansion and bound pass takes: small enough that
/// the jobs spread evenly over the threads (one preempted thread does not hold back the
/// frame with a large part of the pass), large enough that scheduling them costs nothing
/// next to the bound runs (a small triangle's takes well under a microsecond).
const BOUND_JOB: usize = 512;

/// W0803 for each primitive with per-pixel code and no `bound` (the checker's W0004) that
/// the frame drew as itself: how many instances, and over how many pixels their per-pixel
/// code ran (the pixels of the tiles each was binned into: without a bound, every tile).
/// Counts, because the renderer keeps no time per primitive; an instance that returned in
/// its setup is binned nowhere and not counted.
fn report_unbounded(
    program: &Program,
    variants: &[(FuncId, VariantKey)],
    variant_of: &[usize],
    expanded: &[Option<Expanded>],
    opts: &RenderOptions,
    diags: &mut Diagnostics,
) {
    let unbounded: Vec<bool> = variants
        .iter()
        .map(|(f, _)| program.func(*f).runs_unbounded())
        .collect();
    if !unbounded.contains(&true) {
        return;
    }
    let ts = opts.tile_size as u64;
    let tile_pixels = |(tx0, ty0, tx1, ty1): TileRect| {
        let span = |t0: usize, t1: usize, side: u32| {
            (((t1 as u64 + 1) * ts).min(u64::from(side))).saturating_sub(t0 as u64 * ts)
        };
        span(tx0, tx1, opts.width) * span(ty0, ty1, opts.height)
    };
    // Per primitive, in first-drawn order: instances and pixels.
    let mut seen: Vec<(FuncId, u64, u64)> = vec![];
    for (e, &v) in expanded.iter().zip(variant_of) {
        let Some(Expanded::Itself { tiles: Some(tiles), .. }) = e else {
            continue;
        };
        if !unbounded[v] {
            continue;
        }
        let func = variants[v].0;
        let i = match seen.iter().position(|s| s.0 == func) {
            Some(i) => i,
            None => {
                seen.push((func, 0, 0));
                seen.len() - 1
            }
        };
        seen[i].1 += 1;
        seen[i].2 += tile_pixels(*tiles);
    }
    for (func, instances, pixels) in seen {
        let f = program.func(func);
        diags.push(
            Diagnostic::warning(
                "W0803",
                format!(
                    "`{}` has no `bound`: its {instances} instance(s) ran their per-pixel code over {pixels} pixels, {} each on average (the viewport has {})",
                    f.name,
                    pixels / instances,
                    u64::from(opts.width) * u64::from(opts.height)
                ),
            )
            .primary(f.span, "no path of this primitive calls `bound`")
            .help("with `bound(xmin, ymin, xmax, ymax)` around what an instance covers, its per-pixel code runs only over that rectangle"),
        );
    }
}

fn micros_between(from: Instant, to: Instant) -> u64 {
    to.duration_since(from).as_micros() as u64
}

fn compile_one(
    program: &Program,
    source: &mut dyn KernelSource,
    func: FuncId,
    key: &VariantKey,
    param_names: &[&str],
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
                diags.push(Diagnostic::warning("W0802", w.message_for(param_names)).primary(w.span, w.label.clone()));
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

/// The tiles of a frame for `opts`, row by row, cut at the right and bottom edges.
#[doc(hidden)]
pub fn tile_grid(opts: &RenderOptions) -> Vec<Tile> {
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

/// The tiles (inclusive tile-index rectangle) holding a pixel one of whose samples lies in a
/// screen bound (its centre without multisampling), or `None`: exactly the tiles in which a
/// kernel's render call runs a pixel for some sample (`pass_range` in the JIT takes the same
/// pixels per sample). In f64 `x - offset` (a multiple of 1/16) and its floor and ceil are exact for every clamped f32 bound, so no margin is needed; a one-pixel margin each way
/// would send a 20-pixel triangle to 1.29 tiles on average where 1.2 hold a
/// pixel of it, each extra call paying the whole setup for no pixel.
#[doc(hidden)]
pub fn tiles_overlapped(bound: [f32; 4], opts: &RenderOptions) -> Option<TileRect> {
    if bound.iter().any(|v| v.is_nan()) {
        return None;
    }
    let (w, h) = (f64::from(opts.width), f64::from(opts.height));
    // Clamp in float first: infinities and huge values must not overflow the conversion.
    let xmin = f64::from(bound[0]).clamp(-2.0, w + 2.0);
    let ymin = f64::from(bound[1]).clamp(-2.0, h + 2.0);
    let xmax = f64::from(bound[2]).clamp(-2.0, w + 2.0);
    let ymax = f64::from(bound[3]).clamp(-2.0, h + 2.0);
    // Pixel x holds a sample in [xmin, xmax] when xmin <= x + offset <= xmax for one of the
    // samples' offsets (exactly the centre's 0.5 without multisampling).
    let [lo_x, lo_y, hi_x, hi_y] = sample_offset_range(opts.samples);
    let px0 = ceil_clamped(xmin - hi_x).max(0);
    let py0 = ceil_clamped(ymin - hi_y).max(0);
    let px1 = floor_clamped(xmax - lo_x).min(i64::from(opts.width) - 1);
    let py1 = floor_clamped(ymax - lo_y).min(i64::from(opts.height) - 1);
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
#[doc(hidden)]
pub fn floor_clamped(x: f64) -> i64 {
    let t = x as i64;
    t - i64::from((t as f64) > x)
}

/// `x.ceil() as i64` under the same conditions as [`floor_clamped`].
#[doc(hidden)]
pub fn ceil_clamped(x: f64) -> i64 {
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
#[doc(hidden)]
pub struct Bins<'a> {
    pub start: Vec<usize>,
    pub draws: Vec<Draw<'a>>,
}

/// Fewest draws per chunk worth a parallel job of the binning.
#[doc(hidden)]
pub const BIN_CHUNK_DRAWS: usize = 4096;

impl<'a> Bins<'a> {
    /// Bin every draw of `expanded` (instance `i`'s at index `i`, `None` for an instance
    /// without a usable kernel) into the tiles it overlaps, for a grid of `tiles` tiles,
    /// `tiles_x` per row, in up to `chunks` parallel chunks on the current pool (under the
    /// tier-up gate when `compiler` has a compile pending).
    pub fn new(
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
                runs[t][filled[t]] = e.draw(d, &instances[i]);
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
#[doc(hidden)]
pub fn chunk_ranges(
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

/// The `MODE_RENDER` context of a kernel run over `tile` of `target`, without count arrays.
/// The buffer pointers are the frame's at the tile's origin (`wrapping_add`: a frame
/// without planes or counts has empty buffers, and the kernel never dereferences those).
pub(crate) fn tile_context(tile: &Tile, opts: &RenderOptions, target: &FrameTarget<'_>) -> TileCtx {
    let origin = tile.y0 as usize * target.stride + tile.x0 as usize;
    TileCtx {
        x0: tile.x0 as i32,
        y0: tile.y0 as i32,
        x1: tile.x1 as i32,
        y1: tile.y1 as i32,
        stride: target.stride as u32,
        depth: target.depth.wrapping_add(origin),
        gbuf: target.planes.wrapping_add(origin),
        plane_stride: target.plane_pitch as u32,
        num_planes: target.num_planes as u32,
        write_count: target.counts.wrapping_add(origin),
        sample_x: target.sample[0],
        sample_y: target.sample[1],
        ..context(MODE_RENDER, opts)
    }
}

/// Zero `tile`'s part of the frame and render its draws into it; returns the run-time
/// errors the tile's pixel code counted (its setup code's are counted in the bound runs,
/// see [`super::errors`]).
///
/// # Safety
/// `target` names the buffers of a frame reset for `opts`'s tile grid, `tile` is a tile of
/// that grid, and no other task renders `tile` meanwhile ([`FrameTarget`]'s invariant).
unsafe fn render_tile(
    program: &Program,
    tile: &Tile,
    bin: &[Draw],
    opts: &RenderOptions,
    target: FrameTarget<'_>,
) -> Counts {
    // Every tile starts from zeroed buffers, exactly as if freshly allocated; a tile no draw
    // touches is just that. Cleared here, right before the draws, the rectangle is in cache
    // when they run.
    // SAFETY: the caller's contract.
    unsafe { target.clear(tile) };
    let mut errors = Counts::new();
    if bin.is_empty() {
        return errors;
    }
    CountArrays::with(program, |counts| {
        // Every draw starts from this context (a copy: a kernel may change any field of its
        // own, e.g. fuel, the error or the call depth).
        let mut start = tile_context(tile, opts, &target);
        start.setup_counts = counts.scratch();
        start.pixel_counts = counts.counts();
        let mut failed = false;
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
            // SAFETY: the context names the tile's rectangle of the frame's buffers, which
            // this task alone owns ([`FrameTarget`]): the kernel addresses `(y - y0) * stride
            // + (x - x0)` for y in `y0..y1` and x in whole groups from `x0` up to `x1`, i.e.
            // inside the rectangle, in the depth buffer, in each of the `num_planes` planes
            // `plane_stride` apart, and (only when compiled with count_writes ==
            // opts.count_writes, i.e. when the frame has them) in the write counts; and count
            // arrays of the program's slots. The argument block is long enough for the
            // kernel's layout (checked in `render_into` and when calls were recorded).
            unsafe { (draw.entry)(&mut ctx, draw.args.as_ptr()) };
            failed |= ctx.error != 0;
        }
        if failed {
            counts.take(&mut errors);
        }
    });
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
