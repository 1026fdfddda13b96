//! `primflow bench`: JIT kernels against hand-written Rust kernels of the same primitives, on
//! the same scenes, in the same process.
//!
//! Every workload is rendered first by each kernel source and the frames compared bit for
//! bit (a benchmark of kernels that disagree measures nothing); then the sources are timed
//! interleaved (JIT, scalar, SSE, AVX2, JIT on all threads, ...) for several runs and the
//! median frame time is reported, so drift of the machine (clock, other load) hits every
//! kernel alike. Throughput is depth writes per second (pixels that passed coverage and the
//! Z test) and primitives per second.

use std::sync::Arc;
use std::time::Instant;

use indicatif::{ProgressBar, ProgressStyle};
use serde::Serialize;

use crate::diag::{Diagnostics, SourceMap};
use crate::handwritten::{Flavor, Handwritten};
use crate::ir::Program;
use crate::jit::Jit;
use crate::runtime::{Frame, KernelSource, Registry, Renderer, Value};

#[derive(Clone, Debug)]
pub struct BenchOptions {
    /// Only workloads whose name contains this.
    pub filter: Option<String>,
    /// Fewer primitives and runs (finishes in well under two minutes).
    pub quick: bool,
    /// Timed runs per kernel (median reported).
    pub runs: usize,
    pub progress: bool,
}

impl Default for BenchOptions {
    fn default() -> BenchOptions {
        BenchOptions {
            filter: None,
            quick: false,
            runs: 7,
            progress: true,
        }
    }
}

#[derive(Clone, Debug, Serialize)]
pub struct KernelTiming {
    pub kernel: String,
    pub threads: usize,
    pub median_ms: f64,
    pub mpixels_per_s: f64,
    pub mprims_per_s: f64,
}

#[derive(Clone, Debug, Serialize)]
pub struct WorkloadResult {
    pub workload: String,
    pub primitives: usize,
    pub pixels_written: u64,
    pub timings: Vec<KernelTiming>,
    /// JIT throughput over the hand-written kernel's, one thread each (above 1: the JIT is
    /// faster).
    /// `None` where no hand-written kernel exists.
    pub jit_vs_scalar: Option<f64>,
    /// Over the 4-lane SSE4.1 kernel (the JIT's width).
    pub jit_vs_sse: Option<f64>,
    /// Over the 8-lane AVX2 kernel.
    pub jit_vs_simd: Option<f64>,
    /// JIT all-threads throughput over JIT one-thread throughput.
    pub thread_scaling: f64,
    /// JIT frame time with the calling primitives' setup rerun per tile over the time with
    /// it run once (expansion); `None` for workloads without calling primitives.
    pub expand_speedup: Option<f64>,
}

#[derive(Clone, Debug, Serialize)]
pub struct CompileTiming {
    pub variant: String,
    pub micros: u64,
}

#[derive(Clone, Debug, Serialize)]
pub struct BenchReport {
    pub machine: String,
    pub isa: String,
    pub simd_kernel: String,
    pub sse_kernel: String,
    pub threads: usize,
    pub workloads: Vec<WorkloadResult>,
    pub compile: Vec<CompileTiming>,
    /// Parse + check the library, compile the kernels of a one-triangle scene, render it.
    pub time_to_first_pixel_ms: f64,
    pub not_covered: Vec<String>,
}

const SIZE: u32 = 512;

/// One benchmark scene: instances submitted to a renderer.
struct Workload {
    name: String,
    build: Box<dyn Fn(&mut Renderer)>,
    primitives: usize,
    /// The hand-written forms that exist for it (screen_triangle and polygon have all three,
    /// sphere and NURB surface scalar and AVX2); empty: the JIT's figures are shown alone.
    handwritten: &'static [Flavor],
}

const ALL_FLAVORS: [Flavor; 3] = [Flavor::Scalar, Flavor::Sse, Flavor::Avx2];

