//! PNG plots shared by the simulator and the trainer: line charts in panels (each axis
//! named with its quantity and unit, the legend beside the plotting area so it never
//! covers data) and the gait diagram (feet in stance, one row per leg).
//!
//! Every text uses [`FONT`]. plotters' `ttf` backend rasterizes each glyph into a canvas
//! whose left edge is the pen position, and font-kit's blit drops the columns of a glyph
//! that starts left of that edge: in DejaVu Sans `j`, `J`, `T`, `Y` and `_` have a
//! negative left bearing, and at 12 px a `j` lost its stem ("rew_oint_acc"). DejaVu Sans
//! Mono (in `fonts-dejavu-core`, like DejaVu Sans) has no glyph with a negative left
//! bearing, so every label renders whole.

use hexapod_core::robot::{LEG_NAMES, NUM_LEGS, TRIPOD_A_MASK};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use std::path::Path;

/// The font family of every plot text (see the module doc).
pub const FONT: &str = "DejaVu Sans Mono";
/// Text sizes, px: figure title, panel title, axis names, tick and legend labels.
const TITLE_PX: u32 = 20;
const CAPTION_PX: u32 = 16;
const AXIS_PX: u32 = 14;
const LABEL_PX: u32 = 13;

/// Line colours (the "tab10" palette); series beyond it repeat the colours dashed.
pub const COLORS: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
    RGBColor(255, 127, 14),
    RGBColor(23, 190, 207),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
];
/// Colour of tripod A (RF, LM, RR) in the gait diagram.
pub const TRIPOD_A_COLOR: RGBColor = RGBColor(31, 119, 180);
/// Colour of tripod B (LF, RM, LR) in the gait diagram.
pub const TRIPOD_B_COLOR: RGBColor = RGBColor(255, 127, 14);

/// One curve of a panel.
#[derive(Clone, Debug)]
pub struct Line {
    /// Legend label.
    pub label: String,
    /// (x, y) points; non-finite y values leave gaps out.
    pub points: Vec<(f64, f64)>,
    /// Colour.
    pub color: RGBColor,
    /// Dashed (commands, references) instead of solid.
    pub dashed: bool,
    /// A dot on each point (sparse measurements).
    pub markers: bool,
}

impl Line {
    /// A solid line.
    pub fn new(label: impl Into<String>, points: Vec<(f64, f64)>, color: RGBColor) -> Self {
        Self {
            label: label.into(),
            points,
            color,
            dashed: false,
            markers: false,
        }
    }

    /// The `i`-th series of a panel: palette colour `i`, dashed once the palette repeats.
    pub fn nth(i: usize, label: impl Into<String>, points: Vec<(f64, f64)>) -> Self {
        Self {
            dashed: i >= COLORS.len(),
            ..Self::new(label, points, COLORS[i % COLORS.len()])
        }
    }

    /// The same line dashed.
    pub fn dashed(mut self) -> Self {
        self.dashed = true;
        self
    }

    /// The same line with a dot on each point.
    pub fn with_markers(mut self) -> Self {
        self.markers = true;
        self
    }
}

/// `(t, v)` points of a time series sampled at `time_s`.
pub fn trace(time_s: &[f32], values: impl IntoIterator<Item = f32>) -> Vec<(f64, f64)> {
    time_s
        .iter()
        .zip(values)
        .map(|(t, v)| (*t as f64, v as f64))
        .collect()
}

/// A line chart: title, axis names (quantity and unit), curves.
#[derive(Clone, Debug)]
pub struct Panel {
    /// Title above the plotting area.
    pub title: String,
    /// x axis name, e.g. "time (s)".
    pub x_label: String,
    /// y axis name, e.g. "velocity (m/s)".
    pub y_label: String,
    /// Fixed y range; default the data's range with a margin.
    pub y_range: Option<(f64, f64)>,
    /// x is a count (iterations): whole-number ticks only.
    pub integer_x: bool,
    /// The curves.
    pub lines: Vec<Line>,
}

