//! Criterion benches of the screen_triangle kernels: the JIT against the hand-written scalar,
//! SSE4.1 (4 lanes, the JIT's width) and AVX2 twins on the same scenes (`cargo bench --bench screen_triangle`).
//!
//! Each scene is rendered once by every source and the frames compared bit for bit before
//! anything is timed (a benchmark of kernels that disagree measures nothing). Rendering
//! runs on one thread so the figures are per-core kernel speed. `primflow bench` is the
//! broader, interleaved comparison; this is the statistically careful one for one workload.

use std::sync::Arc;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use primflow::bench::{fill_scene, same_frame, small_scene};
use primflow::diag::{Diagnostics, SourceMap};
use primflow::handwritten::{Flavor, Handwritten};
use primflow::ir::Program;
use primflow::jit::Jit;
use primflow::runtime::{KernelSource, Registry, Renderer};

const SIZE: u32 = 256;

fn library() -> Arc<Program> {
    let mut sources = SourceMap::new();
    let mut diags = Diagnostics::new();
    match Registry::load(&mut sources, &[], &[], &mut diags) {
        Some(r) => r.program,
        None => panic!("library does not load:\n{}", diags.render(&sources)),
    }
}

fn bench_scene(c: &mut Criterion, name: &str, scene: &Renderer, program: &Arc<Program>) {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    let mut sources: Vec<(&str, Box<dyn KernelSource + Send>)> = vec![
        ("jit", Box::new(Jit::new(program.clone()).unwrap())),
        ("scalar", Box::new(Handwritten::new(program.clone(), Flavor::Scalar))),
        ("sse", Box::new(Handwritten::new(program.clone(), Flavor::Sse))),
        ("avx2", Box::new(Handwritten::new(program.clone(), Flavor::Avx2))),
    ];
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

fn screen_triangle(c: &mut Criterion) {
    let program = library();
    let fill = fill_scene(&program, SIZE, 8, Some("perspective_linear"), 4);
    bench_scene(
        c,
        "screen_triangle fill 256x256 x8 perspective_linear K=4",
        &fill,
        &program,
    );
    let small = small_scene(&program, SIZE, 5000, 4);
    bench_scene(c, "screen_triangle small 20px perspective_linear K=4", &small, &program);
}

criterion_group!(benches, screen_triangle);
criterion_main!(benches);
