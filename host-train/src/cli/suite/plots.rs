//! The suite's PNG plots, one line per controller: success rate against step height and
//! slope (Fig. 5), commanded against measured under sinusoidal commands with vz, roll and
//! pitch (Fig. 3), the terrain row per kind over training (Fig. 4), and survivors against
//! push magnitude (Table III's search).

use super::report::ControllerReport;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::{Path, PathBuf};

/// One line of a panel.
struct Series {
    name: String,
    points: Vec<(f64, f64)>,
    color: RGBColor,
    points_marked: bool,
}

/// Colour of controller `i` (black is the command).
fn color(i: usize) -> RGBColor {
    const C: [RGBColor; 6] = [
        RGBColor(31, 119, 180),
        RGBColor(214, 39, 40),
        RGBColor(44, 160, 44),
        RGBColor(148, 103, 189),
        RGBColor(255, 127, 14),
        RGBColor(23, 190, 207),
    ];
    C[i % C.len()]
}

fn panel(
    area: &DrawingArea<BitMapBackend, Shift>,
    title: &str,
    x_label: &str,
    y_label: &str,
    y_range: Option<(f64, f64)>,
    series: &[Series],
    legend: SeriesLabelPosition,
) -> Result<(), String> {
    let finite = || series.iter().flat_map(|s| s.points.iter()).filter(|p| p.0.is_finite() && p.1.is_finite());
    let x0 = finite().map(|p| p.0).fold(f64::MAX, f64::min);
    let mut x1 = finite().map(|p| p.0).fold(f64::MIN, f64::max);
    if x1 <= x0 {
        x1 = x0 + 1.0;
    }
    let (y0, y1) = y_range.unwrap_or_else(|| {
        let lo = finite().map(|p| p.1).fold(f64::MAX, f64::min);
        let hi = finite().map(|p| p.1).fold(f64::MIN, f64::max);
        let pad = ((hi - lo).abs() * 0.08).max(1e-2);
        (lo - pad, hi + pad)
    });
    let e = |e: &dyn std::fmt::Display| e.to_string();
    let mut chart = ChartBuilder::on(area)
        .caption(title, ("sans-serif", 20))
        .margin(10)
        .x_label_area_size(34)
        .y_label_area_size(56)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(|x| e(&x))?;
    chart.configure_mesh().light_line_style(TRANSPARENT).x_desc(x_label).y_desc(y_label).draw().map_err(|x| e(&x))?;
    for s in series {
        let style = s.color.stroke_width(2);
        let pts: Vec<(f64, f64)> = s.points.iter().copied().filter(|p| p.1.is_finite()).collect();
        chart
            .draw_series(LineSeries::new(pts.clone(), style))
            .map_err(|x| e(&x))?
            .label(s.name.as_str())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], style));
        if s.points_marked {
            chart.draw_series(pts.iter().map(|p| Circle::new(*p, 4, s.color.filled()))).map_err(|x| e(&x))?;
        }
    }
    chart
        .configure_series_labels()
        .position(legend)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(|x| e(&x))?;
    Ok(())
}