/// (name, interpolation kind) of the four shading parameters of the fill and small workloads.
fn bind(r: &mut Renderer, kind: Option<&str>, k: usize) {
    if let Some(kind) = kind {
        for c in 0..k {
            r.material_interp(&format!("p{c}"), kind, &[])
                .expect("bench scene: material_interp");
        }
    }
}

fn tri(r: &mut Renderer, v: [[f32; 4]; 3], k: usize, rng: &mut Lcg) {
    r.begin("screen_triangle").expect("bench scene: begin");
    r.rast_param("screen_vertex", &Value(v.iter().flatten().copied().collect()))
        .expect("bench scene: rast_param");
    for _ in 0..3 {
        for c in 0..k {
            r.material(&format!("p{c}"), &Value(vec![rng.next() as f32]))
                .expect("bench scene: material");
        }
        r.sequence_point().expect("bench scene: sequence_point");
    }
    r.end().expect("bench scene: end");
}

/// `fill`: full-viewport quads drawn back to front (every pixel passes), per-vertex w in [1, 3].
fn fill(layers: usize, kind: Option<&'static str>, k: usize) -> Workload {
    let label = kind.unwrap_or("none");
    Workload {
        name: format!("fill {label} K={k}"),
        primitives: layers * 2,
        handwritten: &ALL_FLAVORS,
        build: Box::new(move |r| {
            bind(r, kind, k);
            let mut rng = Lcg(1);
            let s = r.options.width as f32;
            for layer in 0..layers {
                let z = (layer + 1) as f32 / (layers + 1) as f32;
                let mut corner = |x: f32, y: f32| [x, y, z, 1.0 + 2.0 * rng.next() as f32];
                let q = [corner(0.0, 0.0), corner(s, 0.0), corner(s, s), corner(0.0, s)];
                tri(r, [q[0], q[1], q[2]], k, &mut rng);
                tri(r, [q[0], q[2], q[3]], k, &mut rng);
            }
        }),
    }
}

/// `small`: triangles of 20 px area, random centre and rotation, back to front.
fn small(count: usize, k: usize) -> Workload {
    Workload {
        name: format!("small perspective_linear K={k}"),
        primitives: count,
        handwritten: &ALL_FLAVORS,
        build: Box::new(move |r| {
            bind(r, Some("perspective_linear"), k);
            let mut rng = Lcg(2);
            // Equilateral, area 20: side^2 * sqrt(3)/4 = 20.
            let radius = (20.0f64 * 4.0 / 3f64.sqrt()).sqrt() / 3f64.sqrt();
            for i in 0..count {
                let z = (i + 1) as f32 / (count + 1) as f32;
                let size = f64::from(r.options.width);
                let (cx, cy) = (rng.next() * size, rng.next() * size);
                let a = rng.next() * std::f64::consts::TAU;
                let v = std::array::from_fn(|j| {
                    let t = a + j as f64 * std::f64::consts::TAU / 3.0;
                    [
                        (cx + radius * t.cos()) as f32,
                        (cy + radius * t.sin()) as f32,
                        z,
                        1.0 + 2.0 * rng.next() as f32,
                    ]
                });
                tri(r, v, k, &mut rng);
            }
        }),
    }
}

/// `sphere`: 20 spheres filling most of the viewport, per-pixel quadrics, normal returned
/// through the `implicit` interpolation.
fn spheres() -> Workload {
    Workload {
        name: "sphere implicit N".into(),
        primitives: 20,
        handwritten: &[Flavor::Scalar, Flavor::Avx2],
        build: Box::new(|r| {
            r.perspective(50.0, 1.0, 100.0);
            r.material_interp("N", "implicit", &[])
                .expect("bench scene: material_interp");
            r.material("N", &Value(vec![0.0, 0.0, 1.0]))
                .expect("bench scene: material");
            let mut rng = Lcg(4);
            for i in 0..20 {
                let (x, y) = ((i % 5) as f64 * 2.2 - 4.4, (i / 5) as f64 * 2.0 - 3.0);
                let z = -8.0 - rng.next() * 2.0;
                r.begin("sphere").expect("bench scene: begin");
                r.rast_param("center", &Value(vec![x as f32, y as f32, z as f32]))
                    .expect("bench scene: center");
                r.rast_param("radius", &Value(vec![1.2 + 0.3 * rng.next() as f32]))
                    .expect("bench scene: radius");
                r.end().expect("bench scene: end");
            }
        }),
    }
}

