//! `host-sim stickslip`: the core's stick-slip detector scored against the plant's truth, and
//! the `speed` reaction against `log`.

use crate::studies::stickslip::{self as score, Mitigation, ScoreConfig};
use rayon::prelude::*;
use std::error::Error;
use std::time::Instant as WallClock;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Number of scenarios in the scored set.
    #[arg(long, default_value_t = 64)]
    scenarios: usize,
    /// Seed of the scenario generator.
    #[arg(long, default_value_t = 7)]
    seed: u64,
    /// Score several generator seeds pooled, e.g. `1-20` (instead of `--seed`): one line per
    /// seed, the tuning and held-out pools and every scored error.
    #[arg(long)]
    seeds: Option<String>,
    /// The tuning seeds among `--seeds` (reported apart from the held-out pool), e.g. `1-5`.
    #[arg(long, default_value = "")]
    tune: String,
    /// Run only these scenarios of the set, `seed#id` (e.g. `4#29,5#42`): to look at a few.
    #[arg(long)]
    only: Option<String>,
    /// Also run every scenario at this step and compare the truth's labels (step independence).
    #[arg(long)]
    compare_dt: Option<f64>,
    /// Run the regression test's small set instead.
    #[arg(long)]
    quick: bool,
    /// Print one line per run.
    #[arg(long)]
    verbose: bool,
    /// Also run the mitigation demonstration (reaction `log` against `speed`).
    #[arg(long)]
    mitigation: bool,
    /// Integration step, s.
    #[arg(long, default_value_t = score::SCORE_DT)]
    dt: f64,
    /// Override the detector's slip threshold `stickslip.drop`, N·m (for tuning).
    #[arg(long)]
    drop: Option<f64>,
    /// Parallel jobs [default: one per core].
    #[arg(long)]
    jobs: Option<usize>,
    /// `load.rated` (the load identification's prior) at the true load off by this fraction
    /// (up on even scenarios, down on odd ones; e.g. 0.08) instead of 1000 kg: the stand-in
    /// for an identified load used before the controller identified it. Scored on its own.
    #[arg(long)]
    load_error: Option<f64>,
    /// Print one line per run with the digest of its phase log, onsets and slip count (to show
    /// that a faster plant changes no label: compare two builds' lines).
    #[arg(long)]
    fingerprint: bool,
    /// Simulate every run to its end (by default the plant stops one tick after STOP: nothing
    /// later is scored).
    #[arg(long)]
    full_run: bool,
}

