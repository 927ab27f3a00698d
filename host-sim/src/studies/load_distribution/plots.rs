//! PNG plots in the layout of seed 001's Figs 2 and 14–21, in the style of [`crate::studies::paper::plots`]
//! (plotters bitmap backend, the same font lookup).

use super::study::{Study, BALL33};
use crate::plotting::{init_font, range, FONT};
use plotters::prelude::*;
use std::error::Error;
use std::path::Path;

type Res = Result<(), Box<dyn Error>>;
type Area<'a> = DrawingArea<BitMapBackend<'a>, plotters::coord::Shift>;

/// One curve: label, points, colour, drawn with point markers.
struct Series {
    label: String,
    pts: Vec<(f64, f64)>,
    color: RGBColor,
    markers: bool,
}

const COLORS: [RGBColor; 6] = [
    RGBColor(20, 20, 20),
    RGBColor(20, 70, 170),
    RGBColor(200, 120, 0),
    RGBColor(170, 40, 30),
    RGBColor(30, 140, 60),
    RGBColor(120, 60, 160),
];

fn chart(area: &Area, caption: &str, x_desc: &str, y_desc: &str, series: &[Series]) -> Res {
    chart_at(
        area,
        caption,
        x_desc,
        y_desc,
        series,
        SeriesLabelPosition::UpperRight,
    )
}

fn chart_at(
    area: &Area,
    caption: &str,
    x_desc: &str,
    y_desc: &str,
    series: &[Series],
    legend: SeriesLabelPosition,
) -> Res {
    let (x0, x1) = range(series.iter().flat_map(|s| s.pts.iter().map(|p| p.0)));
    let (y0, y1) = range(series.iter().flat_map(|s| s.pts.iter().map(|p| p.1)));
    let y0 = if y0 > 0.0 && y0 < 0.25 * y1 { 0.0 } else { y0 };
    let mut ch = ChartBuilder::on(area)
        .caption(caption, (FONT, 16))
        .margin(8)
        .x_label_area_size(34)
        .y_label_area_size(60)
        .build_cartesian_2d(x0..x1, y0..y1)?;
    ch.configure_mesh()
        .x_desc(x_desc)
        .y_desc(y_desc)
        .x_label_formatter(&|x| format!("{x:.0}"))
        .y_label_formatter(&|y| format!("{y:.1}"))
        .label_style((FONT, 12))
        .light_line_style(WHITE.mix(0.0))
        .draw()?;
    for s in series {
        let c = s.color;
        ch.draw_series(LineSeries::new(s.pts.iter().copied(), c.stroke_width(2)))?
            .label(s.label.clone())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], c.stroke_width(2)));
        if s.markers {
            ch.draw_series(s.pts.iter().map(|&p| Circle::new(p, 2, c.filled())))?;
        }
    }
    ch.configure_series_labels()
        .label_font((FONT, 12))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK.mix(0.3))
        .position(legend)
        .draw()?;
    Ok(())
}

fn balls(q: &[f64]) -> Vec<(f64, f64)> {
    q.iter()
        .enumerate()
        .map(|(j, &v)| ((j + 1) as f64, v))
        .collect()
}

fn figure(
    path: &Path,
    size: (u32, u32),
    title: &str,
    draw: impl Fn(&Area) -> Res,
) -> Result<(), String> {
    let go = || -> Res {
        let root = BitMapBackend::new(path, size).into_drawing_area();
        root.fill(&WHITE)?;
        let (top, body) = root.split_vertically(36);
        top.titled(title, (FONT, 20))?;
        draw(&body)?;
        root.present()?;
        Ok(())
    };
    go().map_err(|e| format!("{}: {e}", path.display()))
}

