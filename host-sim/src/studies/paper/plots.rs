//! PNG plots of the paper matrix in the layout of seed 000's Figs 13–15: per case, the friction
//! torque over the whole run, its 0.999–1 s zoom, and θ − θ_i over the zoom window.
//!
//! Drawn with plotters' bitmap backend and its pure-Rust `ab_glyph` text renderer; the font is
//! [`crate::plotting::init_font`]'s.

use super::{CaseResult, Envelope};
use crate::plotting::{range, FONT};
use plotters::prelude::*;
use std::error::Error;
use std::path::Path;

type Res = Result<(), Box<dyn Error>>;

fn envelope_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    caption: &str,
    y_desc: &str,
    env: &Envelope,
    scale: f64,
    color: RGBColor,
) -> Res
where
    DB::ErrorType: 'static,
{
    let t_max = env.last().map_or(1.0, |e| e.0).max(1e-3);
    let (lo, hi) = range(env.iter().flat_map(|e| [e.1 * scale, e.2 * scale]));
    let mut chart = ChartBuilder::on(area)
        .caption(caption, (FONT, 15))
        .margin(6)
        .x_label_area_size(32)
        .y_label_area_size(56)
        .build_cartesian_2d(0.0..t_max.ceil(), lo..hi)?;
    chart
        .configure_mesh()
        .x_desc("t (s)")
        .y_desc(y_desc)
        .label_style((FONT, 12))
        .light_line_style(WHITE.mix(0.0))
        .draw()?;
    chart.draw_series(
        env.iter()
            .map(|&(t, a, b)| PathElement::new(vec![(t, a * scale), (t, b * scale)], color)),
    )?;
    Ok(())
}

fn zoom_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    caption: &str,
    y_desc: &str,
    pts: &[(f64, f64)],
    scale: f64,
    color: RGBColor,
) -> Res
where
    DB::ErrorType: 'static,
{
    let (t0, t1) = pts
        .first()
        .zip(pts.last())
        .map_or((0.0, 1.0), |(a, b)| (a.0, b.0.max(a.0 + 1e-6)));
    let (lo, hi) = range(pts.iter().map(|p| p.1 * scale));
    let mut chart = ChartBuilder::on(area)
        .caption(caption, (FONT, 15))
        .margin(6)
        .x_label_area_size(32)
        .y_label_area_size(56)
        .build_cartesian_2d(t0..t1, lo..hi)?;
    chart
        .configure_mesh()
        .x_desc("t (s)")
        .y_desc(y_desc)
        .x_labels(5)
        .x_label_formatter(&|x| format!("{x:.4}"))
        .label_style((FONT, 12))
        .light_line_style(WHITE.mix(0.0))
        .draw()?;
    chart.draw_series(LineSeries::new(
        pts.iter().map(|&(t, v)| (t, v * scale)),
        color,
    ))?;
    Ok(())
}

/// One row of a figure: torque over the run, its zoom, and θ − θ_i over the zoom.
fn case_row<DB: DrawingBackend>(
    cells: &[DrawingArea<DB, plotters::coord::Shift>],
    r: &CaseResult,
    letters: [&str; 3],
) -> Res
where
    DB::ErrorType: 'static,
{
    let c = &r.case;
    let color = RGBColor(20, 70, 170);
    let label = c.label();
    envelope_panel(
        &cells[0],
        &format!("{}) {label}", letters[0]),
        "T (N·m)",
        &r.plot.torque,
        1.0,
        color,
    )?;
    zoom_panel(
        &cells[1],
        &format!("{}) T, 0.999–1 s", letters[1]),
        "T (N·m)",
        &r.plot.torque_zoom,
        1.0,
        color,
    )?;
    zoom_panel(
        &cells[2],
        &format!("{}) θ − θi, 0.999–1 s", letters[2]),
        "θ − θi (mrad)",
        &r.plot.twist_zoom,
        1e3,
        RGBColor(170, 40, 30),
    )?;
    Ok(())
}

const LETTERS: [[&str; 3]; 6] = [
    ["a", "b", "c"],
    ["d", "e", "f"],
    ["g", "h", "i"],
    ["j", "k", "l"],
    ["m", "n", "o"],
    ["p", "q", "r"],
];

fn letters_of(r: &CaseResult) -> [&'static str; 3] {
    let i = match r.case.panel() {
        "a" => 0,
        "d" => 1,
        "g" => 2,
        "j" => 3,
        "m" => 4,
        _ => 5,
    };
    LETTERS[i]
}

/// The figure of one lubricant: its cases as rows (the paper's a–r layout).
pub fn figure(path: &Path, title: &str, results: &[&CaseResult]) -> Result<(), String> {
    let draw = || -> Res {
        let rows = results.len().max(1);
        let root = BitMapBackend::new(path, (1500, 40 + 300 * rows as u32)).into_drawing_area();
        root.fill(&WHITE)?;
        let (top, body) = root.split_vertically(40);
        top.titled(title, (FONT, 22))?;
        let cells = body.split_evenly((rows, 3));
        for (i, r) in results.iter().enumerate() {
            case_row(&cells[3 * i..3 * i + 3], r, letters_of(r))?;
        }
        root.present()?;
        Ok(())
    };
    draw().map_err(|e| format!("{}: {e}", path.display()))
}

/// One case's three panels side by side.
pub fn case_plot(path: &Path, r: &CaseResult) -> Result<(), String> {
    let draw = || -> Res {
        let root = BitMapBackend::new(path, (1500, 360)).into_drawing_area();
        root.fill(&WHITE)?;
        let (top, body) = root.split_vertically(34);
        top.titled(
            &format!(
                "{} thread, {} (seed 000 Fig. {}{})",
                r.case.lubricant.name(),
                r.case.label(),
                r.case.figure(),
                r.case.panel()
            ),
            (FONT, 18),
        )?;
        let cells = body.split_evenly((1, 3));
        case_row(&cells, r, letters_of(r))?;
        root.present()?;
        Ok(())
    };
    draw().map_err(|e| format!("{}: {e}", path.display()))
}
