//! The protocol's two sizes: a command line in, a reply line out.

/// Longest command line accepted, in bytes, without its terminator and leading blanks.
pub const MAX_LINE_BYTES: usize = 64;
/// Capacity of a reply line in bytes, without its terminator. Longer replies are truncated.
pub const REPLY_CAPACITY: usize = 512;