/// `polygon hither`: quads (4 float parameters, perspective_linear) half of which cross the
/// hither plane and are clipped in the language.
fn polygons(count: usize) -> Workload {
    Workload {
        name: "polygon hither K=4".into(),
        primitives: count,
        handwritten: &ALL_FLAVORS,
        build: Box::new(move |r| {
            r.perspective(60.0, 1.0, 100.0);
            bind(r, Some("perspective_linear"), 4);
            let mut rng = Lcg(5);
            for _ in 0..count {
                let (cx, cy) = (rng.next() * 8.0 - 4.0, rng.next() * 8.0 - 4.0);
                // Near corners at z = -0.5 (in front of the eye, behind the hither plane at 1).
                let (z_near, z_far) = (-0.5 - rng.next(), -6.0 - 4.0 * rng.next());
                r.begin("polygon").expect("bench scene: begin");
                for (x, y, z) in [
                    (cx, cy, z_far),
                    (cx + 2.0, cy, z_far),
                    (cx + 2.0, cy + 2.0, z_near),
                    (cx, cy + 2.0, z_near),
                ] {
                    for c in 0..4 {
                        r.material(&format!("p{c}"), &Value(vec![rng.next() as f32]))
                            .expect("bench scene: material");
                    }
                    r.vertex(x as f32, y as f32, z as f32, 1.0)
                        .expect("bench scene: vertex");
                }
                r.end().expect("bench scene: end");
            }
        }),
    }
}

/// `nurb`: bicubic patches tessellated to 0.5 px in the language.
fn nurbs(count: usize) -> Workload {
    Workload {
        name: "nurb bicubic tol=0.5".into(),
        primitives: count,
        handwritten: &[Flavor::Scalar, Flavor::Avx2],
        build: Box::new(move |r| {
            r.perspective(50.0, 1.0, 100.0);
            let mut rng = Lcg(6);
            for _ in 0..count {
                let (cx, cy, cz) = (rng.next() * 8.0 - 4.0, rng.next() * 6.0 - 3.0, -10.0 - rng.next() * 4.0);
                r.begin("nurb_surface").expect("bench scene: begin");
                r.rast_param("tolerance", &Value(vec![0.5]))
                    .expect("bench scene: tolerance");
                for j in 0..4 {
                    for i in 0..4 {
                        r.rast_param("weight", &Value(vec![1.0])).expect("bench scene: weight");
                        let bump = rng.next() * 1.5 - 0.75;
                        let (x, y, z) = (cx + i as f64 * 0.8, cy + j as f64 * 0.8, cz + bump);
                        r.vertex(x as f32, y as f32, z as f32, 1.0)
                            .expect("bench scene: vertex");
                    }
                }
                r.end().expect("bench scene: end");
            }
        }),
    }
}

fn workloads(quick: bool) -> Vec<Workload> {
    let layers = if quick { 20 } else { 100 };
    let small_count = if quick { 20_000 } else { 200_000 };
    vec![
        fill(layers, Some("perspective_linear"), 4),
        fill(layers, Some("linear"), 4),
        fill(layers, None, 0),
        small(small_count, 4),
        fill(layers, Some("perspective_linear"), 1),
        fill(layers, Some("perspective_linear"), 16),
        small(small_count, 0),
        spheres(),
        polygons(if quick { 500 } else { 5_000 }),
        nurbs(if quick { 20 } else { 50 }),
    ]
}

