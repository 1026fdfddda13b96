//! Criterion benches of the JIT kernels against their hand-written twins on the same scenes
//! (`cargo bench -p primflow-kernel-bench`): screen_triangle (scalar, SSE4.1 at the JIT's 4 lanes, AVX2)
//! on the fill and small workloads, and sphere, polygon (clipped at the hither plane) and NURB
//! surface against the hand-written forms each has.
//!
//! Each scene is rendered once by every source and the frames compared bit for bit before
//! anything is timed (a benchmark of kernels that disagree measures nothing). Rendering
//! runs on one thread so the figures are per-core kernel speed. `primflow bench` is the
//! broader, interleaved comparison; this is the statistically careful one for one workload.

use std::sync::Arc;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use primflow::diag::{Diagnostics, SourceMap};
use primflow::handwritten::{Flavor, Handwritten};
use primflow::ir::Program;
use primflow::jit::Jit;
use primflow::runtime::{KernelSource, Registry, Renderer};
use primflow::workload::{fill_scene, same_frame, shape_scenes, small_scene};

const SIZE: u32 = 256;

fn library() -> Arc<Program> {
    let mut sources = SourceMap::new();
    let mut diags = Diagnostics::new();
    match Registry::load(&mut sources, &[], &[], &mut diags) {
        Some(r) => r.program,
        None => panic!("library does not load:\n{}", diags.render(&sources)),
    }
}

/// The JIT and the hand-written `flavors` on `scene`, one thread.
fn bench_scene(c: &mut Criterion, name: &str, scene: &Renderer, program: &Arc<Program>, flavors: &[Flavor]) {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    let mut sources: Vec<(&str, Box<dyn KernelSource + Send>)> =
        vec![("jit", Box::new(Jit::new(program.clone()).unwrap()))];
    for &flavor in flavors {
        let label = match flavor {
            Flavor::Scalar => "scalar",
            Flavor::Sse => "sse",
            Flavor::Avx2 => "avx2",
        };
        sources.push((label, Box::new(Handwritten::new(program.clone(), flavor))));
    }
    // Correctness first; this also compiles the JIT kernel outside the timed loop.
    let mut frames = vec![];
    for (label, source) in sources.iter_mut() {
        let out = pool.install(|| scene.render(source.as_mut()));
        assert!(!out.diags.has_errors(), "{label}: {:?}", out.diags.items);
        frames.push((*label, out.frame));
    }
    for (label, frame) in &frames[1..] {
        if !same_frame(&frames[0].1, frame) {
            eprintln!("{name}: the {label} frame differs from the JIT's; not timing it");
        }
    }
    let ok: Vec<bool> = frames.iter().map(|(_, f)| same_frame(&frames[0].1, f)).collect();
    let mut group = c.benchmark_group(name);
    group.throughput(Throughput::Elements(scene.instances().len() as u64));
    group.sample_size(20);
    for ((label, source), ok) in sources.iter_mut().zip(ok) {
        if !ok {
            continue;
        }
        group.bench_function(*label, |b| b.iter(|| pool.install(|| scene.render(source.as_mut()))));
    }
    group.finish();
}

const ALL_FLAVORS: [Flavor; 3] = [Flavor::Scalar, Flavor::Sse, Flavor::Avx2];

fn screen_triangle(c: &mut Criterion) {
    let program = library();
    let fill = fill_scene(&program, SIZE, 8, Some("perspective_linear"), 4);
    bench_scene(
        c,
        "screen_triangle fill 256x256 x8 perspective_linear K=4",
        &fill,
        &program,
        &ALL_FLAVORS,
    );
    let small = small_scene(&program, SIZE, 5000, 4);
    bench_scene(
        c,
        "screen_triangle small 20px perspective_linear K=4",
        &small,
        &program,
        &ALL_FLAVORS,
    );
}

/// Sphere (unlit and lit), hither-clipped polygons and NURB patches at 256x256.
fn shapes(c: &mut Criterion) {
    let program = library();
    for (name, scene, flavors) in shape_scenes(&program, SIZE, 200, 8) {
        bench_scene(c, &format!("{name} 256x256"), &scene, &program, flavors);
    }
}

criterion_group!(benches, screen_triangle, shapes);
criterion_main!(benches);
