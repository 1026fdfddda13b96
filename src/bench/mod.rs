//! `primflow bench`: JIT kernels against hand-written Rust kernels of the same primitives, on
//! the same scenes, in the same process.
//!
//! Every workload is rendered first by each kernel source and the frames compared bit for
//! bit (a benchmark of kernels that disagree measures nothing); then the sources are timed
//! interleaved (JIT, scalar, SSE, AVX2, JIT on all threads, ...) for several rounds, each
//! starting one source later, and the median frame time is reported, so drift of the
//! machine (clock, other load) hits every kernel alike; a ratio of two sources is the
//! median of each round's own ratio ([`paired_ratio`]). Each configuration renders its
//! timed frames into one `Frame` of its own, reused from run to run (`Renderer::render_into`), as an application renders frame after
//! frame into the same buffers: a timed frame pays for no frame allocation and no page
//! faults on fresh buffers. Throughput is depth writes per second (pixels that passed coverage and the
//! Z test) and primitives per second.

use std::sync::Arc;
use std::time::Instant;

use indicatif::{ProgressBar, ProgressStyle};
use serde::Serialize;

use crate::diag::{Diagnostics, SourceMap};
use crate::handwritten::{Flavor, Handwritten};
use crate::ir::Program;
use crate::jit::Jit;
use crate::runtime::{render_pool, Frame, KernelSource, Registry, Renderer};

mod llvmpipe;
mod samples;
mod scene;
use crate::workload::{
    bind, effects_scene, layers_for, same_frame, scene, submit, tri_with_params, workloads, EffectSet, GlScene, Lcg,
    Workload, ALL_FLAVORS, EFFECT_SETS, SIZE,
};
pub use llvmpipe::worker as llvmpipe_worker;
use llvmpipe::Llvmpipe;
pub use samples::{format_samples, SamplesRow, SamplesSeries};
pub use scene::{
    example_scenes_to_first_pixel, format_scene_report, run_scene, scene_to_first_pixel, SceneBenchOptions,
    SceneBenchReport, SceneToFirstPixel, SCENE_TTFP_RUNS,
};

#[derive(Clone, Debug)]
pub struct BenchOptions {
    /// Only workloads whose name contains this.
    pub filter: Option<String>,
    /// Fewer primitives, at most 5 runs (finishes in well under two minutes).
    pub quick: bool,
    /// Timed runs per kernel (median reported).
    pub runs: usize,
    pub progress: bool,
    /// A primflow binary to run as `primflow llvmpipe-worker`, timing Mesa's llvmpipe on the
    /// workloads with reference llvmpipe figures ([`llvmpipe`]); `None`: the reference
    /// figures alone.
    pub llvmpipe: Option<std::path::PathBuf>,
}

impl Default for BenchOptions {
    fn default() -> BenchOptions {
        BenchOptions {
            filter: None,
            quick: false,
            runs: 7,
            progress: true,
            llvmpipe: None,
        }
    }
}

/// Which kernel source rendered a row of a workload's timings.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum KernelKind {
    /// The tiered JIT once its tier-1 kernels are in (what every frame after the first few runs).
    Jit,
    /// The JIT's tier-0 kernels (what the first frame runs while tier 1 compiles).
    JitTier0,
    /// A hand-written form.
    Handwritten(Flavor),
    /// The JIT (tier 1) with expansion off: a calling primitive's setup reruns in every tile.
    JitSetupPerTile,
    /// Mesa's llvmpipe drawing the same geometry (see [`llvmpipe`]): on one thread, one
    /// rasterizer thread pinned to one CPU with its main thread; on all threads, a rasterizer
    /// thread per CPU.
    Llvmpipe,
}

#[derive(Clone, Debug, Serialize)]
pub struct KernelTiming {
    pub kind: KernelKind,
    pub kernel: String,
    pub threads: usize,
    pub median_ms: f64,
    /// The fastest of the runs: the figure least inflated by other load on a shared machine.
    pub min_ms: f64,
    /// Every timed run's frame time, one per round, in round order.
    pub runs_ms: Vec<f64>,
    /// Medians of the frame's parts (`RenderStats`): the serial setup (expansion, bound
    /// pass, binning), the tiles, and the deferred shading pass.
    pub setup_ms: f64,
    pub tiles_ms: f64,
    pub shade_ms: f64,
    pub mpixels_per_s: f64,
    pub mprims_per_s: f64,
}

#[derive(Clone, Debug, Serialize)]
pub struct WorkloadResult {
    pub workload: String,
    pub primitives: usize,
    /// Draws of a frame: instances drawn as themselves plus the calls the expanded ones make.
    pub draws: usize,
    pub pixels_written: u64,
    pub timings: Vec<KernelTiming>,
    /// JIT (tier 1) throughput over its tier-0 kernels', one thread each. This and every
    /// ratio of two rows below is [`paired_ratio`]: the median of the rounds' own ratios.
    pub jit_vs_tier0: f64,
    /// JIT throughput over the hand-written kernel's, one thread each (above 1: the JIT is
    /// faster).
    /// `None` where no hand-written kernel exists.
    pub jit_vs_scalar: Option<f64>,
    /// Over the 4-lane SSE4.1 kernel (the JIT's width).
    pub jit_vs_sse: Option<f64>,
    /// Over the 8-lane AVX2 kernel.
    pub jit_vs_simd: Option<f64>,
    /// JIT all-threads throughput over JIT one-thread throughput (paired, as above).
    pub thread_scaling: f64,
    /// The same from the fastest run of each (one core taken by other load for part of the
    /// runs inflates the all-threads median far more than the one-thread one).
    pub thread_scaling_best: f64,
    /// JIT frame time with the calling primitives' setup rerun per tile over the time with
    /// it run once (expansion); `None` for workloads without calling primitives.
    pub expand_speedup: Option<f64>,
    /// llvmpipe on the same geometry, where it was measured (its row is in `timings`).
    pub llvmpipe: Option<LlvmpipeRun>,
    /// Why llvmpipe (on one thread, or else on all) was not measured on a workload that
    /// has its twin, if it failed there.
    pub llvmpipe_error: Option<String>,
}

/// What llvmpipe did on a workload.
#[derive(Clone, Debug, Serialize)]
pub struct LlvmpipeRun {
    /// Its `GL_RENDERER` (LLVM version, vector width).
    pub renderer: String,
    /// The CPU its process was pinned to.
    pub cpu: Option<usize>,
    /// Samples that passed the depth test per frame (the JIT's figure is `pixels_written`).
    pub pixels_written: u64,
    /// Its first frame, shaders compiled on the way.
    pub first_frame_ms: f64,
    /// JIT (tier 1, one thread) throughput over llvmpipe's.
    pub jit_vs_llvmpipe: f64,
    /// The JIT on all threads over llvmpipe with a rasterizer thread per CPU, where that
    /// was measured.
    pub jit_vs_llvmpipe_all_threads: Option<f64>,
    /// llvmpipe's own all-threads throughput over its one-thread throughput.
    pub thread_scaling: Option<f64>,
}

impl WorkloadResult {
    /// The row of `kind` on `threads` threads.
    pub fn timing(&self, kind: KernelKind, threads: usize) -> Option<&KernelTiming> {
        self.timings.iter().find(|t| t.kind == kind && t.threads == threads)
    }
}

