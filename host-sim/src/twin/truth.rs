//! Stick-slip ground truth: episodes labelled from the plant's phase changes.
//!
//! The definition (docs/stick-slip.md, "Episode"):
//! - a **cycle** starts at a breakaway (stick → slip) and ends when the screw sticks again
//!   (slips may reverse on the way: the back-slip after a violent forward slip is part of the
//!   cycle). Its **drop** is the coupling-torque change over the slip, k·|Δ(θ − θ_i)|, its
//!   **period** the time to the next breakaway;
//! - a cycle is **significant** when its drop is at least [`TruthParams::min_drop`] and its
//!   period at least [`TruthParams::min_period`]; the others are **micro** stick-slip;
//! - an **episode** is a chain of at least [`TruthParams::min_cycles`] significant cycles whose
//!   breakaways are at most [`TruthParams::max_gap`] apart, lasting at least
//!   [`TruthParams::min_duration`] from its first breakaway to its last return to stick,
//!   inside the motion window (a breakaway whose slip is still running when the window closes
//!   is not a cycle: the screw stopping at the end of a move is not a stick);
//! - the episode **is confirmed** at the breakaway of its `min_cycles`-th cycle: before that
//!   it is not stick-slip by this definition, so detection latency counts from there;
//! - an episode is **borderline** when it does not survive the thresholds (drop, period,
//!   duration) scaled by [`TruthParams::band`] either way ([`label`]): scored episodes must
//!   hold at the stricter thresholds; what exists only at the looser ones or only at the
//!   nominal ones is borderline, and the score neither asks for nor penalises an onset there;
//! - a scored episode's **extent** is the loose-threshold episode around it: the same
//!   stick-slip, with its start and end decided by the looser thresholds. An onset anywhere in
//!   it detects the episode (stick-slip that grows through the band into a scored episode is
//!   one episode, as the detector's flag sees it); a loose episode that holds no scored one is
//!   borderline as a whole, whatever nominal episodes it holds.
//!   Stick-slip near a threshold is decided by the solver's step (the plant is chaotic there:
//!   a drop of 0.74 or 0.76 N·m, a period of 4.9 or 5.1 ms), so no step-independent truth can
//!   draw the line sharply (docs/stick-slip.md, "Step independence").

use crate::twin::plant::Phase;
use crate::twin::trace::PhaseChange;

/// The thresholds of the definition.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TruthParams {
    /// Smallest coupling-torque drop of a significant cycle, N·m.
    pub min_drop: f64,
    /// Shortest period of a significant cycle, s.
    pub min_period: f64,
    /// Largest gap between consecutive breakaways of an episode, s.
    pub max_gap: f64,
    /// Fewest significant cycles of an episode.
    pub min_cycles: usize,
    /// Shortest episode, s.
    pub min_duration: f64,
    /// The borderline band: episodes must hold with drop, period and duration thresholds
    /// multiplied by this factor (≥ 1) to be scored; those that exist only between the
    /// thresholds divided by it and multiplied by it are borderline. 1: no band.
    pub band: f64,
}

impl TruthParams {
    /// The thresholds scaled by `f` (drop, period, duration; the chain rule unchanged).
    pub fn scaled(&self, f: f64) -> TruthParams {
        TruthParams {
            min_drop: self.min_drop * f,
            min_period: self.min_period * f,
            min_duration: self.min_duration * f,
            band: 1.0,
            ..*self
        }
    }
}

impl Default for TruthParams {
    /// 0.75 N·m, 5 ms, 2 s, 2 cycles, 10 ms, band 1.25 (docs/stick-slip.md gives the
    /// reasons).
    fn default() -> Self {
        Self {
            min_drop: 0.75,
            min_period: 0.005,
            max_gap: 2.0,
            min_cycles: 2,
            min_duration: 0.010,
            band: 1.25,
        }
    }
}