impl Panel {
    /// An empty panel.
    pub fn new(
        title: impl Into<String>,
        x_label: impl Into<String>,
        y_label: impl Into<String>,
    ) -> Self {
        Self {
            title: title.into(),
            x_label: x_label.into(),
            y_label: y_label.into(),
            y_range: None,
            integer_x: false,
            lines: Vec::new(),
        }
    }

    /// Adds a curve.
    pub fn line(mut self, line: Line) -> Self {
        self.lines.push(line);
        self
    }

    /// Fixes the y range.
    pub fn y_range(mut self, lo: f64, hi: f64) -> Self {
        self.y_range = Some((lo, hi));
        self
    }

    /// Whole-number x ticks (iterations).
    pub fn integer_x(mut self) -> Self {
        self.integer_x = true;
        self
    }

    /// A legend is drawn when there is more than one curve.
    fn has_legend(&self) -> bool {
        self.lines.len() > 1
    }

    fn finite_points(&self) -> impl Iterator<Item = &(f64, f64)> {
        self.lines
            .iter()
            .flat_map(|l| l.points.iter())
            .filter(|p| p.0.is_finite() && p.1.is_finite())
    }

    /// The x and y ranges drawn.
    fn ranges(&self) -> ((f64, f64), (f64, f64)) {
        let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        for &(x, y) in self.finite_points() {
            (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
        }
        if x0 > x1 {
            (x0, x1) = (0.0, 1.0);
        }
        if x1 <= x0 {
            x1 = x0 + 1.0;
        }
        let y = self.y_range.unwrap_or_else(|| {
            if y0 > y1 {
                return (0.0, 1.0);
            }
            let pad = ((y1 - y0) * 0.06)
                .max(1e-3 * y0.abs().max(y1.abs()))
                .max(1e-6);
            (y0 - pad, y1 + pad)
        });
        ((x0, x1), y)
    }
}

/// A tick label with as many decimals as ticks about a tenth of `span` apart need (no
/// "1250.5" on a count axis, no "0.30000000000000004").
pub fn tick_label(value: f64, span: f64) -> String {
    let step = (span / 10.0).abs().max(1e-9);
    let decimals = (-step.log10().floor()).clamp(0.0, 6.0) as usize;
    let s = format!("{value:.decimals$}");
    if s.trim_start_matches('-')
        .chars()
        .all(|c| c == '0' || c == '.')
    {
        s.trim_start_matches('-').to_string()
    } else {
        s
    }
}

/// Width of the legend column beside the plotting area, px (0 when no panel has a legend).
pub fn legend_width<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, panels: &[&Panel]) -> u32 {
    let font: TextStyle = (FONT, LABEL_PX).into();
    let widest = panels
        .iter()
        .filter(|p| p.has_legend())
        .flat_map(|p| p.lines.iter())
        .map(|l| {
            area.estimate_text_size(&l.label, &font)
                .map(|(w, _)| w)
                .unwrap_or(8 * l.label.len() as u32)
        })
        .max();
    widest.map_or(0, |w| w + 48)
}

