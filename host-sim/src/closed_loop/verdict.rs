//! The closed loop's verdict: one judge for a run on the host and for the co-simulated
//! firmware's, with one window (from the release of the soft start to the end of the run or the
//! stop request, soft start included) and one feed-rate formula (the part's displacement over
//! the last [`FEED_RATE_CYCLES`] cycles of that window, over their duration).

use serde::Serialize;

use crate::plate::EndStop;

/// Every cycle's mean position within this of centre …
pub const MEAN_POSITION_LIMIT_M: f64 = 50e-6;
/// … the feed rate over the last [`FEED_RATE_CYCLES`] cycles within this of the ideal plate's …
pub const FEED_RATE_TOLERANCE: f64 = 0.01;
pub const FEED_RATE_CYCLES: usize = 50;
/// … and each identified gain within this of the plant file's.
pub const GAIN_TOLERANCE: f64 = 0.01;
/// The start-up (power-up to release) keeps `|x|` within this …
pub const STARTUP_PEAK_LIMIT_M: f64 = 1e-3;
/// … and within this share of the end stops' clearance.
pub const STARTUP_STOP_SHARE: f64 = 1.0 / 3.0;

/// One running cycle as the verdict reads it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct JudgedCycle {
    /// Time at the cycle's start, from power-up.
    pub time_s: f64,
    pub duration_s: f64,
    /// The plate's mean position over the cycle.
    pub mean_position_m: f64,
    /// How far the part moved in the cycle.
    pub part_moved_m: f64,
}

/// What a run gives the judge.
#[derive(Debug, Clone, PartialEq)]
pub struct RunFacts<'a> {
    /// The running cycles from the release of the soft start to the end of the run or the stop
    /// request, in order; empty if the course never released it.
    pub fed: &'a [JudgedCycle],
    /// The course released the soft start.
    pub released: bool,
    /// The soft start's cycles, counted from the release.
    pub ramp_cycles: u64,
    /// The feed rate's window: [`FEED_RATE_CYCLES`], or fewer where the run asks for fewer.
    pub feed_cycles: usize,
    /// Largest `|x|` from power-up to the release (the start-up) and over the whole run.
    pub startup_peak_m: f64,
    pub peak_excursion_m: f64,
    /// The plate's end stops, if it has any.
    pub end_stop_m: Option<f64>,
    pub end_stop: Option<EndStop>,
    /// Why the loop gave up, if it did.
    pub gave_up: Option<&'a str>,
    /// The identified gains `+`, `−` (none if the drive was not identified) and the plant's.
    pub identified_gains: Option<[f64; 2]>,
    pub plant_gains: [f64; 2],
    /// The ideal plate's steady feed rate at the plan in force at the end, and `a_max·T/4` there.
    pub ideal_feed_rate_mps: f64,
    pub velocity_scale_mps: f64,
}

/// The verdict on a closed-loop run, with the figures it was reached from.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Verdict {
    /// Largest `|x|` over the start-up (power-up to release), and its bound.
    pub startup_peak_m: f64,
    pub startup_limit_m: f64,
    /// Largest `|x|` over the whole run.
    pub peak_excursion_m: f64,
    /// Worst `|mean position|` of a cycle from the release on, soft start included …
    pub worst_mean_position_m: Option<f64>,
    /// … the cycle where it was, the release's first counted 1 …
    pub worst_cycle: Option<u64>,
    /// … and from the end of the soft start on.
    pub settled_mean_position_m: Option<f64>,
    /// Cycles judged from the release on.
    pub fed_cycles: usize,
    /// Cycles the feed rate is averaged over.
    pub feed_cycles: usize,
    pub feed_rate_mps: Option<f64>,
    pub ideal_feed_rate_mps: f64,
    /// `feed_rate / ideal − 1`; null where either is missing or the ideal plate does not feed.
    pub feed_rate_difference: Option<f64>,
    /// The identified gains' relative errors `+`, `−`.
    pub gain_errors: Option<[f64; 2]>,
    pub end_stop: Option<EndStop>,
    pub gave_up: Option<String>,
    /// Empty when the run passed; else each criterion it missed.
    pub failures: Vec<String>,
    pub passed: bool,
}

