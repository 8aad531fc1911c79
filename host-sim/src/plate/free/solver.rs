//! The free slide's solver: the course through each segment, chunk by chunk, going on after
//! the part's events and across segments that hold the target.

use crate::plate::linear::{State, F, Q, V, X};
use crate::plate::model::{ContactEvent, Part, PlateModel, Slide};
use crate::plate::solver::{Solver, StretchEnd};

use super::chunk::Chunk;
use super::end_maps::Ends;
use super::slide::FreeSlide;

/// The plate on a free slide and the part on it, through each segment event by event. The plate
/// does not feel the part, so a chunk of its motion, with its turning points and its first
/// contact with an end stop, serves every contact the part passes through within it: after the
/// part's event the course goes on in the same chunk. Where the next segment holds the target,
/// chunks run on over it, and the course goes on across the boundary.
#[derive(Debug, Clone)]
pub struct FreeSolver {
    free: FreeSlide,
    target_n: f64,
    duration_s: f64,
    /// How long the target holds from the segment's start: its duration or more.
    holds_s: f64,
    /// The current chunk, if `valid`.
    chunk: Chunk,
    valid: bool,
    /// Where the last event or the segment's end left the course.
    resume: Option<Resume>,
    /// The ends of chunks of recent lengths.
    ends: Ends,
}

impl FreeSolver {
    /// The solver of `model`'s free slide; `None` if the slide has Coulomb friction, or if the
    /// current loop's rate is one of the slide's own (the mode cannot be split off).
    pub fn new(model: &PlateModel) -> Option<FreeSolver> {
        FreeSlide::new(model).map(|free| FreeSolver {
            free,
            target_n: 0.0,
            duration_s: 0.0,
            holds_s: 0.0,
            chunk: Chunk::default(),
            valid: false,
            resume: None,
            ends: Ends::default(),
        })
    }
}

/// An event's or a segment's end's place in its chunk, to go on from if the next call starts
/// there.
#[derive(Debug, Clone, Copy)]
struct Resume {
    /// The segment's time of the event, as the caller adds it up (0 for the next segment).
    offset_s: f64,
    /// Its time in the chunk.
    in_chunk_s: f64,
    /// The state returned there.
    state: State,
    /// At a segment's end inside the chunk, what lies ahead of it there.
    ahead: Option<Ahead>,
}

/// The part's first event in the chunk after a segment's end inside it (`None` up to the
/// chunk's end), for the contact it had there.
#[derive(Debug, Clone, Copy)]
struct Ahead {
    part: Part,
    first: Option<(ContactEvent, f64)>,
}

fn plate_of(z: &State) -> [f64; 4] {
    [z[X], z[V], z[F], z[Q]]
}

impl Solver for FreeSolver {
    /// Where the last segment held the same target and ended inside its chunk, the course goes
    /// on in that chunk.
    fn begin(&mut self, target_n: f64, duration_s: f64, holds_s: f64) {
        let goes_on = self.valid
            && target_n == self.target_n
            && self.resume.is_some_and(|resume| resume.ahead.is_some());
        if goes_on {
            if let Some(resume) = self.resume.as_mut() {
                resume.offset_s = 0.0;
            }
        } else {
            self.valid = false;
            self.resume = None;
        }
        self.target_n = target_n;
        self.duration_s = duration_s;
        self.holds_s = holds_s.max(duration_s);
    }

    /// Where `z` is the state returned at the last event, with only the part changed since,
    /// and `offset_s` that event's time, the course goes on in that event's chunk. The turning
    /// points of a chunk whose reach stays below `peak_m` are not sought: they could not raise
    /// it.
    fn next_event(
        &mut self,
        _slide: Slide,
        part: Part,
        z: &State,
        offset_s: f64,
        peak_m: &mut f64,
    ) -> StretchEnd {
        let free = &self.free;
        let duration_s = (self.duration_s - offset_s).max(0.0);
        let holds_s = (self.holds_s - offset_s).max(0.0);
        let mut z = *z;
        // The call's time of the chunk's start, the chunk's time of `z`, and the part's first
        // event after it if known.
        let (mut start_s, mut from_s, mut ahead) = match self.resume.take() {
            Some(resume)
                if self.valid
                    && resume.offset_s == offset_s
                    && plate_of(&resume.state) == plate_of(&z) =>
            {
                // The part's event ahead holds if nothing has changed since.
                let ahead = resume
                    .ahead
                    .filter(|ahead| resume.state == z && ahead.part == part);
                (-resume.in_chunk_s, resume.in_chunk_s, ahead)
            }
            _ => {
                self.valid = false;
                (0.0, 0.0, None)
            }
        };
        loop {
            if !self.valid {
                if duration_s - start_s <= 0.0 {
                    return (None, z);
                }
                let length_s = free.longest_chunk_s.min(holds_s - start_s);
                self.chunk
                    .start(free, self.target_n, &z, length_s, *peak_m, &mut self.ends);
                self.valid = true;
                from_s = 0.0;
            }
            let chunk = &mut self.chunk;
            let first = match ahead.take() {
                Some(ahead) => ahead.first,
                None => chunk.part_event(free, part, &z, from_s),
            };
            // The segment's end in the chunk's time, if it comes before the chunk's.
            let length_s = chunk.length_s;
            let end_s = duration_s - start_s;
            let until_s = end_s.min(length_s);
            for &t in chunk.turns.as_slice() {
                if t > from_s && t <= until_s && first.is_none_or(|(_, at)| t <= at) {
                    *peak_m = peak_m.max(chunk.position(t).abs());
                }
            }
            if let Some((event, t)) = first.filter(|&(_, t)| t <= until_s) {
                let state = chunk.state(free, t, part, &z, from_s);
                let elapsed_s = start_s + t;
                self.resume = Some(Resume {
                    offset_s: offset_s + elapsed_s,
                    in_chunk_s: t,
                    state,
                    ahead: None,
                });
                return (Some((event, elapsed_s)), state);
            }
            if end_s < length_s {
                let state = chunk.state(free, end_s, part, &z, from_s);
                self.resume = Some(Resume {
                    offset_s: offset_s + duration_s,
                    in_chunk_s: end_s,
                    state,
                    ahead: Some(Ahead { part, first }),
                });
                return (None, state);
            }
            z = chunk.state(free, length_s, part, &z, from_s);
            self.valid = false;
            if end_s <= length_s {
                return (None, z);
            }
            start_s += length_s;
        }
    }
}