/// Runs `host-sim stickslip`.
pub fn run(a: &Args) -> Result<(), Box<dyn Error>> {
    let wall = WallClock::now();
    let sc = ScoreConfig {
        dt: a.dt,
        drop_threshold: a.drop,
        full_run: a.full_run,
        ..ScoreConfig::default()
    };
    let seeds = match &a.seeds {
        Some(s) => score::parse_seeds(s)?,
        None => vec![a.seed],
    };
    let tune = score::parse_seeds(&a.tune)?;
    let set: Vec<score::Scenario> = if a.quick {
        score::quick_set()
    } else {
        seeds
            .iter()
            .flat_map(|&sd| score::scenario_set(a.scenarios, sd))
            .filter(|s| {
                a.only.as_ref().is_none_or(|o| {
                    o.split(',')
                        .any(|x| x.trim() == format!("{}#{}", s.set, s.id))
                })
            })
            .collect()
    };
    let set = match a.load_error {
        Some(e) if e.is_finite() && (0.0..1.0).contains(&e) => score::with_load_error(&set, e),
        Some(e) => return Err(format!("--load-error {e}: a fraction in [0, 1)").into()),
        None => set,
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(a.jobs.unwrap_or(0))
        .build()?;
    let t = &sc.truth;
    println!(
        "host-sim stickslip: {} scenarios (seed {}), dt = {:.0e} s; episode = ≥ {} cycles of drop ≥ {} N·m and period ≥ {} ms, breakaways ≤ {} s apart, ≥ {} ms long",
        set.len(),
        a.seeds.clone().unwrap_or_else(|| a.seed.to_string()),
        sc.dt,
        t.min_cycles,
        t.min_drop,
        t.min_period * 1e3,
        t.max_gap,
        t.min_duration * 1e3
    );
    if let Some(e) = a.load_error {
        println!(
            "identified-load case: the core's estimator runs at the true load {:+.0} % (even scenarios) / {:+.0} % (odd), not at the rated 1000 kg",
            100.0 * e,
            -100.0 * e
        );
    }
    let results: Vec<score::RunResult> =
        pool.install(|| set.par_iter().map(|s| score::run(s, &sc)).collect());
    if a.verbose {
        for r in &results {
            println!("{}", score::run_line(r));
        }
    }
    if a.fingerprint {
        for r in &results {
            println!(
                "digest {}#{} {:016x}",
                r.scenario.set, r.scenario.id, r.digest
            );
        }
    }
    if let Some(dt2) = a.compare_dt {
        let sc2 = ScoreConfig { dt: dt2, ..sc };
        let other: Vec<score::RunResult> =
            pool.install(|| set.par_iter().map(|s| score::run(s, &sc2)).collect());
        println!("{}", score::step_report(&results, &other, (sc.dt, dt2)));
    }
    if a.seeds.is_some() {
        print!("{}", score::pooled_report(&results, &tune));
        print_time(wall);
        return Ok(());
    }
    let s = score::score(&results);
    println!("{s}");
    if !s.missed.is_empty() {
        println!(
            "missed      {}",
            s.missed
                .iter()
                .map(|(id, t)| format!("#{id} at {t:.3} s"))
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    let goals = [
        ("precision ≥ 95 %", s.precision() >= 0.95),
        ("recall ≥ 95 %", s.recall() >= 0.95),
        ("median latency ≤ 50 ms", s.median_latency() <= 0.050),
        ("no false alarm on smooth runs", s.smooth_alarms == 0),
    ];
    println!(
        "goals       {}",
        goals
            .iter()
            .map(|(g, ok)| format!("{g}: {}", if *ok { "met" } else { "MISSED" }))
            .collect::<Vec<_>>()
            .join("; ")
    );
    if a.mitigation {
        let set = score::mitigation_set();
        let jobs: Vec<(score::Scenario, bool)> =
            set.iter().flat_map(|s| [(*s, false), (*s, true)]).collect();
        let runs: Vec<score::RunResult> = pool.install(|| {
            jobs.par_iter()
                .map(|(s, speed)| {
                    let s = score::Scenario {
                        reaction: if *speed {
                            liftfw::detect::stickslip::Reaction::ChangeSpeed
                        } else {
                            liftfw::detect::stickslip::Reaction::Log
                        },
                        ..*s
                    };
                    score::run(
                        &s,
                        &ScoreConfig {
                            full_run: true,
                            ..sc
                        },
                    )
                })
                .collect()
        });
        println!(
            "mitigation  reaction `speed` (escape {} rad/s) against `log`: stick-slip after the first onset until STOP",
            sc.escape_speed
        );
        for pair in runs.chunks(2) {
            let m = Mitigation {
                scenario: pair[0].scenario,
                log: pair[0].clone(),
                speed: pair[1].clone(),
            };
            let t_on = m.speed.onsets.first().map_or(f64::NAN, |o| o.0);
            let (a_log, n_log) = Mitigation::stick_slip_after(&m.log, t_on);
            let (a_spd, n_spd) = Mitigation::stick_slip_after(&m.speed, t_on);
            println!(
                "  {}: onset {:.3} s; log {:.3} s of stick-slip ({} cycles) → speed {:.3} s ({} cycles); screw speed late {:.2} → {:.2} rad/s",
                m.scenario.name(),
                t_on,
                a_log,
                n_log,
                a_spd,
                n_spd,
                m.log.late_speed,
                m.speed.late_speed
            );
        }
    }
    print_time(wall);
    Ok(())
}

/// The process's CPU time (user + system, all threads), s, where /proc tells it (Linux).
fn cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // Fields after the command name (which may hold spaces, in parentheses): utime and stime
    // are the 12th and 13th, in clock ticks (USER_HZ, 100 on Linux).
    let rest = stat.rsplit_once(')')?.1;
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks = f.get(11)?.parse::<f64>().ok()? + f.get(12)?.parse::<f64>().ok()?;
    Some(ticks / 100.0)
}

fn print_time(wall: WallClock) {
    let cpu = cpu_seconds().map_or("-".to_string(), |c| format!("{c:.1}"));
    println!(
        "wall time   {:.1} s, CPU time {cpu} s (user + system, all threads; wall is inflated when other work shares the cores)",
        wall.elapsed().as_secs_f64()
    );
}