/// Compile time of one workload's variant. `micros` / `tier1_micros` are wall time of the
/// kernel itself (callees excluded), which other threads and processes inflate on a loaded
/// machine; the `*cpu_micros` fields are the compiling thread's CPU time, comparable
/// between runs (see [`crate::jit::CompileCost`]).
#[derive(Clone, Debug, Serialize)]
pub struct CompileTiming {
    /// The workload whose first instance's variant this is.
    pub workload: String,
    pub variant: String,
    /// Tier 0 (what the first frame waits for), wall time, microseconds.
    pub micros: u64,
    /// Tier 1 (compiled in the background; the timed runs use it), wall time, microseconds.
    pub tier1_micros: u64,
    /// Tier 0, the kernel itself, thread CPU time, microseconds.
    pub cpu_micros: u64,
    /// Tier 0, the whole batch (the kernel, the primitives it calls, linking), thread CPU
    /// time, microseconds: what the first frame waits for.
    pub batch_cpu_micros: u64,
    /// Tier 1, the kernel itself, thread CPU time (of the background thread), microseconds.
    pub tier1_cpu_micros: u64,
    /// Tier 1, the whole batch, thread CPU time, microseconds.
    pub tier1_batch_cpu_micros: u64,
    /// Tier 0 again, right after the first compile, in another fresh JIT (thread CPU of
    /// the kernel, microseconds): the compiler's code and data are then in the caches, as
    /// in `examples/compile_probe.rs`, while `cpu_micros` follows rendering (caches
    /// evicted), which on the development machine costs up to twice as much.
    pub warm_cpu_micros: u64,
    /// Of `warm_cpu_micros`, Cranelift's part (instruction selection, register allocation,
    /// emission; see [`crate::jit::CompileCost::codegen_cpu_micros`]): what compiling this
    /// much CLIF costs whatever the front end does.
    pub warm_codegen_cpu_micros: u64,
    /// Instructions in the tier-0 kernel's CLIF.
    pub clif_insts: u64,
}

/// What ran the bench: the machine and the kernels' builds on it.
#[derive(Clone, Debug, Serialize)]
pub struct Machine {
    pub machine: String,
    pub isa: String,
    pub simd_kernel: String,
    pub sse_kernel: String,
    /// The deferred shading pass's build on this CPU ([`crate::runtime::shading::simd_build`]).
    pub shading_kernel: String,
    pub threads: usize,
}

impl Machine {
    fn of(jit: &Jit, threads: usize) -> Machine {
        Machine {
            machine: machine_description(threads),
            isa: jit.isa_summary(),
            simd_kernel: Flavor::Avx2.describe().to_string(),
            sse_kernel: Flavor::Sse.describe().to_string(),
            shading_kernel: crate::runtime::shading::simd_build(),
            threads,
        }
    }

    /// The report's first lines.
    fn header(&self) -> String {
        format!(
            "machine: {}\nJIT: {}\nhand-written SSE: {}\nhand-written SIMD: {}\nshading pass: {}\n\n",
            self.machine, self.isa, self.sse_kernel, self.simd_kernel, self.shading_kernel
        )
    }
}

#[derive(Clone, Debug, Serialize)]
pub struct BenchReport {
    #[serde(flatten)]
    pub machine: Machine,
    pub workloads: Vec<WorkloadResult>,
    pub compile: Vec<CompileTiming>,
    /// Parse + check the library, compile the kernels of a one-triangle scene, render it.
    pub time_to_first_pixel_ms: f64,
    /// The same for each example scene, as `primflow render` runs it (see
    /// [`example_scenes_to_first_pixel`]).
    pub scenes_to_first_pixel: Vec<SceneToFirstPixel>,
    /// What a frame costs per shading effect (`None` when filtered out).
    pub effects: Option<EffectsSeries>,
    /// What N samples per pixel cost against one (`None` when filtered out).
    pub samples: Option<SamplesSeries>,
    /// The JIT's one-thread figures against Mesa llvmpipe's, for the workloads it has.
    pub llvmpipe: Vec<LlvmpipeComparison>,
    /// Which llvmpipe was measured here (renderer, CPU), or why none was.
    pub llvmpipe_status: String,
}

/// The library, with every primitive the workloads draw (a `PRIMFLOW_PRIMS` file replacing
/// one of the library's without it: an error, not a panic while building a scene).
fn library(sources: &mut SourceMap) -> Result<Arc<Program>, String> {
    let mut diags = Diagnostics::new();
    let program = Registry::load(sources, &[], &[], &mut diags)
        .map(|r| r.program)
        .ok_or_else(|| diags.render(sources))?;
    let missing: Vec<&str> = ["screen_triangle", "polygon", "sphere", "nurb_surface"]
        .into_iter()
        .filter(|name| program.find(name).is_none())
        .collect();
    if !missing.is_empty() {
        return Err(format!(
            "the primitive library lacks {} (the bench draws them)",
            missing.join(", ")
        ));
    }
    Ok(program)
}

/// One frame of `r` by `source` on `pool`, and what the render measured; errors refused.
fn render(
    r: &Renderer,
    source: &mut (dyn KernelSource + Send),
    pool: &rayon::ThreadPool,
) -> Result<(Frame, crate::runtime::RenderStats), String> {
    let out = pool.install(|| r.render(source));
    if out.diags.has_errors() {
        return Err(format!("{:?}", out.diags.items));
    }
    Ok((out.frame, out.stats))
}

/// One timed frame rendered into `frame`, reusing its buffers as an application rendering
/// frame after frame does (and as llvmpipe's figures are measured: into the same
/// framebuffer): milliseconds, and the frame's parts ([`FrameParts`]).
fn render_timed_into(
    r: &Renderer,
    source: &mut (dyn KernelSource + Send),
    pool: &rayon::ThreadPool,
    frame: &mut Frame,
) -> Result<FrameParts, String> {
    let started = Instant::now();
    let report = pool.install(|| r.render_into(source, frame));
    let ms = started.elapsed().as_secs_f64() * 1e3;
    if report.diags.has_errors() {
        return Err(format!("{:?}", report.diags.items));
    }
    let s = &report.stats;
    Ok(FrameParts {
        ms,
        setup_ms: s.setup_micros.saturating_sub(s.kernels_micros) as f64 / 1e3,
        tiles_ms: s.tiles_micros as f64 / 1e3,
        shade_ms: s.shade_micros as f64 / 1e3,
    })
}

/// One timed frame: the whole of it and its parts (`RenderStats`), milliseconds.
#[derive(Clone, Copy, Default)]
struct FrameParts {
    ms: f64,
    /// Expansion, bound pass and binning (serial); kernel compiles excluded.
    setup_ms: f64,
    tiles_ms: f64,
    shade_ms: f64,
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

/// How many times faster row `fast` ran than row `slow`: the median over the timed rounds
/// of `slow`'s frame time over `fast`'s in the same round (the ratio of the two medians
/// where the rows have different run counts). Rows of one round run within a second of each
/// other, so a slow stretch of a shared host that spans a round divides out of the round's
/// ratio; in the ratio of medians, each median may come from a different stretch.
pub fn paired_ratio(slow: &KernelTiming, fast: &KernelTiming) -> f64 {
    if slow.runs_ms.len() != fast.runs_ms.len() || slow.runs_ms.is_empty() {
        return slow.median_ms / fast.median_ms;
    }
    paired(&slow.runs_ms, &fast.runs_ms)
}

/// The median of `slow[r] / fast[r]` over rounds `r` (the same number of each).
fn paired(slow: &[f64], fast: &[f64]) -> f64 {
    median(slow.iter().zip(fast).map(|(s, f)| s / f).collect())
}

/// The kernel sources the bench renders a workload with, all for one program.
struct Sources {
    /// Tiered: its first frame runs tier-0 kernels; timed once the tier-1 ones are in.
    jit: Jit,
    /// Tier 0 only: the kernels a first frame runs while tier 1 compiles.
    tier0: Jit,
    /// Scalar, SSE, AVX2 (the order of [`ALL_FLAVORS`]).
    handwritten: [Handwritten; 3],
}

impl Sources {
    fn new(program: &Arc<Program>) -> Result<Sources, String> {
        Ok(Sources {
            jit: Jit::tiered(program.clone()).map_err(|e| e.to_string())?,
            tier0: Jit::at_tier(program.clone(), crate::jit::Tier::Fast).map_err(|e| e.to_string())?,
            handwritten: ALL_FLAVORS.map(|f| Handwritten::new(program.clone(), f)),
        })
    }

