//! `host-sim ballscrew`: seed 001's ball-screw load distribution study: CSVs, plots, the
//! report and, with `--bench`, the solver's timings.

use super::repo_doc;
use crate::studies::load_distribution::{self as bs, study};
use std::error::Error;
use std::path::PathBuf;
use std::time::Instant as WallClock;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Output directory for CSVs and PNGs.
    #[arg(long, default_value = "target/ballscrew")]
    out: PathBuf,
    /// Where to write the report [default: the repository's docs/ballscrew-reproduction.md,
    /// which `host-sim paper` includes in docs/paper-reproduction.md].
    #[arg(long, value_name = "PATH")]
    doc: Option<PathBuf>,
    /// Do not write the report.
    #[arg(long)]
    no_doc: bool,
    /// Skip the PNG plots.
    #[arg(long)]
    no_plots: bool,
    /// Seed of the random error pattern of the bands.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Also time the solver (one 78-ball case; a 100-point sweep) and print the report.
    #[arg(long)]
    bench: bool,
}

/// Min and median of `reps` timings of `f`, seconds.
fn time_it(reps: usize, mut f: impl FnMut()) -> (f64, f64) {
    let mut t: Vec<f64> = (0..reps)
        .map(|_| {
            let w = WallClock::now();
            f();
            w.elapsed().as_secs_f64()
        })
        .collect();
    t.sort_by(f64::total_cmp);
    (t[0], t[t.len() / 2])
}

/// Runs `host-sim ballscrew`.
pub fn run(a: &Args) -> Result<(), Box<dyn Error>> {
    let wall = WallClock::now();
    let cfg = study::StudyConfig {
        seed: a.seed,
        distribution_seeds: [a.seed, a.seed + 1, a.seed + 2],
        ..study::StudyConfig::default()
    };
    let st = study::run(cfg)?;
    let solved = wall.elapsed().as_secs_f64();
    std::fs::create_dir_all(&a.out)?;
    // One CSV per sweep: the load curve; one for the per-ball loads at the figures' loads.
    for sw in st.bands.iter().chain(&st.distributions) {
        let name = sw
            .label
            .replace('±', "pm")
            .replace([' ', '(', ')'], "_")
            .replace("µ", "u");
        let ks = sw.stiffness();
        let mut csv = String::from(
            "fa_n,loaded,axial_displacement_um,stiffness_n_per_m,q_min_n,q_max_n,q78_over_q1\n",
        );
        for (i, c) in sw.cases.iter().enumerate() {
            let (lo, hi) = c.load_range();
            let k = ks.get(i).map_or(String::new(), |k| format!("{:.6e}", k.1));
            csv.push_str(&format!(
                "{},{},{:.6},{k},{lo:.4},{hi:.4},{:.6}\n",
                c.fa,
                c.loaded,
                c.axial_displacement * 1e6,
                c.end_ratio()
            ));
        }
        std::fs::write(a.out.join(format!("sweep_{name}.csv")), csv)?;
    }
    let mut balls = String::from("set,fa_n,ball,error_um,delta_um,q_n,alpha_deg\n");
    for sw in &st.bands {
        for fa in [500.0, 1000.0, 5000.0] {
            if let Some(c) = sw.at(fa) {
                for j in 0..c.q.len() {
                    balls.push_str(&format!(
                        "{},{fa},{},{:.4},{:.6},{:.4},{:.4}\n",
                        sw.label,
                        j + 1,
                        sw.errors[j] * 1e6,
                        c.delta[j] * 1e6,
                        c.q[j],
                        c.alpha[j].to_degrees()
                    ));
                }
            }
        }
    }
    std::fs::write(a.out.join("balls.csv"), balls)?;
    if !a.no_plots {
        bs::plots::write_all(&a.out, &st)?;
    }
    if !a.no_doc {
        let doc = a
            .doc
            .clone()
            .unwrap_or_else(|| repo_doc("ballscrew-reproduction.md"));
        std::fs::write(&doc, study::markdown(&st))?;
        println!("report      {}", doc.display());
    }
    println!(
        "output      {} (CSV{})",
        a.out.display(),
        if a.no_plots { "" } else { ", PNG" }
    );
    println!(
        "study       {} sweeps × {} loads + Figs 14/15, solved in {solved:.3} s",
        st.bands.len() + st.distributions.len(),
        st.config.points
    );
    for sw in &st.bands {
        let c = sw.at(5000.0);
        println!(
            "  {:>6}: loaded at 100/500/1000 N = {}/{}/{}, K_s(1000 N) = {:.3e} N/m, Q78/Q1(5000 N) = {:.3}",
            sw.label,
            sw.at(100.0).map_or(0, |c| c.loaded),
            sw.at(500.0).map_or(0, |c| c.loaded),
            sw.at(1000.0).map_or(0, |c| c.loaded),
            sw.stiffness_at(1000.0).unwrap_or(f64::NAN),
            c.map_or(f64::NAN, |c| c.end_ratio())
        );
    }
    if a.bench {
        let screw = bs::BallScrew::paper();
        let errors = bs::random_errors(a.seed, 2e-6, screw.balls);
        let loads = study::StudyConfig::default().loads();
        let (tmin, tmed) = time_it(20, || {
            let _ = bs::Solver::new(screw, errors.clone());
        });
        println!(
            "bench       K(α) table + solver setup: min {:.3} ms, median {:.3} ms (20 runs)",
            tmin * 1e3,
            tmed * 1e3
        );
        let solver = bs::Solver::new(screw, errors.clone())?;
        for fa in [500.0, 5000.0] {
            let (tmin, tmed) = time_it(200, || {
                let _ = solver.solve(fa, None);
            });
            let c = solver.solve(fa, None)?;
            println!(
                "bench       one case, 78 balls, ±2 µm, F_a = {fa:.0} N, cold start: min {:.1} µs, median {:.1} µs (200 runs; {} Newton iterations, {} passes)",
                tmin * 1e6, tmed * 1e6, c.iterations, c.passes
            );
        }
        let (tmin, tmed) = time_it(20, || {
            let _ = study::sweep(&solver, &loads);
        });
        println!("bench       100-point sweep (100…10 000 N), ±2 µm, warm-started: min {:.2} ms, median {:.2} ms (20 runs)", tmin * 1e3, tmed * 1e3);
        let (tmin, tmed) = time_it(20, || {
            for &fa in &loads {
                let _ = solver.solve(fa, None);
            }
        });
        println!("bench       100-point sweep, every load from a cold start: min {:.2} ms, median {:.2} ms (20 runs)", tmin * 1e3, tmed * 1e3);
        let (tmin, tmed) = time_it(5, || {
            let _ = bs::Solver::new(screw, errors.clone()).and_then(|s| study::sweep(&s, &loads));
        });
        println!("bench       100-point sweep including the solver setup: min {:.2} ms, median {:.2} ms (5 runs)", tmin * 1e3, tmed * 1e3);
    }
    Ok(())
}
