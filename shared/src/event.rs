//! The firmware's event stream (`EVT` lines): one type, its text encoding and its parser.
