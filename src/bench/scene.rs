//! `primflow bench --scene FILE`: the bench's measurements of a user's own scene, and every
//! scene's time to first pixel.
//!
//! A user who writes a primitive wants the figures the built-in workloads get, on their own
//! scene: what its first frame waits for and where that time goes (loading, tier-0
//! compiles, expansion and binning, tiles, shading), what each of its kernel variants costs
//! to compile at both tiers, and how fast frames run with the tier-1 kernels, the tier-0
//! ones, on one thread and on all, and with the hand-written kernels where the scene only
//! draws primitives that have them (checked bit-equal with the JIT's frame first, as every
//! figure of the bench is). The scene is loaded as `primflow render` loads it
//! ([`crate::scene::load_for_render`]), so its own `prims` lines and `--prims` directories
//! count.

use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::Serialize;

use super::{
    compile_timing, format_compile, format_workload, measure, progress_bar, workload_header, CompileTiming, Machine,
    Sources, WorkloadResult,
};
use crate::diag::{Diagnostics, SourceMap};
use crate::handwritten::Flavor;
use crate::jit::Jit;
use crate::runtime::{render_pool, KernelSource};
use crate::workload::ALL_FLAVORS;

/// One scene's time to first pixel, and where it went.
#[derive(Clone, Debug, Serialize)]
pub struct SceneToFirstPixel {
    pub scene: String,
    /// Fastest of [`SCENE_TTFP_RUNS`]: parse the scene and the library files it needs,
    /// start the JIT and the render threads, compile its kernels (tier 0; a tiered JIT),
    /// render its first frame on every thread.
    pub ms: f64,
    /// Of that run: parsing the scene, loading the library files it needs, applying it.
    pub load_ms: f64,
    /// Compiling kernels (tier 0, with the primitives they call), wall time.
    pub compile_ms: f64,
    /// The render after the compiles (expansion, bound pass, binning, tiles, shading), and
    /// of that the serial setup (expansion, bound pass, binning), the tiles and the
    /// deferred shading pass, as `RenderStats` splits it.
    pub render_ms: f64,
    pub setup_ms: f64,
    pub tiles_ms: f64,
    pub shade_ms: f64,
}

/// Each scene is brought to its first pixel this many times; the fastest counts (a shared
/// machine adds its load to the others).
pub const SCENE_TTFP_RUNS: usize = 3;

/// The example scenes, built into the binary so the bench runs anywhere.
const EXAMPLE_SCENES: [(&str, &str); 5] = [
    ("triangles.scene", include_str!("../../examples/triangles.scene")),
    (
        "interpolators.scene",
        include_str!("../../examples/interpolators.scene"),
    ),
    ("spheres.scene", include_str!("../../examples/spheres.scene")),
    ("geometry.scene", include_str!("../../examples/geometry.scene")),
    ("nurb_surface.scene", include_str!("../../examples/nurb_surface.scene")),
];

/// Issue 5's "a scene's time to first pixel <= 20 ms including parsing and compiling every
/// primitive it uses", for the example scenes (see [`scene_to_first_pixel`]).
pub fn example_scenes_to_first_pixel() -> Result<Vec<SceneToFirstPixel>, String> {
    EXAMPLE_SCENES
        .iter()
        .map(|(name, text)| scene_to_first_pixel(name, text, Path::new("."), &[]))
        .collect()
}

/// Scene `text` (named `name`; its `prims` lines resolved against `base`, with the extra
/// primitive directories `dirs`) brought to its first pixel the way `primflow render` does it:
/// everything from parsing the scene and the library files it needs to the finished first
/// frame, tier-0 kernels first and tier-1 ones taking over as the background compiler
/// finishes them. The fastest of [`SCENE_TTFP_RUNS`]. Errors: the scene's diagnostics.
pub fn scene_to_first_pixel(
    name: &str,
    text: &str,
    base: &Path,
    dirs: &[PathBuf],
) -> Result<SceneToFirstPixel, String> {
    let mut best: Option<SceneToFirstPixel> = None;
    for _ in 0..SCENE_TTFP_RUNS {
        let started = Instant::now();
        let mut sources = SourceMap::new();
        let mut diags = Diagnostics::new();
        let file = sources.add(name, text.to_string());
        let r = crate::scene::load_for_render(&mut sources, file, base, dirs, &mut diags)
            .ok_or_else(|| diags.render(&sources))?;
        let load_ms = started.elapsed().as_secs_f64() * 1e3;
        let mut jit = Jit::tiered(r.program().clone()).map_err(|e| e.to_string())?;
        let pool = render_pool(0).map_err(|e| e.to_string())?;
        let frame = pool.install(|| r.render(&mut jit));
        let ms = started.elapsed().as_secs_f64() * 1e3;
        if frame.diags.has_errors() {
            return Err(format!("{name}: {}", frame.diags.render(&sources)));
        }
        // Outside the timing: the next run must not share the machine with this one's
        // tier-1 compiles.
        jit.wait_for_tier_up();
        let s = &frame.stats;
        let micros = |m: u64| m as f64 / 1e3;
        let run = SceneToFirstPixel {
            scene: name.to_string(),
            ms,
            load_ms,
            compile_ms: micros(s.kernels_micros),
            render_ms: micros(s.render_micros.saturating_sub(s.kernels_micros)),
            setup_ms: micros(s.setup_micros.saturating_sub(s.kernels_micros)),
            tiles_ms: micros(s.tiles_micros),
            shade_ms: micros(s.shade_micros),
        };
        if best.as_ref().is_none_or(|b| run.ms < b.ms) {
            best = Some(run);
        }
    }
    best.ok_or_else(|| format!("{name}: not rendered"))
}