/// Write fig02.png and fig14.png … fig21.png into `dir`.
pub fn write_all(dir: &Path, st: &Study) -> Result<(), String> {
    init_font()?;
    let um = |v: f64| v * 1e6;
    // Fig. 2: the error patterns.
    figure(
        &dir.join("fig02.png"),
        (1500, 420),
        "Seed 001 Fig. 2: random equivalent errors E_g(j)",
        |a| {
            let cells = a.split_evenly((1, 3));
            for (i, sw) in st.bands.iter().skip(1).enumerate() {
                chart(
                    &cells[i],
                    &sw.label,
                    "ball j",
                    "E_g (µm)",
                    &[Series {
                        label: sw.label.clone(),
                        pts: balls(&sw.errors.iter().map(|&e| um(e)).collect::<Vec<_>>()),
                        color: COLORS[1 + i],
                        markers: true,
                    }],
                )?;
            }
            Ok(())
        },
    )?;
    // Fig. 14: our model vs Mei's at 5000 N.
    figure(
        &dir.join("fig14.png"),
        (1000, 560),
        "Seed 001 Fig. 14: load distribution by two models, F_a = 5000 N",
        |a| {
            let mut s = Vec::new();
            for (i, c) in st.comparison.iter().enumerate() {
                s.push(Series {
                    label: format!("present, {}", c.label),
                    pts: balls(&c.present.q),
                    color: COLORS[2 * i],
                    markers: true,
                });
                s.push(Series {
                    label: format!("Mei (α = 45°), {}", c.label),
                    pts: balls(&c.mei.q),
                    color: COLORS[2 * i + 1],
                    markers: false,
                });
            }
            chart_at(
                a,
                "",
                "ball j",
                "Q (N)",
                &s,
                SeriesLabelPosition::LowerRight,
            )
        },
    )?;
    // Fig. 15: ball 33 at ∓2 µm.
    figure(
        &dir.join("fig15.png"),
        (1500, 560),
        "Seed 001 Fig. 15: load distribution with an error at ball 33",
        |a| {
            let cells = a.split_evenly((1, 2));
            for (i, se) in st.single.iter().enumerate() {
                let s: Vec<Series> = se
                    .cases
                    .iter()
                    .filter(|c| c.fa >= 1000.0)
                    .enumerate()
                    .map(|(k, c)| Series {
                        label: format!("F_a = {:.0} N", c.fa),
                        pts: balls(&c.q),
                        color: COLORS[k % 6],
                        markers: false,
                    })
                    .collect();
                let cap = format!(
                    "{}) E_g({}) = {:+.0} µm",
                    ["a", "b"][i],
                    BALL33 + 1,
                    se.error * 1e6
                );
                chart(&cells[i], &cap, "ball j", "Q (N)", &s)?;
            }
            Ok(())
        },
    )?;
    // Fig. 16: ±2 µm at 500, 1000, 5000 N.
    figure(
        &dir.join("fig16.png"),
        (1000, 560),
        "Seed 001 Fig. 16: load distribution, errors ±2 µm",
        |a| {
            let sw = &st.bands[2];
            let s: Vec<Series> = [500.0, 1000.0, 5000.0]
                .iter()
                .enumerate()
                .filter_map(|(k, &f)| {
                    sw.at(f).map(|c| Series {
                        label: format!("F_a = {f:.0} N"),
                        pts: balls(&c.q),
                        color: COLORS[k + 1],
                        markers: true,
                    })
                })
                .collect();
            chart(a, "", "ball j", "Q (N)", &s)
        },
    )?;
    // Fig. 17: the four bands at 1000 and 5000 N.
    figure(
        &dir.join("fig17.png"),
        (1500, 900),
        "Seed 001 Fig. 17: load distributions for error bands",
        |a| {
            let cells = a.split_evenly((2, 2));
            for (i, sw) in st.bands.iter().enumerate() {
                let s: Vec<Series> = [1000.0, 5000.0]
                    .iter()
                    .enumerate()
                    .filter_map(|(k, &f)| {
                        sw.at(f).map(|c| Series {
                            label: format!("F_a = {f:.0} N"),
                            pts: balls(&c.q),
                            color: COLORS[k + 1],
                            markers: true,
                        })
                    })
                    .collect();
                chart(
                    &cells[i],
                    &format!("{}) {}", ["a", "b", "c", "d"][i], sw.label),
                    "ball j",
                    "Q (N)",
                    &s,
                )?;
            }
            Ok(())
        },
    )?;
    let per_band = |f: &dyn Fn(&super::study::Sweep) -> Vec<(f64, f64)>| -> Vec<Series> {
        st.bands
            .iter()
            .enumerate()
            .map(|(i, sw)| Series {
                label: sw.label.clone(),
                pts: f(sw),
                color: COLORS[i],
                markers: false,
            })
            .collect()
    };
    figure(
        &dir.join("fig18.png"),
        (1000, 560),
        "Seed 001 Fig. 18: number of loaded balls",
        |a| {
            chart_at(
                a,
                "",
                "F_a (N)",
                "loaded balls",
                &per_band(&|sw| sw.cases.iter().map(|c| (c.fa, c.loaded as f64)).collect()),
                SeriesLabelPosition::LowerRight,
            )
        },
    )?;
    figure(
        &dir.join("fig19.png"),
        (1000, 560),
        "Seed 001 Fig. 19: axial displacement of the nut",
        |a| {
            chart_at(
                a,
                "",
                "F_a (N)",
                "δ_a (µm)",
                &per_band(&|sw| {
                    sw.cases
                        .iter()
                        .map(|c| (c.fa, um(c.axial_displacement)))
                        .collect()
                }),
                SeriesLabelPosition::LowerRight,
            )
        },
    )?;
    figure(
        &dir.join("fig20.png"),
        (1000, 560),
        "Seed 001 Fig. 20: axial contact stiffness",
        |a| {
            chart_at(
                a,
                "",
                "F_a (N)",
                "K_s (10⁸ N/m)",
                &per_band(&|sw| {
                    sw.stiffness()
                        .into_iter()
                        .map(|(f, k)| (f, k / 1e8))
                        .collect()
                }),
                SeriesLabelPosition::LowerRight,
            )
        },
    )?;
    figure(
        &dir.join("fig21.png"),
        (1000, 560),
        "Seed 001 Fig. 21: stiffness for three ±2 µm distributions",
        |a| {
            let s: Vec<Series> = st
                .distributions
                .iter()
                .enumerate()
                .map(|(i, sw)| Series {
                    label: sw.label.clone(),
                    pts: sw
                        .stiffness()
                        .into_iter()
                        .map(|(f, k)| (f, k / 1e8))
                        .collect(),
                    color: COLORS[i + 1],
                    markers: false,
                })
                .collect();
            chart(a, "", "F_a (N)", "K_s (10⁸ N/m)", &s)
        },
    )?;
    Ok(())
}