/// One stick-slip cycle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cycle {
    /// Breakaway time, s.
    pub breakaway: f64,
    /// Time the screw stuck again, s.
    pub stuck: f64,
    /// Coupling-torque drop over the slip, N·m.
    pub drop: f64,
    /// Time to the next breakaway, s (infinite for the last one).
    pub period: f64,
}

/// One labelled episode.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Episode {
    /// First breakaway, s.
    pub start: f64,
    /// Breakaway of the `min_cycles`-th cycle: the episode meets the definition, s.
    pub confirmed: f64,
    /// Last return to stick, s.
    pub end: f64,
    /// Number of cycles.
    pub cycles: usize,
    /// Median drop, N·m.
    pub drop: f64,
    /// The extent an onset detects it in, s: for a scored episode the loose-threshold episode
    /// around it (its start and end), for the others `(start, end)`.
    pub extent: (f64, f64),
}

/// The labels of a run.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Labels {
    /// Every cycle in the window.
    pub cycles: Vec<Cycle>,
    /// Episodes of significant cycles.
    pub episodes: Vec<Episode>,
    /// Chains of micro cycles (drop or period below the thresholds) that would be episodes
    /// under the same chain rule and overlap no episode nor borderline episode: reported, not
    /// scored.
    pub micro: Vec<Episode>,
    /// Borderline episodes: at the loose thresholds holding no scored episode, or at the
    /// nominal thresholds without a strict episode in them (where the loose episode around
    /// holds a scored one). Not scored either way.
    pub borderline: Vec<Episode>,
    /// The episodes at the nominal thresholds, without the band (scored or borderline).
    pub nominal: Vec<Episode>,
}

/// The cycles of a phase log inside `(t0, t1)`, with coupling stiffness `k` (N·m/rad).
pub fn cycles(phases: &[PhaseChange], k: f64, (t0, t1): (f64, f64)) -> Vec<Cycle> {
    let mut out: Vec<Cycle> = Vec::new();
    for (i, w) in phases.windows(2).enumerate() {
        let (before, at) = (w[0], w[1]);
        if !(before.phase == Phase::Stick && matches!(at.phase, Phase::Slip(_))) {
            continue;
        }
        if at.t < t0 || at.t > t1 {
            continue;
        }
        let Some(stick) = phases[i + 2..].iter().find(|p| p.phase == Phase::Stick) else {
            continue;
        };
        if stick.t > t1 {
            continue;
        }
        if let Some(prev) = out.last_mut() {
            prev.period = at.t - prev.breakaway;
        }
        out.push(Cycle {
            breakaway: at.t,
            stuck: stick.t,
            drop: k * (at.twist - stick.twist).abs(),
            period: f64::INFINITY,
        });
    }
    out
}

fn chain(cs: &[&Cycle], p: &TruthParams) -> Vec<Episode> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < cs.len() {
        let mut j = i + 1;
        while j < cs.len() && cs[j].breakaway - cs[j - 1].breakaway <= p.max_gap {
            j += 1;
        }
        let run = &cs[i..j];
        let (start, end) = (run[0].breakaway, run[run.len() - 1].stuck);
        if run.len() >= p.min_cycles && end - start >= p.min_duration {
            let mut drops: Vec<f64> = run.iter().map(|c| c.drop).collect();
            drops.sort_by(f64::total_cmp);
            out.push(Episode {
                start,
                confirmed: run[p.min_cycles.max(1) - 1].breakaway,
                end,
                cycles: run.len(),
                drop: drops[drops.len() / 2],
                extent: (start, end),
            });
        }
        i = j;
    }
    out
}

/// The episodes and micro chains of `cycles` at thresholds `p` (no band).
fn label_at(cycles: &[Cycle], p: &TruthParams) -> (Vec<Episode>, Vec<Episode>) {
    let significant: Vec<&Cycle> = cycles
        .iter()
        .filter(|c| c.drop >= p.min_drop && c.period >= p.min_period)
        .collect();
    let episodes = chain(&significant, p);
    let all: Vec<&Cycle> = cycles.iter().collect();
    let micro = chain(&all, p)
        .into_iter()
        .filter(|m| !episodes.iter().any(|e| overlaps(e, m)))
        .collect();
    (episodes, micro)
}