/// What `primflow bench --scene` measures.
#[derive(Clone, Debug)]
pub struct SceneBenchOptions {
    pub scene: PathBuf,
    /// Extra primitive directories, as `primflow render --prims`.
    pub prims: Vec<PathBuf>,
    /// Timed runs per kernel (median reported).
    pub runs: usize,
    pub progress: bool,
}

/// `primflow bench --scene`'s results.
#[derive(Clone, Debug, Serialize)]
pub struct SceneBenchReport {
    #[serde(flatten)]
    pub machine: Machine,
    pub scene: String,
    pub width: u32,
    pub height: u32,
    pub first_frame: SceneToFirstPixel,
    /// Every kernel variant the scene's instances use, in first-use order.
    pub compile: Vec<CompileTiming>,
    /// The timed frames (`primitives`: the scene's instances).
    pub frames: WorkloadResult,
    /// The hand-written forms not timed, each with the reason (a primitive or key it lacks).
    pub handwritten_skipped: Vec<(String, String)>,
}

/// Benchmark the scene of `opts` (see the module doc). Errors: the scene's diagnostics, or
/// the first disagreement between kernel sources.
pub fn run_scene(opts: &SceneBenchOptions) -> Result<SceneBenchReport, String> {
    let text = crate::scene::read_file(&opts.scene)?;
    let name = opts.scene.display().to_string();
    let base = opts.scene.parent().unwrap_or(Path::new("."));
    let bar = progress_bar(opts.progress)?;
    bar.set_message("first frame");
    let first_frame = scene_to_first_pixel(&name, &text, base, &opts.prims)?;

    let mut sources = SourceMap::new();
    let mut diags = Diagnostics::new();
    let file = sources.add(&name, text);
    let mut r = crate::scene::load_for_render(&mut sources, file, base, &opts.prims, &mut diags)
        .ok_or_else(|| diags.render(&sources))?;
    let program = r.program().clone();
    let threads = rayon::current_num_threads().max(1);
    let one = render_pool(1).map_err(|e| e.to_string())?;
    let all = render_pool(threads).map_err(|e| e.to_string())?;

    bar.set_message("compiles");
    let compile = r
        .variants()
        .list()
        .iter()
        .map(|(func, key)| compile_timing(&program, "", *func, key, &all))
        .collect::<Result<Vec<_>, _>>()?;

    // The hand-written forms that can render the scene: every primitive it draws (and every
    // one those call) must have one for its key.
    let mut src = Sources::new(&program)?;
    let mut forms = vec![];
    let mut handwritten_skipped = vec![];
    for flavor in ALL_FLAVORS {
        let out = one.install(|| r.render(src.handwritten(flavor) as &mut dyn KernelSource));
        match out.diags.items.iter().find(|d| d.is_error()) {
            None => forms.push(flavor),
            Some(d) => handwritten_skipped.push((Flavor::describe(flavor).to_string(), d.message.clone())),
        }
    }
    bar.set_message("frames");
    let primitives = r.instances().len();
    let frames = measure(
        &name,
        &mut r,
        primitives,
        &forms,
        &mut src,
        &one,
        &all,
        opts.runs.max(1),
        None,
        &bar,
    )?;
    bar.finish_and_clear();
    Ok(SceneBenchReport {
        machine: Machine::of(&src.jit, threads),
        scene: name,
        width: r.options.width,
        height: r.options.height,
        first_frame,
        compile,
        frames,
        handwritten_skipped,
    })
}

/// The scene report as text.
pub fn format_scene_report(report: &SceneBenchReport) -> String {
    let f = &report.first_frame;
    let w = &report.frames;
    let mut s = report.machine.header();
    s.push_str(&format!(
        "scene {}: {}x{}, {} primitives, {} draws after expansion, {} pixels written (depth writes) per frame\n\n",
        report.scene, report.width, report.height, w.primitives, w.draws, w.pixels_written
    ));
    s.push_str(&format!(
        "first frame, as `primflow render` (tier-0 kernels, {} threads; fastest of {SCENE_TTFP_RUNS}): {:.1} ms\n\
         \x20 load {:.1} ms (scene, library files it needs), compile {:.1} ms (tier 0), setup {:.1} ms \
         (expansion, bound pass, binning), tiles {:.1} ms, shade {:.1} ms\n\n",
        report.machine.threads, f.ms, f.load_ms, f.compile_ms, f.setup_ms, f.tiles_ms, f.shade_ms
    ));
    s.push_str(&format_compile(&report.compile));
    s.push_str(
        "\nframes (interleaved runs, medians, each into a reused frame; setup, tiles, shade: the\n\
         frame's parts: expansion, bound pass and binning; the tile kernels; deferred shading;\n\
         ratios: the median of each round's ratio)\n",
    );
    s.push_str(&workload_header());
    s.push_str(&format_workload(w, report.machine.threads));
    for (form, why) in &report.handwritten_skipped {
        s.push_str(&format!("not timed: hand-written {form}: {why}\n"));
    }
    s
}
