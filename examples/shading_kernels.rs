//! The deferred shading pass alone, per kernel: the f64 reference, the portable f32 lanes,
//! their AVX2 build and their widest build (AVX-512 where the CPU has it), on the bench's
//! effects scenes (512 x 512, every pixel visible), one thread, interleaved round by round:
//!
//! `cargo run --release --example shading_kernels -- [RUNS]` (default 15 runs).
//!
//! Prints, per effect set, the median shading time of each kernel, ns per shaded pixel, the
//! ratios to the reference, and the largest per-channel difference from the reference.

use primflow::diag::{Diagnostics, SourceMap};
use primflow::jit::Jit;
use primflow::runtime::shading::ShadingKernel;
use primflow::runtime::Registry;
use primflow::workload::{effects_scene, EFFECT_SETS};

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.partial_cmp(b).unwrap_or(std::cmp::Ordering::Equal));
    v[v.len() / 2]
}

fn main() -> Result<(), String> {
    let runs: usize = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(15)
        .max(1);
    let mut sources = SourceMap::new();
    let mut diags = Diagnostics::new();
    let program = Registry::load(&mut sources, &[], &[], &mut diags)
        .ok_or_else(|| diags.render(&sources))?
        .program;
    let mut jit = Jit::new(program.clone()).map_err(|e| e.to_string())?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .map_err(|e| e.to_string())?;
    let kernels = [
        ShadingKernel::ReferenceF64,
        ShadingKernel::Portable,
        ShadingKernel::Avx2,
        ShadingKernel::Simd,
    ];
    println!("shading pass, 512x512, 1 thread, median of {runs} interleaved runs (simd: the widest the CPU has)");
    println!(
        "{:<26} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8} {:>9} {:>10} {:>10}",
        "effects",
        "f64 ms",
        "port. ms",
        "avx2 ms",
        "simd ms",
        "port. x",
        "avx2 x",
        "simd x",
        "f64 ns/px",
        "simd ns/px",
        "max |diff|"
    );
    for (name, set) in EFFECT_SETS.iter().filter(|(_, s)| s.lights > 0 || s.fog || s.texture) {
        let mut scene = effects_scene(&program, 512, 20, *set);
        let mut times = vec![vec![]; kernels.len()];
        let mut colours = vec![vec![]; kernels.len()];
        for round in 0..=runs {
            for (i, &k) in kernels.iter().enumerate() {
                scene.shading_setup.kernel = k;
                let out = pool.install(|| scene.render(&mut jit));
                if round == 0 {
                    // Warm-up (compiles the kernel); keep the colours to compare.
                    colours[i] = out.frame.color_values().unwrap_or_default();
                } else {
                    times[i].push(out.stats.shade_micros as f64 / 1e3);
                }
            }
        }
        let worst = colours[3]
            .iter()
            .zip(&colours[0])
            .flat_map(|(a, b)| (0..3).map(move |k| (a[k] - b[k]).abs()))
            .fold(0f32, f32::max);
        let ms: Vec<f64> = times.into_iter().map(median).collect();
        let pixels = 512.0 * 512.0;
        println!(
            "{:<26} {:>8.2} {:>8.2} {:>8.2} {:>8.2} {:>7.2}x {:>7.2}x {:>7.2}x {:>9.1} {:>10.1} {:>10.2e}",
            name,
            ms[0],
            ms[1],
            ms[2],
            ms[3],
            ms[0] / ms[1],
            ms[0] / ms[2],
            ms[0] / ms[3],
            ms[0] * 1e6 / pixels,
            ms[3] * 1e6 / pixels,
            worst
        );
    }
    Ok(())
}