fn overlaps(a: &Episode, b: &Episode) -> bool {
    a.start <= b.end && b.start <= a.end
}

/// Label a run: its phase log, coupling stiffness `k` and motion window.
///
/// - **Scored** episodes: those at the nominal thresholds that contain an episode at the strict
///   ones (thresholds × band). Each gets as its extent the loose episode (thresholds / band)
///   around it.
/// - **Borderline**: the nominal episodes without a strict one in them, and every loose
///   episode that holds no scored one (whether or not it holds nominal ones: stick-slip whose
///   period or drop sits in the band for most of a run, with a few cycles over the nominal
///   threshold, is borderline throughout, not "nothing" outside those cycles).
/// - **Micro**: chains of all cycles that overlap neither.
pub fn label(phases: &[PhaseChange], k: f64, window: (f64, f64), p: &TruthParams) -> Labels {
    let cycles = cycles(phases, k, window);
    let (nominal, micro) = label_at(&cycles, &p.scaled(1.0));
    let (episodes, mut borderline): (Vec<Episode>, Vec<Episode>) = if p.band > 1.0 {
        let (strict, _) = label_at(&cycles, &p.scaled(p.band));
        let (loose, _) = label_at(&cycles, &p.scaled(1.0 / p.band));
        let (mut episodes, mut border): (Vec<Episode>, Vec<Episode>) = nominal
            .iter()
            .partition(|e| strict.iter().any(|s| overlaps(e, s)));
        for e in &mut episodes {
            // Every nominal cycle is a loose one, so a loose episode contains each nominal one;
            // the guard keeps the extent a superset of the episode whatever the thresholds.
            if let Some(l) = loose.iter().find(|l| overlaps(e, l)) {
                e.extent = (l.start.min(e.start), l.end.max(e.end));
            }
        }
        // A loose episode that holds no scored one is borderline as a whole; it covers the
        // unscored nominal ones inside it, which stay listed only where their loose episode
        // holds a scored one too.
        let free: Vec<Episode> = loose
            .into_iter()
            .filter(|l| !episodes.iter().any(|e| overlaps(e, l)))
            .collect();
        border.retain(|b| !free.iter().any(|l| overlaps(b, l)));
        border.extend(free);
        (episodes, border)
    } else {
        (nominal.clone(), Vec::new())
    };
    borderline.sort_by(|a, b| a.start.total_cmp(&b.start));
    let micro = micro
        .into_iter()
        .filter(|m| {
            !borderline.iter().any(|b| overlaps(b, m))
                && !episodes
                    .iter()
                    .any(|e| e.extent.0 <= m.end && m.start <= e.extent.1)
        })
        .collect();
    Labels {
        cycles,
        episodes,
        micro,
        borderline,
        nominal,
    }
}

/// Whether two labellings of one scenario (at two steps) agree under the band rule: every
/// scored episode of each overlaps a scored or borderline episode of the other. A run is
/// smooth at both or at neither (its borderline episodes aside).
pub fn agree(a: &Labels, b: &Labels) -> bool {
    let covered = |x: &Labels, y: &Labels| {
        x.episodes.iter().all(|e| {
            y.episodes
                .iter()
                .chain(&y.borderline)
                .any(|f| overlaps(e, f))
        })
    };
    covered(a, b) && covered(b, a)
}

