//! `feeder-ctl watch`: the board's telemetry live in the terminal (`view`), recorded to CSV on
//! request; headless with `--seconds`, for scripts and tests.

mod view;

use std::io;
use std::path::Path;
use std::time::{Duration, Instant};

use feeder_shared::telemetry::Record;
use ratatui::crossterm::event::{self, Event, KeyEventKind};

use crate::console::Console;
use crate::recording;
use view::View;

/// How long each look at the link waits.
const LISTEN: Duration = Duration::from_millis(20);
/// How often the live view is drawn.
const FRAME: Duration = Duration::from_millis(50);

/// Listens for `seconds` of wall time with telemetry on; writes the records to `record` if
/// given. The records received.
pub fn headless(console: &mut Console, seconds: f64, record: Option<&Path>) -> io::Result<usize> {
    start(console)?;
    let deadline = Instant::now() + Duration::from_secs_f64(seconds);
    let mut records = Vec::new();
    let listened = (|| {
        while Instant::now() < deadline {
            console.listen(LISTEN)?;
            records.extend(console.take_telemetry());
        }
        Ok(())
    })();
    finish(console, record, records, listened)
}

/// The live view until the operator leaves it (`q`); writes the records to `record` if given.
pub fn live(console: &mut Console, record: Option<&Path>, source: String) -> io::Result<usize> {
    start(console)?;
    let mut view = View::new(source);
    let mut records = Vec::new();
    let mut terminal = ratatui::init();
    let shown = (|| {
        let mut drawn = Instant::now() - FRAME;
        loop {
            console.listen(LISTEN)?;
            for record in console.take_telemetry() {
                view.push(record);
                records.push(record);
            }
            while event::poll(Duration::ZERO)? {
                if let Event::Key(key) = event::read()? {
                    if key.kind == KeyEventKind::Press && view.key(key.code) {
                        return Ok(());
                    }
                }
            }
            if drawn.elapsed() >= FRAME {
                terminal.draw(|frame| view.draw(frame))?;
                drawn = Instant::now();
            }
        }
    })();
    ratatui::restore();
    finish(console, record, records, shown)
}

fn start(console: &mut Console) -> io::Result<()> {
    let reply = console.command("telemetry on")?;
    if !reply.starts_with("OK") {
        return Err(io::Error::other(format!(
            "the board refused telemetry: {reply}"
        )));
    }
    Ok(())
}

/// Turns telemetry off and writes what was recorded, also after a failure.
fn finish(
    console: &mut Console,
    record: Option<&Path>,
    mut records: Vec<Record>,
    outcome: io::Result<()>,
) -> io::Result<usize> {
    let stopped = console.command("telemetry off").map(drop);
    records.extend(console.take_telemetry());
    if let Some(path) = record {
        recording::write(path, &records)?;
    }
    outcome.and(stopped).map(|()| records.len())
}
