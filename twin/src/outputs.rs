//! What the board's outputs did, as the twin's pins and registers show it, and its check
//! against the segments the firmware reports: every segment's level must reach the output on the
//! segment's own tick (the DAC's code that TIM2's update latches through TRGO, with the level's
//! sign about the zero code; or TIM1's duty and direction that its update loads), and the output
//! must drive no level anywhere else. The firmware's log
//! says what it meant to do; this is what the hardware did.

use std::cell::RefCell;
use std::rc::Rc;

use feeder_shared::event::SegmentEvent;

use crate::machine::Plate;
use crate::peripherals::Output;
use crate::Cycles;

/// Every change on the outputs, shared between the plate's seat on the board and the check.
#[derive(Clone, Default)]
pub struct OutputRecord(Rc<RefCell<Vec<Output>>>);

impl OutputRecord {
    pub fn changes(&self) -> Vec<Output> {
        self.0.borrow().clone()
    }
}

impl Plate for OutputRecord {
    fn level(&mut self, at: Cycles, code: u32) {
        self.0.borrow_mut().push(Output::Dac { at, code });
    }

    fn enable(&mut self, at: Cycles, on: bool) {
        self.0.borrow_mut().push(Output::Enable { at, on });
    }

    fn pwm(&mut self, at: Cycles, duty_counts: u32, forward: bool) {
        self.0.borrow_mut().push(Output::Pwm {
            at,
            duty_counts,
            forward,
        });
    }

    fn count(&mut self, _at: Cycles) -> i32 {
        0
    }

    fn reset(&mut self, at: Cycles) {
        self.0.borrow_mut().push(Output::Reset { at });
    }
}

/// The check's findings.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct OutputCheck {
    /// Segments whose level the output took on their tick with the right sign.
    pub matched: usize,
    /// What did not match, one sentence each.
    pub problems: Vec<String>,
    /// Output changes at no segment's start (the power-up zero and a halt's zero aside).
    pub stray: usize,
}

/// The sign of the level an output change drives: a DAC code about `zero_code`, or a PWM duty
/// with its direction (no duty, or the main output off, is zero).
fn level_sign(change: &Output, zero_code: u32) -> Option<(Cycles, i8)> {
    match *change {
        Output::Dac { at, code } => {
            Some((at, (i64::from(code) - i64::from(zero_code)).signum() as i8))
        }
        Output::Pwm {
            at,
            duty_counts,
            forward,
        } => Some((
            at,
            match (duty_counts, forward) {
                (0, _) => 0,
                (_, true) => 1,
                (_, false) => -1,
            },
        )),
        Output::Enable { .. } | Output::Reset { .. } => None,
    }
}

/// What a segment's level on the output may be.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Levels {
    /// The plan's: a level of the segment's sign (zero for a zero level).
    Planned,
    /// A closed loop's trims on the plan's: a `±a` level keeps its sign, a zero level (an idle
    /// period's, a settle segment's, a cycle's plateau) carries the loop's bias, of either sign
    /// or none; every segment still takes a level on its tick.
    Trimmed,
}

/// Checks `changes` against `segments` on a timeline whose tick 0 is core time `origin` and
/// whose ticks last `cycles_per_tick` core cycles, with `zero_code` the DAC's code of zero
/// acceleration and `levels` what a segment's level may be.
pub fn check(
    changes: &[Output],
    segments: &[SegmentEvent],
    origin: Cycles,
    cycles_per_tick: Cycles,
    zero_code: u32,
    levels: Levels,
) -> OutputCheck {
    let signs: Vec<(Cycles, i8)> = changes
        .iter()
        .filter_map(|change| level_sign(change, zero_code))
        .collect();
    let sign_at = |at: Cycles| {
        signs
            .iter()
            .take_while(|(when, _)| *when <= at)
            .last()
            .map(|&(_, sign)| sign)
    };
    let mut check = OutputCheck::default();
    let mut starts = std::collections::BTreeSet::new();
    for segment in segments {
        let at = origin + segment.actual_tick * cycles_per_tick;
        starts.insert(at);
        let sign = sign_at(at);
        let biased = levels == Levels::Trimmed && segment.level == 0;
        if sign == Some(segment.level) || (biased && sign.is_some()) {
            check.matched += 1;
        } else {
            check.problems.push(format!(
                "cycle {} {}: the output held {} on tick {}, not a level of sign {}",
                segment.cycle,
                segment.kind.name(),
                sign.map_or("nothing".into(), |sign| format!("a level of sign {sign}")),
                segment.actual_tick,
                segment.level
            ));
        }
    }
    // A change at no segment's start that drives a level: the power-up zero and a halt's zero
    // are no such change.
    check.stray = signs
        .iter()
        .filter(|(at, sign)| !starts.contains(at) && *sign != 0)
        .count();
    check
}

