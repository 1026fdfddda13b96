//! One PNG per knob: the primary error figure (max over pixels) against the median frame
//! time, both on log scales, one labelled point per setting.
//!
//! A log scale has no zero: an error of exactly 0 (a setting that matches the reference,
//! or a pixel count of none) is drawn at the bottom edge of the plot, marked "= 0" in its
//! label, so it stays visible instead of vanishing.

use std::path::Path;

use plotters::prelude::*;

use super::KnobReport;

/// Draw `knob`'s plot into `path`.
pub fn knob_plot(knob: &KnobReport, path: &Path) -> Result<(), String> {
    let Some(first) = knob.rows.first() else {
        return Ok(());
    };
    let (metric, unit) = (first.metric.clone(), first.unit.clone());
    let points: Vec<(String, f64, f64)> = knob
        .rows
        .iter()
        .filter(|r| r.metric == metric)
        .map(|r| (r.setting.clone(), r.median_ms, r.max))
        .collect();
    let positive = |v: f64| v > 0.0 && v.is_finite();
    let t_lo = points
        .iter()
        .map(|p| p.1)
        .filter(|&t| positive(t))
        .fold(f64::INFINITY, f64::min);
    let t_hi = points.iter().map(|p| p.1).filter(|&t| positive(t)).fold(0.0, f64::max);
    let e_lo = points
        .iter()
        .map(|p| p.2)
        .filter(|&e| positive(e))
        .fold(f64::INFINITY, f64::min);
    let e_hi = points.iter().map(|p| p.2).filter(|&e| positive(e)).fold(0.0, f64::max);
    // Ranges with a margin of a factor 2 (a decade when everything is one value).
    let (t_lo, t_hi) = if t_lo.is_finite() {
        (t_lo / 2.0, t_hi * 2.0)
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
        .caption(knob.title.as_str(), ("sans-serif", 22))
        .margin(16)
        .x_label_area_size(48)
        .y_label_area_size(80)
        .build_cartesian_2d((t_lo..t_hi).log_scale(), (e_lo..e_hi).log_scale())
        .map_err(|e| err(Box::new(e)))?;
    chart
        .configure_mesh()
        .x_desc("median time per frame (ms, one thread)")
        .y_desc(format!("max {metric} ({unit})"))
        .draw()
        .map_err(|e| err(Box::new(e)))?;
    let colour = Palette99::pick(4).to_rgba();
    chart
        .draw_series(points.iter().map(|(label, t, e)| {
            let (y, label) = if positive(*e) {
                (*e, label.clone())
            } else {
                (floor, format!("{label} (= 0)"))
            };
            EmptyElement::at((*t, y))
                + Circle::new((0, 0), 5, colour.filled())
                + Text::new(label, (8, -14), ("sans-serif", 14))
        }))
        .map_err(|e| err(Box::new(e)))?;
    root.present().map_err(|e| err(Box::new(e)))?;
    Ok(())
}
