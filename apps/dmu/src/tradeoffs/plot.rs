//! One plot per knob, SVG through plotters (no system fonts needed): the
//! setting along x, time on the left axis (blue), error on the right (red).
//! Log axes are drawn as log10 of the value with the labels turned back into
//! values, so one chart type serves linear and log knobs alike.

use plotters::prelude::*;

use super::Knob;
use super::report::number;

/// Smallest error shown on a log axis: a 0 error sits on the floor.
const LOG_FLOOR: f64 = 1e-12;

fn axis_value(v: f64, log: bool) -> f64 {
    if log { v.max(LOG_FLOOR).log10() } else { v }
}

fn axis_label(v: f64, log: bool) -> String {
    if log {
        number(10f64.powf(v))
    } else {
        number(v)
    }
}

/// A range holding `values` with a margin, never empty.
fn range(values: impl Iterator<Item = f64>, from_zero: bool) -> std::ops::Range<f64> {
    let (mut lo, mut hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    if !lo.is_finite() {
        (lo, hi) = (0.0, 1.0);
    }
    if from_zero {
        lo = lo.min(0.0);
    }
    let pad = ((hi - lo) * 0.05).max(if hi.abs() > 0.0 { hi.abs() * 0.05 } else { 0.5 });
    (if from_zero && lo >= 0.0 { lo } else { lo - pad })..(hi + pad)
}

/// The knob's plot as an SVG document.
pub fn svg(k: &Knob) -> anyhow::Result<String> {
    let mut out = String::new();
    draw(k, &mut out).map_err(|e| anyhow::anyhow!("{e}"))?;
    Ok(out)
}

fn draw(k: &Knob, out: &mut String) -> Result<(), Box<dyn std::error::Error>> {
    let categorical = k.points.iter().any(|p| p.label.is_some());
    let x = |s: f64| axis_value(s, k.log_x);
    let time: Vec<(f64, f64)> = k.points.iter().map(|p| (x(p.setting), p.time_ms)).collect();
    let error: Vec<(f64, f64)> = k
        .points
        .iter()
        .map(|p| (x(p.setting), axis_value(p.error, k.log_error)))
        .collect();
    let xr = range(time.iter().map(|p| p.0), false);
    let tr = range(time.iter().map(|p| p.1), true);
    let er = range(error.iter().map(|p| p.1), !k.log_error);
    let labels: Vec<(f64, String)> = k
        .points
        .iter()
        .map(|p| (x(p.setting), p.setting_text()))
        .collect();
    let x_label = |v: &f64| {
        if categorical {
            labels
                .iter()
                .find(|(s, _)| (s - v).abs() < 1e-9)
                .map(|(_, l)| l.clone())
                .unwrap_or_default()
        } else {
            axis_label(*v, k.log_x)
        }
    };
    let root = SVGBackend::with_string(out, (800, 480)).into_drawing_area();
    root.fill(&WHITE)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            format!("{}: {}", k.section, k.name),
            ("sans-serif", 20).into_font(),
        )
        .margin(12)
        .x_label_area_size(48)
        .y_label_area_size(72)
        .right_y_label_area_size(72)
        .build_cartesian_2d(xr.clone(), tr)?
        .set_secondary_coord(xr, er);
    let x_desc = match (k.unit.is_empty(), k.log_x) {
        (true, _) => k.name.clone(),
        (false, false) => format!("{} ({})", k.name, k.unit),
        (false, true) => format!("{} ({}, log)", k.name, k.unit),
    };
    let time_label = |v: &f64| number(*v);
    let error_label = |v: &f64| axis_label(*v, k.log_error);
    let mut mesh = chart.configure_mesh();
    mesh.x_desc(x_desc)
        .y_desc(format!("{}, ms", k.time))
        .x_label_formatter(&x_label)
        .y_label_formatter(&time_label);
    if categorical {
        mesh.x_labels(labels.len() * 2 + 1);
    }
    mesh.draw()?;
    chart
        .configure_secondary_axes()
        .y_desc(format!(
            "error, {}{}",
            k.error_unit,
            if k.log_error { " (log)" } else { "" }
        ))
        .y_label_formatter(&error_label)
        .draw()?;
    chart
        .draw_series(LineSeries::new(time.iter().copied(), BLUE.stroke_width(2)))?
        .label(format!("{}, ms (left)", k.time))
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLUE.stroke_width(2)));
    chart.draw_series(
        time.iter()
            .map(|&(x, y)| Circle::new((x, y), 4, BLUE.filled())),
    )?;
    chart
        .draw_secondary_series(LineSeries::new(error.iter().copied(), RED.stroke_width(2)))?
        .label(format!("error vs {} (right)", k.reference))
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], RED.stroke_width(2)));
    chart.draw_secondary_series(
        error
            .iter()
            .map(|&(x, y)| TriangleMarker::new((x, y), 5, RED.filled())),
    )?;
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperMiddle)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()?;
    root.present()?;
    Ok(())
}
