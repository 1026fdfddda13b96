//! The benchmark's effects series (`primflow bench`): its frames differ exactly the
//! way each effect says (fog blends every pixel towards the fog colour by the distance of
//! the nearest layer, the checker halves the base colour on odd squares and leaves the rest,
//! lights change the colour), the thread count changes nothing, a frame with no effect shows
//! `Cs` and runs no shading code; and the report has a row per effect set, the thread
//! figures and the llvmpipe comparison. Outcomes only: nothing here asserts a timing.

use crate::support;

use std::sync::Arc;

use indicatif::ProgressBar;
use primflow::bench::{effects_series, format_effects, format_table, run, BenchOptions};
use primflow::ir::Program;
use primflow::jit::Jit;
use primflow::runtime::{Frame, Renderer};
use primflow::workload::{effects_scene, EffectSet, EFFECTS_FOG_COLOUR, EFFECT_SETS};

const SIZE: u32 = 32;
const LAYERS: usize = 2;

fn set(name: &str) -> EffectSet {
    EFFECT_SETS
        .iter()
        .find(|(n, _)| *n == name)
        .map(|&(_, s)| s)
        .unwrap_or_else(|| panic!("no effect set {name}"))
}

fn render(r: &Renderer, jit: &mut Jit, threads: usize) -> (Frame, primflow::runtime::RenderStats) {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
    let out = pool.install(|| r.render(jit));
    assert!(out.diags.items.is_empty(), "render diagnostics: {:?}", out.diags.items);
    (out.frame, out.stats)
}

fn colours(f: &Frame) -> Vec<[f32; 3]> {
    (0..f.height)
        .flat_map(|y| (0..f.width).map(move |x| f.color_at(x, y)))
        .collect()
}

fn frames(program: &Arc<Program>) -> Vec<(&'static str, Frame)> {
    let mut jit = Jit::new(program.clone()).unwrap();
    EFFECT_SETS
        .iter()
        .map(|&(name, s)| {
            let r = effects_scene(program, SIZE, LAYERS, s);
            let (one, _) = render(&r, &mut jit, 1);
            let (two, _) = render(&r, &mut jit, 2);
            assert_eq!(
                one.color_values(),
                two.color_values(),
                "{name}: colours depend on the thread count"
            );
            assert_eq!(
                one.depth_values(),
                two.depth_values(),
                "{name}: depth depends on the thread count"
            );
            (name, one)
        })
        .collect()
}

#[test]
fn each_effect_changes_the_colours_the_way_it_should() {
    let program = support::library();
    let frames = frames(&program);
    let none = &frames[0].1;
    let find = |name: &str| &frames.iter().find(|(n, _)| *n == name).unwrap().1;

    // No effect: no shading pass, every pixel covered and showing its Cs.
    assert!(!none.is_shaded());
    for y in 0..SIZE {
        for x in 0..SIZE {
            assert!(none.written(x, y), "({x}, {y}) not covered");
            let cs = none.param_at("Cs", x, y).unwrap();
            assert_eq!(none.color_at(x, y), [cs[0], cs[1], cs[2]].map(|c| c.clamp(0.0, 1.0)));
        }
    }
    let base = colours(none);

    // Fog: c' = f c + (1 - f) fog, f = (end - distance) / (end - start) with start 0, end
    // 0.5, distance 1 - z from the eye and the nearest layer at z = LAYERS / (LAYERS + 1).
    let fog = colours(find("fog"));
    let f = (0.5 - (1.0 - LAYERS as f64 / (LAYERS as f64 + 1.0))) / 0.5;
    for (c, b) in fog.iter().zip(&base) {
        for k in 0..3 {
            let expected = f * f64::from(b[k]) + (1.0 - f) * EFFECTS_FOG_COLOUR[k];
            assert!(
                (f64::from(c[k]) - expected).abs() < 1e-4,
                "fog: {c:?} from {b:?}, expected component {k} = {expected}"
            );
        }
    }

    // Texture: odd checker squares of st * 8 are exactly half the base colour, even ones
    // unchanged; both kinds occur.
    let textured = find("texture");
    let (mut odd, mut even) = (0, 0);
    for y in 0..SIZE {
        for x in 0..SIZE {
            let st = textured.param_at("st", x, y).unwrap();
            let cell = (f64::from(st[0]) * 8.0).floor() + (f64::from(st[1]) * 8.0).floor();
            let b = none.color_at(x, y);
            let c = textured.color_at(x, y);
            if cell.rem_euclid(2.0) == 1.0 {
                odd += 1;
                assert_eq!(c, b.map(|v| v * 0.5), "odd square at ({x}, {y})");
            } else {
                even += 1;
                assert_eq!(c, b, "even square at ({x}, {y})");
            }
        }
    }
    assert!(odd > 100 && even > 100, "checker squares: {odd} odd, {even} even");

    // Lights: (nearly) every pixel's colour changes; the all-effects frame differs from
    // every single-effect frame.
    let lit = colours(find("8 lights"));
    let changed = lit.iter().zip(&base).filter(|(a, b)| a != b).count();
    assert!(
        changed * 10 >= base.len() * 9,
        "lights changed only {changed} of {} pixels",
        base.len()
    );
    let all = colours(find("8 lights + fog + texture"));
    for name in ["8 lights", "fog", "texture"] {
        assert_ne!(all, colours(find(name)), "all effects vs {name}");
    }
}