    fn handwritten(&mut self, flavor: Flavor) -> &mut Handwritten {
        let i = ALL_FLAVORS.iter().position(|&f| f == flavor).unwrap_or(0);
        &mut self.handwritten[i]
    }
}

/// The rows of a workload's timings, in report order: a source, and whether it runs on
/// all threads.
const ROWS: [(KernelKind, bool); 9] = [
    (KernelKind::Jit, false),
    (KernelKind::JitTier0, false),
    (KernelKind::Handwritten(Flavor::Scalar), false),
    (KernelKind::Handwritten(Flavor::Sse), false),
    (KernelKind::Handwritten(Flavor::Avx2), false),
    (KernelKind::Llvmpipe, false),
    (KernelKind::Jit, true),
    (KernelKind::Llvmpipe, true),
    (KernelKind::JitSetupPerTile, false),
];

fn row_name(kind: KernelKind, all_threads: bool) -> String {
    match kind {
        KernelKind::Llvmpipe if all_threads => "llvmpipe, all CPUs".into(),
        KernelKind::Jit => "JIT".into(),
        KernelKind::JitTier0 => "JIT tier 0".into(),
        KernelKind::Handwritten(Flavor::Scalar) => "scalar".into(),
        KernelKind::Handwritten(Flavor::Sse) => format!("SSE {}", Flavor::Sse.describe()),
        KernelKind::Handwritten(Flavor::Avx2) => format!("SIMD {}", Flavor::Avx2.describe()),
        KernelKind::JitSetupPerTile => "JIT, setup per tile".into(),
        KernelKind::Llvmpipe => "llvmpipe, 1 CPU".into(),
    }
}

/// llvmpipe's twin of workload `name` (the quick bench's sizes when `quick`), for the
/// llvmpipe worker.
fn gl_scene(quick: bool, name: &str) -> Option<GlScene> {
    workloads(quick)
        .into_iter()
        .find(|w| w.name == name)?
        .gl
        .map(|make| make())
}

/// llvmpipe for [`measure`]: the running workers (one thread, and all threads where there
/// are more), the workload's name as the worker finds it and whether the bench is quick.
struct GlTwin<'a> {
    one: Option<&'a mut Llvmpipe>,
    all: Option<&'a mut Llvmpipe>,
    name: &'a str,
    quick: bool,
}

/// Measure one workload: render it with every source and check the frames agree bit for bit
/// (the JIT's tier-0 and tier-1 kernels, the hand-written `forms`, the per-tile path of a
/// scene of calling primitives; a benchmark of kernels that disagree measures nothing),
/// count the pixels written, then time `runs` interleaved rounds, each configuration
/// rendering into a frame of its own reused from round to round. `r`'s options are
/// restored before returning.
#[allow(clippy::too_many_arguments)]
fn measure(
    name: &str,
    r: &mut Renderer,
    primitives: usize,
    forms: &[Flavor],
    src: &mut Sources,
    one: &rayon::ThreadPool,
    all: &rayon::ThreadPool,
    runs: usize,
    gl: Option<GlTwin>,
    bar: &ProgressBar,
) -> Result<WorkloadResult, String> {
    let threads = all.current_num_threads();
    bar.inc_length((5 + runs) as u64);
    let (reference, draws, expands) = frames_agree(name, r, forms, src, one)?;
    bar.inc(3);
    r.options.count_writes = true;
    let counted = render(r, &mut src.jit, one);
    r.options.count_writes = false;
    let pixels: u64 = counted?
        .0
        .write_count_values()
        .map_or(0, |c| c.iter().map(|&x| x as u64).sum());
    // llvmpipe's first frames (its shaders compile then); a worker that fails is left out
    // of this workload from then on, not the bench. Index 0: one thread, 1: all threads.
    let (mut gl_workers, mut gl_firsts, mut gl_errors) = ([None, None], [None, None], [None, None]);
    if let Some(twin) = gl {
        gl_workers = [twin.one, twin.all];
        for (i, slot) in gl_workers.iter_mut().enumerate() {
            if let Some(worker) = slot.as_deref_mut() {
                match worker.setup(twin.quick, twin.name) {
                    Ok(first) => gl_firsts[i] = Some(first),
                    Err(e) => {
                        gl_errors[i] = Some(e);
                        *slot = None;
                    }
                }
            }
        }
    }
    bar.inc(2);

    let mut times: [Vec<FrameParts>; ROWS.len()] = Default::default();
    let mut frames: [Frame; ROWS.len()] = std::array::from_fn(|_| Frame::empty());
    for round in 0..runs {
        // Each round starts one row later, so no source always runs right after the same
        // other one (an all-threads row leaves both CPUs' caches and llvmpipe's threads
        // settling; the row after it used to be the JIT's one-thread row every time).
        for i in (0..ROWS.len()).map(|k| (k + round) % ROWS.len()) {
            let (kind, all_threads) = ROWS[i];
            let pool = if all_threads { all } else { one };
            if kind == KernelKind::Llvmpipe {
                let w = usize::from(all_threads);
                match gl_workers[w].as_deref_mut().map(Llvmpipe::frame) {
                    // Its frame has no parts the bench can see.
                    Some(Ok(f)) => times[i].push(FrameParts {
                        ms: f.ms,
                        setup_ms: f64::NAN,
                        tiles_ms: f64::NAN,
                        shade_ms: f64::NAN,
                    }),
                    // A worker that fails mid-way loses its row, not the bench.
                    Some(Err(e)) => {
                        gl_errors[w] = Some(e);
                        gl_workers[w] = None;
                        times[i].clear();
                    }
                    None => {}
                }
                continue;
            }
            let source: &mut (dyn KernelSource + Send) = match kind {
                KernelKind::Jit => &mut src.jit,
                KernelKind::JitTier0 => &mut src.tier0,
                KernelKind::Handwritten(f) if forms.contains(&f) => src.handwritten(f),
                KernelKind::JitSetupPerTile if expands => &mut src.jit,
                _ => continue,
            };
            r.options.expand_calls = kind != KernelKind::JitSetupPerTile;
            let timed = render_timed_into(r, source, pool, &mut frames[i]);
            r.options.expand_calls = true;
            times[i].push(timed?);
        }
        bar.inc(1);
    }
    if !frames.iter().all(|f| f.width == 0 || same_frame(&reference, f)) {
        return Err(format!("{name}: a frame rendered into reused buffers differs"));
    }
    let timings = kernel_timings(times, pixels, &gl_firsts, primitives, threads);
    let row = |kind: KernelKind, n: usize| timings.iter().find(|t| t.kind == kind && t.threads == n);
    let over_jit =
        |kind: KernelKind| row(kind, 1).map(|t| row(KernelKind::Jit, 1).map_or(f64::NAN, |jit| paired_ratio(t, jit)));
    let (thread_scaling, thread_scaling_best) = match (row(KernelKind::Jit, 1), row(KernelKind::Jit, threads)) {
        (Some(one), Some(all)) if threads > 1 => (paired_ratio(one, all), one.min_ms / all.min_ms),
        _ => (f64::NAN, f64::NAN),
    };
    Ok(WorkloadResult {
        workload: name.to_string(),
        primitives,
        draws,
        pixels_written: pixels,
        jit_vs_tier0: over_jit(KernelKind::JitTier0).unwrap_or(f64::NAN),
        jit_vs_scalar: over_jit(KernelKind::Handwritten(Flavor::Scalar)),
        jit_vs_sse: over_jit(KernelKind::Handwritten(Flavor::Sse)),
        jit_vs_simd: over_jit(KernelKind::Handwritten(Flavor::Avx2)),
        thread_scaling,
        thread_scaling_best,
        expand_speedup: over_jit(KernelKind::JitSetupPerTile),
        llvmpipe: match (&gl_workers[0], gl_firsts[0]) {
            (Some(worker), Some(first)) => {
                let all_threads = |kind| row(kind, threads).filter(|_| threads > 1);
                let lp_all = all_threads(KernelKind::Llvmpipe);
                Some(LlvmpipeRun {
                    renderer: worker.renderer.clone(),
                    cpu: worker.cpu,
                    pixels_written: first.samples,
                    first_frame_ms: first.ms,
                    jit_vs_llvmpipe: over_jit(KernelKind::Llvmpipe).unwrap_or(f64::NAN),
                    jit_vs_llvmpipe_all_threads: lp_all
                        .zip(all_threads(KernelKind::Jit))
                        .map(|(lp, jit)| paired_ratio(lp, jit)),
                    thread_scaling: lp_all
                        .zip(row(KernelKind::Llvmpipe, 1))
                        .map(|(all, one)| paired_ratio(one, all)),
                })
            }
            _ => None,
        },
        llvmpipe_error: match gl_errors {
            [Some(e), _] => Some(e),
            [None, Some(e)] => Some(format!("with a rasterizer thread per CPU: {e}")),
            [None, None] => None,
        },
        timings,
    })
}