/// A tiny deterministic generator, so every run benchmarks the same scene.
struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

fn library(sources: &mut SourceMap) -> Result<Arc<Program>, String> {
    let mut diags = Diagnostics::new();
    Registry::load(sources, &[], &[], &mut diags)
        .map(|r| r.program)
        .ok_or_else(|| diags.render(sources))
}

fn render(
    r: &Renderer,
    source: &mut (dyn KernelSource + Send),
    pool: &rayon::ThreadPool,
) -> Result<(Frame, f64), String> {
    let started = Instant::now();
    let out = pool.install(|| r.render(source));
    let ms = started.elapsed().as_secs_f64() * 1e3;
    if out.diags.has_errors() {
        return Err(format!("{:?}", out.diags.items));
    }
    Ok((out.frame, ms))
}

/// A `size` x `size` renderer holding workload `w`'s primitives.
fn scene(program: &Arc<Program>, size: u32, w: &Workload, count_writes: bool) -> Renderer {
    let mut r = Renderer::new(program.clone());
    r.set_image_size(size, size).expect("bench scene: image size");
    r.options.count_writes = count_writes;
    (w.build)(&mut r);
    r
}

/// The `fill` workload (full-viewport quads back to front) at `size` x `size`; the criterion
/// benches use it too.
pub fn fill_scene(program: &Arc<Program>, size: u32, layers: usize, kind: Option<&'static str>, k: usize) -> Renderer {
    scene(program, size, &fill(layers, kind, k), false)
}

/// The `small` workload (20 px triangles, perspective_linear) at `size` x `size`.
pub fn small_scene(program: &Arc<Program>, size: u32, count: usize, k: usize) -> Renderer {
    scene(program, size, &small(count, k), false)
}