/// `|value| ≤ limit`; false for NaN.
fn within(value: f64, limit: f64) -> bool {
    value.abs() <= limit
}

/// The start-up's bound of `|x|` on a plate whose end stops are at `end_stop_m`.
pub fn startup_limit_m(end_stop_m: Option<f64>) -> f64 {
    end_stop_m.map_or(STARTUP_PEAK_LIMIT_M, |stop| {
        STARTUP_PEAK_LIMIT_M.min(STARTUP_STOP_SHARE * stop)
    })
}

impl Verdict {
    /// Judges a run. The start-up's peak is reported beside its bound, not yet held to it.
    pub fn judge(facts: &RunFacts<'_>) -> Verdict {
        let mut failures = Vec::new();
        if let Some(reason) = facts.gave_up {
            failures.push(format!("the loop gave up: {reason}"));
        }
        if let Some(stop) = facts.end_stop {
            failures.push(format!(
                "end stop at {:+.1} mm after {:.4} s",
                stop.position_m * 1e3,
                stop.time_s
            ));
        }
        let gain_errors = facts.identified_gains.map(|[p, n]| {
            [
                p / facts.plant_gains[0] - 1.0,
                n / facts.plant_gains[1] - 1.0,
            ]
        });
        match gain_errors {
            Some(errors) => {
                for (sign, error) in ["+", "−"].into_iter().zip(errors) {
                    if !within(error, GAIN_TOLERANCE) {
                        failures.push(format!(
                            "gain {sign} identified {:.2} % {}: over {:.0} %",
                            error.abs() * 1e2,
                            if error < 0.0 { "low" } else { "high" },
                            GAIN_TOLERANCE * 1e2
                        ));
                    }
                }
            }
            None => failures.push("the drive was not identified".into()),
        }
        if !facts.released {
            failures.push("the course never released the soft start".into());
        }
        let worst = facts
            .fed
            .iter()
            .enumerate()
            .max_by(|a, b| {
                a.1.mean_position_m
                    .abs()
                    .total_cmp(&b.1.mean_position_m.abs())
            })
            .map(|(i, c)| (i as u64 + 1, c.mean_position_m.abs()));
        let settled_mean_position_m = facts
            .fed
            .iter()
            .skip(facts.ramp_cycles as usize)
            .map(|c| c.mean_position_m.abs())
            .reduce(f64::max);
        if let Some((_, worst_m)) = worst.filter(|(_, m)| !within(*m, MEAN_POSITION_LIMIT_M)) {
            failures.push(format!(
                "worst mean position {:.1} µm: over {:.0} µm",
                worst_m * 1e6,
                MEAN_POSITION_LIMIT_M * 1e6
            ));
        }
        let feed_rate_mps = feed_rate_mps(facts.fed, facts.feed_cycles);
        let ideal = facts.ideal_feed_rate_mps;
        let feed_rate_difference = feed_rate_mps
            .filter(|_| ideal != 0.0)
            .map(|rate| rate / ideal - 1.0);
        match (feed_rate_mps, feed_rate_difference) {
            (Some(_), Some(difference)) if !within(difference, FEED_RATE_TOLERANCE) => failures
                .push(format!(
                    "feed rate {:.2} % {} the ideal plate's: over {:.0} %",
                    difference.abs() * 1e2,
                    if difference < 0.0 { "below" } else { "above" },
                    FEED_RATE_TOLERANCE * 1e2
                )),
            // Where the ideal part does not move, the real one must not either: within the
            // same share of the velocity scale a_max·T/4.
            (Some(rate), None) if !within(rate, FEED_RATE_TOLERANCE * facts.velocity_scale_mps) => {
                failures.push(format!(
                    "feed rate {:.2} mm/s where the ideal plate's part does not move",
                    rate * 1e3
                ))
            }
            (None, _) if facts.released => failures.push(format!(
                "fewer than {} cycles fed before the end",
                facts.feed_cycles
            )),
            _ => {}
        }
        Verdict {
            startup_peak_m: facts.startup_peak_m,
            startup_limit_m: startup_limit_m(facts.end_stop_m),
            peak_excursion_m: facts.peak_excursion_m,
            worst_mean_position_m: worst.map(|(_, m)| m),
            worst_cycle: worst.map(|(i, _)| i),
            settled_mean_position_m,
            fed_cycles: facts.fed.len(),
            feed_cycles: facts.feed_cycles,
            feed_rate_mps,
            ideal_feed_rate_mps: ideal,
            feed_rate_difference,
            gain_errors,
            end_stop: facts.end_stop,
            gave_up: facts.gave_up.map(str::to_owned),
            passed: failures.is_empty(),
            failures,
        }
    }

