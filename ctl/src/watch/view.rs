//! `watch`'s view: the last records as charts (position, trims, slack, parts per minute), a
//! header with the newest record and a footer with the keys. Pure: it draws what [`View`] holds,
//! so a test backend renders it exactly as a terminal does.

use std::collections::VecDeque;

use feeder_shared::telemetry::Record;
use ratatui::crossterm::event::KeyCode;
use ratatui::layout::{Constraint, Layout, Rect};
use ratatui::style::{Color, Style};
use ratatui::symbols::Marker;
use ratatui::text::Line;
use ratatui::widgets::{Axis, Block, Chart, Dataset, GraphType, Paragraph};
use ratatui::Frame;

/// Records kept for the view: the widest window.
const KEPT: usize = 20_000;
/// The windows `+` and `-` step through, in cycles.
const WINDOWS: [usize; 6] = [50, 100, 250, 500, 1000, 5000];

/// A chart of the view.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Panel {
    Position,
    Trims,
    Slack,
    Parts,
}

impl Panel {
    pub const ALL: [Panel; 4] = [Panel::Position, Panel::Trims, Panel::Slack, Panel::Parts];

    fn title(self) -> &'static str {
        match self {
            Panel::Position => "mean position, um",
            Panel::Trims => "trims (+a, -a factors)",
            Panel::Slack => "least preload slack, ticks",
            Panel::Parts => "parts per minute",
        }
    }

    /// Decimals of the value axis's labels.
    fn decimals(self) -> usize {
        match self {
            Panel::Position | Panel::Parts => 1,
            Panel::Trims => 4,
            Panel::Slack => 0,
        }
    }

    /// The panel's signals: a name, a colour and the value of a record.
    fn signals(self) -> &'static [(&'static str, Color, fn(&Record) -> Option<f64>)] {
        match self {
            Panel::Position => &[("mean", Color::Cyan, |r| r.mean_m.map(|m| m * 1e6))],
            Panel::Trims => &[
                ("+a", Color::Green, |r| r.trim_positive),
                ("-a", Color::Magenta, |r| r.trim_negative),
            ],
            Panel::Slack => &[("slack", Color::Blue, |r| r.slack_ticks.map(f64::from))],
            Panel::Parts => &[("parts", Color::White, |r| r.parts_per_minute)],
        }
    }
}

/// What `watch` shows.
#[derive(Debug, Clone)]
pub struct View {
    records: VecDeque<Record>,
    /// The records shown while paused (recording goes on).
    frozen: Option<Vec<Record>>,
    window: usize,
    shown: [bool; 4],
    source: String,
}

impl View {
    pub fn new(source: String) -> Self {
        View {
            records: VecDeque::new(),
            frozen: None,
            window: 2,
            shown: [true; 4],
            source,
        }
    }

    pub fn push(&mut self, record: Record) {
        if self.records.len() == KEPT {
            self.records.pop_front();
        }
        self.records.push_back(record);
    }

    /// Applies a key; true when it asks to leave.
    pub fn key(&mut self, key: KeyCode) -> bool {
        match key {
            KeyCode::Char('q') | KeyCode::Esc => return true,
            KeyCode::Char(' ') | KeyCode::Char('p') => {
                self.frozen = match self.frozen {
                    Some(_) => None,
                    None => Some(self.records.iter().copied().collect()),
                }
            }
            KeyCode::Char('+') => self.window = self.window.saturating_sub(1),
            KeyCode::Char('-') => self.window = (self.window + 1).min(WINDOWS.len() - 1),
            KeyCode::Char(digit @ '1'..='4') => {
                let index = digit as usize - '1' as usize;
                self.shown[index] = !self.shown[index];
            }
            _ => {}
        }
        false
    }

    /// The records in the window, oldest first.
    fn window(&self) -> Vec<Record> {
        let all: Vec<Record> = match &self.frozen {
            Some(frozen) => frozen.clone(),
            None => self.records.iter().copied().collect(),
        };
        let newest = all.last().map_or(0, |record| record.cycle);
        let from = newest.saturating_sub(WINDOWS[self.window] as u64);
        all.into_iter()
            .filter(|record| record.cycle >= from)
            .collect()
    }

