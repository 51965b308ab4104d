//! vizsim: a cycle-accurate simulator of hardware volume ray casting architectures.
//! See docs/ARCHITECTURE.md for the map of the crate.

pub mod error;
pub mod volume;

pub use error::{Error, Result};
