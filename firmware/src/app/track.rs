//! Track control (on a board with a part sensor): the light barrier near the track's end, read
//! by the shared `Track`, pauses the feeder while the track is full and resumes it when it has
//! room (`SupervisorEvent::TrackFull`, `TrackEmpty`); the parts per minute go to `status`.

use defmt::info;
use embassy_futures::select::{select, Either};
use embassy_time::{Duration, Instant, Timer};
use feeder_shared::closed_loop::{Track, TrackState};
use feeder_shared::SupervisorEvent;

use crate::mailbox::REQUESTS;
use crate::ports::PartSensor;
use crate::{configured, status};

type Barrier = <crate::board::Hardware as crate::ports::Parts>::PartSensor;

/// Reads the barrier at each change, and again when a state change falls due without one.
#[embassy_executor::task]
pub async fn track_task(mut barrier: Barrier) {
    let mut track = Track::new(configured::get().track);
    let mut blocked = false;
    status::publish_track(track.report());
    loop {
        let due = track
            .change_due_s()
            .map(|s| Duration::from_micros((s * 1e6) as u64 + 1));
        let reading = match due {
            Some(due) => match select(barrier.changed(), Timer::after(due)).await {
                Either::First(reading) => reading,
                Either::Second(()) => blocked,
            },
            None => barrier.changed().await,
        };
        blocked = reading;
        let before = track.state();
        let now_s = Instant::now().as_micros() as f64 * 1e-6;
        let state = track.update(now_s, blocked);
        if state != before {
            info!("track: {=str}", state.name());
            REQUESTS
                .send(match state {
                    TrackState::Full => SupervisorEvent::TrackFull,
                    TrackState::Empty => SupervisorEvent::TrackEmpty,
                })
                .await;
        }
        status::publish_track(track.report());
    }
}
