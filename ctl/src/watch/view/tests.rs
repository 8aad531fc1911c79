use feeder_shared::closed_loop::{Stage, TrackState};
use feeder_shared::Phase;
use ratatui::backend::TestBackend;
use ratatui::Terminal;

use super::*;

/// The golden rendering, in `tests/expected/` (`FEEDER_BLESS=overwrite` writes it anew).
const GOLDEN: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../tests/expected/watch-view.txt"
);

/// 300 cycles of a plate settling onto its centre while the parts come.
fn records() -> Vec<Record> {
    (0..300u64)
        .map(|cycle| {
            let t = cycle as f64;
            Record {
                stage: Some(Stage::Feeding),
                mean_m: Some(40e-6 * (-t / 60.0).exp() * (t / 9.0).cos()),
                peak_m: Some(1.25e-3 + 20e-6 * (t / 30.0).sin()),
                trim_positive: Some(1.0 + 0.002 * (-t / 80.0).exp()),
                trim_negative: Some(1.0 - 0.001 * (-t / 80.0).exp()),
                bias_mps2: Some(0.01),
                slack_ticks: Some(19_900 + (cycle % 7) as u32 * 5),
                edge_work_cycles: None,
                cpu_load_pct: None,
                track: Some(TrackState::Empty),
                parts_per_minute: Some((t / 5.0).min(40.0)),
                ..Record::new(1000 + cycle, 20_000 + 20 * cycle, Phase::Running, None)
            }
        })
        .collect()
}

fn rendered(view: &View) -> String {
    let mut terminal = Terminal::new(TestBackend::new(100, 34)).expect("a test terminal");
    terminal
        .draw(|frame| view.draw(frame))
        .expect("the view draws");
    let buffer = terminal.backend().buffer();
    let mut text = String::new();
    for y in 0..buffer.area.height {
        let line: String = (0..buffer.area.width)
            .map(|x| buffer[(x, y)].symbol())
            .collect();
        text.push_str(line.trim_end());
        text.push('\n');
    }
    text
}

#[test]
fn the_view_renders_as_its_snapshot() {
    let mut view = View::new("TCP 127.0.0.1:4444".into());
    for record in records() {
        view.push(record);
    }
    view.key(KeyCode::Char('-'));
    let text = rendered(&view);
    if std::env::var_os("FEEDER_BLESS").is_some_and(|value| value == "overwrite") {
        std::fs::write(GOLDEN, &text).expect("the snapshot is written");
    }
    let golden = std::fs::read_to_string(GOLDEN).expect("tests/expected/watch-view.txt");
    assert_eq!(
        text, golden,
        "the view changed; FEEDER_BLESS=overwrite writes it anew"
    );
}

#[test]
fn keys_pause_zoom_and_pick_the_charts() {
    let mut view = View::new("test".into());
    for record in records() {
        view.push(record);
    }
    assert_eq!(view.window().len(), 251, "250 cycles back from the newest");
    view.key(KeyCode::Char('+'));
    assert_eq!(view.window().len(), 101);
    view.key(KeyCode::Char('-'));
    view.key(KeyCode::Char('-'));
    assert_eq!(view.window().len(), 300, "500 cycles: all there is");
    view.key(KeyCode::Char(' '));
    view.push(Record::new(2000, 0, Phase::Stopped, None));
    assert_eq!(view.window().last().map(|r| r.cycle), Some(1299), "paused");
    view.key(KeyCode::Char(' '));
    assert_eq!(view.window().last().map(|r| r.cycle), Some(2000));
    view.key(KeyCode::Char('2'));
    assert!(!rendered(&view).contains("trims (+a, -a factors)"));
    assert!(view.key(KeyCode::Char('q')));
}
