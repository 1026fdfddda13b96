//! One thread against two on the bench's `fill perspective_linear` scene (512 x 512, JIT),
//! interleaved, with the render's own phase split, for the target "2 threads >= 1.8x 1 thread
//! on the fill workload" (docs/performance.md, "What limits the targets"):
//!
//! `cargo run --release --example thread_scaling -- [LAYERS [RUNS [TILE [K]]]]`
//! (defaults 20 layers as in `bench --quick`, 15 runs, 64 px tiles, K = 4).
//!
//! Three pools: one thread, the renderer's `render_pool(2)` (each thread pinned to a CPU of its
//! own, see `runtime::pool`) and a plain rayon pool of two threads, which shows what pinning
//! changes. Two ways of rendering, interleaved run by run: `reused` renders every frame into the same
//! `Frame` per thread count (`Renderer::render_into`), as an application does, so no frame
//! pays for allocating and faulting in fresh buffers (what `primflow bench` times); `fresh`
//! calls `Renderer::render`, which returns a new frame every time. Prints, per way and
//! pool, the median and minimum frame time and the median setup (compile lookup,
//! bound pass, binning: serial), tiles (tile clears and kernels, straight into the frame: parallel)
//! and shading times, then the 2-thread / 1-thread ratios. Run it when the machine is idle:
//! on a shared 2-core machine any other process takes one of the two cores.

use std::time::{Duration, Instant};

use primflow::diag::{Diagnostics, SourceMap};
use primflow::jit::Jit;
use primflow::runtime::{render_pool, Frame, Registry, RenderStats};
use primflow::workload::fill_scene;

fn arg<T: std::str::FromStr>(i: usize, default: T) -> T {
    std::env::args().nth(i).and_then(|s| s.parse().ok()).unwrap_or(default)
}

fn median<T: Copy + PartialOrd>(mut v: Vec<T>) -> T {
    v.sort_by(|a, b| a.partial_cmp(b).unwrap_or(std::cmp::Ordering::Equal));
    v[v.len() / 2]
}

/// Idle time before each frame: a 60 Hz application's frame period.
const IDLE: Duration = Duration::from_millis(16);

/// One timed frame: (frame ms, setup us, tiles us, shade us).
type Run = (f64, u64, u64, u64);

fn run_of(started: Instant, s: &RenderStats) -> Run {
    (
        started.elapsed().as_secs_f64() * 1e3,
        s.setup_micros,
        s.tiles_micros,
        s.shade_micros,
    )
}

fn main() -> Result<(), String> {
    let (layers, runs, tile, k) = (arg(1, 20usize), arg(2, 15usize).max(1), arg(3, 64u32), arg(4, 4usize));
    let mut sources = SourceMap::new();
    let mut diags = Diagnostics::new();
    let program = Registry::load(&mut sources, &[], &[], &mut diags)
        .ok_or_else(|| diags.render(&sources))?
        .program;
    let mut scene = fill_scene(&program, 512, layers, Some("perspective_linear"), k);
    scene.set_tile_size(tile).map_err(|e| e.message)?;
    let mut jit = Jit::new(program.clone()).map_err(|e| e.to_string())?;
    // The renderer's pools (`render_pool`: with 2 threads, each pinned to a CPU) and a plain
    // rayon pool of 2, whose threads the scheduler places.
    let plain = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .map_err(|e| e.to_string())?;
    let pools = [
        ("1 thread", render_pool(1).map_err(|e| e.to_string())?),
        (
            "2 threads, render_pool (pinned)",
            render_pool(2).map_err(|e| e.to_string())?,
        ),
        ("2 threads, plain rayon pool", plain),
    ];
    // Compile outside the timed runs.
    let _ = pools[0].1.install(|| scene.render(&mut jit));
    let mut frames: Vec<Frame> = pools.iter().map(|_| Frame::empty()).collect();
    // [way][pool] -> one entry per run; way 0 = reused frame, 1 = fresh frame. Before every
    // frame the process idles for IDLE, as an interactive application does between frames:
    // the pool's threads and the cores go to sleep, and what wakes them is part of the frame.
    let mut runs_of: [Vec<Vec<Run>>; 2] = [vec![vec![]; pools.len()], vec![vec![]; pools.len()]];
    for _ in 0..runs {
        for (p, (_, pool)) in pools.iter().enumerate() {
            std::thread::sleep(IDLE);
            let started = Instant::now();
            let report = pool.install(|| scene.render_into(&mut jit, &mut frames[p]));
            runs_of[0][p].push(run_of(started, &report.stats));
        }
        for (p, (_, pool)) in pools.iter().enumerate() {
            std::thread::sleep(IDLE);
            let started = Instant::now();
            let out = pool.install(|| scene.render(&mut jit));
            runs_of[1][p].push(run_of(started, &out.stats));
        }
    }
    for (way, name) in ["reused frame (render_into)", "fresh frame (render)"]
        .iter()
        .enumerate()
    {
        let mut med_ms = vec![];
        let mut min_ms = vec![];
        for ((label, _), times) in pools.iter().zip(&runs_of[way]) {
            let ms: Vec<f64> = times.iter().map(|t| t.0).collect();
            let (m, lo) = (median(ms.clone()), ms.iter().copied().fold(f64::INFINITY, f64::min));
            println!(
                "{name}, {label}: frame median {m:.2} ms (min {lo:.2}); phases (median us): setup {} tiles {} shade {}",
                median(times.iter().map(|t| t.1).collect()),
                median(times.iter().map(|t| t.2).collect()),
                median(times.iter().map(|t| t.3).collect()),
            );
            med_ms.push(m);
            min_ms.push(lo);
        }
        for p in 1..pools.len() {
            println!(
                "{name}: fill perspective_linear K={k}, {layers} layers, tile {tile}, {runs} runs: {} / 1 thread = {:.2}x (medians), {:.2}x (minima)",
                pools[p].0,
                med_ms[0] / med_ms[p],
                min_ms[0] / min_ms[p]
            );
        }
    }
    Ok(())
}