/// Render workload `name` with every source [`measure`] times and check the frames agree
/// bit for bit: the JIT's tier-1 and tier-0 kernels, the hand-written `forms`, and for a
/// scene of calling primitives the per-tile path (`RenderOptions::expand_calls` off). The
/// JIT's first frame (the reference), the number of draws and whether the scene expands.
fn frames_agree(
    name: &str,
    r: &mut Renderer,
    forms: &[Flavor],
    src: &mut Sources,
    one: &rayon::ThreadPool,
) -> Result<(Frame, usize, bool), String> {
    // The JIT's first frame may run tier-0 kernels; the tier-1 ones must agree with it bit
    // for bit, and the timed runs below use them.
    let (reference, stats) = render(r, &mut src.jit, one)?;
    let draws = stats.instances - stats.expanded_instances + stats.expanded_calls;
    src.jit.wait_for_tier_up();
    if !same_frame(&reference, &render(r, &mut src.jit, one)?.0) {
        return Err(format!("{name}: the JIT's tier-1 frame differs from its tier-0 frame"));
    }
    if !same_frame(&reference, &render(r, &mut src.tier0, one)?.0) {
        return Err(format!(
            "{name}: the JIT's tier-0-only frame differs from its tiered one"
        ));
    }
    for &flavor in forms {
        if !same_frame(&reference, &render(r, src.handwritten(flavor), one)?.0) {
            return Err(format!(
                "{name}: the hand-written {} kernel's frame differs from the JIT's",
                row_name(KernelKind::Handwritten(flavor), false)
            ));
        }
    }
    // A scene of calling primitives (polygon, NURB) also times the per-tile path, where the
    // caller's setup reruns in every tile (`RenderOptions::expand_calls` off): the
    // before/after of expansion, checked equal first.
    let expands = r
        .instances()
        .iter()
        .any(|inst| crate::abi::expands(r.program(), inst.func));
    if expands {
        r.options.expand_calls = false;
        let per_tile = render(r, &mut src.jit, one);
        r.options.expand_calls = true;
        if !same_frame(&reference, &per_tile?.0) {
            return Err(format!("{name}: the per-tile frame differs from the expanded one"));
        }
    }
    Ok((reference, draws, expands))
}

/// One [`KernelTiming`] per row that ran: medians of the timed rounds, throughput by the
/// JIT's count of depth writes `pixels` (llvmpipe's by its own first frame's samples).
fn kernel_timings(
    times: [Vec<FrameParts>; ROWS.len()],
    pixels: u64,
    gl_firsts: &[Option<llvmpipe::GlFrame>; 2],
    primitives: usize,
    threads: usize,
) -> Vec<KernelTiming> {
    times
        .into_iter()
        .enumerate()
        .filter(|(_, t)| !t.is_empty())
        .map(|(i, t)| {
            let part = |f: fn(&FrameParts) -> f64| median(t.iter().map(f).collect());
            let ms = part(|p| p.ms);
            let (kind, all_threads) = ROWS[i];
            // llvmpipe's throughput by its own count of the pixels it wrote.
            let pixels = match (kind, gl_firsts[usize::from(all_threads)]) {
                (KernelKind::Llvmpipe, Some(first)) => first.samples,
                _ => pixels,
            };
            KernelTiming {
                kind,
                kernel: row_name(kind, all_threads),
                threads: if all_threads { threads } else { 1 },
                median_ms: ms,
                min_ms: t.iter().map(|p| p.ms).fold(f64::INFINITY, f64::min),
                runs_ms: t.iter().map(|p| p.ms).collect(),
                setup_ms: part(|p| p.setup_ms),
                tiles_ms: part(|p| p.tiles_ms),
                shade_ms: part(|p| p.shade_ms),
                mpixels_per_s: pixels as f64 / ms / 1e3,
                mprims_per_s: primitives as f64 / ms / 1e3,
            }
        })
        .collect()
}

/// Compile time of `func`'s variant `key` at both tiers on fresh JITs (see [`CompileTiming`]),
/// compiled on a thread of `pool` as a render compiles them: tier 0's helper tasks then
/// share its CPUs as in a frame (outside a pool, the calling thread and all of rayon's
/// global pool would take them, one thread more than the CPUs).
fn compile_timing(
    program: &Arc<Program>,
    workload: &str,
    func: crate::ir::FuncId,
    key: &crate::abi::VariantKey,
    pool: &rayon::ThreadPool,
) -> Result<CompileTiming, String> {
    pool.install(|| compile_timing_here(program, workload, func, key))
}

fn compile_timing_here(
    program: &Arc<Program>,
    workload: &str,
    func: crate::ir::FuncId,
    key: &crate::abi::VariantKey,
) -> Result<CompileTiming, String> {
    let mut fresh = Jit::tiered(program.clone()).map_err(|e| e.to_string())?;
    let kernel = fresh.kernel(func, key).map_err(|e| e.to_string())?;
    // The same variant again at once, caches warm (see `CompileTiming::warm_cpu_micros`).
    let mut warm = Jit::at_tier(program.clone(), crate::jit::Tier::Fast).map_err(|e| e.to_string())?;
    warm.kernel(func, key).map_err(|e| e.to_string())?;
    let warm_cost = warm.compile_cost(func, key).unwrap_or_default();
    fresh.wait_for_tier_up();
    let tier1 = fresh.tier_up_kernel(func, key);
    let cost = fresh.compile_cost(func, key).unwrap_or_default();
    let tier1_cost = fresh.tier_up_compile_cost(func, key).unwrap_or_default();
    Ok(CompileTiming {
        workload: workload.to_string(),
        variant: format!(
            "{} {}",
            program.func(func).name,
            runs_of(&crate::runtime::describe_key(key))
        ),
        micros: kernel.compile_micros,
        tier1_micros: tier1.map_or(0, |k| k.compile_micros),
        cpu_micros: cost.cpu_micros,
        batch_cpu_micros: cost.batch_cpu_micros,
        tier1_cpu_micros: tier1_cost.cpu_micros,
        tier1_batch_cpu_micros: tier1_cost.batch_cpu_micros,
        warm_cpu_micros: warm_cost.cpu_micros,
        warm_codegen_cpu_micros: warm_cost.codegen_cpu_micros,
        clif_insts: warm_cost.clif_insts,
    })
}

