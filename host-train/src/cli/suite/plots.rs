//! The suite's PNG plots, one line per controller: success rate against step height and
//! slope (Fig. 5), commanded against measured under sinusoidal commands with vz, roll and
//! pitch (Fig. 3), the terrain row per kind over training (Fig. 4), and survivors against
//! push magnitude (Table III's search).

use super::report::ControllerReport;
use host_sim::plot::{write_panels, Line, Panel, COLORS};
use plotters::style::{RGBColor, BLACK};
use std::path::{Path, PathBuf};

/// Colour of controller `i` (black is the command).
fn color(i: usize) -> RGBColor {
    COLORS[i % COLORS.len()]
}

/// A one-panel figure.
fn single(path: &Path, panel: Panel) -> Result<(), String> {
    write_panels(path, None, 1, (1000, 540), &[panel])
        .map_err(|e| format!("{}: {e}", path.display()))
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
        (
            "success_stairs_up.png",
            "Stairs up: success rate",
            "step height (cm)",
            |f| match f {
                host_sim::course::Feature::StairsUp { step_height_m } => {
                    Some(*step_height_m as f64 * 100.0)
                }
                _ => None,
            },
        ),
        (
            "success_stairs_down.png",
            "Stairs down: success rate",
            "step height (cm)",
            |f| match f {
                host_sim::course::Feature::StairsDown { step_height_m } => {
                    Some(*step_height_m as f64 * 100.0)
                }
                _ => None,
            },
        ),
        (
            "success_slopes_up.png",
            "Slopes up: success rate",
            "slope (deg)",
            |f| match f {
                host_sim::course::Feature::SlopeUp { slope_deg } => Some(*slope_deg as f64),
                _ => None,
            },
        ),
        (
            "success_slopes_down.png",
            "Slopes down: success rate",
            "slope (deg)",
            |f| match f {
                host_sim::course::Feature::SlopeDown { slope_deg } => Some(*slope_deg as f64),
                _ => None,
            },
        ),
    ];
    for (file, title, x_label, pick) in panels {
        let lines: Vec<Line> = reports
            .iter()
            .enumerate()
            .filter_map(|(i, r)| {
                let t = r.terrain.as_ref()?;
                let points: Vec<(f64, f64)> = t
                    .features
                    .iter()
                    .filter_map(|f| Some((pick(&f.feature)?, f.success_rate())))
                    .collect();
                (!points.is_empty())
                    .then(|| Line::new(r.name.as_str(), points, color(i)).with_markers())
            })
            .collect();
        if !lines.is_empty() {
            let panel = lines.into_iter().fold(
                Panel::new(title, x_label, "success rate").y_range(-0.02, 1.05),
                Panel::line,
            );
            single(&out(file), panel)?;
        }
    }
    // The friction sweep: success rate against contact friction, one panel per feature.
    let sweeps: Vec<(usize, &ControllerReport, &[super::friction::FrictionPoint])> = reports
        .iter()
        .enumerate()
        .filter_map(|(i, r)| Some((i, r, r.friction_sweep.as_deref()?)))
        .collect();
    if let Some((_, _, first)) = sweeps.first().filter(|(_, _, s)| !s.is_empty()) {
        let panels: Vec<Panel> = first[0]
            .features
            .iter()
            .enumerate()
            .map(|(k, feature)| {
                let mut panel = Panel::new(
                    format!("{}: success rate", feature.name),
                    "friction coefficient of the foot contacts",
                    "success rate",
                )
                .y_range(-0.02, 1.05);
                if let host_sim::course::Feature::SlopeUp { slope_deg } = feature.feature {
                    let bound = super::friction::least_friction_to_stand(slope_deg) as f64;
                    panel = panel.line(Line::new(
                        format!("tan {slope_deg:.0} deg (no robot stands below)"),
                        vec![(bound, 0.0), (bound, 1.0)],
                        BLACK,
                    ));
                }
                sweeps.iter().fold(panel, |panel, (i, r, points)| {
                    let line: Vec<(f64, f64)> = points
                        .iter()
                        .filter_map(|p| {
                            Some((p.contact_friction as f64, p.features.get(k)?.success_rate()))
                        })
                        .collect();
                    panel.line(Line::new(r.name.as_str(), line, color(*i)).with_markers())
                })
            })
            .collect();
        write_panels(
            &out("success_friction.png"),
            None,
            panels.len(),
            (800, 540),
            &panels,
        )
        .map_err(|e| format!("success_friction.png: {e}"))?;
    }
    // Fig. 3: per command axis, four stacked panels.
    for axis in 0..super::sine::AXES.len() {
        let runs: Vec<(usize, &ControllerReport, &super::sine::SineRun)> = reports
            .iter()
            .enumerate()
            .filter_map(|(i, r)| Some((i, r, r.sine.as_ref()?.get(axis)?)))
            .collect();
        let Some((_, _, first)) = runs.first() else {
            continue;
        };
        let unit = if axis == 2 { "rad/s" } else { "m/s" };
        let path = out(&format!("sine_{}.png", super::sine::AXES[axis]));
        let trace = |s: &super::sine::SineRun, v: &[f32]| -> Vec<(f64, f64)> {
            s.time_s
                .iter()
                .zip(v)
                .map(|(t, y)| (*t as f64, *y as f64))
                .collect()
        };
        let name = super::sine::AXES[axis];
        let mut tracking = Panel::new(
            format!("{name} command: tracking (command dashed)"),
            "time (s)",
            format!("{name} ({unit})"),
        )
        .line(Line::new("command", trace(first, &first.commanded), BLACK).dashed());
        for (i, r, s) in &runs {
            tracking = tracking.line(Line::new(
                format!("{} measured", r.name),
                trace(s, &s.measured),
                color(*i),
            ));
        }
        let mut panels = vec![tracking];
        type Series = fn(&super::sine::SineRun) -> &[f32];
        let rest: [(&str, &str, Series); 3] = [
            ("vertical velocity vz", "vz (m/s)", |s| &s.vz_m_s),
            ("roll", "roll (deg)", |s| &s.roll_deg),
            ("pitch", "pitch (deg)", |s| &s.pitch_deg),
        ];
        for (what, y_label, get) in rest {
            let panel = runs.iter().fold(
                Panel::new(format!("{name} command: {what}"), "time (s)", y_label),
                |p, (i, r, s)| p.line(Line::new(r.name.as_str(), trace(s, get(s)), color(*i))),
            );
            panels.push(panel);
        }
        write_panels(&path, None, 1, (1000, 330), &panels)
            .map_err(|e| format!("{}: {e}", path.display()))?;
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
        let lines: Vec<Line> = reports
            .iter()
            .enumerate()
            .filter_map(|(i, r)| {
                let c = r.curriculum.as_ref()?;
                top = top.max(c.rows.saturating_sub(1) as f64);
                let k = c.kinds.iter().find(|k| k.kind == kind)?;
                Some(Line::new(r.name.as_str(), k.points.clone(), color(i)))
            })
            .collect();
        let panel = Panel::new(
            format!("{kind}: mean terrain row"),
            "iteration",
            "terrain row (level)",
        )
        .integer_x()
        .y_range(0.0, top);
        single(
            &out(&format!("curriculum_{kind}.png")),
            lines.into_iter().fold(panel, Panel::line),
        )?;
    }
    // Table III's search: survivors against magnitude, walking, per axis and rule.
    for (axis, name) in [
        (super::push::Axis::X, "X"),
        (super::push::Axis::Y, "Y"),
        (super::push::Axis::Z, "Z"),
    ] {
        let mut panel = Panel::new(
            format!("Pushes along {name} while walking: survivors"),
            "push magnitude (m/s)",
            "fraction surviving",
        )
        .y_range(-0.02, 1.05);
        for (i, r) in reports.iter().enumerate() {
            let Some(p) = &r.push else { continue };
            let Some(cond) = p
                .conditions
                .iter()
                .find(|c| c.axis == axis && c.gait == super::push::Gait::Walk)
            else {
                continue;
            };
            let pts = |f: fn(&super::push::PointResult) -> usize| -> Vec<(f64, f64)> {
                cond.points
                    .iter()
                    .map(|q| (q.magnitude_m_s as f64, f(q) as f64 / q.robots.max(1) as f64))
                    .collect()
            };
            panel = panel.line(
                Line::new(
                    format!("{} strict", r.name),
                    pts(|q| q.survived_strict),
                    color(i),
                )
                .with_markers(),
            );
            panel = panel.line(
                Line::new(
                    format!("{} current", r.name),
                    pts(|q| q.survived_current),
                    color(i),
                )
                .with_markers()
                .dashed(),
            );
        }
        if !panel.lines.is_empty() {
            single(&out(&format!("push_{name}_walk.png")), panel)?;
        }
    }
    Ok(written)
}
