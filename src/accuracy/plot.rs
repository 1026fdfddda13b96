//! One PNG per knob: every error figure of the knob (max over pixels) against the median
//! frame time, both on log scales, one series per figure (the sphere's silhouette error in
//! px and normal error in degrees, a NURB's geometric error and differing pixels, ...).
//! The primary figure's points carry the setting labels; the legend names each series
//! with its unit, which is what makes sharing one log axis between units readable.
//!
//! A log scale has no zero: an error of exactly 0 (a setting that matches the reference,
//! or a pixel count of none) is drawn at the bottom edge of the plot, marked "= 0" in its
//! label, so it stays visible instead of vanishing.

use std::path::Path;

use plotters::prelude::*;

use super::KnobReport;

/// One figure's points: (setting, median ms, max error).
struct Series {
    name: String,
    points: Vec<(String, f64, f64)>,
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
    let all = || series.iter().flat_map(|s| s.points.iter());
    let positive = |v: f64| v > 0.0 && v.is_finite();
    let t_lo = all()
        .map(|p| p.1)
        .filter(|&t| positive(t))
        .fold(f64::INFINITY, f64::min);
    let t_hi = all().map(|p| p.1).filter(|&t| positive(t)).fold(0.0, f64::max);
    let e_lo = all()
        .map(|p| p.2)
        .filter(|&e| positive(e))
        .fold(f64::INFINITY, f64::min);
    let e_hi = all().map(|p| p.2).filter(|&e| positive(e)).fold(0.0, f64::max);
    // Ranges with a margin of a factor 2 (a decade when everything is one value).
    let (t_lo, t_hi) = if t_lo.is_finite() {
        // Room on the right for the labels of the slowest points.
        (t_lo / 2.0, t_hi * 5.0)
    } else {
        (0.1, 10.0)
    };
    let (e_lo, e_hi) = if e_lo.is_finite() {
        (e_lo / 4.0, e_hi * 4.0)
    } else {
        (0.1, 10.0)
    };
    let floor = e_lo * 1.2;

    let err = |e: Box<dyn std::error::Error>| format!("plot `{}`: {e}", path.display());
    let root = BitMapBackend::new(path, (800, 560)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(Box::new(e)))?;
    let mut chart = ChartBuilder::on(&root)
        .caption(knob.title.as_str(), ("sans-serif", 20))
        .margin(16)
        .x_label_area_size(48)
        .y_label_area_size(80)
        .build_cartesian_2d((t_lo..t_hi).log_scale(), (e_lo..e_hi).log_scale())
        .map_err(|e| err(Box::new(e)))?;
    let y_desc = if series.len() == 1 {
        series[0].name.clone()
    } else {
        "max error (units in the legend)".to_string()
    };
    chart
        .configure_mesh()
        .x_desc("median time per frame (ms, one thread)")
        .y_desc(y_desc)
        // Log-scale ticks like 1e-5 print as 9.99...e-6 through `{}`: three significant digits.
        .y_label_formatter(&|v: &f64| format!("{v:.2e}"))
        .draw()
        .map_err(|e| err(Box::new(e)))?;
    for (k, s) in series.iter().enumerate() {
        let colour = Palette99::pick(4 + 3 * k).to_rgba();
        let primary = k == 0;
        let at = |e: f64| if positive(e) { e } else { floor };
        chart
            .draw_series(s.points.iter().map(|(label, t, e)| {
                let text = match (primary, positive(*e)) {
                    (false, _) => String::new(),
                    (true, true) => label.clone(),
                    (true, false) => format!("{label} (= 0)"),
                };
                let size = if primary { 5 } else { 4 };
                EmptyElement::at((*t, at(*e)))
                    + Circle::new((0, 0), size, colour.filled())
                    + Text::new(text, (8, -14), ("sans-serif", 13))
            }))
            .map_err(|e| err(Box::new(e)))?
            .label(s.name.clone())
            .legend(move |(x, y)| Circle::new((x + 10, y), 5, colour.filled()));
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()
        .map_err(|e| err(Box::new(e)))?;
    root.present().map_err(|e| err(Box::new(e)))?;
    Ok(())
}
