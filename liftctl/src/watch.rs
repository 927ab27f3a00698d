//! `liftctl watch`: poll `status`, print it, log it as CSV, plot it as PNG.

use crate::board::{Board, Error, Status};
use plotters::prelude::*;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// One sample: seconds since the watch started, and the status.
#[derive(Clone, Debug, PartialEq)]
pub struct Sample {
    /// Wall-clock time since the start, s.
    pub t: f64,
    /// The status.
    pub status: Status,
}

/// The CSV header.
pub const CSV_HEADER: &str =
    "t_s,state,height_mm,speed_rad_s,current_a,friction_torque_nm,stick_slip,fault";

/// One CSV row.
pub fn csv_row(s: &Sample) -> String {
    let st = &s.status;
    format!(
        "{:.3},{},{},{},{},{},{},{}",
        s.t,
        st.state,
        // Empty while the board is unhomed (it does not know the height).
        st.height_mm.map(|h| h.to_string()).unwrap_or_default(),
        st.speed,
        st.current,
        st.friction_torque,
        u8::from(st.stick_slip),
        st.fault
    )
}

/// How long to watch.
#[derive(Clone, Debug)]
pub struct WatchOptions {
    /// Between polls.
    pub interval: Duration,
    /// Stop after this long.
    pub duration: Option<Duration>,
    /// Stop once the lift is at rest (at once if it already is).
    pub until_rest: bool,
    /// Print each sample.
    pub print: bool,
    /// CSV log.
    pub csv: Option<PathBuf>,
    /// PNG plot.
    pub plot: Option<PathBuf>,
}

/// Consecutive lost or garbled replies before giving up.
const MAX_MISSES: u32 = 3;

/// Watch until the duration ends, the lift comes to rest (with `until_rest`), `stop` is set
/// (Ctrl-C) or the board stops answering. A lost or garbled reply is reported and skipped.
pub fn watch(board: &mut Board, o: &WatchOptions, stop: &AtomicBool) -> Result<Vec<Sample>, Error> {
    let mut csv = match &o.csv {
        Some(p) => {
            let mut f = std::fs::File::create(p)
                .map_err(|e| Error::Local(format!("{}: {e}", p.display())))?;
            writeln!(f, "{CSV_HEADER}").map_err(|e| Error::Local(e.to_string()))?;
            Some(f)
        }
        None => None,
    };
    let start = Instant::now();
    let mut samples = Vec::new();
    let mut misses = 0;
    while !stop.load(Ordering::SeqCst) {
        let t0 = Instant::now();
        match board.status() {
            Ok(status) => {
                misses = 0;
                let s = Sample {
                    t: start.elapsed().as_secs_f64(),
                    status,
                };
                if o.print {
                    println!("{}", line(&s));
                }
                if let Some(f) = csv.as_mut() {
                    writeln!(f, "{}", csv_row(&s)).map_err(|e| Error::Local(e.to_string()))?;
                }
                let rest = s.status.at_rest();
                samples.push(s);
                if o.until_rest && rest {
                    break;
                }
            }
            // Ctrl-C during a poll: the watch ends as between polls.
            Err(Error::Interrupted { .. }) => break,
            Err(e @ (Error::Timeout { .. } | Error::Garbled { .. })) => {
                misses += 1;
                eprintln!("liftctl watch: {e}; sample skipped");
                if misses >= MAX_MISSES {
                    return Err(Error::Local(format!(
                        "{e}\nthe board stopped answering ({MAX_MISSES} replies in a row lost or \
                         garbled)"
                    )));
                }
            }
            Err(e) => return Err(e),
        }
        if o.duration.is_some_and(|d| start.elapsed() >= d) {
            break;
        }
        if let Some(rest) = o.interval.checked_sub(t0.elapsed()) {
            std::thread::sleep(rest);
        }
    }
    if let Some(p) = &o.plot {
        plot(p, &samples).map_err(|e| Error::Local(format!("plot {}: {e}", p.display())))?;
    }
    Ok(samples)
}

/// A sample for people.
pub fn line(s: &Sample) -> String {
    let st = &s.status;
    format!(
        "{:8.2} s  {:<8}  {:>10}  {:6.2} rad/s  {:6.2} A  T_r {:6.3} Nm  stick-slip {:<3}  fault {}",
        s.t,
        st.state,
        match st.height_mm {
            Some(h) => format!("{h:7.1} mm"),
            None => "unhomed".to_string(),
        },
        st.speed,
        st.current,
        st.friction_torque,
        if st.stick_slip { "yes" } else { "no" },
        st.fault
    )
}

const FONT: &str = liftfw_plotfont::FAMILY;

/// Register a TrueType font for the plot's labels: `$LIFTCTL_FONT`, else a system sans-serif
/// face.
pub fn init_font() -> Result<PathBuf, String> {
    liftfw_plotfont::register("LIFTCTL_FONT")
}

fn bounds(v: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = v.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
        (a.min(x), b.max(x))
    });
    if !(lo.is_finite() && hi.is_finite()) {
        return (-1.0, 1.0);
    }
    let pad = ((hi - lo) * 0.08).max(1e-3);
    (lo - pad, hi + pad)
}

/// Four panels over time: height, screw speed, current, estimated friction torque.
pub fn plot(path: &Path, samples: &[Sample]) -> Result<(), Box<dyn std::error::Error>> {
    init_font()?;
    let root = BitMapBackend::new(path, (1000, 900)).into_drawing_area();
    root.fill(&WHITE)?;
    let root = root.titled("liftctl watch", (FONT, 22))?;
    let panels = root.split_evenly((4, 1));
    let t_end = samples.last().map_or(1.0, |s| s.t).max(1e-3);
    type Get = fn(&Status) -> f64;
    let series: [(&str, Get, RGBColor); 4] = [
        // Unhomed samples have no height: NaN, left out of the bounds and the line.
        ("height, mm", |s| s.height_mm.unwrap_or(f64::NAN), BLUE),
        ("screw speed, rad/s", |s| s.speed, GREEN),
        ("motor current, A", |s| s.current, RED),
        ("friction torque T_r, N·m", |s| s.friction_torque, MAGENTA),
    ];
    for (area, (label, get, color)) in panels.iter().zip(series) {
        let (lo, hi) = bounds(
            samples
                .iter()
                .map(|s| get(&s.status))
                .filter(|v| v.is_finite()),
        );
        let mut chart = ChartBuilder::on(area)
            .margin(8)
            .x_label_area_size(30)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..t_end, lo..hi)?;
        chart
            .configure_mesh()
            .x_desc("t, s")
            .y_desc(label)
            .label_style((FONT, 13))
            .axis_desc_style((FONT, 14))
            .draw()?;
        chart.draw_series(LineSeries::new(
            samples
                .iter()
                .map(|s| (s.t, get(&s.status)))
                .filter(|(_, v)| v.is_finite()),
            color.stroke_width(2),
        ))?;
    }
    root.present()?;
    Ok(())
}
