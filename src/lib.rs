//! vizsim: a cycle-accurate simulator of hardware volume ray casting architectures.
//! See docs/ARCHITECTURE.md for the map of the crate.

// Per-axis loops over [_; 3] index several arrays at once; iterator chains would hide that.
#![allow(clippy::needless_range_loop)]

pub mod advise;
pub mod arch;
pub mod camera;
pub mod compare;
pub mod config;
pub mod dynamic;
pub mod error;
pub mod experiment;
pub mod figures;
pub mod functional;
pub mod input;
pub mod leapvalues;
pub mod occupancy;
pub mod output;
pub mod path;
pub mod plot;
pub mod precision;
pub mod render;
pub mod run;
pub mod shading;
pub mod skip;
pub mod tables;
pub mod text;
pub mod transfer;
pub mod volume;
// 2-way blocking (issue 16).
pub mod blocking;
pub mod bound;
// Ray start and end (issue 15).
pub mod bricks;
pub mod budget;
pub mod clip;
// Iso-surface mode (issue 15, part 5).
pub mod iso;

pub use error::{Error, Result};

/// `eprintln!` for notes and errors: a line on standard error, where a standard error that
/// cannot be written (a full log disk, `2>/dev/full`) is ignored instead of panicking, so that a
/// note never stops a command and an error still exits with status 1.
#[macro_export]
macro_rules! note {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr(), $($arg)*);
    }};
}