/// Draws `panel` into `area`, its legend (if any) in a column `legend_px` wide on the right.
pub fn draw_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    panel: &Panel,
    legend_px: u32,
) -> anyhow::Result<()>
where
    DB::ErrorType: 'static,
{
    let (plot_area, legend_area) =
        area.split_horizontally(area.dim_in_pixel().0.saturating_sub(legend_px));
    let ((x0, x1), (y0, y1)) = panel.ranges();
    let mut chart = ChartBuilder::on(&plot_area)
        .caption(&panel.title, (FONT, CAPTION_PX))
        .margin(8)
        .margin_right(16)
        .x_label_area_size(44)
        .y_label_area_size(78)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let (x_span, y_span) = (x1 - x0, y1 - y0);
    // Whole-number ticks: at most one per unit of x, unlabelled if plotters picks a half.
    let x_ticks = if panel.integer_x {
        (x_span as usize + 1).clamp(2, 10)
    } else {
        10
    };
    let x_fmt = |x: &f64| {
        if panel.integer_x {
            if (x - x.round()).abs() < 1e-6 {
                format!("{}", x.round() as i64)
            } else {
                String::new()
            }
        } else {
            tick_label(*x, x_span)
        }
    };
    let y_fmt = |y: &f64| tick_label(*y, y_span);
    chart
        .configure_mesh()
        .light_line_style(RGBColor(235, 235, 235))
        .bold_line_style(RGBColor(210, 210, 210))
        .x_labels(x_ticks)
        .y_labels(8)
        .x_label_formatter(&x_fmt)
        .y_label_formatter(&y_fmt)
        .label_style((FONT, LABEL_PX))
        .axis_desc_style((FONT, AXIS_PX))
        .x_desc(&panel.x_label)
        .y_desc(&panel.y_label)
        .draw()
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    for line in &panel.lines {
        let style = line.color.stroke_width(2);
        // Gaps at non-finite values: one polyline per finite run.
        for run in line
            .points
            .split(|p| !(p.0.is_finite() && p.1.is_finite()))
            .filter(|r| !r.is_empty())
        {
            if line.dashed {
                chart
                    .draw_series(DashedLineSeries::new(run.iter().copied(), 8, 5, style))
                    .map_err(|e| anyhow::anyhow!("{e}"))?;
            } else {
                // Segment by segment: plotters joins a wide polyline with unlimited miters,
                // which draws a sharp spike as a long needle past the data (and the panel).
                let segments = run
                    .windows(2)
                    .map(|w| PathElement::new(vec![w[0], w[1]], style));
                chart
                    .draw_series(segments)
                    .map_err(|e| anyhow::anyhow!("{e}"))?;
            }
            if line.markers {
                chart
                    .draw_series(run.iter().map(|p| Circle::new(*p, 3, line.color.filled())))
                    .map_err(|e| anyhow::anyhow!("{e}"))?;
            }
        }
    }
    if panel.has_legend() && legend_px > 0 {
        let entries: Vec<LegendEntry> = panel
            .lines
            .iter()
            .map(|l| LegendEntry {
                label: &l.label,
                color: l.color,
                dashed: l.dashed,
                filled: false,
            })
            .collect();
        draw_legend(&legend_area, &entries)?;
    }
    Ok(())
}

/// One legend row: a line sample (or a filled box) and its label.
struct LegendEntry<'a> {
    label: &'a str,
    color: RGBColor,
    dashed: bool,
    filled: bool,
}

fn draw_legend<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    entries: &[LegendEntry],
) -> anyhow::Result<()>
where
    DB::ErrorType: 'static,
{
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| anyhow::anyhow!("{e}");
    let row_px = LABEL_PX as i32 + 6;
    let top = 36;
    for (i, e) in entries.iter().enumerate() {
        let y = top + i as i32 * row_px;
        let style = e.color.stroke_width(2);
        if e.filled {
            area.draw(&Rectangle::new([(4, y - 5), (30, y + 5)], e.color.filled()))
                .map_err(err)?;
        } else if e.dashed {
            area.draw(&PathElement::new(vec![(4, y), (13, y)], style))
                .map_err(err)?;
            area.draw(&PathElement::new(vec![(19, y), (30, y)], style))
                .map_err(err)?;
        } else {
            area.draw(&PathElement::new(vec![(4, y), (30, y)], style))
                .map_err(err)?;
        }
        let font = (FONT, LABEL_PX)
            .into_font()
            .color(&BLACK)
            .pos(Pos::new(HPos::Left, VPos::Center));
        area.draw(&Text::new(e.label.to_string(), (36, y), font))
            .map_err(err)?;
    }
    Ok(())
}

/// Writes `panels` into a PNG, `columns` panels per row, each `panel_px` (width, height),
/// under `title` if given; the legends of all panels get one column width so the plotting
/// areas line up.
pub fn write_panels(
    path: &Path,
    title: Option<&str>,
    columns: usize,
    panel_px: (u32, u32),
    panels: &[Panel],
) -> anyhow::Result<()> {
    let columns = columns.max(1);
    let rows = panels.len().div_ceil(columns).max(1);
    let title_px = if title.is_some() { 36 } else { 0 };
    let size = (
        panel_px.0 * columns as u32,
        panel_px.1 * rows as u32 + title_px,
    );
    let root = BitMapBackend::new(path, size).into_drawing_area();
    root.fill(&WHITE)?;
    let body = match title {
        Some(t) => root.titled(t, (FONT, TITLE_PX))?,
        None => root.clone(),
    };
    let refs: Vec<&Panel> = panels.iter().collect();
    let legend_px = legend_width(&body, &refs);
    for (area, panel) in body.split_evenly((rows, columns)).iter().zip(panels) {
        draw_panel(area, panel, legend_px)?;
    }
    root.present()?;
    Ok(())
}

