//! PNG plots of trajectories: time series panels and a gait diagram (feet in contact).

use plotters::prelude::*;
use std::path::Path;

/// One named curve.
pub struct Series<'a> {
    /// Legend label.
    pub label: &'a str,
    /// Values, one per time sample.
    pub values: &'a [f32],
}

/// Draws one panel per entry of `panels` (title, curves) over `time_s`, stacked vertically.
pub fn time_series(path: &Path, time_s: &[f32], panels: &[(&str, Vec<Series>)]) -> anyhow::Result<()> {
    let height = 260 * panels.len() as u32;
    let root = BitMapBackend::new(path, (1000, height)).into_drawing_area();
    root.fill(&WHITE)?;
    let areas = root.split_evenly((panels.len(), 1));
    let t_end = time_s.last().copied().unwrap_or(1.0).max(1e-3);
    let colors = [RED, BLUE, GREEN, MAGENTA, CYAN, BLACK];
    for (area, (title, series)) in areas.iter().zip(panels) {
        let (mut lo, mut hi) = (f32::MAX, f32::MIN);
        for s in series {
            for v in s.values.iter().filter(|v| v.is_finite()) {
                lo = lo.min(*v);
                hi = hi.max(*v);
            }
        }
        if lo > hi {
            (lo, hi) = (0.0, 1.0);
        }
        let pad = ((hi - lo) * 0.1).max(1e-3);
        let mut chart = ChartBuilder::on(area)
            .caption(*title, ("sans-serif", 18))
            .margin(8)
            .x_label_area_size(28)
            .y_label_area_size(55)
            .build_cartesian_2d(0f32..t_end, (lo - pad)..(hi + pad))?;
        chart.configure_mesh().x_desc("time [s]").draw()?;
        for (k, s) in series.iter().enumerate() {
            let color = colors[k % colors.len()];
            chart
                .draw_series(LineSeries::new(time_s.iter().copied().zip(s.values.iter().copied()), color.stroke_width(2)))?
                .label(s.label)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2)));
        }
        chart.configure_series_labels().background_style(WHITE.mix(0.8)).border_style(BLACK).draw()?;
    }
    root.present()?;
    Ok(())
}

/// Gait diagram: one row per leg, a bar where the foot is on the ground.
/// `contact_masks[k]` has bit i set when leg i touches the ground at `time_s[k]`.
pub fn gait_diagram(path: &Path, time_s: &[f32], contact_masks: &[u8], leg_names: &[&str]) -> anyhow::Result<()> {
    let root = BitMapBackend::new(path, (1000, 320)).into_drawing_area();
    root.fill(&WHITE)?;
    let t_end = time_s.last().copied().unwrap_or(1.0).max(1e-3);
    let n = leg_names.len();
    let mut chart = ChartBuilder::on(&root)
        .caption("Gait diagram (feet in contact)", ("sans-serif", 18))
        .margin(8)
        .x_label_area_size(28)
        .y_label_area_size(45)
        .build_cartesian_2d(-0.06 * t_end..t_end, 0f32..n as f32)?;
    chart.configure_mesh().x_desc("time [s]").y_labels(0).disable_y_mesh().draw()?;
    chart.draw_series(leg_names.iter().enumerate().map(|(leg, name)| {
        Text::new(name.to_uppercase(), (-0.05 * t_end, (n - 1 - leg) as f32 + 0.65), ("sans-serif", 16))
    }))?;
    let dt = if time_s.len() > 1 { time_s[1] - time_s[0] } else { 0.02 };
    for (leg, _) in leg_names.iter().enumerate() {
        let row = (n - 1 - leg) as f32;
        let color = if hexapod_core::robot::TRIPOD_A_MASK & (1 << leg) != 0 { BLUE } else { RED };
        chart.draw_series(time_s.iter().zip(contact_masks).filter(|(_, m)| *m & (1 << leg) != 0).map(|(t, _)| {
            Rectangle::new([(*t, row + 0.15), (*t + dt, row + 0.85)], color.filled())
        }))?;
    }
    root.present()?;
    Ok(())
}