/// Bit-for-bit equal depth and shading-parameter planes.
pub fn same_frame(a: &Frame, b: &Frame) -> bool {
    a.depth == b.depth
        && a.planes.len() == b.planes.len()
        && a.planes
            .iter()
            .zip(&b.planes)
            .all(|(x, y)| x.iter().zip(y).all(|(p, q)| p.to_bits() == q.to_bits()))
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

pub fn run(opts: &BenchOptions) -> Result<BenchReport, String> {
    let ttfp = time_to_first_pixel()?;
    let mut sources = SourceMap::new();
    let program = library(&mut sources)?;
    let threads = rayon::current_num_threads().max(1);
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .map_err(|e| e.to_string())?;
    let all = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| e.to_string())?;
    let runs = if opts.quick { opts.runs.min(3) } else { opts.runs }.max(1);
    let selected: Vec<Workload> = workloads(opts.quick)
        .into_iter()
        .filter(|w| opts.filter.as_ref().is_none_or(|f| w.name.contains(f.as_str())))
        .collect();

    let bar = if opts.progress {
        ProgressBar::new((selected.len() * (runs * 5 + 5)) as u64)
    } else {
        ProgressBar::hidden()
    };
    bar.set_style(ProgressStyle::with_template("{bar:40} {pos}/{len} {msg}").map_err(|e| e.to_string())?);

    let mut jit = Jit::new(program.clone()).map_err(|e| e.to_string())?;
    let mut scalar = Handwritten::new(program.clone(), Flavor::Scalar);
    let mut sse = Handwritten::new(program.clone(), Flavor::Sse);
    let mut simd = Handwritten::new(program.clone(), Flavor::Avx2);
    let mut results = vec![];
    let mut compile = vec![];
    for w in &selected {
        bar.set_message(w.name.clone());
        let r = scene(&program, SIZE, w, false);

        // Compile time of this workload's variant, on a fresh JIT.
        let mut fresh = Jit::new(program.clone()).map_err(|e| e.to_string())?;
        for inst in r.instances().iter().take(1) {
            let kernel = fresh.kernel(inst.func, &inst.key).map_err(|e| e.to_string())?;
            compile.push(CompileTiming {
                variant: crate::runtime::describe_key(&inst.key),
                micros: kernel.compile_micros,
            });
        }

        // Correctness first: all four produce the same frame; count the pixels written.
        let (reference, _) = render(&r, &mut jit, &one)?;
        for (name, flavor, source) in [
            ("scalar", Flavor::Scalar, &mut scalar as &mut (dyn KernelSource + Send)),
            ("SSE", Flavor::Sse, &mut sse),
            ("SIMD", Flavor::Avx2, &mut simd),
        ] {
            if w.handwritten.contains(&flavor) {
                let (frame, _) = render(&r, source, &one)?;
                if !same_frame(&reference, &frame) {
                    return Err(format!(
                        "{}: the hand-written {name} kernel's frame differs from the JIT's",
                        w.name
                    ));
                }
            }
            bar.inc(1);
        }
        // Workloads of calling primitives (polygon, NURB) also time the per-tile path, where
        // the caller's setup reruns in every tile (`RenderOptions::expand_calls` off): the
        // before/after of expansion, checked equal first.
        let per_tile = r
            .instances()
            .iter()
            .any(|inst| crate::abi::expands(&program, inst.func))
            .then(|| {
                let mut p = scene(&program, SIZE, w, false);
                p.options.expand_calls = false;
                p
            });
        if let Some(p) = &per_tile {
            if !same_frame(&reference, &render(p, &mut jit, &one)?.0) {
                return Err(format!("{}: the per-tile frame differs from the expanded one", w.name));
            }
        }
        let counted = scene(&program, SIZE, w, true);
        let (frame, _) = render(&counted, &mut jit, &one)?;
        let pixels: u64 = frame
            .write_counts
            .as_ref()
            .map_or(0, |c| c.iter().map(|&x| x as u64).sum());
        bar.inc(2);

        // Interleaved timed runs.
        let mut times: [Vec<f64>; 6] = Default::default();
        for _ in 0..runs {
            times[0].push(render(&r, &mut jit, &one)?.1);
            for (slot, flavor, source) in [
                (1, Flavor::Scalar, &mut scalar),
                (2, Flavor::Sse, &mut sse),
                (3, Flavor::Avx2, &mut simd),
            ] {
                if w.handwritten.contains(&flavor) {
                    times[slot].push(render(&r, source, &one)?.1);
                }
            }
            times[4].push(render(&r, &mut jit, &all)?.1);
            if let Some(p) = &per_tile {
                times[5].push(render(p, &mut jit, &one)?.1);
            }
            bar.inc(5);
        }
        let names = [
            "JIT".to_string(),
            "scalar".to_string(),
            format!("SSE {}", Flavor::Sse.describe()),
            format!("SIMD {}", Flavor::Avx2.describe()),
            "JIT".to_string(),
            "JIT, setup per tile".to_string(),
        ];
        let timings: Vec<KernelTiming> = times
            .into_iter()
            .zip(names)
            .enumerate()
            .filter(|(_, (t, _))| !t.is_empty())
            .map(|(i, (t, kernel))| {
                let ms = median(t);
                KernelTiming {
                    kernel,
                    threads: if i == 4 { threads } else { 1 },
                    median_ms: ms,
                    mpixels_per_s: pixels as f64 / ms / 1e3,
                    mprims_per_s: w.primitives as f64 / ms / 1e3,
                }
            })
            .collect();
        let ms = |kernel: &str, threads: usize| {
            timings
                .iter()
                .find(|t| t.kernel.starts_with(kernel) && t.threads == threads)
                .map(|t| t.median_ms)
        };
        let jit_one = ms("JIT", 1).unwrap_or(f64::NAN);
        results.push(WorkloadResult {
            workload: w.name.clone(),
            primitives: w.primitives,
            pixels_written: pixels,
            jit_vs_scalar: ms("scalar", 1).map(|t| t / jit_one),
            jit_vs_sse: ms("SSE", 1).map(|t| t / jit_one),
            jit_vs_simd: ms("SIMD", 1).map(|t| t / jit_one),
            thread_scaling: ms("JIT", threads).map_or(f64::NAN, |t| jit_one / t),
            expand_speedup: ms("JIT, setup per tile", 1).map(|t| t / jit_one),
            timings,
        });
    }
    bar.finish_and_clear();
    Ok(BenchReport {
        machine: machine_description(threads),
        isa: jit.isa_summary(),
        simd_kernel: Flavor::Avx2.describe().to_string(),
        sse_kernel: Flavor::Sse.describe().to_string(),
        threads,
        workloads: results,
        compile,
        time_to_first_pixel_ms: ttfp,
        not_covered: vec!["effects series (the shading pass is not timed by this benchmark yet)".into()],
    })
}

