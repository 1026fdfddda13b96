//! `primflow accuracy`: what accuracy costs in time, measured.
//!
//! Every *knob* (procedural vs tessellated sphere, NURB tessellation tolerance, linear vs
//! perspective-correct interpolation, the arithmetic of coverage, the lighting space, depth
//! precision, the library shaders) is a list of *settings*, each a way to render one standard scene. Each setting
//! renders once for correctness and its error figures, computed against the f64
//! [`reference`] renderer of the same [`scene::Scene`] (never a constant); then all settings
//! of the knob are timed interleaved (A, B, C, A, B, C, ...) in this one process on one
//! thread, so machine drift hits them alike, and the median frame time is reported with its
//! ratio to the most accurate setting's. The result is a table ([`format_table`]), CSV and
//! JSON ([`write_outputs`]) and one error-vs-time plot per knob ([`plot`]).
//!
//! A frame's time is everything the setting does per frame: for tessellated geometry the
//! projection and submission of its triangles, for host-side lighting the lighting of its
//! vertices, then the render (bound pass, binning, kernels). Compilation is excluded: the
//! first, untimed render compiles every kernel.

pub mod antialiasing;
pub mod coverage;
pub mod knobs;
pub mod plot;
pub mod reference;
pub mod scene;
pub mod shading;

use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

use indicatif::{ProgressBar, ProgressStyle};
use serde::{Deserialize, Serialize};

use crate::diag::{Diagnostics, SourceMap};
use crate::ir::Program;
use crate::jit::Jit;
use crate::runtime::{Frame, Registry, Renderer};

use reference::RefFrame;

/// The knob-variant primitives (`accuracy/prims/`), compiled into the binary so the command
/// works wherever it is run from.
pub const VARIANT_PRIMS: [(&str, &str); 7] = [
    (
        "acc_tri_fixed16.prim",
        include_str!("../../accuracy/prims/acc_tri_fixed16.prim"),
    ),
    (
        "acc_tri_fixed8.prim",
        include_str!("../../accuracy/prims/acc_tri_fixed8.prim"),
    ),
    (
        "acc_tri_f32.prim",
        include_str!("../../accuracy/prims/acc_tri_f32.prim"),
    ),
    (
        "acc_depth_f32.prim",
        include_str!("../../accuracy/prims/acc_depth_f32.prim"),
    ),
    (
        "acc_depth_fixed24.prim",
        include_str!("../../accuracy/prims/acc_depth_fixed24.prim"),
    ),
    (
        "acc_depth_fixed16.prim",
        include_str!("../../accuracy/prims/acc_depth_fixed16.prim"),
    ),
    (
        "acc_depth_half.prim",
        include_str!("../../accuracy/prims/acc_depth_half.prim"),
    ),
];

#[derive(Clone, Debug)]
pub struct AccuracyOptions {
    /// Only knobs whose name contains this (`sphere`, `nurb`, `nurb_polynomial`, `interpolation`,
    /// `arithmetic`, `lighting`, `depth`, `shading`).
    pub filter: Option<String>,
    /// Small images, fewer settings and runs: under a minute on two cores.
    pub quick: bool,
    /// Timed runs per setting (the median is reported); at least 1.
    pub runs: usize,
    pub progress: bool,
}

impl Default for AccuracyOptions {
    fn default() -> AccuracyOptions {
        AccuracyOptions {
            filter: None,
            quick: false,
            runs: 7,
            progress: true,
        }
    }
}

/// One error figure of one setting.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Metric {
    pub name: String,
    pub unit: String,
    /// The worst pixel (for a pixel count: the count).
    pub max: f64,
    /// The mean over the pixels the metric is defined on (for a pixel count: the fraction
    /// of the scene's covered pixels).
    pub mean: f64,
    /// How many pixels the figure was taken over.
    pub pixels: u64,
}