/// Feet in stance over time: `stance_masks[k]` has bit i set when leg i is in stance over
/// `[time_s[k], time_s[k] + dt_s)`.
#[derive(Clone, Debug)]
pub struct Gait<'a> {
    /// Title above the diagram.
    pub title: &'a str,
    /// Sample times, s.
    pub time_s: &'a [f32],
    /// Stance bits per sample (leg order RF RM RR LF LM LR).
    pub stance_masks: &'a [u8],
    /// Sample period, s.
    pub dt_s: f32,
}

/// Legend width the gait diagram needs beside it, px.
pub fn gait_legend_width<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>) -> u32 {
    let font: TextStyle = (FONT, LABEL_PX).into();
    area.estimate_text_size(TRIPOD_LABELS[0], &font)
        .map(|(w, _)| w + 48)
        .unwrap_or(260)
}

const TRIPOD_LABELS: [&str; 2] = ["tripod A (RF LM RR)", "tripod B (LF RM LR)"];

/// Draws a gait diagram into `area`: six rows, RF at the top to LR at the bottom (the joint
/// order), a bar where the foot is in stance, tripod A and B in their colours; the legend
/// in a column `legend_px` wide on the right.
pub fn draw_gait<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    gait: &Gait,
    legend_px: u32,
) -> anyhow::Result<()>
where
    DB::ErrorType: 'static,
{
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| anyhow::anyhow!("{e}");
    let (plot_area, legend_area) =
        area.split_horizontally(area.dim_in_pixel().0.saturating_sub(legend_px));
    let t0 = gait.time_s.first().copied().unwrap_or(0.0) as f64;
    let t1 = (gait.time_s.last().copied().unwrap_or(1.0) + gait.dt_s) as f64;
    let t1 = if t1 > t0 { t1 } else { t0 + 1.0 };
    let mut chart = ChartBuilder::on(&plot_area)
        .caption(gait.title, (FONT, CAPTION_PX))
        .margin(8)
        .margin_right(16)
        .x_label_area_size(44)
        .y_label_area_size(78)
        .build_cartesian_2d(t0..t1, -0.5f64..NUM_LEGS as f64 - 0.5)
        .map_err(err)?;
    let row_of = |leg: usize| (NUM_LEGS - 1 - leg) as f64;
    let y_fmt = |y: &f64| {
        let r = y.round();
        if (y - r).abs() < 1e-6 && (0.0..NUM_LEGS as f64).contains(&r) {
            LEG_NAMES[NUM_LEGS - 1 - r as usize].to_uppercase()
        } else {
            String::new()
        }
    };
    let span = t1 - t0;
    let x_fmt = |x: &f64| tick_label(*x, span);
    chart
        .configure_mesh()
        .disable_y_mesh()
        .light_line_style(RGBColor(235, 235, 235))
        .bold_line_style(RGBColor(210, 210, 210))
        .y_labels(NUM_LEGS)
        .y_label_formatter(&y_fmt)
        .x_label_formatter(&x_fmt)
        .label_style((FONT, LABEL_PX))
        .axis_desc_style((FONT, AXIS_PX))
        .x_desc("time (s)")
        .y_desc("leg")
        .draw()
        .map_err(err)?;
    for leg in 0..NUM_LEGS {
        let color = if TRIPOD_A_MASK & (1 << leg) != 0 {
            TRIPOD_A_COLOR
        } else {
            TRIPOD_B_COLOR
        };
        let row = row_of(leg);
        // Runs of consecutive stance samples as one bar each.
        let mut bars = Vec::new();
        let mut start: Option<f64> = None;
        for (k, (t, m)) in gait.time_s.iter().zip(gait.stance_masks).enumerate() {
            let down = m & (1 << leg) != 0;
            match (down, start) {
                (true, None) => start = Some(*t as f64),
                (false, Some(s)) => {
                    bars.push((s, *t as f64));
                    start = None;
                }
                _ => {}
            }
            if k + 1 == gait.time_s.len() {
                if let Some(s) = start {
                    bars.push((s, (*t + gait.dt_s) as f64));
                }
            }
        }
        chart
            .draw_series(
                bars.into_iter().map(|(a, b)| {
                    Rectangle::new([(a, row - 0.35), (b, row + 0.35)], color.filled())
                }),
            )
            .map_err(err)?;
    }
    if legend_px > 0 {
        let entries = [
            LegendEntry {
                label: TRIPOD_LABELS[0],
                color: TRIPOD_A_COLOR,
                dashed: false,
                filled: true,
            },
            LegendEntry {
                label: TRIPOD_LABELS[1],
                color: TRIPOD_B_COLOR,
                dashed: false,
                filled: true,
            },
        ];
        draw_legend(&legend_area, &entries)?;
    }
    Ok(())
}