/// Parse and check the whole library, compile the kernels of a one-triangle scene and render
/// it: what a user waits for before the first pixel.
fn time_to_first_pixel() -> Result<f64, String> {
    let started = Instant::now();
    let mut sources = SourceMap::new();
    let program = library(&mut sources)?;
    let mut r = Renderer::new(program.clone());
    r.set_image_size(64, 64).map_err(|e| e.message.clone())?;
    bind(&mut r, Some("perspective_linear"), 4);
    tri(
        &mut r,
        [[1.0, 1.0, 0.5, 1.0], [60.0, 4.0, 0.5, 1.0], [9.0, 60.0, 0.5, 1.0]],
        4,
        &mut Lcg(3),
    );
    let mut jit = Jit::new(program).map_err(|e| e.to_string())?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .map_err(|e| e.to_string())?;
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
    format!("{cpu}, {threads} threads")
}

/// The report as a text table.
pub fn format_table(report: &BenchReport) -> String {
    let mut s = String::new();
    s.push_str(&format!(
        "machine: {}\nJIT: {}\nhand-written SSE: {}\nhand-written SIMD: {}\n\n",
        report.machine, report.isa, report.sse_kernel, report.simd_kernel
    ));
    s.push_str(&format!(
        "{:<32} {:<26} {:>7} {:>10} {:>10} {:>10}\n",
        "workload", "kernel", "threads", "ms", "Mpix/s", "Mprim/s"
    ));
    for w in &report.workloads {
        for t in &w.timings {
            s.push_str(&format!(
                "{:<32} {:<26} {:>7} {:>10.2} {:>10.1} {:>10.3}\n",
                w.workload, t.kernel, t.threads, t.median_ms, t.mpixels_per_s, t.mprims_per_s
            ));
        }
        let ratio = |r: Option<f64>| r.map_or("n/a (no hand-written kernel)".to_string(), |r| format!("{r:.2}x"));
        s.push_str(&format!(
            "{:<32} JIT/scalar {}   JIT/SSE {}   JIT/AVX2 {}   {} threads/1 thread {:.2}x\n",
            "",
            ratio(w.jit_vs_scalar),
            ratio(w.jit_vs_sse),
            ratio(w.jit_vs_simd),
            report.threads,
            w.thread_scaling
        ));
        if let Some(x) = w.expand_speedup {
            s.push_str(&format!(
                "{:<32} setup once per primitive (expanded) vs once per tile: {x:.2}x faster\n",
                ""
            ));
        }
        s.push('\n');
    }
    s.push_str("JIT compile time per variant:\n");
    for c in &report.compile {
        s.push_str(&format!("  {:>6} us  {}\n", c.micros, c.variant));
    }
    s.push_str(&format!(
        "time to first pixel (parse + check library, compile, render): {:.1} ms\n",
        report.time_to_first_pixel_ms
    ));
    if !report.not_covered.is_empty() {
        s.push_str("not benchmarked yet: ");
        s.push_str(&report.not_covered.join("; "));
        s.push('\n');
    }
    s
}