#[test]
fn effects_scene_runs_one_kernel_for_every_set() {
    // Every set renders the same primitives with the same kernel: same depth and G-buffer,
    // and a frame's effects are the set's.
    let program = support::library();
    let mut jit = Jit::new(program.clone()).unwrap();
    let none = effects_scene(&program, SIZE, LAYERS, set("none (colour = Cs)"));
    let (reference, stats) = render(&none, &mut jit, 1);
    assert_eq!(stats.kernels_compiled, 1);
    for &(name, s) in &EFFECT_SETS[1..] {
        let r = effects_scene(&program, SIZE, LAYERS, s);
        let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
        let out = pool.install(|| r.render(&mut jit));
        assert!(
            primflow::workload::same_frame(&reference, &out.frame),
            "{name}: G-buffer differs"
        );
        assert_eq!(out.effects.lit, s.lights > 0, "{name}");
        assert_eq!(out.effects.fog, s.fog, "{name}");
        assert_eq!(out.effects.texture, s.texture, "{name}");
        assert_eq!(r.shading_setup.lights.len(), s.lights, "{name}");
        assert!(out.frame.is_shaded(), "{name}: no shading pass");
    }
}

#[test]
fn series_table_has_a_row_per_effect_set() {
    let program = support::library();
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    let two = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
    let series = effects_series(&program, SIZE, LAYERS, 1, &one, &two, &ProgressBar::hidden()).unwrap();
    // Every set with the Rust pass, and every set but `none` again with language shaders,
    // right after it.
    assert_eq!(series.rows.len(), 2 * EFFECT_SETS.len() - 1);
    assert_eq!(series.threads, 2);
    let table = format_effects(&series);
    let rust: Vec<_> = series.rows.iter().filter(|r| !r.language).collect();
    for ((name, s), row) in EFFECT_SETS.iter().zip(&rust) {
        assert_eq!(&row.effects, name);
        assert_eq!(row.set, *s);
        assert!(row.language_over_rust.is_none());
        assert!(
            table.lines().any(|l| l.starts_with(name)),
            "no row for {name} in\n{table}"
        );
    }
    for pair in series.rows[1..].chunks(2) {
        let (r, l) = (&pair[0], &pair[1]);
        assert!(
            !r.language && l.language && l.set == r.set,
            "{} then {}",
            r.effects,
            l.effects
        );
        assert_eq!(l.effects, format!("{} [language]", r.effects));
        assert!(l.language_over_rust.is_some_and(|x| x > 0.0 && x.is_finite()));
    }
    assert_eq!(series.rows[0].ratio_to_none, 1.0);
    assert_eq!(series.rows[0].extra_ms, 0.0);
}

#[test]
fn report_has_effects_thread_figures_and_llvmpipe_rows() {
    // The smallest real run: the sphere workloads and the effects series (512 x 512, one
    // timed run each).
    // `..default()` keeps this test compiling when BenchOptions gains a field.
    #[allow(clippy::needless_update)]
    let opts = BenchOptions {
        filter: Some("sphere".into()),
        quick: true,
        runs: 1,
        progress: false,
        ..BenchOptions::default()
    };
    let report = run(&opts).unwrap();
    let names: Vec<&str> = report.workloads.iter().map(|w| w.workload.as_str()).collect();
    assert!(names.contains(&"sphere implicit N"), "{names:?}");
    assert!(names.iter().any(|n| n.starts_with("sphere lit")), "{names:?}");
    // Filtered to spheres: no effects series.
    assert!(report.effects.is_none());
    for w in &report.workloads {
        for threads in [1, report.machine.threads] {
            assert!(
                w.timings.iter().any(|t| t.kernel == "JIT" && t.threads == threads),
                "{}: no JIT figure for {threads} threads",
                w.workload
            );
        }
        assert!(w.pixels_written > 0, "{}", w.workload);
    }
    assert_eq!(report.llvmpipe.len(), 2, "{:?}", report.llvmpipe);
    for c in &report.llvmpipe {
        assert_eq!(c.llvmpipe, 88.0);
        assert!((c.ratio - c.jit_one_thread / 88.0).abs() < 1e-12);
        // The sphere has scalar and AVX2 kernels: the fastest of them stands beside the JIT.
        let (kernel, figure) = c.best_handwritten.as_ref().expect("hand-written sphere kernels");
        let w = report.workloads.iter().find(|w| w.workload == c.workload).unwrap();
        let fastest = w
            .timings
            .iter()
            .filter(|t| t.threads == 1 && !t.kernel.starts_with("JIT"))
            .map(|t| t.mpixels_per_s)
            .fold(0.0, f64::max);
        assert_eq!(*figure, fastest, "{kernel}");
    }
    // Every example scene reaches its first pixel, each phase inside the whole.
    let scenes: Vec<&str> = report.scenes_to_first_pixel.iter().map(|t| t.scene.as_str()).collect();
    assert_eq!(
        scenes,
        [
            "triangles.scene",
            "interpolators.scene",
            "spheres.scene",
            "geometry.scene",
            "nurb_surface.scene"
        ]
    );
    for t in &report.scenes_to_first_pixel {
        assert!(t.compile_ms > 0.0 && t.render_ms > 0.0, "{t:?}");
        assert!(t.compile_ms + t.render_ms <= t.ms, "{t:?}");
    }
    let table = format_table(&report);
    assert!(table.contains("example scenes to first pixel"), "{table}");
    assert!(table.contains("thread scaling"), "{table}");
    // No llvmpipe worker asked for: the reference figures stand alone.
    assert!(table.contains("issue's figure   88.0: JIT"), "{table}");
    assert!(table.contains("llvmpipe here: -"), "{table}");
    assert!(table.contains("hand-written best"), "{table}");
    assert_eq!(report.llvmpipe_status, "not asked for");
    let json = serde_json::to_value(&report).unwrap();
    assert!(json["llvmpipe"].as_array().is_some_and(|a| a.len() == 2));
    assert!(json["effects"].is_null());
    assert_eq!(json["scenes_to_first_pixel"].as_array().map(Vec::len), Some(5));
}