/// Whether two labellings agree exactly at the nominal thresholds: the same number of
/// episodes (scored + borderline at nominal), pairwise overlapping.
pub fn agree_nominal(a: &[Episode], b: &[Episode]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| overlaps(x, y))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::twin::plant::Dir;

    fn ph(t: f64, phase: Phase, twist: f64) -> PhaseChange {
        PhaseChange { t, phase, twist }
    }

    /// Stick-slip every 0.1 s from 0.2 s, drop 0.3 rad (48 N·m at k = 160).
    fn sawtooth(n: usize) -> Vec<PhaseChange> {
        let mut v = vec![ph(0.0, Phase::Stick, 0.0)];
        for i in 0..n {
            let t = 0.2 + 0.1 * i as f64;
            v.push(ph(t, Phase::Slip(Dir::Up), -0.47));
            v.push(ph(t + 0.0005, Phase::Slip(Dir::Down), 0.18));
            v.push(ph(t + 0.001, Phase::Stick, -0.17));
        }
        v
    }

    #[test]
    fn a_sawtooth_is_one_episode_confirmed_at_its_second_breakaway() {
        let l = label(&sawtooth(10), 160.0, (0.0, 5.0), &TruthParams::default());
        assert_eq!(l.cycles.len(), 10);
        assert_eq!(l.episodes.len(), 1);
        let e = l.episodes[0];
        assert!((e.confirmed - 0.3).abs() < 1e-12);
        assert_eq!(e.cycles, 10);
        assert!((e.drop - 48.0).abs() < 1e-9);
        assert!(l.micro.is_empty());
    }

    #[test]
    fn one_breakaway_then_smooth_sliding_is_no_episode() {
        let v = vec![
            ph(0.0, Phase::Stick, 0.0),
            ph(0.1, Phase::Slip(Dir::Up), -0.2),
            ph(2.9, Phase::Stick, -0.05),
        ];
        // The stop at 2.9 s lies outside the motion window: no cycle at all.
        let l = label(&v, 160.0, (0.0, 2.7), &TruthParams::default());
        assert!(l.cycles.is_empty() && l.episodes.is_empty());
    }

    #[test]
    fn small_or_fast_cycles_are_micro_stick_slip() {
        let mut v = vec![ph(0.0, Phase::Stick, 0.0)];
        for i in 0..50 {
            let t = 0.1 + 0.0016 * i as f64;
            v.push(ph(t, Phase::Slip(Dir::Down), 0.007));
            v.push(ph(t + 0.0006, Phase::Stick, 0.004));
        }
        let l = label(&v, 160.0, (0.0, 5.0), &TruthParams::default());
        assert!(l.episodes.is_empty());
        assert_eq!(l.micro.len(), 1);
    }

    /// Two cycles of drop `d` N·m 20 ms apart from 0.1 s (k = 160 N·m/rad).
    fn two_cycles(d: f64) -> Vec<PhaseChange> {
        let mut v = vec![ph(0.0, Phase::Stick, 0.0)];
        for i in 0..2 {
            let t = 0.1 + 0.02 * f64::from(i);
            v.push(ph(t, Phase::Slip(Dir::Up), -d / 160.0));
            v.push(ph(t + 0.0005, Phase::Stick, 0.0));
        }
        v
    }

    #[test]
    fn episodes_near_a_threshold_are_borderline() {
        let p = TruthParams::default();
        let at = |d: f64| label(&two_cycles(d), 160.0, (0.0, 5.0), &p);
        // Clear of the band (0.6…0.9375 N·m): scored, or nothing at all.
        let big = at(1.0);
        assert_eq!((big.episodes.len(), big.borderline.len()), (1, 0));
        let small = at(0.5);
        assert!(small.episodes.is_empty() && small.borderline.is_empty());
        assert_eq!(small.micro.len(), 1);
        // Above the nominal threshold but under the strict one, and under the nominal one but
        // above the loose one: borderline either way, never scored.
        for d in [0.8, 0.7] {
            let l = at(d);
            assert!(l.episodes.is_empty(), "{d}");
            assert_eq!(l.borderline.len(), 1, "{d}");
            assert!(l.micro.is_empty(), "{d}");
        }
        assert_eq!(at(0.8).nominal.len(), 1);
        assert!(at(0.7).nominal.is_empty());
        // Step agreement: a scored episode at one step and a borderline one at the other agree
        // under the band rule, not at the nominal thresholds.
        assert!(agree(&at(1.0), &at(0.7)));
        assert!(!agree_nominal(&at(1.0).nominal, &at(0.7).nominal));
        assert!(!agree(&at(1.0), &at(0.5)));
        // Without a band the nominal thresholds decide alone.
        let nb = TruthParams { band: 1.0, ..p };
        let l = label(&two_cycles(0.8), 160.0, (0.0, 5.0), &nb);
        assert_eq!((l.episodes.len(), l.borderline.len()), (1, 0));
    }

    /// Cycles of drop `d` N·m every `period` s from `t0`, `n` of them (k = 160 N·m/rad).
    fn train(v: &mut Vec<PhaseChange>, t0: f64, period: f64, d: f64, n: usize) {
        for i in 0..n {
            let t = t0 + period * i as f64;
            v.push(ph(t, Phase::Slip(Dir::Down), -d / 160.0));
            v.push(ph(t + 0.0005, Phase::Stick, 0.0));
        }
    }

    #[test]
    fn band_stick_slip_with_a_short_nominal_episode_is_borderline_throughout() {
        // Generator seed 20 #50's shape: 0.92 N·m every 4.8 ms for the whole run (loose, under
        // the nominal 5 ms), and near its end three cycles 5.1 ms apart (a short nominal
        // episode, no strict one). The loose episode overlaps that nominal one; it used to be
        // dropped for it, leaving the run's first 0.5 s "nothing" and an onset there a false
        // alarm. It is borderline throughout now.
        let mut v = vec![ph(0.0, Phase::Stick, 0.0)];
        train(&mut v, 0.1, 0.0048, 0.92, 100);
        let t = v.last().map_or(0.0, |p| p.t) + 0.0043;
        train(&mut v, t, 0.0051, 0.92, 4);
        let t = v.last().map_or(0.0, |p| p.t) + 0.0043;
        train(&mut v, t, 0.0048, 0.92, 20);
        let l = label(&v, 160.0, (0.0, 5.0), &TruthParams::default());
        assert!(l.episodes.is_empty(), "{:?}", l.episodes);
        assert_eq!(l.nominal.len(), 1, "{:?}", l.nominal);
        assert_eq!(l.borderline.len(), 1, "{:?}", l.borderline);
        let b = l.borderline[0];
        assert!(
            (b.start - 0.1).abs() < 1e-9 && b.end >= l.nominal[0].end,
            "{b:?}"
        );
        assert!(l.micro.is_empty());
    }

    #[test]
    fn a_scored_episode_extends_over_the_band_stick_slip_around_it() {
        // 0.7 N·m every 10 ms from 0.1 s (loose only), then 1.0 N·m every 10 ms from 0.3 s
        // (scored), then 0.7 N·m again: one episode, detected by an onset anywhere in 0.1 s …
        // its end.
        let mut v = vec![ph(0.0, Phase::Stick, 0.0)];
        train(&mut v, 0.1, 0.01, 0.7, 20);
        train(&mut v, 0.3, 0.01, 1.0, 10);
        train(&mut v, 0.4, 0.01, 0.7, 10);
        let l = label(&v, 160.0, (0.0, 5.0), &TruthParams::default());
        assert_eq!(l.episodes.len(), 1, "{:?}", l.episodes);
        let e = l.episodes[0];
        assert!((e.start - 0.3).abs() < 1e-9 && (e.confirmed - 0.31).abs() < 1e-9);
        assert!((e.extent.0 - 0.1).abs() < 1e-9, "{e:?}");
        assert!((e.extent.1 - 0.4905).abs() < 1e-9, "{e:?}");
        assert!(l.borderline.is_empty() && l.micro.is_empty(), "{l:?}");
    }
}
