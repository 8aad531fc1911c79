//! Cross-crate tests live in `tests/`.

/// The worst work per edge under QEMU that the tests allow, in instructions
/// (`feeder_emulator::NS_PER_INSTRUCTION` each): from the edge, when the output switched,
/// through the wake-up, the `EVT` trace and the supervision to the preload of the next segment.
/// Measured: 10,765 at most for the scripted image (the edge that takes the start request and
/// the new plan, with its log lines), about 4,200 on average, in 1000 cycles at 50 and at
/// 100 Hz, about 2900 of each edge's instructions being the `EVT seg` line; 14,940 for the
/// closed-loop image, whose cycle starts also exchange with the plant, log the capture and hand
/// the boundary to the closed loop.
pub const EDGE_WORK_BUDGET_INSTRUCTIONS: f64 = 16_000.0;
