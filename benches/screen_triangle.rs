//! Criterion benches of the screen_triangle kernels: the JIT against the hand-written scalar
//! and AVX2 twins on the same scenes (`cargo bench --bench screen_triangle`).
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
use primflow::runtime::{Frame, KernelSource, Registry, Renderer, Value};

const SIZE: u32 = 256;

fn library() -> Arc<Program> {
    let mut sources = SourceMap::new();
    let mut diags = Diagnostics::new();
    match Registry::load(&mut sources, &[], &[], &mut diags) {
        Some(r) => r.program,
        None => panic!("library does not load:\n{}", diags.render(&sources)),
    }
}

/// A small deterministic generator, so every run benchmarks the same scene.
struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f32 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((self.0 >> 11) as f64 / (1u64 << 53) as f64) as f32
    }
}

fn triangle(r: &mut Renderer, v: [[f32; 4]; 3], k: usize, rng: &mut Lcg) {
    r.begin("screen_triangle").unwrap();
    r.rast_param("screen_vertex", &Value(v.iter().flatten().copied().collect()))
        .unwrap();
    for _ in 0..3 {
        for c in 0..k {
            r.material(&format!("p{c}"), &Value(vec![rng.next()])).unwrap();
        }
        r.sequence_point().unwrap();
    }
    r.end().unwrap();
}

/// Full-viewport quads back to front, 4 perspective_linear components.
fn fill_scene(program: &Arc<Program>, layers: usize) -> Renderer {
    let mut r = Renderer::new(program.clone());
    r.set_image_size(SIZE, SIZE).unwrap();
    for c in 0..4 {
        r.material_interp(&format!("p{c}"), "perspective_linear", &[]).unwrap();
    }
    let mut rng = Lcg(1);
    let s = SIZE as f32;
    for layer in 0..layers {
        let z = (layer + 1) as f32 / (layers + 1) as f32;
        let mut corner = |x: f32, y: f32| [x, y, z, 1.0 + 2.0 * rng.next()];
        let q = [corner(0.0, 0.0), corner(s, 0.0), corner(s, s), corner(0.0, s)];
        triangle(&mut r, [q[0], q[1], q[2]], 4, &mut rng);
        triangle(&mut r, [q[0], q[2], q[3]], 4, &mut rng);
    }
    r
}

/// Triangles of about 20 px area at random places, 4 perspective_linear components.
fn small_scene(program: &Arc<Program>, count: usize) -> Renderer {
    let mut r = Renderer::new(program.clone());
    r.set_image_size(SIZE, SIZE).unwrap();
    for c in 0..4 {
        r.material_interp(&format!("p{c}"), "perspective_linear", &[]).unwrap();
    }
    let mut rng = Lcg(2);
    let radius = (20.0f32 * 4.0 / 3f32.sqrt()).sqrt() / 3f32.sqrt();
    for i in 0..count {
        let z = (i + 1) as f32 / (count + 1) as f32;
        let (cx, cy) = (rng.next() * SIZE as f32, rng.next() * SIZE as f32);
        let a = rng.next() * std::f32::consts::TAU;
        let v = std::array::from_fn(|j| {
            let t = a + j as f32 * std::f32::consts::TAU / 3.0;
            [cx + radius * t.cos(), cy + radius * t.sin(), z, 1.0 + 2.0 * rng.next()]
        });
        triangle(&mut r, v, 4, &mut rng);
    }
    r
}

fn same(a: &Frame, b: &Frame) -> bool {
    a.depth == b.depth
        && a.planes.len() == b.planes.len()
        && a.planes
            .iter()
            .zip(&b.planes)
            .all(|(x, y)| x.iter().zip(y).all(|(p, q)| p.to_bits() == q.to_bits()))
}

fn bench_scene(c: &mut Criterion, name: &str, scene: &Renderer, program: &Arc<Program>) {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    let mut sources: Vec<(&str, Box<dyn KernelSource + Send>)> = vec![
        ("jit", Box::new(Jit::new(program.clone()).unwrap())),
        ("scalar", Box::new(Handwritten::new(program.clone(), Flavor::Scalar))),
        ("simd", Box::new(Handwritten::new(program.clone(), Flavor::Simd))),
    ];
    // Correctness first; this also compiles the JIT kernel outside the timed loop.
    let mut frames = vec![];
    for (label, source) in sources.iter_mut() {
        let out = pool.install(|| scene.render(source.as_mut()));
        assert!(!out.diags.has_errors(), "{label}: {:?}", out.diags.items);
        frames.push((*label, out.frame));
    }
    for (label, frame) in &frames[1..] {
        if !same(&frames[0].1, frame) {
            eprintln!("{name}: the {label} frame differs from the JIT's; not timing it");
        }
    }
    let ok: Vec<bool> = frames.iter().map(|(_, f)| same(&frames[0].1, f)).collect();
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
    let fill = fill_scene(&program, 8);
    bench_scene(
        c,
        "screen_triangle fill 256x256 x8 perspective_linear K=4",
        &fill,
        &program,
    );
    let small = small_scene(&program, 5000);
    bench_scene(c, "screen_triangle small 20px perspective_linear K=4", &small, &program);
}

criterion_group!(benches, screen_triangle);
criterion_main!(benches);
