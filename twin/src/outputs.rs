//! What the board's outputs did, as the twin's pins and registers show it, and its check
//! against the segments the firmware reports: every segment's level must reach the DAC's output
//! on the segment's own tick (TIM2's update latching the preloaded code through TRGO), with the
//! level's sign about the zero code, and the output must change nowhere else. The firmware's log
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

/// Checks `changes` against `segments` on a timeline whose tick 0 is core time `origin`, with
/// `zero_code` the code of zero acceleration.
pub fn check(
    changes: &[Output],
    segments: &[SegmentEvent],
    origin: Cycles,
    zero_code: u32,
) -> OutputCheck {
    let latches: Vec<(Cycles, u32)> = changes
        .iter()
        .filter_map(|change| match *change {
            Output::Dac { at, code } => Some((at, code)),
            Output::Enable { .. } | Output::Reset { .. } => None,
        })
        .collect();
    let code_at = |at: Cycles| {
        latches
            .iter()
            .take_while(|(when, _)| *when <= at)
            .last()
            .map(|&(_, code)| code)
    };
    let mut check = OutputCheck::default();
    let mut starts = std::collections::BTreeSet::new();
    for segment in segments {
        let at = origin + segment.actual_tick;
        starts.insert(at);
        let sign = code_at(at).map(|code| (code as i64 - zero_code as i64).signum() as i8);
        if sign == Some(segment.level) {
            check.matched += 1;
        } else {
            check.problems.push(format!(
                "cycle {} {}: the output held {} on tick {}, not a level of sign {}",
                segment.cycle,
                segment.kind.name(),
                code_at(at).map_or("nothing".into(), |code| format!("code {code}")),
                segment.actual_tick,
                segment.level
            ));
        }
    }
    check.stray = latches
        .iter()
        .filter(|(at, code)| !starts.contains(at) && *code != zero_code)
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
        let found = check(&changes, &[segment(100, 1)], 1000, 2048);
        assert_eq!(
            (found.matched, found.problems.len(), found.stray),
            (1, 0, 1)
        );
        let late = check(&changes, &[segment(99, 1)], 1000, 2048);
        assert_eq!(
            late.matched, 0,
            "the code came a tick after the segment's start"
        );
        let wrong = check(&changes, &[segment(250, 1)], 1000, 2048);
        assert_eq!(
            wrong.problems.len(),
            1,
            "a negative code for a positive level"
        );
    }
}