#[cfg(test)]
mod tests {
    use feeder_shared::SegmentKind;

    use super::*;

    fn segment(actual_tick: u64, level: i8) -> SegmentEvent {
        SegmentEvent {
            cycle: 1,
            kind: SegmentKind::Accelerate,
            planned_tick: actual_tick,
            actual_tick,
            ticks: 100,
            level,
            step: 1,
            steps: 1,
            slack_ticks: None,
        }
    }

    #[test]
    fn a_level_on_its_tick_matches_and_one_late_or_of_the_wrong_sign_does_not() {
        let changes = [
            Output::Dac {
                at: 1000,
                code: 2048,
            },
            Output::Dac {
                at: 1100,
                code: 3000,
            },
            Output::Dac {
                at: 1250,
                code: 1000,
            },
        ];
        let found = check(&changes, &[segment(100, 1)], 1000, 1, 2048, Levels::Planned);
        assert_eq!(
            (found.matched, found.problems.len(), found.stray),
            (1, 0, 1)
        );
        let late = check(&changes, &[segment(99, 1)], 1000, 1, 2048, Levels::Planned);
        assert_eq!(
            late.matched, 0,
            "the code came a tick after the segment's start"
        );
        let wrong = check(&changes, &[segment(250, 1)], 1000, 1, 2048, Levels::Planned);
        assert_eq!(
            wrong.problems.len(),
            1,
            "a negative code for a positive level"
        );
    }

    /// Under a closed loop a zero level carries the loop's bias, of either sign; a `±a` level
    /// of the wrong sign, and a segment on whose tick the output holds nothing yet, still fail.
    #[test]
    fn a_trimmed_zero_level_may_carry_a_bias_but_a_trimmed_a_keeps_its_sign() {
        let changes = [
            Output::Dac {
                at: 1000,
                code: 2050,
            },
            Output::Dac {
                at: 1100,
                code: 1000,
            },
        ];
        let found = check(&changes, &[segment(0, 0)], 1000, 1, 2048, Levels::Trimmed);
        assert_eq!(found.matched, 1, "{:?}", found.problems);
        let planned = check(&changes, &[segment(0, 0)], 1000, 1, 2048, Levels::Planned);
        assert_eq!(planned.matched, 0, "a bias is no planned zero");
        let wrong = check(&changes, &[segment(100, 1)], 1000, 1, 2048, Levels::Trimmed);
        assert_eq!(wrong.matched, 0, "a negative code for a trimmed +a");
        let early = check(&changes, &[segment(0, 0)], 999, 1, 2048, Levels::Trimmed);
        assert_eq!(
            early.matched, 0,
            "nothing on the output at the segment's tick"
        );
    }

    #[test]
    fn a_pwm_level_is_its_duty_with_its_direction_on_ticks_of_the_carrier() {
        let changes = [
            Output::Pwm {
                at: 1000,
                duty_counts: 0,
                forward: true,
            },
            Output::Pwm {
                at: 1000 + 2 * 8500,
                duty_counts: 4000,
                forward: false,
            },
        ];
        // 20 kHz ticks: 8 500 core cycles each.
        let found = check(
            &changes,
            &[segment(0, 0), segment(2, -1)],
            1000,
            8500,
            0,
            Levels::Planned,
        );
        assert_eq!((found.matched, found.stray), (2, 0), "{:?}", found.problems);
        let wrong = check(&changes, &[segment(2, 1)], 1000, 8500, 0, Levels::Planned);
        assert_eq!(wrong.matched, 0, "backward for a forward level");
    }
}