impl Metric {
    pub fn new(name: &str, unit: &str, max: f64, mean: f64, pixels: u64) -> Metric {
        Metric {
            name: name.into(),
            unit: unit.into(),
            max,
            mean,
            pixels,
        }
    }

    /// Max and mean of `errors` (0 and 0 for none).
    pub fn of(name: &str, unit: &str, errors: &[f64]) -> Metric {
        let max = errors.iter().copied().fold(0.0, f64::max);
        let mean = if errors.is_empty() {
            0.0
        } else {
            errors.iter().sum::<f64>() / errors.len() as f64
        };
        Metric::new(name, unit, max, mean, errors.len() as u64)
    }

    /// A count of bad pixels out of `total`.
    pub fn count(name: &str, bad: u64, total: u64) -> Metric {
        Metric::new(name, "px", bad as f64, bad as f64 / total.max(1) as f64, bad)
    }
}

/// What a setting rendered.
pub enum Output {
    Jit(Frame),
    Reference(RefFrame),
}

/// What settings share: the compiled program, one JIT (kernels cached across settings) and
/// a one-thread pool.
pub struct Ctx {
    pub program: Arc<Program>,
    pub jit: Jit,
    pool: rayon::ThreadPool,
}

impl Ctx {
    /// The library plus the knob variants, compiled.
    pub fn new() -> Result<Ctx, String> {
        let mut sources = SourceMap::new();
        let mut diags = Diagnostics::new();
        let (mut files, _) = Registry::load_sources(&mut sources, &[], &[], &mut diags);
        for (name, text) in VARIANT_PRIMS {
            files.push(sources.add(format!("accuracy/prims/{name}"), text));
        }
        let registry = Registry::compile(&sources, files, &mut diags)
            .filter(|_| !diags.has_errors())
            .ok_or_else(|| diags.render(&sources))?;
        let jit = Jit::new(registry.program.clone()).map_err(|e| e.to_string())?;
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .map_err(|e| e.to_string())?;
        Ok(Ctx {
            program: registry.program,
            jit,
            pool,
        })
    }

    /// Render on the one-thread pool; compile errors and run-time warnings are failures
    /// (an accuracy figure of a broken render would mean nothing).
    pub fn render(&mut self, r: &Renderer) -> Result<Frame, String> {
        let jit = &mut self.jit;
        let out = self.pool.install(|| r.render(jit));
        if let Some(d) = out.diags.items.first() {
            return Err(format!("{}: {}", d.code, d.message));
        }
        Ok(out.frame)
    }

    pub fn has_primitive(&self, name: &str) -> bool {
        self.program.find(name).is_some()
    }
}

/// A way to render a knob's scene. `run` is called once untimed (its output is measured)
/// and then `runs` times timed.
pub struct Setting<'a> {
    pub label: String,
    pub run: Box<dyn FnMut(&mut Ctx) -> Result<Output, String> + 'a>,
}

impl<'a> Setting<'a> {
    pub fn new(label: impl Into<String>, run: impl FnMut(&mut Ctx) -> Result<Output, String> + 'a) -> Setting<'a> {
        Setting {
            label: label.into(),
            run: Box::new(run),
        }
    }
}

/// A knob: its settings on one scene and how to measure an output against the reference.
pub struct Knob<'a> {
    pub name: &'static str,
    pub title: &'static str,
    pub settings: Vec<Setting<'a>>,
    /// Error figures of the output of setting `i` (the first argument); the first figure
    /// is the knob's primary one (plotted, and deciding which setting is the most
    /// accurate).
    pub measure: Box<dyn Fn(usize, &Output) -> Result<Vec<Metric>, String> + 'a>,
    /// Settings the knob would have but cannot run here, with the reason.
    pub missing: Vec<String>,
}

