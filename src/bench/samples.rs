//! The multisampling series: what N samples per pixel cost against one, on the fill and
//! small-triangle workloads, measured side by side (and, where a worker runs, llvmpipe's own
//! 4x multisampling on the same geometry).
//!
//! Every sample count of a workload is first rendered once on one thread and once on all,
//! the two frames compared (the image must not depend on the thread count); then `runs` interleaved rounds, one thread, every count of the workload in
//! turn, and the ratio of each count's frame time to the one-sample frame's is the median of
//! the rounds' own ratios ([`super::paired`]). llvmpipe's frames, when a worker runs, follow
//! each workload's rounds, `runs` at each of its counts.

use std::sync::Arc;
use std::time::Instant;

use indicatif::ProgressBar;
use serde::Serialize;

use super::llvmpipe::Llvmpipe;
use super::{median, paired};
use crate::ir::Program;
use crate::jit::Jit;
use crate::runtime::samples::ALLOWED_SAMPLES;
use crate::runtime::Frame;
use crate::workload::{scene, workloads, SIZE};

/// The workloads of the series: full-viewport layers (fill-bound) and 20-pixel triangles
/// (setup-bound), both with four perspective-correct parameters.
const WORKLOADS: [&str; 2] = ["fill perspective_linear K=4", "small perspective_linear K=4"];

/// One (workload, sample count) of the series.
#[derive(Clone, Debug, Serialize)]
pub struct SamplesRow {
    pub workload: String,
    pub samples: u32,
    /// Whole frame, one thread (median).
    pub frame_ms: f64,
    /// Of which the tile kernels, all samples (median).
    pub tiles_ms: f64,
    /// Of which the resolve (and any shading), median.
    pub shade_ms: f64,
    /// Frame time over the one-sample frame's (paired by round).
    pub ratio_to_one: f64,
    /// llvmpipe's frame at this sample count on one thread (multisampled renderbuffers,
    /// resolved by a blit in the timed frame) and its ratio to its own one-sample frame
    /// (medians: its counts run one after the other, the worker holding one scene at a
    /// time), for the counts it was asked for (1 and 4) when a worker runs.
    pub llvmpipe_ms: Option<f64>,
    pub llvmpipe_ratio_to_one: Option<f64>,
}

#[derive(Clone, Debug, Serialize)]
pub struct SamplesSeries {
    pub size: u32,
    pub rows: Vec<SamplesRow>,
}

/// Whether the series runs under `filter` ("samples" or a workload name of it).
pub(super) fn samples_selected(filter: Option<&str>) -> bool {
    filter.is_none_or(|f| "samples".contains(f) || WORKLOADS.iter().any(|w| w.contains(f)))
}

/// llvmpipe's sample counts in the series.
const LLVMPIPE_SAMPLES: [u32; 2] = [1, 4];

