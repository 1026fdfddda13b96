//! One PNG per knob: every error figure of the knob (max over pixels) against the median
//! frame time, one panel per figure, stacked over one shared time axis, each panel with its
//! own error axis named with its unit (the sphere's silhouette error in px and normal error
//! in degrees, a NURB's geometric error and differing pixels, ...). Both axes are log
//! scales; each spans at least a decade, so it has at least two labelled ticks, and tick
//! labels are the round values they stand for ([`tick_label`]: `1e-5`, `0.25`, `300`).
//! Every point carries its setting's label.
//!
//! A log scale has no zero: an error of exactly 0 (a setting that matches the reference,
//! or a pixel count of none) is drawn at the bottom edge of its panel, marked "= 0" in its
//! label, so it stays visible instead of vanishing.

use std::path::Path;

use plotters::prelude::*;

use super::KnobReport;

/// One figure's points: (setting, median ms, max error).
struct Series {
    name: String,
    points: Vec<(String, f64, f64)>,
}

fn positive(v: f64) -> bool {
    v > 0.0 && v.is_finite()
}

/// The log-scale range drawn for values `lo..=hi` (positive, or infinite/0 when there are
/// none): a `margin` factor each side, widened about its middle to at least a decade.
fn log_range(lo: f64, hi: f64, margin: (f64, f64)) -> (f64, f64) {
    if !lo.is_finite() || !positive(hi) {
        return (0.1, 10.0);
    }
    let (lo, hi) = (lo / margin.0, hi * margin.1);
    if hi / lo >= 10.0 {
        (lo, hi)
    } else {
        let middle = (lo * hi).sqrt();
        (middle / 10f64.sqrt(), middle * 10f64.sqrt())
    }
}

/// A tick's label: the value to three significant digits, as plain decimals from 0.001 to
/// 99,999 and as `Me±X` beyond (`1e-5`, `2.5e6`), with no trailing zeros. A log axis's tick
/// at 1e-5 is computed as 9.999...e-6; it prints as `1e-5`.
pub fn tick_label(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let mut exp = v.abs().log10().floor() as i32;
    let mut mantissa = (v / 10f64.powi(exp) * 100.0).round() / 100.0;
    if mantissa.abs() >= 10.0 {
        mantissa /= 10.0;
        exp += 1;
    }
    let trim = |s: String| {
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s
        }
    };
    if (-3..5).contains(&exp) {
        let decimals = (2 - exp).max(0) as usize;
        trim(format!("{:.*}", decimals, mantissa * 10f64.powi(exp)))
    } else {
        format!("{}e{exp}", trim(format!("{mantissa:.2}")))
    }
}

/// Draw `knob`'s plot into `path`.
pub fn knob_plot(knob: &KnobReport, path: &Path) -> Result<(), String> {
    let mut series: Vec<Series> = vec![];
    for r in &knob.rows {
        let name = format!("max {} ({})", r.metric, r.unit);
        let at = match series.iter().position(|s| s.name == name) {
            Some(at) => at,
            None => {
                series.push(Series { name, points: vec![] });
                series.len() - 1
            }
        };
        series[at].points.push((r.setting.clone(), r.median_ms, r.max));
    }
    if series.is_empty() {
        return Ok(());
    }
    let times = || {
        series
            .iter()
            .flat_map(|s| s.points.iter().map(|p| p.1))
            .filter(|&t| positive(t))
    };
    // Room on the right for the labels of the slowest points.
    let (t_lo, t_hi) = log_range(
        times().fold(f64::INFINITY, f64::min),
        times().fold(0.0, f64::max),
        (2.0, 5.0),
    );

    let err = |e: Box<dyn std::error::Error>| format!("plot `{}`: {e}", path.display());
    let panel_height = 380;
    let root = BitMapBackend::new(path, (860, 60 + panel_height * series.len() as u32)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(Box::new(e)))?;
    let root = root
        .titled(knob.title.as_str(), ("sans-serif", 20))
        .map_err(|e| err(Box::new(e)))?;
    let panels = root.split_evenly((series.len(), 1));
    for (k, (s, panel)) in series.iter().zip(&panels).enumerate() {
        let errors = || s.points.iter().map(|p| p.2).filter(|&e| positive(e));
        let (e_lo, e_hi) = log_range(
            errors().fold(f64::INFINITY, f64::min),
            errors().fold(0.0, f64::max),
            (4.0, 4.0),
        );
        let floor = e_lo * 1.2;
        let mut chart = ChartBuilder::on(panel)
            .margin(16)
            .x_label_area_size(48)
            .y_label_area_size(90)
            .build_cartesian_2d((t_lo..t_hi).log_scale(), (e_lo..e_hi).log_scale())
            .map_err(|e| err(Box::new(e)))?;
        chart
            .configure_mesh()
            .x_desc("median time per frame (ms, one thread)")
            .y_desc(s.name.as_str())
            .x_label_formatter(&|v: &f64| tick_label(*v))
            .y_label_formatter(&|v: &f64| tick_label(*v))
            .draw()
            .map_err(|e| err(Box::new(e)))?;
        let colour = Palette99::pick(4 + 3 * k).to_rgba();
        let at = |e: f64| if positive(e) { e } else { floor };
        chart
            .draw_series(s.points.iter().map(|(label, t, e)| {
                let text = if positive(*e) {
                    label.clone()
                } else {
                    format!("{label} (= 0)")
                };
                EmptyElement::at((*t, at(*e)))
                    + Circle::new((0, 0), 5, colour.filled())
                    + Text::new(text, (8, -14), ("sans-serif", 13))
            }))
            .map_err(|e| err(Box::new(e)))?;
    }
    root.present().map_err(|e| err(Box::new(e)))?;
    Ok(())
}