/// One table row: a setting's figure.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Row {
    pub knob: String,
    pub setting: String,
    pub metric: String,
    pub unit: String,
    pub max: f64,
    pub mean: f64,
    pub pixels: u64,
    pub median_ms: f64,
    /// Time over the time of the knob's most accurate setting.
    pub time_ratio: f64,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct KnobReport {
    pub name: String,
    pub title: String,
    /// The label of the setting with the smallest primary error (ties: the first).
    pub most_accurate: String,
    pub rows: Vec<Row>,
    pub missing: Vec<String>,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Report {
    pub machine: String,
    pub quick: bool,
    pub runs: usize,
    pub knobs: Vec<KnobReport>,
    pub total_seconds: f64,
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}

/// Measure one knob: every setting once for its errors, then interleaved timed runs.
pub fn measure_knob(knob: &mut Knob, ctx: &mut Ctx, runs: usize, bar: &ProgressBar) -> Result<KnobReport, String> {
    let mut metrics = vec![];
    for (i, s) in knob.settings.iter_mut().enumerate() {
        bar.set_message(format!("{}: {}", knob.name, s.label));
        let out = (s.run)(ctx).map_err(|e| format!("{} / {}: {e}", knob.name, s.label))?;
        metrics.push((knob.measure)(i, &out).map_err(|e| format!("{} / {}: {e}", knob.name, s.label))?);
        bar.inc(1);
    }
    let mut times = vec![vec![]; knob.settings.len()];
    for _ in 0..runs.max(1) {
        for (s, t) in knob.settings.iter_mut().zip(&mut times) {
            let started = Instant::now();
            (s.run)(ctx).map_err(|e| format!("{} / {}: {e}", knob.name, s.label))?;
            t.push(started.elapsed().as_secs_f64() * 1e3);
            bar.inc(1);
        }
    }
    let medians: Vec<f64> = times.into_iter().map(median).collect();
    let primary = |m: &Vec<Metric>| m.first().map_or(f64::INFINITY, |m| m.max);
    let best = (0..metrics.len())
        .min_by(|&a, &b| primary(&metrics[a]).total_cmp(&primary(&metrics[b])))
        .unwrap_or(0);
    let mut rows = vec![];
    for (i, (s, ms)) in knob.settings.iter().zip(metrics).enumerate() {
        for m in ms {
            rows.push(Row {
                knob: knob.name.into(),
                setting: s.label.clone(),
                metric: m.name,
                unit: m.unit,
                max: m.max,
                mean: m.mean,
                pixels: m.pixels,
                median_ms: medians[i],
                time_ratio: medians[i] / medians[best],
            });
        }
    }
    Ok(KnobReport {
        name: knob.name.into(),
        title: knob.title.into(),
        most_accurate: knob.settings.get(best).map(|s| s.label.clone()).unwrap_or_default(),
        rows,
        missing: knob.missing.clone(),
    })
}

/// Run every selected knob.
pub fn run(opts: &AccuracyOptions) -> Result<Report, String> {
    let started = Instant::now();
    let mut ctx = Ctx::new()?;
    let scenes = knobs::Scenes::new(opts.quick, &ctx)?;
    let mut selected = knobs::all(&scenes, opts.quick, &ctx);
    if let Some(f) = &opts.filter {
        selected.retain(|k| k.name.contains(f.as_str()));
        if selected.is_empty() {
            return Err(format!(
                "no knob matches `{f}` (knobs: sphere, nurb, nurb_polynomial, interpolation, arithmetic, lighting, depth, shading)"
            ));
        }
    }
    let runs = if opts.quick { opts.runs.min(3) } else { opts.runs }.max(1);
    let steps: usize = selected.iter().map(|k| k.settings.len() * (runs + 1)).sum();
    let bar = if opts.progress {
        ProgressBar::new(steps as u64)
    } else {
        ProgressBar::hidden()
    };
    bar.set_style(ProgressStyle::with_template("{bar:40} {pos}/{len} {elapsed} {msg}").map_err(|e| e.to_string())?);
    let mut reports = vec![];
    for knob in &mut selected {
        reports.push(measure_knob(knob, &mut ctx, runs, &bar)?);
    }
    bar.finish_and_clear();
    Ok(Report {
        machine: machine_summary(),
        quick: opts.quick,
        runs,
        knobs: reports,
        total_seconds: started.elapsed().as_secs_f64(),
    })
}

/// CPU model and core count, for the report header.
fn machine_summary() -> String {
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|m| m.trim().to_string())
        })
        .unwrap_or_else(|| std::env::consts::ARCH.to_string());
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    format!("{cpu}, {cores} core(s)")
}

