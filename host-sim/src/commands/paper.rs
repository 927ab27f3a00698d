//! `host-sim paper`: seed 000's matrix in parallel, its CSVs, plots, summary and the
//! reproduction report.

use super::{repo_doc, SimArgs};
use crate::studies::paper::{self, plots, CaseResult, MatrixConfig, Steady};
use crate::twin::physics::Lubricant;
use crate::twin::plant::StructureDamping;
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;
use std::error::Error;
use std::path::PathBuf;
use std::time::Instant as WallClock;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Output directory for CSVs, PNGs and summary.md.
    #[arg(long, default_value = "target/paper")]
    out: PathBuf,
    /// Where to write the generated reproduction report [default: the repository's
    /// docs/paper-reproduction.md]. A docs/ballscrew-reproduction.md beside it is included.
    #[arg(long, value_name = "PATH")]
    doc: Option<PathBuf>,
    /// Do not write the reproduction report.
    #[arg(long)]
    no_doc: bool,
    /// Skip the PNG plots.
    #[arg(long)]
    no_plots: bool,
    /// Skip the steady-sliding companion runs (constant c_x = 1e6, lifting, 1 s).
    #[arg(long)]
    no_steady: bool,
    /// Parallel jobs [default: one per core].
    #[arg(long)]
    jobs: Option<usize>,
    /// Duration, speed, damping (main matrix) and step of every run.
    #[command(flatten)]
    sim: SimArgs,
    /// Sampling rate of the per-run CSVs, Hz (the 0.999–1 s window is written at every step).
    #[arg(long, default_value_t = 1000.0)]
    csv_hz: f64,
}

/// One job of the paper command: a case of the main matrix (with files) or a companion run.
struct Job {
    case: paper::Case,
    steady: bool,
}

/// Runs `host-sim paper`.
pub fn run(a: &Args) -> Result<(), Box<dyn Error>> {
    let wall = WallClock::now();
    let d = MatrixConfig::default();
    let m = MatrixConfig {
        cruise: a.sim.cruise.unwrap_or(d.cruise),
        duration: a.sim.duration.unwrap_or(d.duration),
        dt: a.sim.dt.unwrap_or(d.dt),
        stepping: SimArgs::stepping(a.sim.tol, a.sim.h_max),
        damping: a
            .sim
            .cx
            .map_or(StructureDamping::Table1, StructureDamping::Constant),
        ..d
    };
    let steady_cx = 1e6;
    let ms = MatrixConfig {
        duration: m.duration.min(1.0),
        damping: StructureDamping::Constant(steady_cx),
        record_rate: 2000.0,
        ..m
    };
    std::fs::create_dir_all(&a.out)?;
    let plots = !a.no_plots;
    if plots {
        match crate::plotting::init_font() {
            Ok(p) => println!("font        {}", p.display()),
            Err(e) => return Err(e.into()),
        }
    }
    let mut jobs: Vec<Job> = paper::matrix()
        .into_iter()
        .map(|case| Job {
            case,
            steady: false,
        })
        .collect();
    if !a.no_steady {
        // Lifting only: lowering under c_x = 1e6 turns the damping negative (docs/plant.md).
        jobs.extend(
            paper::matrix()
                .into_iter()
                .filter(|c| c.lifting)
                .map(|case| Job { case, steady: true }),
        );
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(a.jobs.unwrap_or(0))
        .build()?;
    let pb = ProgressBar::new(jobs.len() as u64);
    pb.set_style(
        ProgressStyle::with_template(
            "{spinner} [{elapsed_precise}] {bar:40} {pos}/{len} runs  {msg}",
        )?
        .progress_chars("=> "),
    );
    let csv_every = (m.record_rate / a.csv_hz.max(1e-9)).round().max(1.0) as usize;
    let out: Vec<Result<(CaseResult, bool, f64), String>> = pool.install(|| {
        jobs.par_iter()
            .map(|job| {
                let t0 = WallClock::now();
                let cfg = if job.steady { &ms } else { &m };
                let (r, trace) = paper::run_case(job.case, cfg);
                if !job.steady {
                    let stem = job.case.slug();
                    let csv = paper::csv_trace(&trace, csv_every, m.zoom);
                    let path = a.out.join(format!("{stem}.csv"));
                    let f = std::fs::File::create(&path)
                        .map_err(|e| format!("{}: {e}", path.display()))?;
                    csv.write_csv(std::io::BufWriter::new(f))
                        .map_err(|e| format!("{}: {e}", path.display()))?;
                    drop(trace);
                    if plots {
                        plots::case_plot(&a.out.join(format!("{stem}.png")), &r)?;
                    }
                }
                let secs = t0.elapsed().as_secs_f64();
                pb.set_message(format!(
                    "{}{}",
                    job.case.slug(),
                    if job.steady { " (steady)" } else { "" }
                ));
                pb.inc(1);
                Ok((r, job.steady, secs))
            })
            .collect()
    });
    pb.finish_and_clear();
    let mut main = Vec::new();
    let mut steady = Vec::new();
    let mut run_secs = Vec::new();
    for o in out {
        let (r, is_steady, secs) = o?;
        if is_steady {
            steady.push(r);
        } else {
            run_secs.push((r.case.slug(), secs));
            main.push(r);
        }
    }
    if plots {
        for l in Lubricant::ALL {
            let rs: Vec<&CaseResult> = main.iter().filter(|r| r.case.lubricant == l).collect();
            let fig = rs.first().map_or(13, |r| r.case.figure());
            let path = a.out.join(format!("fig{fig}_{}.png", l.name()));
            plots::figure(
                &path,
                &format!(
                    "{} thread: friction torque T and θ − θi (layout of seed 000 Fig. {fig})",
                    l.name()
                ),
                &rs,
            )?;
        }
    }
    let steady = (!a.no_steady).then_some(Steady {
        c_x: steady_cx,
        results: steady,
    });
    let total = wall.elapsed().as_secs_f64();
    let mut summary = paper::summary_markdown(&main, &m);
    summary.push_str(&format!(
        "\nWall time: {total:.2} s for {} runs on {} threads (per run: {}).\n",
        jobs.len(),
        pool.current_num_threads(),
        run_secs
            .iter()
            .map(|(s, t)| format!("{s} {t:.2} s"))
            .collect::<Vec<_>>()
            .join(", ")
    ));
    std::fs::write(a.out.join("summary.md"), &summary)?;
    println!("{}", paper::matrix_table(&main));
    if !a.no_doc {
        let doc = a
            .doc
            .clone()
            .unwrap_or_else(|| repo_doc("paper-reproduction.md"));
        let ball = doc.with_file_name("ballscrew-reproduction.md");
        let ball = std::fs::read_to_string(&ball).ok();
        let text = paper::reproduction_markdown(&main, steady.as_ref(), &m, ball.as_deref())?;
        std::fs::write(&doc, text)?;
        println!("report      {}", doc.display());
    }
    println!(
        "output      {} (CSV{}, summary.md)",
        a.out.display(),
        if plots { ", PNG" } else { "" }
    );
    println!(
        "wall time   {total:.2} s for {} runs ({} of the matrix + {} steady companions) on {} threads",
        jobs.len(),
        main.len(),
        jobs.len() - main.len(),
        pool.current_num_threads()
    );
    Ok(())
}
