//! A stack overflow on purpose, for the board's fault drill and the emulated scenarios: a
//! recursion without bound, which faults once the stack crosses the bottom of RAM (flip-link)
//! and so reaches the HardFault entry (`crate::fault`).

/// Calls itself until the stack runs out. Each call keeps an array that `black_box` makes the
/// compiler put on the stack and reads it after the inner call, so the recursion stays a
/// recursion.
#[allow(unconditional_recursion)]
#[inline(never)]
pub fn recurse(depth: u32) -> u32 {
    let mut frame = [depth; 64];
    core::hint::black_box(&mut frame);
    recurse(depth.wrapping_add(1)).wrapping_add(frame[depth as usize % frame.len()])
}
