//! The closed loop on a real plate: the plants it is designed for ([`envelope`]), the course from the first start to feeding ([`course`]),
//! identification of the drive at start-up ([`mod@identify`]), the cycle-rate loop that keeps the plate centred and its stroke right ([`cycle_loop`]) from the
//! planned motion of a cycle ([`shape`]), and track control with a part sensor ([`track`]).

pub mod course;
pub mod cycle_loop;
pub mod cycle_map;
pub mod disturbance;
pub mod envelope;
pub mod feed;
pub mod identify;
pub mod settle;
pub mod shape;
pub mod track;

pub use course::{
    mean_position_m, Course, CourseConfig, CourseError, CycleTrims, Decision, LateTrims,
    LoopReport, PositionSample, Probe, Stage,
};
pub use cycle_loop::{CycleLoop, LoopError, LoopLimits, Stroke, Trims};
pub use cycle_map::CycleMap;
pub use envelope::{Cause, Envelope, ENVELOPE};
pub use feed::{compensate, feed_rate_mps, FeedCompensation, FeedRequest, PlateModel};
pub use identify::{
    identify, identify_counted, identify_given, GainPrior, Identification, Identified,
    IdentifyError, IdentifyLimits, Latch,
};
pub use settle::Settle;
pub use shape::{CommandSegment, CycleShape, SegmentMotion};
pub use track::{Track, TrackConfig, TrackReport, TrackState};