/// A variant key's description with runs of equal bindings counted (`linear:1 x16`): the
/// compile table's lines stay readable for wide keys.
pub fn runs_of(key: &str) -> String {
    let mut out: Vec<(String, usize)> = vec![];
    for part in key.split(',') {
        match out.last_mut() {
            Some((last, n)) if last == part => *n += 1,
            _ => out.push((part.to_string(), 1)),
        }
    }
    out.iter()
        .map(|(part, n)| if *n == 1 { part.clone() } else { format!("{part} x{n}") })
        .collect::<Vec<_>>()
        .join(",")
}

/// A progress bar in the bench's style (hidden when `show` is off); measuring grows its length.
fn progress_bar(show: bool) -> Result<ProgressBar, String> {
    let bar = if show {
        ProgressBar::new(0)
    } else {
        ProgressBar::hidden()
    };
    bar.set_style(ProgressStyle::with_template("{bar:40} {pos}/{len} {msg}").map_err(|e| e.to_string())?);
    Ok(bar)
}

pub fn run(opts: &BenchOptions) -> Result<BenchReport, String> {
    let ttfp = time_to_first_pixel()?;
    let scenes_to_first_pixel = example_scenes_to_first_pixel()?;
    let mut sources = SourceMap::new();
    let program = library(&mut sources)?;
    let threads = rayon::current_num_threads().max(1);
    let one = render_pool(1).map_err(|e| e.to_string())?;
    let all = render_pool(threads).map_err(|e| e.to_string())?;
    let runs = if opts.quick { opts.runs.min(5) } else { opts.runs }.max(1);
    let selected: Vec<Workload> = workloads(opts.quick)
        .into_iter()
        .filter(|w| opts.filter.as_ref().is_none_or(|f| w.name.contains(f.as_str())))
        .collect();
    let bar = progress_bar(opts.progress)?;
    let mut src = Sources::new(&program)?;
    // llvmpipe only where a workload has its twin: one worker with one rasterizer thread,
    // and where there are more CPUs one with a rasterizer thread per CPU.
    let mut llvmpipe = None;
    let mut llvmpipe_all = None;
    let mut llvmpipe_status = "not asked for".to_string();
    if let Some(exe) = opts
        .llvmpipe
        .as_ref()
        .filter(|_| selected.iter().any(|w| w.gl.is_some()) || samples::samples_selected(opts.filter.as_deref()))
    {
        match Llvmpipe::start(exe, 1) {
            Ok(lp) => {
                llvmpipe_status = format!(
                    "{}, pinned to CPU {}",
                    lp.renderer,
                    lp.cpu.map_or("-".into(), |c| c.to_string())
                );
                llvmpipe = Some(lp);
                if threads > 1 {
                    match Llvmpipe::start(exe, threads) {
                        Ok(lp) => llvmpipe_all = Some(lp),
                        Err(e) => llvmpipe_status.push_str(&format!("; with {threads} rasterizer threads: {e}")),
                    }
                }
            }
            Err(e) => llvmpipe_status = format!("not measured: {e}"),
        }
    }
    let mut results = vec![];
    let mut compile = vec![];
    for w in &selected {
        bar.set_message(w.name.clone());
        let mut r = scene(&program, SIZE, w, false);
        if let Some(inst) = r.instances().first() {
            compile.push(compile_timing(&program, &w.name, inst.func, &inst.key, &all)?);
        }
        results.push(measure(
            &w.name,
            &mut r,
            w.primitives,
            w.handwritten,
            &mut src,
            &one,
            &all,
            runs,
            w.gl.as_ref().map(|_| GlTwin {
                one: llvmpipe.as_mut(),
                all: llvmpipe_all.as_mut(),
                name: &w.name,
                quick: opts.quick,
            }),
            &bar,
        )?);
    }
    drop(llvmpipe_all);
    let samples = if samples::samples_selected(opts.filter.as_deref()) {
        bar.set_message("multisampling series");
        Some(samples::samples_series(
            &program,
            opts.quick,
            runs,
            &one,
            &all,
            llvmpipe.as_mut(),
            &bar,
        )?)
    } else {
        None
    };
    drop(llvmpipe);
    let effects = if effects_selected(opts.filter.as_deref()) {
        bar.set_message("effects series");
        Some(effects_series(
            &program,
            SIZE,
            layers_for(opts.quick),
            runs,
            &one,
            &all,
            &bar,
        )?)
    } else {
        None
    };
    bar.finish_and_clear();
    let llvmpipe = llvmpipe_comparisons(&results);
    Ok(BenchReport {
        machine: Machine::of(&src.jit, threads),
        workloads: results,
        compile,
        time_to_first_pixel_ms: ttfp,
        scenes_to_first_pixel,
        effects,
        samples,
        llvmpipe,
        llvmpipe_status,
    })
}

/// Parse and check the whole library, compile the kernels of a one-triangle scene and render
/// it: what a user waits for before the first pixel (tier-0 kernels; tier 1 compiles in the
/// background meanwhile).
pub fn time_to_first_pixel() -> Result<f64, String> {
    let started = Instant::now();
    let mut sources = SourceMap::new();
    let program = library(&mut sources)?;
    let mut r = Renderer::new(program.clone());
    r.set_image_size(64, 64).map_err(|e| e.message.clone())?;
    bind(&mut r, Some("perspective_linear"), 4);
    let t = tri_with_params(
        [[1.0, 1.0, 0.5, 1.0], [60.0, 4.0, 0.5, 1.0], [9.0, 60.0, 0.5, 1.0]],
        4,
        &mut Lcg(3),
    );
    submit(&mut r, &t, 4);
    let mut jit = Jit::tiered(program).map_err(|e| e.to_string())?;
    let pool = render_pool(1).map_err(|e| e.to_string())?;
    render(&r, &mut jit, &pool)?;
    Ok(started.elapsed().as_secs_f64() * 1e3)
}

fn machine_description(threads: usize) -> String {
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .map(|l| l.split(':').nth(1).unwrap_or("").trim().to_string())
        })
        .unwrap_or_else(|| std::env::consts::ARCH.to_string());
    // The all-threads runs' pool (`render_pool`): pinned threads scale, unpinned ones may not.
    let pinned = match crate::runtime::pool::pinning_plan(threads) {
        Some(cpus) => format!("pinned to CPUs {cpus:?}"),
        None => "not pinned".to_string(),
    };
    format!("{cpu}, {threads} threads ({pinned})")
}