/// Run the series (see the module doc); `llvmpipe`: a one-thread worker, when one runs.
pub(super) fn samples_series(
    program: &Arc<Program>,
    quick: bool,
    runs: usize,
    one: &rayon::ThreadPool,
    all: &rayon::ThreadPool,
    mut llvmpipe: Option<&mut Llvmpipe>,
    bar: &ProgressBar,
) -> Result<SamplesSeries, String> {
    let mut jit = Jit::new(program.clone()).map_err(|e| e.to_string())?;
    let mut rows = vec![];
    let counts = ALLOWED_SAMPLES;
    bar.inc_length((WORKLOADS.len() * counts.len() * (2 + runs)) as u64);
    for w in workloads(quick).iter().filter(|w| WORKLOADS.contains(&w.name.as_str())) {
        let scenes: Vec<_> = counts
            .iter()
            .map(|&n| {
                let mut r = scene(program, SIZE, w, false);
                r.set_samples(n).map_err(|e| e.message)?;
                Ok(r)
            })
            .collect::<Result<_, String>>()?;
        for (r, n) in scenes.iter().zip(counts) {
            let single = one.install(|| r.render(&mut jit));
            let multi = all.install(|| r.render(&mut jit));
            if single.diags.has_errors() {
                return Err(format!("samples {}: {:?}", w.name, single.diags.items));
            }
            let image = single.frame.to_rgb8();
            if !single.frame.same_buffers(&multi.frame) || image != multi.frame.to_rgb8() {
                return Err(format!(
                    "{} at {n} samples: the frame depends on the thread count",
                    w.name
                ));
            }
            if single.frame.sample_count() != n as usize {
                return Err(format!(
                    "{} at {n} samples: the frame has {}",
                    w.name,
                    single.frame.sample_count()
                ));
            }
            bar.inc(2);
        }
        let mut gl_times: Vec<Vec<f64>> = vec![vec![]; LLVMPIPE_SAMPLES.len()];
        let mut times: Vec<Vec<[f64; 3]>> = vec![vec![]; counts.len()];
        let mut frames: Vec<Frame> = counts.iter().map(|_| Frame::empty()).collect();
        for _ in 0..runs {
            for ((r, t), f) in scenes.iter().zip(&mut times).zip(&mut frames) {
                let started = Instant::now();
                let report = one.install(|| r.render_into(&mut jit, f));
                let ms = started.elapsed().as_secs_f64() * 1e3;
                let s = &report.stats;
                t.push([ms, s.tiles_micros as f64 / 1e3, s.shade_micros as f64 / 1e3]);
                bar.inc(1);
            }
        }
        // The worker holds one scene (and sample count) at a time: its counts one after the
        // other, `runs` frames each.
        if let Some(lp) = llvmpipe.as_deref_mut() {
            for (k, &n) in LLVMPIPE_SAMPLES.iter().enumerate() {
                lp.setup_samples(quick, &w.name, n)?;
                for _ in 0..runs {
                    gl_times[k].push(lp.frame()?.ms);
                }
            }
        }
        let frames_of = |t: &[[f64; 3]]| t.iter().map(|x| x[0]).collect::<Vec<_>>();
        let med = |t: &[[f64; 3]], k: usize| median(t.iter().map(|x| x[k]).collect());
        for (i, (&n, t)) in counts.iter().zip(&times).enumerate() {
            let gl = LLVMPIPE_SAMPLES
                .iter()
                .position(|&m| m == n)
                .filter(|&k| !gl_times[k].is_empty());
            rows.push(SamplesRow {
                workload: w.name.clone(),
                samples: n,
                frame_ms: med(t, 0),
                tiles_ms: med(t, 1),
                shade_ms: med(t, 2),
                ratio_to_one: if i == 0 {
                    1.0
                } else {
                    paired(&frames_of(t), &frames_of(&times[0]))
                },
                llvmpipe_ms: gl.map(|k| median(gl_times[k].clone())),
                llvmpipe_ratio_to_one: gl.map(|k| median(gl_times[k].clone()) / median(gl_times[0].clone())),
            });
        }
    }
    Ok(SamplesSeries { size: SIZE, rows })
}

/// The series as a table.
pub fn format_samples(series: &SamplesSeries) -> String {
    let mut s = format!(
        "multisampling, {0}x{0}, one thread (each sample rendered and shaded at its position, box resolve; ratios paired by round):\n",
        series.size
    );
    s.push_str(&format!(
        "  {:<30} {:>7} {:>9} {:>9} {:>9} {:>8} {:>13} {:>9}\n",
        "workload", "samples", "ms", "tiles", "resolve", "x 1 spp", "llvmpipe ms", "x 1 spp"
    ));
    for r in &series.rows {
        let opt = |v: Option<f64>, prec: usize| v.map_or("-".to_string(), |v| format!("{v:.prec$}"));
        s.push_str(&format!(
            "  {:<30} {:>7} {:>9.2} {:>9.2} {:>9.2} {:>8.2} {:>13} {:>9}\n",
            r.workload,
            r.samples,
            r.frame_ms,
            r.tiles_ms,
            r.shade_ms,
            r.ratio_to_one,
            opt(r.llvmpipe_ms, 2),
            opt(r.llvmpipe_ratio_to_one, 2),
        ));
    }
    s
}
