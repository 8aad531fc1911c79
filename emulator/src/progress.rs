//! A scripted run's progress, read from its decoded log as it streams past: the cycle begun last
//! and the emulated time, from the firmware's `EVT` segment lines ([`feeder_shared::event`]).

use std::io::{self, BufRead, BufReader, Read, Write};

use feeder_shared::event::{parse_line, Event};
use feeder_shared::scenario::QEMU_TICK_HZ;

/// How far a run has come.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Progress {
    /// The cycle (or idle period) begun last.
    pub cycle: u64,
    /// The output's time at that segment.
    pub emulated_s: f64,
}

impl Progress {
    /// Takes in one decoded log line; whether it moved the run on.
    pub fn update(&mut self, line: &str) -> bool {
        let Ok(Some(Event::Segment(segment))) = parse_line(line) else {
            return false;
        };
        self.cycle = segment.cycle;
        self.emulated_s = segment.actual_tick as f64 / f64::from(QEMU_TICK_HZ);
        true
    }
}

/// Copies the decoded `log` to `out` line by line as it comes, each line flushed at once, and
/// hands `seen` the progress after every line that moved it. Ends at the end of `log`.
pub fn relay(
    log: impl Read,
    mut out: impl Write,
    mut seen: impl FnMut(&Progress),
) -> io::Result<()> {
    let mut progress = Progress::default();
    let mut reader = BufReader::new(log);
    let mut line = Vec::new();
    while reader.read_until(b'\n', &mut line)? > 0 {
        out.write_all(&line)?;
        out.flush()?;
        if progress.update(&String::from_utf8_lossy(&line)) {
            seen(&progress);
        }
        line.clear();
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    const LOG: &str = "INFO  feeder firmware up on QEMU mps2-an386\n\
        EVT plan tick=0 period_s=0.02 duty=0.586 stroke_m=0.0025 clock_hz=1000000 ramp=25\n\
        EVT seg cycle=0 kind=idle planned=0 actual=0 ticks=20000 level=0 step=0 steps=25\n\
        EVT start tick=20000\n\
        EVT seg cycle=1 kind=accelerate planned=20000 actual=20000 ticks=1713 level=1 step=1 steps=25 slack=19830\n\
        EVT seg cycle=1 kind=plateau planned=21713 actual=21713 ticks=8000 level=0 step=1 steps=25 slack=1700\n";

    #[test]
    fn the_log_passes_unchanged_and_each_segment_moves_the_run_on() {
        let mut out = Vec::new();
        let mut seen = Vec::new();
        relay(LOG.as_bytes(), &mut out, |progress| seen.push(*progress)).unwrap();
        assert_eq!(out, LOG.as_bytes());
        assert_eq!(
            seen,
            [
                Progress {
                    cycle: 0,
                    emulated_s: 0.0
                },
                Progress {
                    cycle: 1,
                    emulated_s: 0.02
                },
                Progress {
                    cycle: 1,
                    emulated_s: 0.021713
                },
            ]
        );
    }

    #[test]
    fn a_last_line_without_its_end_is_passed_on_too() {
        let mut out = Vec::new();
        relay("INFO  no end".as_bytes(), &mut out, |_| {}).unwrap();
        assert_eq!(out, b"INFO  no end");
    }
}