/// The report as a text table.
pub fn format_table(report: &BenchReport) -> String {
    let mut s = report.machine.header();
    s.push_str(
        "ms: median frame time; setup, tiles, shade: its parts (expansion, bound pass and binning;\n\
         the tile kernels; the deferred shading pass), medians; ratios: the median of each\n\
         round's ratio\n",
    );
    s.push_str(&workload_header());
    for w in &report.workloads {
        s.push_str(&format_workload(w, report.machine.threads));
        s.push('\n');
    }
    s.push_str(&format_scaling_and_llvmpipe(report));
    s.push('\n');
    if let Some(effects) = &report.effects {
        s.push_str(&format_effects(effects));
        s.push('\n');
    }
    if let Some(samples) = &report.samples {
        s.push_str(&format_samples(samples));
        s.push('\n');
    }
    s.push_str(&format_compile(&report.compile));
    s.push_str(&format!(
        "time to first pixel (parse + check library, compile, render): {:.1} ms\n",
        report.time_to_first_pixel_ms
    ));
    if !report.scenes_to_first_pixel.is_empty() {
        s.push_str(&format!(
            "example scenes to first pixel, as `primflow render` (parse the scene and the library files it needs, tier-0 compile, first frame on {} threads; fastest of {SCENE_TTFP_RUNS}):\n",
            report.machine.threads
        ));
        for t in &report.scenes_to_first_pixel {
            s.push_str(&format!(
                "  {:<22} {:>7.1} ms   (compile {:.1} ms, render {:.1} ms)\n",
                t.scene, t.ms, t.compile_ms, t.render_ms
            ));
        }
    }
    s
}

/// One workload's rows (kernel, threads, frame time and its parts, throughput) and ratios.
/// The compile-time table: per variant, both tiers.
pub fn format_compile(compile: &[CompileTiming]) -> String {
    let mut s = String::new();
    s.push_str(
        "JIT compile time per variant, microseconds: thread CPU of the kernel (of its whole batch:\n\
         callees, linking) and wall time of the kernel; tier 0 is what the first frame waits for,\n\
         tier 1 compiles in the background (its wall time includes waiting for a core); warm:\n\
         tier 0 compiled again at once in a fresh JIT (caches warm, as in compile_probe), and of\n\
         that Cranelift's part (instruction selection, register allocation, emission), which\n\
         grows with the kernel's tier-0 CLIF instructions\n",
    );
    s.push_str(&format!(
        "  {:>22} {:>8} {:>18} {:>6} | {:>22} {:>8}\n",
        "tier 0 CPU (batch)", "wall", "warm (Cranelift)", "CLIF", "tier 1 CPU (batch)", "wall"
    ));
    for c in compile {
        s.push_str(&format!(
            "  {:>22} {:>8} {:>18} {:>6} | {:>22} {:>8}  {}{}\n",
            format!("{} ({})", c.cpu_micros, c.batch_cpu_micros),
            c.micros,
            format!("{} ({})", c.warm_cpu_micros, c.warm_codegen_cpu_micros),
            c.clif_insts,
            format!("{} ({})", c.tier1_cpu_micros, c.tier1_batch_cpu_micros),
            c.tier1_micros,
            if c.workload.is_empty() {
                String::new()
            } else {
                format!("{}: ", c.workload)
            },
            c.variant
        ));
    }
    s
}

/// The header of [`format_workload`]'s rows.
pub fn workload_header() -> String {
    format!(
        "{:<32} {:<26} {:>7} {:>9} {:>8} {:>8} {:>8} {:>9} {:>9}\n",
        "workload", "kernel", "threads", "ms", "setup", "tiles", "shade", "Mpix/s", "Mprim/s"
    )
}

pub fn format_workload(w: &WorkloadResult, threads: usize) -> String {
    let mut s = String::new();
    // A part the source does not report (llvmpipe's) is a dash.
    let part = |ms: f64| {
        if ms.is_nan() {
            "-".to_string()
        } else {
            format!("{ms:.2}")
        }
    };
    for t in &w.timings {
        s.push_str(&format!(
            "{:<32} {:<26} {:>7} {:>9.2} {:>8} {:>8} {:>8} {:>9.1} {:>9.3}\n",
            w.workload,
            t.kernel,
            t.threads,
            t.median_ms,
            part(t.setup_ms),
            part(t.tiles_ms),
            part(t.shade_ms),
            t.mpixels_per_s,
            t.mprims_per_s
        ));
    }
    let ratio = |r: Option<f64>| r.map_or("n/a (no hand-written kernel)".to_string(), |r| format!("{r:.2}x"));
    s.push_str(&format!(
        "{:<32} JIT/tier 0 {:.2}x   JIT/scalar {}   JIT/SSE {}   JIT/AVX2 {}   {} threads/1 thread {:.2}x\n",
        "",
        w.jit_vs_tier0,
        ratio(w.jit_vs_scalar),
        ratio(w.jit_vs_sse),
        ratio(w.jit_vs_simd),
        threads,
        w.thread_scaling
    ));
    if let Some(l) = &w.llvmpipe {
        s.push_str(&format!("{:<32} JIT/llvmpipe {:.2}x", "", l.jit_vs_llvmpipe));
        if let (Some(ratio), Some(scaling)) = (l.jit_vs_llvmpipe_all_threads, l.thread_scaling) {
            s.push_str(&format!(
                "   on {threads} threads: JIT/llvmpipe {ratio:.2}x (llvmpipe {threads} threads/1 thread {scaling:.2}x)"
            ));
        }
        s.push_str(&format!(
            "   (llvmpipe's first frame, shaders compiled on the way: {:.1} ms)\n",
            l.first_frame_ms
        ));
    }
    if let Some(e) = &w.llvmpipe_error {
        s.push_str(&format!("{:<32} llvmpipe not measured: {e}\n", ""));
    }
    if let Some(x) = w.expand_speedup {
        s.push_str(&format!(
            "{:<32} setup once per primitive (expanded) vs once per tile: {x:.2}x the speed\n",
            ""
        ));
    }
    s
}

// ---------------------------------------------------------------------------------------
// The effects series: what the deferred shading pass costs, effect by effect.
// ---------------------------------------------------------------------------------------

/// One frame of the effects series, timed (medians over the interleaved runs).
#[derive(Clone, Debug, Serialize)]
pub struct EffectsRow {
    pub effects: String,
    pub set: EffectSet,
    /// The frame is shaded by the library shaders the fixed lines map to (JIT), not by the
    /// hand-written Rust pass.
    pub language: bool,
    /// For a language row: its frame time over the Rust row's of the same set (paired by
    /// round); above 1 the language shaders are slower.
    pub language_over_rust: Option<f64>,
    /// Whole frame (bound pass, tiles, shading), one thread.
    pub frame_ms: f64,
    /// Of which the tile kernels (the same primitives in every row).
    pub kernels_ms: f64,
    /// Of which the deferred shading pass (0 when the scene turns no effect on).
    pub shading_ms: f64,
    /// Frame time minus the `none` frame's (medians), and the ratio to it (paired by
    /// round, as [`paired_ratio`]).
    pub extra_ms: f64,
    pub ratio_to_none: f64,
    /// Whole frame with all threads, and 1-thread time over it (paired by round).
    pub frame_ms_all_threads: f64,
    pub shading_ms_all_threads: f64,
    pub thread_scaling: f64,
}

#[derive(Clone, Debug, Serialize)]
pub struct EffectsSeries {
    pub size: u32,
    pub layers: usize,
    pub threads: usize,
    pub rows: Vec<EffectsRow>,
}

/// Whether the effects series runs under `filter` (any of its row names, or "effects").
fn effects_selected(filter: Option<&str>) -> bool {
    filter.is_none_or(|f| {
        "effects".contains(f)
            || EFFECT_SETS
                .iter()
                .any(|(name, _)| format!("effects {name}").contains(f))
    })
}

