//! A QEMU run's progress on standard error while it runs: the cycle begun last against the cycle
//! at which the stop is requested, and the emulated time against the wall time, on one line
//! rewritten in place. Only on a terminal: in a log or a pipe it would be noise.

use std::io::Write;
use std::time::{Duration, Instant};

use feeder_emulator::Progress;

/// The least time between two updates of the line.
const UPDATE_INTERVAL: Duration = Duration::from_millis(250);

/// Erases the line the cursor is on and returns to its start.
const ERASE_LINE: &str = "\r\x1b[2K";

/// The progress line of one run, written to `out`.
pub struct Meter<W: Write> {
    out: W,
    /// Whether `out` is a terminal: otherwise nothing is written.
    terminal: bool,
    stop_at_cycle: u32,
    started: Instant,
    last_update: Option<Instant>,
}

impl<W: Write> Meter<W> {
    pub fn new(out: W, terminal: bool, stop_at_cycle: u32) -> Self {
        Meter {
            out,
            terminal,
            stop_at_cycle,
            started: Instant::now(),
            last_update: None,
        }
    }

    /// Rewrites the line with `progress`, at most every [`UPDATE_INTERVAL`].
    pub fn show(&mut self, progress: &Progress) {
        let now = Instant::now();
        let due = self
            .last_update
            .is_none_or(|last| now.duration_since(last) >= UPDATE_INTERVAL);
        if !self.terminal || !due {
            return;
        }
        self.last_update = Some(now);
        let wall_s = now.duration_since(self.started).as_secs_f64();
        // A progress line that cannot be written is left out; the run goes on.
        let _ = write!(
            self.out,
            "{ERASE_LINE}xtask: QEMU at cycle {} (stop at {}), {:.2} s emulated in {:.1} s",
            progress.cycle, self.stop_at_cycle, progress.emulated_s, wall_s
        );
        let _ = self.out.flush();
    }

    /// Erases the line, so that what follows starts on a clean one.
    pub fn finish(&mut self) {
        if self.last_update.is_some() {
            let _ = write!(self.out, "{ERASE_LINE}");
            let _ = self.out.flush();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const AT_CYCLE_12: Progress = Progress {
        cycle: 12,
        emulated_s: 0.24,
    };

    #[test]
    fn on_a_terminal_the_line_shows_cycles_and_times_then_is_erased() {
        let mut out = Vec::new();
        let mut meter = Meter::new(&mut out, true, 300);
        meter.show(&AT_CYCLE_12);
        meter.show(&Progress {
            cycle: 13,
            emulated_s: 0.26,
        });
        meter.finish();
        let text = String::from_utf8(out).unwrap();
        assert!(
            text.starts_with("\r\x1b[2Kxtask: QEMU at cycle 12 (stop at 300), 0.24 s emulated in "),
            "{text:?}"
        );
        assert!(!text.contains("cycle 13"), "updated too often: {text:?}");
        assert!(text.ends_with(" s\r\x1b[2K"), "{text:?}");
    }

    #[test]
    fn elsewhere_nothing_is_written() {
        let mut out = Vec::new();
        let mut meter = Meter::new(&mut out, false, 300);
        meter.show(&AT_CYCLE_12);
        meter.finish();
        assert!(out.is_empty());
    }
}