    /// The criteria the run missed, by name, each once, in order of name.
    pub fn criteria_missed(&self) -> Vec<&'static str> {
        let mut missed: Vec<&'static str> = self.failures.iter().map(|f| criterion(f)).collect();
        missed.sort_unstable();
        missed.dedup();
        missed
    }

    /// The verdict line: `closed loop: PASSED` or `closed loop: FAILED (…)`.
    pub fn line(&self) -> String {
        if self.passed {
            "closed loop: PASSED".into()
        } else {
            format!("closed loop: FAILED ({})", self.failures.join("; "))
        }
    }
}

/// The criterion a failure names, for a tally.
fn criterion(failure: &str) -> &'static str {
    [
        ("the loop gave up", "gave up"),
        ("end stop", "end stop"),
        ("worst mean position", "mean position"),
        ("feed rate", "feed rate"),
        ("fewer than", "feed rate"),
        ("not identified", "not identified"),
        ("gain", "identified gain"),
        ("never released", "not released"),
    ]
    .into_iter()
    .find(|(start, _)| failure.contains(start))
    .map_or("other", |(_, name)| name)
}

/// The part's displacement over the last `cycles` of `fed` over their duration; `None` with
/// fewer cycles (or none asked for).
pub fn feed_rate_mps(fed: &[JudgedCycle], cycles: usize) -> Option<f64> {
    let last = fed.get(fed.len().checked_sub(cycles)?..)?;
    let span_s: f64 = last.iter().map(|c| c.duration_s).sum();
    (cycles > 0 && span_s > 0.0).then(|| last.iter().map(|c| c.part_moved_m).sum::<f64>() / span_s)
}

#[cfg(test)]
mod tests {
    use super::*;

    const IDEAL_MPS: f64 = 0.1;

    /// `count` cycles of 20 ms, each `mean_m` from centre, the part moving at `feed_mps`.
    fn cycles(count: usize, mean_m: f64, feed_mps: f64) -> Vec<JudgedCycle> {
        (0..count)
            .map(|i| JudgedCycle {
                time_s: 0.02 * i as f64,
                duration_s: 0.02,
                mean_position_m: mean_m,
                part_moved_m: feed_mps * 0.02,
            })
            .collect()
    }