/// Render the effects series at `size` x `size`: first every frame once on each pool, checking
/// that the thread count changes nothing and that every effect changes the colours (a
/// benchmark of an effect that does nothing measures nothing); then `runs` interleaved rounds
/// (every set, one thread then all threads) and the medians.
pub fn effects_series(
    program: &Arc<Program>,
    size: u32,
    layers: usize,
    runs: usize,
    one: &rayon::ThreadPool,
    all: &rayon::ThreadPool,
    bar: &ProgressBar,
) -> Result<EffectsSeries, String> {
    let mut jit = Jit::new(program.clone()).map_err(|e| e.to_string())?;
    // Every set twice: the Rust pass, then the same fixed lines as library shaders (the
    // `none` set has no shading either way).
    let sets: Vec<(String, EffectSet, bool)> = EFFECT_SETS
        .iter()
        .flat_map(|&(name, set)| {
            let language = (set != EFFECT_SETS[0].1).then(|| (format!("{name} [language]"), set, true));
            std::iter::once((name.to_string(), set, false)).chain(language)
        })
        .collect();
    let scenes: Vec<Renderer> = sets
        .iter()
        .map(|&(_, set, language)| {
            let mut r = effects_scene(program, size, layers, set);
            r.options.fixed_shading_in_language = language;
            r
        })
        .collect();
    bar.inc_length((sets.len() * (2 + 2 * runs)) as u64);
    let render_timed = |r: &Renderer, jit: &mut Jit, pool: &rayon::ThreadPool| {
        let started = Instant::now();
        let out = pool.install(|| r.render(jit));
        let ms = started.elapsed().as_secs_f64() * 1e3;
        if out.diags.has_errors() {
            return Err(format!("effects series: {:?}", out.diags.items));
        }
        Ok((out, ms))
    };

    let mut none_colours: Option<Vec<[f32; 3]>> = None;
    for ((name, set, _), r) in sets.iter().zip(&scenes) {
        let (single, _) = render_timed(r, &mut jit, one)?;
        let (multi, _) = render_timed(r, &mut jit, all)?;
        if !same_frame(&single.frame, &multi.frame) || single.frame.color_values() != multi.frame.color_values() {
            return Err(format!("effects {name}: the frame depends on the thread count"));
        }
        let colours = rendered_colours(&single.frame);
        match &none_colours {
            None => none_colours = Some(colours),
            Some(none) => {
                if single.effects.lit != (set.lights > 0)
                    || single.effects.fog != set.fog
                    || single.effects.texture != set.texture
                    || colours == *none
                {
                    return Err(format!(
                        "effects {name}: the shading pass did not change the colours (effects run: {})",
                        single.effects
                    ));
                }
            }
        }
        bar.inc(2);
    }

    // Interleaved timed rounds: [set][one, all] -> (frame ms, kernels ms, shading ms), each
    // (set, pool) rendering into its own frame, reused from round to round.
    let mut times: Vec<[Vec<[f64; 3]>; 2]> = vec![Default::default(); scenes.len()];
    let mut frames: Vec<[Frame; 2]> = scenes.iter().map(|_| [Frame::empty(), Frame::empty()]).collect();
    for _ in 0..runs {
        for ((r, t), f) in scenes.iter().zip(times.iter_mut()).zip(frames.iter_mut()) {
            for (slot, pool) in [one, all].into_iter().enumerate() {
                let started = Instant::now();
                let report = pool.install(|| r.render_into(&mut jit, &mut f[slot]));
                let ms = started.elapsed().as_secs_f64() * 1e3;
                if report.diags.has_errors() {
                    return Err(format!("effects series: {:?}", report.diags.items));
                }
                let s = &report.stats;
                t[slot].push([ms, s.tiles_micros as f64 / 1e3, s.shade_micros as f64 / 1e3]);
                bar.inc(1);
            }
        }
    }
    let med = |v: &[[f64; 3]], k: usize| median(v.iter().map(|x| x[k]).collect());
    let frames_of = |v: &[[f64; 3]]| v.iter().map(|x| x[0]).collect::<Vec<f64>>();
    let none_ms = med(&times[0][0], 0);
    let none_runs = frames_of(&times[0][0]);
    let rows = sets
        .iter()
        .zip(&times)
        .enumerate()
        .map(|(i, ((name, set, language), [t1, tn]))| {
            let frame_ms = med(t1, 0);
            let runs = frames_of(t1);
            let frame_ms_all_threads = med(tn, 0);
            // A language row follows its Rust row.
            let language_over_rust = language.then(|| paired(&runs, &frames_of(&times[i - 1][0])));
            EffectsRow {
                effects: name.clone(),
                set: *set,
                language: *language,
                language_over_rust,
                frame_ms,
                kernels_ms: med(t1, 1),
                shading_ms: med(t1, 2),
                extra_ms: frame_ms - none_ms,
                // Paired by round, as the workloads' ratios (`paired_ratio`).
                ratio_to_none: paired(&runs, &none_runs),
                frame_ms_all_threads,
                shading_ms_all_threads: med(tn, 2),
                thread_scaling: paired(&runs, &frames_of(tn)),
            }
        })
        .collect();
    Ok(EffectsSeries {
        size,
        layers,
        threads: all.current_num_threads(),
        rows,
    })
}

/// Every pixel's displayed colour (clamped), row-major.
fn rendered_colours(frame: &Frame) -> Vec<[f32; 3]> {
    (0..frame.height)
        .flat_map(|y| (0..frame.width).map(move |x| (x, y)))
        .map(|(x, y)| frame.color_at(x, y))
        .collect()
}

/// The effects series as a text table.
pub fn format_effects(series: &EffectsSeries) -> String {
    let mut s = format!(
        "effects series: {size}x{size}, {layers} full-viewport layers (Cs, N, st perspective_linear), JIT; \
         frame = bound pass + tile kernels (written straight into the frame) + deferred shading; \
         [language] rows shade with the library shaders the fixed lines map to, inside the tile tasks \
         (their shading ms is only gathering the colours), lang/rust = their frame over the Rust row's\n",
        size = series.size,
        layers = series.layers
    );
    s.push_str(&format!(
        "{:<37} {:>9} {:>10} {:>10} {:>9} {:>8} {:>11} {:>10} {:>9} {:>8}\n",
        "effects",
        "frame ms",
        "kernels ms",
        "shading ms",
        "+ms",
        "x none",
        format!("{}t frame ms", series.threads),
        format!("{}t shade ms", series.threads),
        format!("{}t/1t", series.threads),
        "lang/rust"
    ));
    for r in &series.rows {
        s.push_str(&format!(
            "{:<37} {:>9.2} {:>10.2} {:>10.2} {:>+9.2} {:>7.2}x {:>11.2} {:>10.2} {:>8.2}x {:>8}\n",
            r.effects,
            r.frame_ms,
            r.kernels_ms,
            r.shading_ms,
            r.extra_ms,
            r.ratio_to_none,
            r.frame_ms_all_threads,
            r.shading_ms_all_threads,
            r.thread_scaling,
            r.language_over_rust.map(|x| format!("{x:.2}x")).unwrap_or_default()
        ));
    }
    s
}

// ---------------------------------------------------------------------------------------
// Thread scaling and the llvmpipe reference figures.
// ---------------------------------------------------------------------------------------

/// Mesa llvmpipe (LLVM JIT, 8-wide AVX2, one rasterizer thread) on the same workloads, as
/// measured on another machine (the reference figures): (workload, figure, unit). Units: `Mpix/s` = depth writes (hit pixels)
/// per second, `Mprim/s` = primitives per second.
pub const LLVMPIPE: [(&str, f64, &str); 6] = [
    ("fill perspective_linear K=4", 746.0, "Mpix/s"),
    ("fill linear K=4", 842.0, "Mpix/s"),
    ("fill none K=0", 976.0, "Mpix/s"),
    ("small perspective_linear K=4", 2.1, "Mprim/s"),
    ("sphere implicit N", 88.0, "Mpix/s"),
    ("sphere lit", 88.0, "Mpix/s"),
];