    /// Draws the view into `frame`.
    pub fn draw(&self, frame: &mut Frame) {
        let records = self.window();
        let panels: Vec<Panel> = Panel::ALL
            .into_iter()
            .zip(self.shown)
            .filter_map(|(panel, shown)| shown.then_some(panel))
            .collect();
        let mut constraints = vec![Constraint::Length(3)];
        constraints.extend(panels.iter().map(|_| Constraint::Fill(1)));
        constraints.push(Constraint::Length(1));
        let areas = Layout::vertical(constraints).split(frame.area());
        frame.render_widget(self.header(&records), areas[0]);
        for (panel, area) in panels.iter().zip(areas.iter().skip(1)) {
            draw_panel(frame, *panel, &records, *area);
        }
        let footer = Paragraph::new(Line::from(format!(
            "q quit  space {}  +/- window ({} cycles)  1-4 charts",
            if self.frozen.is_some() {
                "resume"
            } else {
                "pause"
            },
            WINDOWS[self.window]
        )));
        frame.render_widget(footer, areas[areas.len() - 1]);
    }

    fn header(&self, records: &[Record]) -> Paragraph<'static> {
        let [first, second] = match records.last() {
            Some(record) => summary(record),
            None => ["no telemetry yet".to_string(), String::new()],
        };
        let paused = if self.frozen.is_some() {
            " (paused)"
        } else {
            ""
        };
        Paragraph::new(vec![
            Line::from(format!("feeder watch: {}{}", self.source, paused)),
            Line::from(first),
            Line::from(second),
        ])
    }
}

/// The newest record in words, for the header's two lines.
fn summary(record: &Record) -> [String; 2] {
    let number = |value: Option<f64>, scale: f64, decimals: usize| match value {
        Some(value) => format!("{:.decimals$}", value * scale),
        None => "-".into(),
    };
    [
        format!(
            "cycle {}  {}  loop {}  mean {} um  peak {} um",
            record.cycle,
            record.phase.name(),
            record.stage.map_or("-", |stage| stage.name()),
            number(record.mean_m, 1e6, 1),
            number(record.peak_m, 1e6, 1),
        ),
        format!(
            "trims {} / {}  bias {} m/s2  slack {} ticks  parts {}/min  fault {}",
            number(record.trim_positive, 1.0, 5),
            number(record.trim_negative, 1.0, 5),
            number(record.bias_mps2, 1.0, 4),
            record
                .slack_ticks
                .map_or("-".into(), |slack| slack.to_string()),
            number(record.parts_per_minute, 1.0, 1),
            record.fault.map_or("none", |fault| fault.name()),
        ),
    ]
}

fn draw_panel(frame: &mut Frame, panel: Panel, records: &[Record], area: Rect) {
    let series: Vec<(&str, Color, Vec<(f64, f64)>)> = panel
        .signals()
        .iter()
        .map(|(name, color, value)| {
            let points = records
                .iter()
                .filter_map(|record| value(record).map(|v| (record.cycle as f64, v)))
                .collect();
            (*name, *color, points)
        })
        .collect();
    let (x_min, x_max) = match (records.first(), records.last()) {
        (Some(first), Some(last)) => (
            first.cycle as f64,
            (last.cycle as f64).max(first.cycle as f64 + 1.0),
        ),
        _ => (0.0, 1.0),
    };
    let values = series
        .iter()
        .flat_map(|(_, _, points)| points.iter().map(|&(_, y)| y));
    let (y_min, y_max) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), y| {
        (lo.min(y), hi.max(y))
    });
    let (y_min, y_max) = match y_min.is_finite() {
        true if y_max > y_min => (y_min, y_max),
        true => (y_min - 1.0, y_max + 1.0),
        false => (0.0, 1.0),
    };
    let datasets = series
        .iter()
        .map(|(name, color, points)| {
            Dataset::default()
                .name(*name)
                .marker(Marker::Braille)
                .graph_type(GraphType::Line)
                .style(Style::default().fg(*color))
                .data(points)
        })
        .collect();
    let decimals = panel.decimals();
    let label = |value: f64| format!("{value:.decimals$}");
    let chart = Chart::new(datasets)
        .block(Block::bordered().title(panel.title()))
        .x_axis(
            Axis::default()
                .bounds([x_min, x_max])
                .labels([format!("{x_min:.0}"), format!("{x_max:.0}")]),
        )
        .y_axis(
            Axis::default()
                .bounds([y_min, y_max])
                .labels([label(y_min), label(y_max)]),
        );
    frame.render_widget(chart, area);
}

#[cfg(test)]
mod tests;