/// Writes a gait diagram PNG.
pub fn write_gait(path: &Path, gait: &Gait) -> anyhow::Result<()> {
    let root = BitMapBackend::new(path, (1000, 330)).into_drawing_area();
    root.fill(&WHITE)?;
    let legend_px = gait_legend_width(&root);
    draw_gait(&root, gait, legend_px)?;
    root.present()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Inked pixels of `text` drawn at the smallest text size of the plots in [`FONT`].
    fn ink(text: &str) -> usize {
        let (w, h) = (120u32, 24u32);
        let mut buf = vec![255u8; (w * h * 3) as usize];
        {
            let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
            root.draw(&Text::new(text.to_string(), (6, 4), (FONT, LABEL_PX)))
                .unwrap();
            root.present().unwrap();
        }
        buf.chunks(3).filter(|p| p[0] < 200).count()
    }

    #[test]
    fn every_glyph_of_a_label_is_drawn() {
        // A `j` is about as much ink as an `l`: its stem is not dropped.
        assert!(2 * ink("j") >= ink("l"), "j {} l {}", ink("j"), ink("l"));
        for c in ['J', 'T', 'Y', '_'] {
            assert!(ink(&c.to_string()) >= 4, "{c}: {}", ink(&c.to_string()));
        }
        assert!(ink("rew_joint_acc") > ink("rew_oint_acc") + 4);
    }

    #[test]
    fn tick_labels_fit_the_span() {
        assert_eq!(tick_label(1250.0, 1000.0), "1250");
        assert_eq!(tick_label(0.30000000000000004, 1.0), "0.3");
        assert_eq!(tick_label(-0.0001, 1.0), "0.0");
        assert_eq!(tick_label(2.5, 5.0), "2.5");
        assert_eq!(tick_label(0.05, 0.4), "0.05");
    }

    #[test]
    fn panels_and_gait_render() {
        let dir = std::env::temp_dir().join(format!("host-sim-plot-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let t: Vec<f32> = (0..100).map(|k| k as f32 * 0.02).collect();
        let panel = Panel::new("velocity", "time (s)", "velocity (m/s)")
            .line(Line::nth(0, "vx", trace(&t, t.iter().map(|x| x.sin()))))
            .line(Line::nth(0, "vx command", trace(&t, t.iter().map(|_| 0.3))).dashed());
        write_panels(&dir.join("p.png"), Some("test"), 1, (900, 300), &[panel]).unwrap();
        let masks: Vec<u8> = (0..100)
            .map(|k| {
                if (k / 10) % 2 == 0 {
                    TRIPOD_A_MASK
                } else {
                    !TRIPOD_A_MASK & 0x3f
                }
            })
            .collect();
        write_gait(
            &dir.join("g.png"),
            &Gait {
                title: "gait",
                time_s: &t,
                stance_masks: &masks,
                dt_s: 0.02,
            },
        )
        .unwrap();
        for f in ["p.png", "g.png"] {
            assert!(std::fs::metadata(dir.join(f)).unwrap().len() > 1000);
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