    /// A run just inside every criterion.
    fn facts(fed: &[JudgedCycle]) -> RunFacts<'_> {
        RunFacts {
            fed,
            released: true,
            ramp_cycles: 25,
            feed_cycles: FEED_RATE_CYCLES,
            startup_peak_m: 0.9e-3,
            peak_excursion_m: 1.3e-3,
            end_stop_m: Some(5e-3),
            end_stop: None,
            gave_up: None,
            identified_gains: Some([1.02 * 1.009, 0.98 * 0.991]),
            plant_gains: [1.02, 0.98],
            ideal_feed_rate_mps: IDEAL_MPS,
            velocity_scale_mps: 0.73,
        }
    }

    #[test]
    fn a_run_within_every_criterion_passes() {
        let fed = cycles(60, 49e-6, IDEAL_MPS * 1.009);
        let verdict = Verdict::judge(&facts(&fed));
        assert_eq!(verdict.line(), "closed loop: PASSED");
        assert!(verdict.passed && verdict.failures.is_empty());
        assert_eq!(verdict.feed_cycles, 50);
        assert!((verdict.feed_rate_mps.unwrap() / (IDEAL_MPS * 1.009) - 1.0).abs() < 1e-12);
    }

    /// Each criterion alone, just beyond its limit, fails the run and is named.
    #[test]
    fn each_criterion_missed_alone_fails_the_run_by_name() {
        let good = cycles(60, 49e-6, IDEAL_MPS);
        let mut off_centre = cycles(60, 0.0, IDEAL_MPS);
        off_centre[3].mean_position_m = -51e-6;
        let slow = cycles(60, 0.0, IDEAL_MPS * 0.989);
        let short = cycles(49, 0.0, IDEAL_MPS);
        let cases: [(&str, RunFacts<'_>); 7] = [
            (
                "worst mean position 51.0 µm: over 50 µm",
                facts(&off_centre),
            ),
            (
                "feed rate 1.10 % below the ideal plate's: over 1 %",
                facts(&slow),
            ),
            ("fewer than 50 cycles fed before the end", facts(&short)),
            (
                "gain − identified 1.10 % low: over 1 %",
                RunFacts {
                    identified_gains: Some([1.02, 0.98 * 0.989]),
                    ..facts(&good)
                },
            ),
            (
                "end stop at -5.0 mm after 1.5000 s",
                RunFacts {
                    end_stop: Some(EndStop {
                        time_s: 1.5,
                        position_m: -5e-3,
                        velocity_mps: -0.2,
                    }),
                    ..facts(&good)
                },
            ),
            (
                "the loop gave up: centring needs more",
                RunFacts {
                    gave_up: Some("centring needs more"),
                    ..facts(&good)
                },
            ),
            (
                "the drive was not identified",
                RunFacts {
                    identified_gains: None,
                    ..facts(&good)
                },
            ),
        ];
        for (failure, facts) in cases {
            let verdict = Verdict::judge(&facts);
            assert!(!verdict.passed, "{failure}");
            assert_eq!(verdict.failures, [failure]);
        }
    }

    #[test]
    fn a_course_that_never_released_fails_without_a_feed_rate() {
        let verdict = Verdict::judge(&RunFacts {
            released: false,
            ..facts(&[])
        });
        assert_eq!(
            verdict.failures,
            ["the course never released the soft start"]
        );
        assert_eq!(verdict.worst_mean_position_m, None);
        assert_eq!(verdict.feed_rate_mps, None);
    }

    #[test]
    fn a_feed_rate_that_is_not_a_number_fails() {
        let fed = cycles(60, 0.0, f64::NAN);
        let verdict = Verdict::judge(&facts(&fed));
        assert_eq!(verdict.failures.len(), 1, "{:?}", verdict.failures);
    }

    #[test]
    fn where_the_ideal_part_stands_the_real_one_must_too() {
        let fed = cycles(60, 0.0, 0.02 * 0.73);
        let verdict = Verdict::judge(&RunFacts {
            ideal_feed_rate_mps: 0.0,
            ..facts(&fed)
        });
        assert_eq!(
            verdict.failures,
            ["feed rate 14.60 mm/s where the ideal plate's part does not move"]
        );
    }

    #[test]
    fn the_start_up_bound_is_a_third_of_the_stops_below_3_mm() {
        assert_eq!(startup_limit_m(None), 1e-3);
        assert_eq!(startup_limit_m(Some(5e-3)), 1e-3);
        assert!((startup_limit_m(Some(2.4e-3)) - 0.8e-3).abs() < 1e-15);
    }
}