/// The JIT's one-thread figure on a workload against llvmpipe's — the figure, and
/// llvmpipe measured here on the same geometry where it could be — with the fastest
/// hand-written kernel's beside it: where that one falls short of llvmpipe too, the limit is
/// not the compiler but the width and the frame around the kernels.
#[derive(Clone, Debug, Serialize)]
pub struct LlvmpipeComparison {
    pub workload: String,
    pub unit: String,
    /// Issue 5's figure for llvmpipe.
    pub llvmpipe: f64,
    pub jit_one_thread: f64,
    /// `jit_one_thread / llvmpipe` (above 1: faster than the figure).
    pub ratio: f64,
    /// llvmpipe measured in this run (same unit; Mpix/s by its own count of pixels written).
    pub measured: Option<f64>,
    /// The JIT's throughput over the measured llvmpipe's, by frame time (above 1: faster).
    pub measured_ratio: Option<f64>,
    /// The same on all threads (llvmpipe with a rasterizer thread per CPU): the JIT's
    /// figure, llvmpipe's, and the ratio by frame time.
    pub jit_all_threads: Option<f64>,
    pub measured_all_threads: Option<f64>,
    pub measured_all_threads_ratio: Option<f64>,
    /// Pixels written per frame: the JIT's depth writes and llvmpipe's passing samples.
    pub jit_pixels: u64,
    pub measured_pixels: Option<u64>,
    /// The fastest hand-written kernel on one thread: its name and figure (same unit).
    pub best_handwritten: Option<(String, f64)>,
}

/// Compare the measured workloads that llvmpipe has a figure for.
pub fn llvmpipe_comparisons(results: &[WorkloadResult]) -> Vec<LlvmpipeComparison> {
    LLVMPIPE
        .iter()
        .filter_map(|&(name, reference, unit)| {
            let w = results.iter().find(|w| w.workload.starts_with(name))?;
            let figure = |t: &KernelTiming| {
                if unit == "Mprim/s" {
                    t.mprims_per_s
                } else {
                    t.mpixels_per_s
                }
            };
            let jit = w.timing(KernelKind::Jit, 1)?;
            let measured = w.timing(KernelKind::Llvmpipe, 1);
            let all_threads = |kind| w.timings.iter().find(|t| t.kind == kind && t.threads > 1);
            let measured_all_threads_ratio = w.llvmpipe.as_ref().and_then(|l| l.jit_vs_llvmpipe_all_threads);
            let best_handwritten = w
                .timings
                .iter()
                .filter(|t| matches!(t.kind, KernelKind::Handwritten(_)) && t.threads == 1)
                .max_by(|a, b| figure(a).total_cmp(&figure(b)))
                .map(|t| (t.kernel.clone(), figure(t)));
            Some(LlvmpipeComparison {
                workload: w.workload.clone(),
                unit: unit.to_string(),
                llvmpipe: reference,
                jit_one_thread: figure(jit),
                ratio: figure(jit) / reference,
                measured: measured.map(figure),
                measured_ratio: w.llvmpipe.as_ref().map(|l| l.jit_vs_llvmpipe),
                jit_all_threads: all_threads(KernelKind::Jit)
                    .map(figure)
                    .filter(|_| measured_all_threads_ratio.is_some()),
                measured_all_threads: all_threads(KernelKind::Llvmpipe)
                    .map(figure)
                    .filter(|_| measured_all_threads_ratio.is_some()),
                measured_all_threads_ratio,
                jit_pixels: w.pixels_written,
                measured_pixels: w.llvmpipe.as_ref().map(|l| l.pixels_written),
                best_handwritten,
            })
        })
        .collect()
}

/// Per workload: JIT one thread, all threads, and the ratio, by medians and by the fastest
/// run; then llvmpipe's figures.
fn format_scaling_and_llvmpipe(report: &BenchReport) -> String {
    let n = report.machine.threads;
    let mut s = format!(
        "thread scaling (JIT, ms per whole frame: bound pass, tile clears and kernels, and the \
         deferred shading pass where the scene has effects, as in `sphere lit`): 1 thread vs {n} threads, \
         medians and fastest runs (on a shared machine, load on one core inflates the {n}-thread median most)\n\
         {:<36} {:>9} {:>9} {:>7}   {:>9} {:>9} {:>7}\n",
        "",
        "1t med",
        format!("{n}t med"),
        "ratio",
        "1t best",
        format!("{n}t best"),
        "ratio",
    );
    for w in &report.workloads {
        if let (Some(one), Some(all)) = (
            w.timing(KernelKind::Jit, 1),
            w.timing(KernelKind::Jit, report.machine.threads),
        ) {
            s.push_str(&format!(
                "  {:<34} {:>9.2} {:>9.2} {:>6.2}x   {:>9.2} {:>9.2} {:>6.2}x\n",
                w.workload,
                one.median_ms,
                all.median_ms,
                w.thread_scaling,
                one.min_ms,
                all.min_ms,
                w.thread_scaling_best
            ));
        }
    }
    if !report.llvmpipe.is_empty() {
        s.push_str(&format!(
            "\nagainst Mesa llvmpipe, one thread: measured here ({}; one rasterizer thread, the same geometry, \
             frames interleaved with the JIT's; its pixels: samples passing its depth test, over the JIT's depth \
             writes) and the reference figures measured on another machine (8-wide AVX2, one rasterizer thread, \"this machine kind\"); the \
             fastest hand-written kernel beside them:\n",
            report.llvmpipe_status
        ));
        for c in &report.llvmpipe {
            s.push_str(&format!(
                "  {:<34} JIT {:>7.1} {:<7}",
                c.workload, c.jit_one_thread, c.unit
            ));
            let best = |against: f64| {
                c.best_handwritten
                    .as_ref()
                    .map(|(_, figure)| format!(", hand-written best {:.2}x", figure / against))
                    .unwrap_or_default()
            };
            match (c.measured, c.measured_ratio, c.measured_pixels) {
                (Some(figure), Some(ratio), Some(px)) => s.push_str(&format!(
                    " | llvmpipe here {figure:>7.1} (pixels {:.3}x the JIT's): JIT {ratio:.2}x{}",
                    px as f64 / c.jit_pixels.max(1) as f64,
                    best(figure)
                )),
                _ => s.push_str(" | llvmpipe here: -"),
            }
            s.push_str(&format!(
                " | issue's figure {:>6.1}: JIT {:.2}x{}",
                c.llvmpipe,
                c.ratio,
                best(c.llvmpipe)
            ));
            if let Some((kernel, figure)) = &c.best_handwritten {
                s.push_str(&format!(" ({kernel} {figure:.1})"));
            }
            s.push('\n');
        }
        let all_threads: Vec<_> = report
            .llvmpipe
            .iter()
            .filter_map(|c| {
                Some((
                    c,
                    c.jit_all_threads?,
                    c.measured_all_threads?,
                    c.measured_all_threads_ratio?,
                ))
            })
            .collect();
        if !all_threads.is_empty() {
            s.push_str(&format!(
                "against Mesa llvmpipe on {n} threads (a rasterizer thread per CPU, unpinned; the JIT on its {n}-thread pool):\n"
            ));
            for (c, jit, lp, ratio) in all_threads {
                s.push_str(&format!(
                    "  {:<34} JIT {jit:>7.1} {:<7} | llvmpipe {lp:>7.1}: JIT {ratio:.2}x\n",
                    c.workload, c.unit
                ));
            }
        }
    }
    s
}
