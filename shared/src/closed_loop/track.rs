//! Track control with one part sensor, as vibratory-feeder controllers do it: a light barrier
//! near the end of the track. Blocked for `full_after_s` without a break, the track is full and
//! the feeder pauses; clear for `empty_after_s`, it has room and the feeder runs again. The
//! barrier's rising edges, one per part, give the parts per minute.

use heapless::Deque;

/// The hysteresis of a track.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TrackConfig {
    pub full_after_s: f64,
    pub empty_after_s: f64,
}

/// Whether the track has room for more parts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum TrackState {
    /// Room: feed.
    Empty,
    /// Full: pause.
    Full,
}

impl TrackState {
    /// The state's name in replies and logs.
    pub const fn name(self) -> &'static str {
        match self {
            TrackState::Empty => "room",
            TrackState::Full => "full",
        }
    }
}

/// What track control reports (the console's `status`).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TrackReport {
    pub state: TrackState,
    pub parts_per_minute: f64,
}

/// Parts counted for the rate, at most.
const RATE_PARTS: usize = 16;

/// The track's state from the barrier's readings.
#[derive(Debug, Clone)]
pub struct Track {
    config: TrackConfig,
    state: TrackState,
    /// The barrier's last reading and since when it has read so.
    blocked: bool,
    since_s: f64,
    last_s: f64,
    arrivals_s: Deque<f64, RATE_PARTS>,
}

impl Track {
    /// A track that starts empty with the barrier clear at time 0.
    pub fn new(config: TrackConfig) -> Self {
        Track {
            config,
            state: TrackState::Empty,
            blocked: false,
            since_s: 0.0,
            last_s: 0.0,
            arrivals_s: Deque::new(),
        }
    }

    /// The barrier read `blocked` at `t_s` (not before the previous reading); the state after it.
    pub fn update(&mut self, t_s: f64, blocked: bool) -> TrackState {
        let t_s = t_s.max(self.last_s);
        self.last_s = t_s;
        if blocked != self.blocked {
            self.blocked = blocked;
            self.since_s = t_s;
            if blocked {
                if self.arrivals_s.is_full() {
                    self.arrivals_s.pop_front();
                }
                // Cannot fail: a slot was freed above.
                let _ = self.arrivals_s.push_back(t_s);
            }
        }
        let held_s = t_s - self.since_s;
        self.state = match (self.state, self.blocked) {
            (TrackState::Empty, true) if held_s >= self.config.full_after_s => TrackState::Full,
            (TrackState::Full, false) if held_s >= self.config.empty_after_s => TrackState::Empty,
            (state, _) => state,
        };
        self.state
    }

    pub fn state(&self) -> TrackState {
        self.state
    }

    /// How long the barrier must keep its reading from now for the state to change, if it is
    /// on its way to a change.
    pub fn change_due_s(&self) -> Option<f64> {
        let held_s = self.last_s - self.since_s;
        match (self.state, self.blocked) {
            (TrackState::Empty, true) => Some((self.config.full_after_s - held_s).max(0.0)),
            (TrackState::Full, false) => Some((self.config.empty_after_s - held_s).max(0.0)),
            _ => None,
        }
    }

    /// The state and the parts per minute.
    pub fn report(&self) -> TrackReport {
        TrackReport {
            state: self.state,
            parts_per_minute: self.parts_per_minute(),
        }
    }

    /// Parts per minute over the last parts counted (at most 16): 0 before the second part.
    pub fn parts_per_minute(&self) -> f64 {
        match (self.arrivals_s.front(), self.arrivals_s.back()) {
            (Some(first), Some(last)) if last > first => {
                60.0 * (self.arrivals_s.len() - 1) as f64 / (last - first)
            }
            _ => 0.0,
        }
    }
}