fn single(path: &Path, title: &str, x_label: &str, y_label: &str, y_range: Option<(f64, f64)>, series: &[Series]) -> Result<(), String> {
    let root = BitMapBackend::new(path, (900, 540)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let legend = if x_label == "iteration" { SeriesLabelPosition::UpperLeft } else { SeriesLabelPosition::LowerLeft };
    panel(&root, title, x_label, y_label, y_range, series, legend)?;
    root.present().map_err(|e| e.to_string())
}

/// Draws every plot the reports have data for into `dir`; returns the files written.
pub fn draw_all(dir: &Path, reports: &[ControllerReport]) -> Result<Vec<PathBuf>, String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let mut written = Vec::new();
    let mut out = |name: &str| {
        let p = dir.join(name);
        written.push(p.clone());
        p
    };
    // Fig. 5: success rate against the feature's size.
    type Pick = fn(&host_sim::course::Feature) -> Option<f64>;
    let panels: [(&str, &str, &str, Pick); 4] = [
        ("success_stairs_up.png", "Stairs up: success rate", "step height, cm", |f| match f {
            host_sim::course::Feature::StairsUp { step_height_m } => Some(*step_height_m as f64 * 100.0),
            _ => None,
        }),
        ("success_stairs_down.png", "Stairs down: success rate", "step height, cm", |f| match f {
            host_sim::course::Feature::StairsDown { step_height_m } => Some(*step_height_m as f64 * 100.0),
            _ => None,
        }),
        ("success_slopes_up.png", "Slopes up: success rate", "slope, deg", |f| match f {
            host_sim::course::Feature::SlopeUp { slope_deg } => Some(*slope_deg as f64),
            _ => None,
        }),
        ("success_slopes_down.png", "Slopes down: success rate", "slope, deg", |f| match f {
            host_sim::course::Feature::SlopeDown { slope_deg } => Some(*slope_deg as f64),
            _ => None,
        }),
    ];
    for (file, title, x_label, pick) in panels {
        let series: Vec<Series> = reports
            .iter()
            .enumerate()
            .filter_map(|(i, r)| {
                let t = r.terrain.as_ref()?;
                let points: Vec<(f64, f64)> = t.features.iter().filter_map(|f| Some((pick(&f.feature)?, f.success_rate()))).collect();
                (!points.is_empty()).then(|| Series { name: r.name.clone(), points, color: color(i), points_marked: true })
            })
            .collect();
        if !series.is_empty() {
            single(&out(file), title, x_label, "success rate", Some((-0.02, 1.05)), &series)?;
        }
    }
    // Fig. 3: per command axis, four stacked panels.
    for axis in 0..super::sine::AXES.len() {
        let runs: Vec<(usize, &ControllerReport, &super::sine::SineRun)> =
            reports.iter().enumerate().filter_map(|(i, r)| Some((i, r, r.sine.as_ref()?.get(axis)?))).collect();
        let Some((_, _, first)) = runs.first() else { continue };
        let unit = if axis == 2 { "rad/s" } else { "m/s" };
        let path = out(&format!("sine_{}.png", super::sine::AXES[axis]));
        let root = BitMapBackend::new(&path, (900, 1300)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let areas = root.split_evenly((4, 1));
        let trace = |s: &super::sine::SineRun, v: &[f32]| -> Vec<(f64, f64)> {
            s.time_s.iter().zip(v).map(|(t, y)| (*t as f64, *y as f64)).collect()
        };
        let mut tracking = vec![Series {
            name: "command".into(),
            points: trace(first, &first.commanded),
            color: BLACK,
            points_marked: false,
        }];
        tracking.extend(runs.iter().map(|(i, r, s)| Series {
            name: format!("{} measured", r.name),
            points: trace(s, &s.measured),
            color: color(*i),
            points_marked: false,
        }));
        let name = super::sine::AXES[axis];
        panel(&areas[0], &format!("{name} command: tracking"), "time, s", &format!("{name}, {unit}"), None, &tracking, SeriesLabelPosition::LowerLeft)?;
        let rest: [(&str, &str, fn(&super::sine::SineRun) -> &[f32]); 3] = [
            ("vz", "vz, m/s", |s| &s.vz_m_s),
            ("roll", "roll, deg", |s| &s.roll_deg),
            ("pitch", "pitch, deg", |s| &s.pitch_deg),
        ];
        for (k, (what, y_label, get)) in rest.iter().enumerate() {
            let series: Vec<Series> = runs
                .iter()
                .map(|(i, r, s)| Series { name: r.name.clone(), points: trace(s, get(s)), color: color(*i), points_marked: false })
                .collect();
            panel(&areas[k + 1], &format!("{name} command: {what}"), "time, s", y_label, None, &series, SeriesLabelPosition::LowerLeft)?;
        }
        root.present().map_err(|e| e.to_string())?;
    }
    // Fig. 4: terrain row per kind over iterations.
    let mut kinds: Vec<String> = reports
        .iter()
        .filter_map(|r| r.curriculum.as_ref())
        .flat_map(|c| c.kinds.iter().map(|k| k.kind.clone()))
        .collect();
    kinds.sort();
    kinds.dedup();
    for kind in kinds {
        let mut top = 1.0f64;
        let series: Vec<Series> = reports
            .iter()
            .enumerate()
            .filter_map(|(i, r)| {
                let c = r.curriculum.as_ref()?;
                top = top.max(c.rows.saturating_sub(1) as f64);
                let k = c.kinds.iter().find(|k| k.kind == kind)?;
                Some(Series { name: r.name.clone(), points: k.points.clone(), color: color(i), points_marked: false })
            })
            .collect();
        single(&out(&format!("curriculum_{kind}.png")), &format!("{kind}: terrain row"), "iteration", "mean row", Some((0.0, top)), &series)?;
    }
    // Table III's search: survivors against magnitude, walking, per axis and rule.
    for (axis, name) in [(super::push::Axis::X, "X"), (super::push::Axis::Y, "Y"), (super::push::Axis::Z, "Z")] {
        let mut series = Vec::new();
        for (i, r) in reports.iter().enumerate() {
            let Some(p) = &r.push else { continue };
            let Some(cond) = p.conditions.iter().find(|c| c.axis == axis && c.gait == super::push::Gait::Walk) else { continue };
            let pts = |f: fn(&super::push::PointResult) -> usize| -> Vec<(f64, f64)> {
                cond.points.iter().map(|q| (q.magnitude_m_s as f64, f(q) as f64 / q.robots.max(1) as f64)).collect()
            };
            series.push(Series { name: format!("{} strict", r.name), points: pts(|q| q.survived_strict), color: color(i), points_marked: true });
            let light = color(i);
            let light = RGBColor(light.0 / 2 + 127, light.1 / 2 + 127, light.2 / 2 + 127);
            series.push(Series { name: format!("{} current", r.name), points: pts(|q| q.survived_current), color: light, points_marked: true });
        }
        if !series.is_empty() {
            single(
                &out(&format!("push_{name}_walk.png")),
                &format!("Pushes along {name} while walking: survivors"),
                "push magnitude, m/s",
                "fraction surviving",
                Some((-0.02, 1.05)),
                &series,
            )?;
        }
    }
    Ok(written)
}