fn fmt_num(v: f64) -> String {
    if v == 0.0 {
        "0".into()
    } else if v.fract() == 0.0 && v.abs() < 1e9 {
        // Pixel counts (and whole numbers generally) without a fraction.
        format!("{v:.0}")
    } else if v.abs() >= 1e4 || v.abs() < 1e-3 {
        format!("{v:.2e}")
    } else {
        format!("{v:.4}")
    }
}

/// The report as a text table, one row per (knob, setting, metric).
pub fn format_table(report: &Report) -> String {
    let mut s = format!(
        "machine: {}; {} timed run(s) per setting, median, one thread{}\n\n",
        report.machine,
        report.runs,
        if report.quick { "; quick run" } else { "" }
    );
    s.push_str(&format!(
        "{:<15} {:<30} {:<21} {:>10} {:>10} {:>8} {:>10} {:>8}\n",
        "knob", "setting", "error", "max", "mean", "pixels", "ms/frame", "time x"
    ));
    for k in &report.knobs {
        for r in &k.rows {
            let metric = format!("{} ({})", r.metric, r.unit);
            s.push_str(&format!(
                "{:<15} {:<30} {:<21} {:>10} {:>10} {:>8} {:>10.3} {:>8.2}\n",
                r.knob,
                r.setting,
                metric,
                fmt_num(r.max),
                fmt_num(r.mean),
                r.pixels,
                r.median_ms,
                r.time_ratio
            ));
        }
        s.push_str(&format!("{:<15} most accurate: {}\n", "", k.most_accurate));
        for m in &k.missing {
            s.push_str(&format!("{:<15} not measured: {m}\n", ""));
        }
        s.push('\n');
    }
    s.push_str(&format!("total {:.1} s\n", report.total_seconds));
    s
}

fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

/// The rows as CSV (header first).
pub fn to_csv(report: &Report) -> String {
    let mut s = String::from("knob,setting,metric,unit,max,mean,pixels,median_ms,time_ratio\n");
    for k in &report.knobs {
        for r in &k.rows {
            s.push_str(&format!(
                "{},{},{},{},{},{},{},{},{}\n",
                csv_field(&r.knob),
                csv_field(&r.setting),
                csv_field(&r.metric),
                csv_field(&r.unit),
                r.max,
                r.mean,
                r.pixels,
                r.median_ms,
                r.time_ratio
            ));
        }
    }
    s
}

/// Write `accuracy.csv`, `accuracy.json` and one `<knob>.png` per knob into `dir`; returns
/// the paths written.
pub fn write_outputs(report: &Report, dir: &Path) -> Result<Vec<String>, String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("cannot create `{}`: {e}", dir.display()))?;
    let mut written = vec![];
    let csv = dir.join("accuracy.csv");
    std::fs::write(&csv, to_csv(report)).map_err(|e| format!("cannot write `{}`: {e}", csv.display()))?;
    written.push(csv.display().to_string());
    let json = dir.join("accuracy.json");
    let text = serde_json::to_string_pretty(report).map_err(|e| e.to_string())?;
    std::fs::write(&json, text).map_err(|e| format!("cannot write `{}`: {e}", json.display()))?;
    written.push(json.display().to_string());
    for k in &report.knobs {
        let png = dir.join(format!("{}.png", k.name));
        plot::knob_plot(k, &png)?;
        written.push(png.display().to_string());
    }
    Ok(written)
}
